"""The nodes' stop on Ctrl-C/SIGTERM (gnss_ins_common.ros_node_main.run_node): a request the
spin loop reads, not an interrupt inside a callback or a context shut down under it.

The node here keeps its executor busy all the time (a 1 kHz timer whose callback computes for
3 ms and publishes), so the signal always lands inside a callback: with rclpy's own handlers
the context went away under the publish ("publisher's context is invalid", logged FATAL) on
every stop, and EventsExecutor's time-out is never reached while it is this busy."""

from __future__ import annotations

import os
import signal
import subprocess
import sys

import pytest
from support.pacing import pause
from support.waiting import wait_for

from gnss_ins_common.ros_node_main import StopSignals

pytestmark = pytest.mark.ros

BUSY_NODE = """
import sys, time
from rclpy.node import Node
from std_msgs.msg import String
from gnss_ins_common.ros_node_main import run_node

class Busy(Node):
    def __init__(self):
        super().__init__("busy")
        self.pub = self.create_publisher(String, "busy", 10)
        self.create_timer(0.001, self.tick)
        self.ticks = 0

    def tick(self):
        end = time.perf_counter() + 0.003
        while time.perf_counter() < end:
            pass
        self.ticks += 1
        if self.ticks == 20:
            print("spinning", flush=True)
        self.pub.publish(String(data=str(self.ticks)))

sys.exit(run_node(Busy, sys.argv))
"""


def _node_process(program: str, first_line: str) -> subprocess.Popen[str]:
    """``program`` run by this interpreter, once it has printed ``first_line``."""
    process = subprocess.Popen(
        [sys.executable, "-c", program],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    assert process.stdout is not None
    assert process.stdout.readline().strip() == first_line
    return process


def _busy_node() -> subprocess.Popen[str]:
    return _node_process(BUSY_NODE, "spinning")


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_busy_node_stops_in_order_on_a_signal(signum: int) -> None:
    process = _busy_node()
    pause(0.5)  # busy for a while
    process.send_signal(signum)
    try:
        output, _ = process.communicate(timeout=20)
    finally:
        process.kill()  # if the signal did not end it (then the time-out fails the test)
    assert process.returncode == 0, output
    for noise in ("context is invalid", "FATAL", "Traceback", "callback error"):
        assert noise not in output, output


def test_a_signal_is_a_request_while_spinning_and_an_interrupt_before() -> None:
    # What the handlers were: Python's default_int_handler for SIGINT, or SIG_IGN when this
    # process started in the background of a non-interactive shell (a CI runner may).
    before = signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)
    with StopSignals() as stop:
        with pytest.raises(KeyboardInterrupt):
            os.kill(os.getpid(), signal.SIGTERM)
            pause(1.0)  # interrupted: the handler runs at the next bytecode
        stop.spinning = True
        wait = stop.wait()
        os.kill(os.getpid(), signal.SIGINT)  # no exception now
        wait_for(wait.done, 5.0, poll_s=0.01)
        assert stop.requested and wait.done()
        assert stop.wait().done()  # a wait after the request ends at once
    assert (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)) == before


STARTING_NODE = """
import ctypes, sys, time
from rclpy.node import Node
from gnss_ins_common.ros_node_main import run_node

CALLBACK = ctypes.CFUNCTYPE(None)


class Compiling(Node):
    '''Builds for a long time inside callbacks from native code, as numba compiling the
    fusion kernels with an empty cache: an exception there is swallowed by ctypes and the
    library then fails on its own.'''

    def __init__(self):
        super().__init__("compiling")
        failed = []

        def step():
            try:
                time.sleep(0.01)
            except BaseException:
                failed.append(True)
                raise

        native = CALLBACK(step)
        print("building", flush=True)
        for _ in range(3000):
            native()  # Python -> C -> Python, as an LLVM callback
            if failed:
                raise RuntimeError("no compiled object yet")


sys.exit(run_node(Compiling, sys.argv))
"""


def test_a_stop_while_a_native_library_builds_the_node_ends_it_quietly() -> None:
    process = _node_process(STARTING_NODE, "building")
    pause(0.5)  # building for a while
    process.send_signal(signal.SIGINT)
    try:
        output, _ = process.communicate(timeout=20)
    finally:
        process.kill()
    assert process.returncode == 0, output
    assert "stopped while starting" in output
    assert "Traceback" not in output and "Exception ignored" not in output, output
