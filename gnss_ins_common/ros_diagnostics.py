"""Building and publishing diagnostic_msgs for the gnss_ins nodes."""

from __future__ import annotations

from collections.abc import Mapping

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.node import Node

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


class DiagnosticsPublisher:
    """Publishes statuses on the absolute ``/diagnostics`` topic (aggregator convention) and
    reports the node's incompatible peers (see ros_endpoints) in the first status."""

    def __init__(self, node: Node, endpoints: Endpoints) -> None:
        """Create the publisher on ``node``; ``endpoints`` made the node's other endpoints."""
        self._node = node
        self._endpoints = endpoints
        self._publisher = endpoints.publisher(DiagnosticArray, "/diagnostics", 10)

    def publish(self, *statuses: DiagnosticStatus) -> None:
        """Publish the statuses, stamped now on the node's clock. Incompatible peers raise the
        first status to WARN, lead its message and are counted in ``incompatible_peers``."""
        problems = self._endpoints.problems()
        if statuses:
            first = statuses[0]
            first.values.append(KeyValue(key="incompatible_peers", value=str(len(problems))))
            if problems:
                first.level = max(first.level, WARN)
                first.message = f"{problems[0]}; {first.message}"
        array = DiagnosticArray(status=list(statuses))
        array.header.stamp = self._node.get_clock().now().to_msg()
        self._publisher.publish(array)
