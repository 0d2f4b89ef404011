"""Building and publishing diagnostic_msgs for the gnss_ins nodes."""

from __future__ import annotations

from collections.abc import Mapping

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.node import Node

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
    """Publishes statuses on the absolute ``/diagnostics`` topic (aggregator convention)."""

    def __init__(self, node: Node) -> None:
        """Create the publisher on ``node``."""
        self._node = node
        self._publisher = node.create_publisher(DiagnosticArray, "/diagnostics", 10)

    def publish(self, *statuses: DiagnosticStatus) -> None:
        """Publish the statuses, stamped now on the node's clock."""
        array = DiagnosticArray(status=list(statuses))
        array.header.stamp = self._node.get_clock().now().to_msg()
        self._publisher.publish(array)
