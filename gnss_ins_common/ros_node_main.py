"""The ``main`` shared by the gnss_ins node executables."""

from __future__ import annotations

import re
import sys
import traceback
from collections.abc import Callable, Sequence

import rclpy
from rclpy._rclpy_pybind11 import RCLError
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node

from gnss_ins_common.params import ParameterValueError, check_parameter_files
from gnss_ins_common.ros_diagnostics import callback_errors


def spin_guarded(executor: Executor, node: Node, keep_going: Callable[[], bool]) -> None:
    """Spin ``executor`` while ``keep_going()``; an exception from a callback is counted and
    logged in ``node``'s ``callback_errors`` (ros_diagnostics) instead of ending the node."""
    while keep_going():
        try:
            executor.spin_once(timeout_sec=0.1)
        except (KeyboardInterrupt, ExternalShutdownException):
            raise
        except Exception as exc:
            callback_errors(node).record(exc, _callback_name(exc))


def _callback_name(exc: BaseException) -> str:
    """The function the executor called: the frame after rclpy's innermost one."""
    frames = traceback.extract_tb(exc.__traceback__)
    rclpy_frames = [i for i, f in enumerate(frames) if "/rclpy/" in f.filename]
    after = rclpy_frames[-1] + 1 if rclpy_frames else len(frames) - 1
    return frames[after].name if 0 <= after < len(frames) else "callback"


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
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        spin_guarded(executor, node, rclpy.ok)
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
