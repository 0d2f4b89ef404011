"""Building and publishing diagnostic_msgs for the gnss_ins nodes."""

from __future__ import annotations

import functools
import threading
import weakref
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.node import Node

if TYPE_CHECKING:  # ros_endpoints guards its callbacks with ``guarded`` below
    from gnss_ins_common.ros_endpoints import Endpoints

#: Status levels (one-byte ``bytes`` values, as the message field wants them).
OK: bytes = DiagnosticStatus.OK
WARN: bytes = DiagnosticStatus.WARN
ERROR: bytes = DiagnosticStatus.ERROR
STALE: bytes = DiagnosticStatus.STALE


def _format(value: object) -> str:
    if isinstance(value, float):
        return f"{value:.6g}"
    return str(value)


def make_status(
    name: str, hardware_id: str, level: bytes, message: str, values: Mapping[str, object]
) -> DiagnosticStatus:
    """One DiagnosticStatus; floats are printed with 6 significant digits."""
    return DiagnosticStatus(
        level=level,
        name=name,
        message=message,
        hardware_id=hardware_id,
        values=[KeyValue(key=key, value=_format(value)) for key, value in values.items()],
    )


#: Seconds between log lines of one kind of callback error after its first.
CALLBACK_ERROR_LOG_PERIOD_S = 10.0


class CallbackErrors:
    """Exceptions raised by a node's subscription and timer callbacks, caught around each
    callback (``guarded``) or by the spin loop (``ros_node_main.spin_guarded``) so that one bad
    message or tick does not end the node.

    Each kind (exception type and callback) is logged at ERROR the first time, then at most once
    per ``CALLBACK_ERROR_LOG_PERIOD_S`` with its count."""

    def __init__(self, node: Node) -> None:
        """Errors of ``node``."""
        self._logger = node.get_logger()
        self.count = 0
        self._kinds: dict[str, int] = {}
        self._new: list[str] = []
        self._lock = threading.Lock()  # serial reader threads record too

    def record(self, exc: BaseException, where: str) -> None:
        """Count ``exc``, raised in the callback ``where``, and log it (rate-limited per kind)."""
        kind = f"{type(exc).__name__} in {where}"
        message = f"callback error ({kind}): {exc}"
        with self._lock:
            self.count += 1
            seen = self._kinds.get(kind, 0)
            self._kinds[kind] = seen + 1
            self._new.append(message)
        if seen == 0:
            self._logger.error(f"{message}; the node goes on, further ones are counted")
        else:
            self._logger.error(
                f"{message} ({seen + 1} of this kind)",
                throttle_duration_sec=CALLBACK_ERROR_LOG_PERIOD_S,
            )

    def take_new(self) -> list[str]:
        """The errors since the last call (the status they go into), oldest first."""
        with self._lock:
            new, self._new = self._new, []
        return new


_CALLBACK_ERRORS: weakref.WeakKeyDictionary[Node, CallbackErrors] = weakref.WeakKeyDictionary()


def callback_errors(node: Node) -> CallbackErrors:
    """The callback error counter of ``node`` (made on first use)."""
    errors = _CALLBACK_ERRORS.get(node)
    if errors is None:
        errors = _CALLBACK_ERRORS[node] = CallbackErrors(node)
    return errors


def guarded(node: Node, callback: Callable[..., None]) -> Callable[..., None]:
    """``callback`` with its exceptions counted and logged in ``node``'s ``CallbackErrors`` (under
    its own name) instead of raised to the executor. The spin loop catches them too, but
    EventsExecutor logs each as fatal with a traceback first and, for a subscription, leaves the
    rest of a burst of messages queued until later ones arrive."""
    errors = callback_errors(node)
    name = getattr(callback, "__name__", "callback")

    @functools.wraps(callback)  # rclpy reads the callback's signature (message info or not)
    def call(*args: Any) -> None:
        try:
            callback(*args)
        except Exception as exc:
            errors.record(exc, name)

    return call


class DiagnosticsPublisher:
    """Publishes statuses on the absolute ``/diagnostics`` topic (aggregator convention) and
    reports the node's incompatible peers (see ros_endpoints) and callback errors (see
    ``CallbackErrors``) in the first status."""

    def __init__(self, node: Node, endpoints: Endpoints) -> None:
        """Create the publisher on ``node``; ``endpoints`` made the node's other endpoints."""
        self._node = node
        self._endpoints = endpoints
        self._publisher = endpoints.publisher(DiagnosticArray, "/diagnostics", 10)

    def publish(self, *statuses: DiagnosticStatus) -> None:
        """Publish the statuses, stamped now on the node's clock. Incompatible peers and callback
        errors since the last status raise the first status to WARN and lead its message; they
        are counted in ``incompatible_peers`` and ``callback_errors`` (since start-up)."""
        peers = self._endpoints.problems()
        errors = callback_errors(self._node)
        problems = [*peers, *errors.take_new()[-1:]]
        if statuses:
            first = statuses[0]
            first.values.append(KeyValue(key="incompatible_peers", value=str(len(peers))))
            first.values.append(KeyValue(key="callback_errors", value=str(errors.count)))
            if problems:
                first.level = max(first.level, WARN)
                first.message = f"{problems[0]}; {first.message}"
        array = DiagnosticArray(status=list(statuses))
        array.header.stamp = self._node.get_clock().now().to_msg()
        self._publisher.publish(array)
