"""TF broadcasting of ins_fusion_node: /tf from ins/odometry, /tf_static for the sensor frames.

tf2_msgs comes from the sourced ROS install, or without one from the interface package the
Makefile's ``venv`` target generates (ros_interfaces/tf2_msgs). Same QoS as tf2_ros's
TransformBroadcaster (depth 100) and StaticTransformBroadcaster (transient local, depth 1).
"""

from __future__ import annotations

from geometry_msgs.msg import TransformStamped
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile
from rclpy.serialization import serialize_message
from tf2_msgs.msg import TFMessage

from ins_fusion.adapters.tf_frames import FrameTransform

_STATIC_QOS = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def transform_template(parent: str, child: str) -> bytes:
    """A serialized TFMessage of one transform parent → child (for ``adapters.cdr_out``)."""
    transform = TransformStamped(child_frame_id=child)
    transform.header.frame_id = parent
    return bytes(serialize_message(TFMessage(transforms=[transform])))


class TfBroadcaster:
    """Sends the static transforms once at construction; ``send`` the odometry's transform."""

    def __init__(self, node: Node, static: list[FrameTransform], dynamic: bool) -> None:
        self._static_pub = node.create_publisher(TFMessage, "/tf_static", _STATIC_QOS)
        self._pub = node.create_publisher(TFMessage, "/tf", 100) if dynamic else None
        stamp = node.get_clock().now().to_msg()
        transforms = []
        for frame in static:
            msg = TransformStamped()
            msg.header.stamp = stamp
            msg.header.frame_id, msg.child_frame_id = frame.parent, frame.child
            t, q = msg.transform.translation, msg.transform.rotation
            t.x, t.y, t.z = frame.translation_m
            q.x, q.y, q.z, q.w = frame.quat_xyzw
            transforms.append(msg)
        self._static_pub.publish(TFMessage(transforms=transforms))

    def send(self, transform: bytes) -> None:
        """A serialized TFMessage (``transform_template`` rewritten by ``adapters.cdr_out``) on
        /tf, when dynamic."""
        if self._pub is not None:
            self._pub.publish(transform)
