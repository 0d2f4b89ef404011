"""The rclpy half of ``gnss_ins echo`` and ``gnss_ins topics``: the graph's topics and a
subscription that hands each message to a callback. A look at the graph writes no ROS log file."""

from __future__ import annotations

import signal
import sys
import time
from collections.abc import Callable
from typing import Any

import rclpy
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions

from gnss_ins_common.ros_node_main import SpinSlices, make_executor
from ins_fusion.tools.ros_record import message_class

#: Longest spin between two looks at the time and at a stop request [s].
SPIN_PERIOD_S = 0.1
#: The graph counts as discovered once it has not changed for this long [s] (endpoints of a
#: dozen processes come in over a few seconds) ...
SETTLE_S = 1.0
#: ... or after this long past the first topic [s].
SETTLE_LIMIT_S = 10.0


class _Look:
    """A node on the domain until Ctrl-C/SIGTERM or the end of ``with``."""

    def __enter__(self) -> _Look:
        rclpy.init(
            args=["--ros-args", "--disable-external-lib-logs"],
            signal_handler_options=SignalHandlerOptions.NO,
        )
        self.node: Node = rclpy.create_node("gnss_ins_look", start_parameter_services=False)
        self.executor = make_executor()
        self.executor.add_node(self.node)
        self.slices = SpinSlices(self.node, SPIN_PERIOD_S)
        self.stop = False
        for signum in (signal.SIGINT, signal.SIGTERM):
            signal.signal(signum, self._request_stop)
        return self

    def _request_stop(self, *_: object) -> None:
        self.stop = True

    def spin_until(self, done: Callable[[], bool], seconds: float) -> bool:
        """Spin until ``done()``, a stop request or ``seconds``; whether ``done()``."""
        end = time.monotonic() + seconds
        while not self.stop and not done() and time.monotonic() < end:
            self.slices.spin(self.executor, min(SPIN_PERIOD_S, max(end - time.monotonic(), 0.0)))
        return done()

    def __exit__(self, *_: object) -> None:
        self.executor.shutdown(timeout_sec=2.0)
        self.node.destroy_node()
        rclpy.try_shutdown()


def topics(wait_s: float) -> list[tuple[str, str, int, int]]:
    """(name, type, publishers, subscribers) of every topic seen within ``wait_s``, once the
    graph has settled (unchanged for SETTLE_S, at most SETTLE_LIMIT_S), this process's own
    endpoints left out."""
    with _Look() as look:
        node = look.node
        own = node.get_name()

        def graph() -> list[tuple[str, str, int, int]]:
            return [
                (
                    name,
                    ", ".join(types),
                    sum(i.node_name != own for i in node.get_publishers_info_by_topic(name)),
                    sum(i.node_name != own for i in node.get_subscriptions_info_by_topic(name)),
                )
                for name, types in sorted(node.get_topic_names_and_types())
            ]

        if look.spin_until(lambda: any(t[0] != "/rosout" for t in graph()), wait_s):
            end = time.monotonic() + SETTLE_LIMIT_S
            seen = graph()
            while not look.stop and time.monotonic() < end:
                look.spin_until(lambda: False, SETTLE_S)
                if (now := graph()) == seen:
                    break
                seen = now
        return graph()


def echo(
    topic: str,
    count: int,
    wait_s: float,
    show: Callable[[Any], None],
    refuse: Callable[[Any], str | None] = lambda _: None,
) -> int:
    """Hand each message of ``topic`` to ``show`` until ``count`` (0: no limit) or a stop;
    1 when no publisher appears within ``wait_s`` or ``refuse(message class)`` names a reason
    not to listen."""
    with _Look() as look:
        node = look.node

        def publisher_types() -> list[str]:
            return [i.topic_type for i in node.get_publishers_info_by_topic(topic)]

        if not look.spin_until(lambda: bool(publisher_types()), wait_s):
            if look.stop:
                return 0
            print(f"gnss_ins echo: no publisher of {topic} within {wait_s:g} s", file=sys.stderr)
            return 1
        msgtype = publisher_types()[0]
        try:
            cls = message_class(msgtype)
        except (ImportError, AttributeError):
            print(f"gnss_ins echo: {topic} has type {msgtype}, not installed here", file=sys.stderr)
            return 1
        if (reason := refuse(cls)) is not None:
            print(f"gnss_ins echo: {reason}", file=sys.stderr)
            return 1
        received = 0

        def take(message: Any) -> None:
            nonlocal received
            if count and received >= count:
                return
            received += 1
            show(message)

        qos = QoSProfile(
            depth=100,
            reliability=ReliabilityPolicy.BEST_EFFORT,
            durability=DurabilityPolicy.VOLATILE,
        )
        node.create_subscription(cls, topic, take, qos)
        look.spin_until(lambda: bool(count) and received >= count, float("inf"))
        return 0
