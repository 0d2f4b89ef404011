"""TF of ins_fusion_node (REP-105): static sensor frames on /tf_static from the installation
parameters, the odometry's transform on /tf per tf_mode (the drive in test_fusion_node checks the
moving map -> base_link against ins/odometry)."""

from __future__ import annotations

import numpy as np
import pytest
import rclpy
from rclpy.qos import DurabilityPolicy, QoSProfile
from scipy.spatial.transform import Rotation
from support.ros_harness import overrides, spinning, wait_for
from tf2_msgs.msg import TFMessage

from ins_fusion.adapters.tf_frames import quat_from_rpy_deg, static_transforms, world_frame
from ins_fusion.core.settings.params import PARAMETERS
from ins_fusion.node import InsFusionNode

pytestmark = pytest.mark.ros
DEFAULTS = {spec.name: spec.default for spec in PARAMETERS}


def test_rpy_follows_tf2_set_rpy():
    """Yaw 90 deg turns the sensor's x onto base_link's y; roll then pitch about the new axes."""
    quat = Rotation.from_quat(quat_from_rpy_deg([0.0, 0.0, 90.0]))
    assert quat.apply([1.0, 0.0, 0.0]) == pytest.approx([0.0, 1.0, 0.0], abs=1e-12)
    composed = Rotation.from_quat(quat_from_rpy_deg([10.0, 20.0, 30.0]))
    manual = (
        Rotation.from_rotvec([0, 0, np.radians(30.0)])
        * Rotation.from_rotvec([0, np.radians(20.0), 0])
        * Rotation.from_rotvec([np.radians(10.0), 0, 0])
    )
    assert composed.as_matrix() == pytest.approx(manual.as_matrix(), abs=1e-12)


def test_static_transforms_and_world_frame_from_the_parameters():
    frames = static_transforms(DEFAULTS)
    assert [(f.parent, f.child) for f in frames] == [
        ("base_link", "imu_link"),
        ("base_link", "gnss_link"),
    ]
    assert frames[1].translation_m == tuple(DEFAULTS["gnss_lever_arm"])
    named = static_transforms({**DEFAULTS, "attitude_frame": "adu5_link"})
    assert named[-1].child == "adu5_link" and named[-1].translation_m == (0.0, 0.0, 0.0)
    assert world_frame(DEFAULTS) == "map"
    assert world_frame({**DEFAULTS, "tf_mode": "odom"}) == "odom"


@pytest.mark.ros
def test_node_sends_the_sensor_frames_on_tf_static_and_no_tf_when_told():
    rclpy.init()
    node = InsFusionNode(
        parameter_overrides=overrides(
            tf_mode="none",
            attitude_frame="adu5_link",
            imu_mounting_rpy_deg=[0.0, 0.0, 90.0],
            imu_lever_arm=[0.5, -0.2, 1.0],
            gnss_lever_arm=[0.1, 0.0, 1.8],
            attitude_mounting_rpy_deg=[0.0, 0.0, -90.0],
        )
    )
    listener = rclpy.create_node("tf_listener")
    received: list[TFMessage] = []
    static_qos = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    # Subscribed after the node sent them: transient local delivers them to late joiners.
    listener.create_subscription(TFMessage, "/tf_static", received.append, static_qos)
    try:
        with spinning(node, listener):
            assert wait_for(lambda: bool(received), 20.0), "nothing on /tf_static"
        assert listener.count_publishers("/tf") == 0  # tf_mode none
    finally:
        node.destroy_node()
        listener.destroy_node()
        rclpy.shutdown()
    frames = {t.child_frame_id: t for t in received[-1].transforms}
    assert sorted(frames) == ["adu5_link", "gnss_link", "imu_link"]
    assert {t.header.frame_id for t in frames.values()} == {"base_link"}
    imu = frames["imu_link"].transform
    assert (imu.translation.x, imu.translation.y, imu.translation.z) == (0.5, -0.2, 1.0)
    q = imu.rotation
    assert (q.x, q.y, q.z, q.w) == pytest.approx((0.0, 0.0, np.sqrt(0.5), np.sqrt(0.5)))
    gnss = frames["gnss_link"].transform.translation
    assert (gnss.x, gnss.y, gnss.z) == (0.1, 0.0, 1.8)
    assert frames["adu5_link"].transform.rotation.z == pytest.approx(-np.sqrt(0.5))
