"""What the serial driver nodes share on the ROS side: the link on the node's clock and logger."""

from __future__ import annotations

from collections.abc import Callable

import serial
from rclpy.node import Node

from gnss_ins_common.ros_diagnostics import callback_errors
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
