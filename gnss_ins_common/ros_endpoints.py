"""Publishers and subscriptions whose QoS and type mismatches are found by polling, not by events.

rclpy gives every publisher and subscription two event handlers (incompatible QoS, incompatible
type) that sit in the executor's wait set; the executor rebuilds that set twice per received
message, which for ins_fusion_node's 134 Hz IMU input cost about 5 % of a core (measured:
15.4 % -> 10.4 % without them). Endpoints creates the endpoints without those handlers and checks
the ROS graph instead when the node publishes its diagnostics (once a second by default): each
mismatch is logged once, like rclpy's own warning, and reported on /diagnostics.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.qos_overriding_options import QoSOverridingOptions
from rclpy.subscription import Subscription
from rclpy.topic_endpoint_info import TopicEndpointInfo

from gnss_ins_common.ros_diagnostics import guarded


def type_name(msg_type: Any) -> str:
    """'pkg/msg/Name' of a generated message class (the form the ROS graph reports)."""
    return f"{msg_type.__module__.split('.')[0]}/msg/{msg_type.__name__}"


class Endpoints:
    """Creates a node's publishers and subscriptions and finds incompatible peers."""

    def __init__(self, node: Node) -> None:
        """Endpoints of ``node``."""
        self._node = node
        self._publishers: list[tuple[Publisher, str]] = []
        self._subscriptions: list[tuple[Subscription, str]] = []
        self._reported: set[str] = set()

    def publisher(self, msg_type: Any, topic: str, qos: QoSProfile | int) -> Publisher:
        """A publisher without QoS event handlers."""
        publisher = self._node.create_publisher(
            msg_type,
            topic,
            qos,
            event_callbacks=PublisherEventCallbacks(use_default_callbacks=False),
        )
        self._publishers.append((publisher, type_name(msg_type)))
        return publisher

    def subscription(
        self,
        msg_type: Any,
        topic: str,
        callback: Callable[[Any], None],
        qos: QoSProfile | int,
        *,
        raw: bool = False,
        overridable: bool = False,
    ) -> Subscription:
        """A subscription without QoS event handlers whose callback's exceptions are counted in
        the node's callback errors (ros_diagnostics.guarded); ``raw``: the callback gets the
        serialized message (bytes); ``overridable``: its history, depth and reliability can be
        set by the standard ROS parameters ``qos_overrides.<topic>.subscription.<policy>``."""
        subscription = self._node.create_subscription(
            msg_type,
            topic,
            guarded(self._node, callback),
            qos,
            event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False),
            raw=raw,
            qos_overriding_options=(
                QoSOverridingOptions.with_default_policies() if overridable else None
            ),
        )
        self._subscriptions.append((subscription, type_name(msg_type)))
        return subscription

    def problems(self) -> list[str]:
        """Every peer now in the graph that cannot talk to one of our endpoints, one line each;
        new ones are also logged as warnings."""
        node = self._node
        found: list[str] = []
        for sub, expected in self._subscriptions:
            for info in node.get_publishers_info_by_topic(sub.topic_name):
                found += _mismatch(
                    sub.topic_name, info, expected, info.qos_profile, sub.qos_profile, "publisher"
                )
        for pub, expected in self._publishers:
            for info in node.get_subscriptions_info_by_topic(pub.topic_name):
                found += _mismatch(
                    pub.topic_name,
                    info,
                    expected,
                    pub.qos_profile,
                    info.qos_profile,
                    "subscription",
                )
        for problem in found:
            if problem not in self._reported:
                self._reported.add(problem)
                node.get_logger().warning(problem)
        return found


def _mismatch(
    topic: str,
    info: TopicEndpointInfo,
    expected: str,
    publisher_qos: QoSProfile,
    subscription_qos: QoSProfile,
    peer: str,
) -> list[str]:
    """What keeps the peer ``info`` on ``topic`` from talking to our endpoint (empty: nothing).

    Reliability and durability only, the policies that differ between sensor and default QoS:
    rclpy's qos_check_compatible flags deadline and liveliness on every pair here, because the
    graph reports an unset deadline as its 'infinite' value and ours as 'default'.
    """
    where = f"{peer} {info.node_namespace.rstrip('/')}/{info.node_name} on {topic}"
    if info.topic_type != expected:
        return [f"{where} has type {info.topic_type}, expected {expected}: no messages flow"]
    problems = []
    if (
        publisher_qos.reliability == ReliabilityPolicy.BEST_EFFORT
        and subscription_qos.reliability == ReliabilityPolicy.RELIABLE
    ):
        problems.append("a best-effort publisher and a reliable subscription")
    if (
        publisher_qos.durability == DurabilityPolicy.VOLATILE
        and subscription_qos.durability == DurabilityPolicy.TRANSIENT_LOCAL
    ):
        problems.append("a volatile publisher and a transient-local subscription")
    return [f"{where}: incompatible QoS, {p}: no messages flow" for p in problems]
