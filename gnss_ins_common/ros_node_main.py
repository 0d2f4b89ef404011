"""The ``main`` shared by the gnss_ins node executables.

The nodes spin rclpy's EventsExecutor (``rclpy.experimental``) when this rclpy has it: it takes
each message from rcl's on-new-message callback in C++, where SingleThreadedExecutor rebuilds its
whole wait set in Python for every message (ins_fusion_node at 134 Hz: about half of its CPU,
docs/benchmarks.md). It is spun ``spin_until_future_complete`` with a time-out in a loop: its
``spin()`` busy-waits in rclpy 7.1 (a full core). ``GNSS_INS_EXECUTOR=single`` in the
environment selects SingleThreadedExecutor instead.

Ctrl-C and SIGTERM are a stop request that the spin loop reads between its waits (``StopSignals``),
not rclpy's own handlers: those shut the context down from their own thread at once, so a
callback running at that moment failed to publish ("publisher's context is invalid") and the
interrupt was raised inside it. The node stops in order instead: executor, node, context.
"""

from __future__ import annotations

import os
import re
import signal
import sys
import threading
import traceback
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager

import rclpy
from rclpy._rclpy_pybind11 import RCLError
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from rclpy.task import Future

from gnss_ins_common.params import ParameterValueError, check_parameter_files
from gnss_ins_common.ros_diagnostics import callback_errors

#: Environment variable that selects the nodes' executor: "events" (default) or "single".
EXECUTOR_ENV = "GNSS_INS_EXECUTOR"
#: Longest spin of a node between two looks at ``rclpy.ok()`` [s]. A stop request ends the spin
#: at once (StopSignals completes the future it waits on), so this only bounds the reaction to
#: a context shut down from elsewhere; each return costs a Python round (0.1 s: ~0.15 % of a
#: core more than 1 s in an idle node, measured).
NODE_SPIN_PERIOD_S = 1.0


def make_executor() -> Executor:
    """The nodes' executor: EventsExecutor if this rclpy has one and ``$GNSS_INS_EXECUTOR`` is
    not "single", else SingleThreadedExecutor (ParameterValueError for another value)."""
    choice = os.environ.get(EXECUTOR_ENV, "events")
    if choice not in ("events", "single"):
        raise ParameterValueError(f"{EXECUTOR_ENV}={choice!r}: expected 'events' or 'single'")
    if choice == "events":
        try:
            from rclpy.experimental import EventsExecutor
        except ImportError:  # an older rclpy
            pass
        else:
            return EventsExecutor()
    return SingleThreadedExecutor()


def spin_guarded(
    executor: Executor,
    node: Node,
    keep_going: Callable[[], bool],
    period_s: float = 0.1,
    waits: Callable[[], Future] = Future,
) -> None:
    """Spin ``executor`` while ``keep_going()`` (asked every ``period_s``, every callback run in
    between, and whenever the future from ``waits()`` it waits on is done); an exception from a
    callback is counted and logged in ``node``'s ``callback_errors`` (ros_diagnostics) instead
    of ending the node."""
    while keep_going():
        try:
            # A future new each time (its done callbacks do not pile up): all the events of
            # period_s in one call, not one Python loop per message. EventsExecutor's time-out
            # is not reached while callbacks keep it busy; the future ends the wait then.
            executor.spin_until_future_complete(waits(), timeout_sec=period_s)
        except (KeyboardInterrupt, ExternalShutdownException):
            raise
        except Exception as exc:
            callback_errors(node).record(exc, _callback_name(exc))


def _callback_name(exc: BaseException) -> str:
    """The function the executor called: the frame after the innermost one of rclpy or of this
    module (EventsExecutor calls from C++: no rclpy frame in between)."""
    frames = traceback.extract_tb(exc.__traceback__)
    outer = [i for i, f in enumerate(frames) if "/rclpy/" in f.filename or f.filename == __file__]
    after = outer[-1] + 1 if outer else len(frames) - 1
    return frames[after].name if 0 <= after < len(frames) else "callback"


