"""The rclpy half of ``gnss_ins echo`` and ``gnss_ins topics``: the graph's topics and a
subscription that hands each message to a callback, on a look's node (ros_look)."""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from typing import Any

from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from ins_fusion.tools.ros_look import LookNode
from ins_fusion.tools.ros_record import message_class

#: Longest spin between two looks at the time and at a stop request [s].
SPIN_PERIOD_S = 0.1
#: The graph counts as discovered once it has not changed for this long [s] (endpoints of a
#: dozen processes come in over a few seconds) ...
SETTLE_S = 1.0
#: ... or after this long past the first topic [s].
SETTLE_LIMIT_S = 10.0


def topics(wait_s: float) -> list[tuple[str, str, int, int]]:
    """(name, type, publishers, subscribers) of every topic seen within ``wait_s``, once the
    graph has settled (unchanged for SETTLE_S, at most SETTLE_LIMIT_S), this process's own
    endpoints left out."""
    with LookNode("gnss_ins_look", SPIN_PERIOD_S) as look:
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
    with LookNode("gnss_ins_look", SPIN_PERIOD_S) as look:
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
