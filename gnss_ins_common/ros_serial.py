"""What the serial driver nodes share on the ROS side: the link on the node's clock and logger."""

from __future__ import annotations

from collections.abc import Callable

import serial
from rclpy.node import Node

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
    """A started SerialLink that stamps reads on the node's clock and logs through its logger."""
    logger = node.get_logger()
    link = SerialLink(
        settings,
        on_open=on_open,
        on_data=on_data,
        now=lambda: node_time_s(node),
        log=logger.warning,
        info=logger.info,
    )
    link.start()
    return link
