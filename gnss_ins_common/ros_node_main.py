"""The ``main`` shared by the gnss_ins node executables."""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from typing import Protocol

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node

from gnss_ins_common.params import ParameterValueError


class ClosableNode(Protocol):
    """A node that stops its own threads in ``close()`` before it is destroyed."""

    def close(self) -> None: ...


def run_node(factory: Callable[[], Node], args: Sequence[str] | None = None) -> int:
    """Init rclpy, build the node, spin until Ctrl-C/SIGTERM; exit code 2 on bad parameters."""
    rclpy.init(args=list(args) if args is not None else sys.argv)
    node: Node | None = None
    try:
        node = factory()
        rclpy.spin(node)
    except ParameterValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            close = getattr(node, "close", None)
            if close is not None:
                close()
            node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
    return 0
