"""TF of ins_fusion_node (REP-105): which frames it broadcasts and the static sensor transforms.

``map`` (or ``odom``) → ``base_link`` comes from ins/odometry; ``base_link`` → ``imu_link``,
``gnss_link`` and, when named, the attitude receiver's frame come from the installation
parameters (lever arms in base_link FLU [m], REP-103 roll, pitch, yaw of the sensor frame in
base_link). Pure data (no ROS): ``ins_fusion.ros_tf`` turns it into tf2_msgs/TFMessage.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from scipy.spatial.transform import Rotation


@dataclass(frozen=True)
class FrameTransform:
    """Pose of ``child`` in ``parent``: translation [m] and rotation quaternion (x, y, z, w)."""

    parent: str
    child: str
    translation_m: tuple[float, float, float]
    quat_xyzw: tuple[float, float, float, float]


def world_frame(params: Mapping[str, Any]) -> str:
    """Frame of ins/odometry and parent of its transform: odom_frame in tf_mode odom, else
    map_frame."""
    return str(params["odom_frame"] if params["tf_mode"] == "odom" else params["map_frame"])


def quat_from_rpy_deg(rpy_deg: Any) -> tuple[float, float, float, float]:
    """(x, y, z, w) of REP-103 roll, pitch, yaw [deg] (z-y'-x'' intrinsic, as tf2's setRPY)."""
    roll, pitch, yaw = (math.radians(float(a)) for a in rpy_deg)
    x, y, z, w = Rotation.from_euler("ZYX", [yaw, pitch, roll]).as_quat()
    return (float(x), float(y), float(z), float(w))


def static_transforms(params: Mapping[str, Any]) -> list[FrameTransform]:
    """base_frame → imu_frame, gnss_frame and (when attitude_frame is set) attitude_frame.

    The attitude receiver's frame has an orientation parameter but no position one: its
    transform carries the rotation only (origin at base_link)."""
    base = str(params["base_frame"])

    def vec(name: str) -> tuple[float, float, float]:
        x, y, z = (float(v) for v in params[name])
        return (x, y, z)

    transforms = [
        FrameTransform(
            base,
            str(params["imu_frame"]),
            vec("imu_lever_arm"),
            quat_from_rpy_deg(params["imu_mounting_rpy_deg"]),
        ),
        FrameTransform(
            base, str(params["gnss_frame"]), vec("gnss_lever_arm"), (0.0, 0.0, 0.0, 1.0)
        ),
    ]
    if params["attitude_frame"]:
        transforms.append(
            FrameTransform(
                base,
                str(params["attitude_frame"]),
                (0.0, 0.0, 0.0),
                quat_from_rpy_deg(params["attitude_mounting_rpy_deg"]),
            )
        )
    return transforms
