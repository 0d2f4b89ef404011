"""What the serial driver nodes share on the ROS side: the link on the node's clock and logger,
the raw record of the port (gnss_ins_msgs/SerialChunk)."""

from __future__ import annotations

import array
from collections.abc import Callable

import serial
from gnss_ins_msgs.msg import SerialChunk
from rclpy.node import Node
from rclpy.qos import QoSProfile

from gnss_ins_common.message_fields import set_header
from gnss_ins_common.ros_diagnostics import callback_errors
from gnss_ins_common.ros_endpoints import Endpoints
from gnss_ins_common.serial_link import LinkSettings, SerialLink


def node_time_s(node: Node) -> float:
    """The node's ROS clock now [s] (wall time, or /clock with use_sim_time)."""
    return node.get_clock().now().nanoseconds * 1e-9


def start_serial_link(
    node: Node,
    settings: LinkSettings,
    on_open: Callable[[serial.Serial], None],
    on_data: Callable[[bytes, float], None],
) -> SerialLink:
    """A started SerialLink that stamps reads on the node's clock and logs through its logger;
    exceptions of ``on_data`` are the node's callback errors (ros_diagnostics)."""
    logger = node.get_logger()
    errors = callback_errors(node)

    def guarded_on_data(chunk: bytes, received_s: float) -> None:
        try:
            on_data(chunk, received_s)
        except Exception as exc:  # a decoding bug must not take the link down
            if not node.context.ok():
                # Ctrl-C/SIGTERM shut ROS down before the node closes this link: publishing
                # fails until then, which is no error of the data.
                return
            errors.record(exc, getattr(on_data, "__name__", "on_data"))

    link = SerialLink(
        settings,
        on_open=on_open,
        on_data=guarded_on_data,
        now=lambda: node_time_s(node),
        log=logger.warning,
        info=logger.info,
    )
    link.start()
    return link


class RawPublisher:
    """A port's reads and (re)opens as gnss_ins_msgs/SerialChunk messages on ``topic``: one per
    read (``data``) or port event (``event``), stamped with the time fed to the driver core."""

    def __init__(
        self, endpoints: Endpoints, topic: str, frame_id: str, qos: QoSProfile | int
    ) -> None:
        """The publisher of ``topic``; ``frame_id``: the node's."""
        self._publisher = endpoints.publisher(SerialChunk, topic, qos)
        self._frame_id = frame_id

    def data(self, chunk: bytes, time_ns: int) -> None:
        """The bytes of one read at host time ``time_ns`` [ns]."""
        msg = SerialChunk(event=SerialChunk.DATA)
        # An array of typecode 'B' is taken whole; bytes would be checked element by element.
        msg.data = array.array("B", chunk)
        set_header(msg, time_ns, self._frame_id)
        self._publisher.publish(msg)

    def event(self, first_open: bool, time_ns: int) -> None:
        """The port was opened and the device set up at ``time_ns`` [ns]: for the node's first
        time (``STARTED``, a new driver) or again (``OPENED``, the driver reset)."""
        msg = SerialChunk(event=SerialChunk.STARTED if first_open else SerialChunk.OPENED)
        set_header(msg, time_ns, self._frame_id)
        self._publisher.publish(msg)