class SpinSlices:
    """Spins an executor in slices of at most ``period_s``: a timer of ``node`` ends each slice
    (EventsExecutor's time-out is not reached while messages keep it busy), so the caller's loop
    gets its turn at least every ``period_s``."""

    def __init__(self, node: Node, period_s: float) -> None:
        self._wait = Future()
        self._timer = node.create_timer(period_s, self._end)

    def spin(self, executor: Executor, timeout_s: float) -> None:
        """Spin until the next tick of the timer, or ``timeout_s`` when idle."""
        self._wait = Future()
        executor.spin_until_future_complete(self._wait, timeout_sec=timeout_s)

    def cancel(self) -> None:
        """Stop the timer (the executor's last spins drain what is left)."""
        self._timer.cancel()

    def wake(self) -> None:
        """End the current slice now: from a signal handler or another thread (the future is
        completed on a thread of its own: the interrupted code may hold its non-reentrant
        lock)."""
        threading.Thread(target=self._end, daemon=True).start()

    def _end(self) -> None:
        if not self._wait.done():
            self._wait.set_result(None)


class StopSignals:
    """SIGINT and SIGTERM as a stop request while installed (a context manager): ``requested``
    turns True, the future of the latest ``wait()`` is completed (the executor's spin returns)
    and the interrupted code goes on; before ``spinning`` is set (the node is being built) they
    raise KeyboardInterrupt, as Python's default SIGINT handler does."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self) -> None:
        self.requested = False
        self.spinning = False
        self._previous: list[tuple[signal.Signals, object]] = []
        self._wait = Future()

    def wait(self) -> Future:
        """A new future for the executor to spin on; done at a stop request."""
        self._wait = Future()
        if self.requested:
            self._wait.set_result(None)
        return self._wait

    def __enter__(self) -> StopSignals:
        self._previous = [(signum, signal.signal(signum, self._handle)) for signum in self.SIGNALS]
        return self

    def __exit__(self, *_: object) -> None:
        for signum, handler in self._previous:
            signal.signal(signum, handler)  # type: ignore[arg-type]

    def _handle(self, signum: int, _frame: object) -> None:
        self.requested = True
        if not self.spinning:
            raise KeyboardInterrupt(signal.Signals(signum).name)
        # From another thread: the interrupted code may hold the future's (non-reentrant) lock.
        threading.Thread(target=self._end_wait, daemon=True).start()

    def _end_wait(self) -> None:
        wait = self._wait
        if not wait.done():
            wait.set_result(None)


def _init(args: list[str]) -> None:
    """``rclpy.init`` without rclpy's signal handlers (module docstring), the parameter files
    checked first; ParameterValueError if they or the other ROS arguments are refused (rcl's
    message without its source locations)."""
    check_parameter_files(args)
    try:
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    except RCLError as exc:
        raise ParameterValueError(re.sub(r", at /\S+:\d+", "", str(exc))) from exc


@contextmanager
def _quiet_after_stop(stop: StopSignals) -> Iterator[None]:
    """While installed: an exception a callback from native code could not raise (printed by
    Python as "Exception ignored ...") is not printed when it is the stop's KeyboardInterrupt."""
    previous = sys.unraisablehook

    def hook(unraisable: sys.UnraisableHookArgs) -> None:
        if not (stop.requested and isinstance(unraisable.exc_value, KeyboardInterrupt)):
            previous(unraisable)

    sys.unraisablehook = hook
    try:
        yield
    finally:
        sys.unraisablehook = previous


def run_node(factory: Callable[[], Node], args: Sequence[str] | None = None) -> int:
    """Init rclpy, build the node, spin until Ctrl-C/SIGTERM; exit code 2 on bad parameters or
    parameter files."""
    try:
        _init(list(args) if args is not None else sys.argv)
    except ParameterValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    node: Node | None = None
    executor: Executor | None = None
    stop = StopSignals()
    try:
        with stop, _quiet_after_stop(stop):
            node = factory()
            executor = make_executor()
            executor.add_node(node)
            stop.spinning = True
            spin_guarded(
                executor,
                node,
                lambda: rclpy.ok() and not stop.requested,
                NODE_SPIN_PERIOD_S,
                stop.wait,
            )
    except ParameterValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception:
        if not stop.requested:
            raise
        # The stop's KeyboardInterrupt raised inside a native library's callback (numba
        # compiling the fusion kernels at start-up) is swallowed there and surfaces as another
        # error: the process was asked to stop, and stops.
        print("stopped while starting", file=sys.stderr)
    finally:
        if executor is not None:  # its callbacks off the node's endpoints before they go
            executor.shutdown(timeout_sec=2.0)
        if node is not None:
            close = getattr(node, "close", None)
            if close is not None:
                close()
            node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
    return 0
