"""A short-lived node of the tools on the vehicle's domain (``gnss_ins status``, ``topics``,
``echo``): rclpy without its signal handlers (Ctrl-C/SIGTERM set ``stop`` and end the current
spin at once), the nodes' executor spun in slices, everything shut down at the end of ``with``.
A look writes no ROS log file (each ``gnss_ins status`` left an empty one in ~/.ros/log); the
daemon's status server, which runs for hours, does."""

from __future__ import annotations

import signal
import time
from collections.abc import Callable

import rclpy
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from gnss_ins_common.ros_node_main import SpinSlices, make_executor


class LookNode:
    """``node`` spun by ``spin``/``spin_until`` in slices of at most ``period_s`` [s]."""

    def __init__(self, name: str, period_s: float, log_file: bool = False) -> None:
        self._name = name
        self.period_s = period_s
        self._log_file = log_file
        self.stop = False

    def __enter__(self) -> LookNode:
        rclpy.init(
            args=None if self._log_file else ["--ros-args", "--disable-external-lib-logs"],
            signal_handler_options=SignalHandlerOptions.NO,
        )
        self.node: Node = rclpy.create_node(self._name, start_parameter_services=False)
        self.executor = make_executor()  # the nodes' (EventsExecutor): no wait set per message
        self.executor.add_node(self.node)
        self._slices = SpinSlices(self.node, self.period_s)
        for signum in (signal.SIGINT, signal.SIGTERM):
            signal.signal(signum, self._request_stop)
        return self

    def _request_stop(self, *_: object) -> None:
        self.stop = True
        self._slices.wake()

    def spin(self, timeout_s: float) -> None:
        """Spin for at most ``timeout_s`` [s] (and at most one slice)."""
        self._slices.spin(self.executor, timeout_s)

    def spin_until(self, done: Callable[[], bool], seconds: float) -> bool:
        """Spin until ``done()``, a stop request or ``seconds``; whether ``done()``."""
        end = time.monotonic() + seconds
        while not self.stop and not done() and time.monotonic() < end:
            self.spin(min(self.period_s, max(end - time.monotonic(), 0.0)))
        return done()

    def __exit__(self, *_: object) -> None:
        self.executor.shutdown(timeout_sec=2.0)  # its callbacks off the node's endpoints first
        self.node.destroy_node()
        rclpy.try_shutdown()
