"""The ``main`` shared by the gnss_ins node executables."""

from __future__ import annotations

import re
import sys
from collections.abc import Callable, Sequence
from typing import Protocol

import rclpy
from rclpy._rclpy_pybind11 import RCLError
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node

from gnss_ins_common.params import ParameterValueError, check_parameter_files


class ClosableNode(Protocol):
    """A node that stops its own threads in ``close()`` before it is destroyed."""

    def close(self) -> None: ...


def _init(args: list[str]) -> None:
    """``rclpy.init`` with the parameter files checked first; ParameterValueError if they or
    the other ROS arguments are refused (rcl's message without its source locations)."""
    check_parameter_files(args)
    try:
        rclpy.init(args=args)
    except RCLError as exc:
        raise ParameterValueError(re.sub(r", at /\S+:\d+", "", str(exc))) from exc


def run_node(factory: Callable[[], Node], args: Sequence[str] | None = None) -> int:
    """Init rclpy, build the node, spin until Ctrl-C/SIGTERM; exit code 2 on bad parameters or
    parameter files."""
    try:
        _init(list(args) if args is not None else sys.argv)
    except ParameterValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
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
