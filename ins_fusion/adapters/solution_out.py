"""The fused solution as nav_msgs/Odometry and NavSatFix, for rclpy and rosbags messages (no ROS).

One conversion for the node (rclpy messages) and the replay tool (rosbags messages), whose message
classes differ but whose fields do not: ``fill_*`` set fields by attribute. Conventions
(REP-103/105, nav_msgs/Odometry):
- pose in ``map`` = the ENU tangent plane at the datum; orientation of base_link (FLU) in ENU;
  pose covariance over (x, y, z, rotation about X, Y, Z of the parent frame), row-major 6x6;
- twist in the child frame base_link (FLU): velocity rotated into the body, its covariance too;
  angular rate bias-corrected, its covariance from the gyro noise density at the IMU rate;
- NavSatFix covariance in ENU [m^2], COVARIANCE_TYPE_KNOWN.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from gnss_ins_common.message_fields import fill_navsatfix, set_header, stamp_ns
from gnss_ins_common.navsat import SERVICE_GPS, CovarianceType, NavSatStatus
from gnss_ins_common.types import FloatArray
from ins_fusion.core.engine.engine import InsSolution
from ins_fusion.core.output.output_numbers import NUMBERS, ODOMETRY, output_numbers
from ins_fusion.core.output.solution_rows import pack


@dataclass(frozen=True)
class OdometryArrays:
    """The numbers of one nav_msgs/Odometry (positions in m, angles in rad, rates in rad/s)."""

    position_enu_m: FloatArray
    orientation_xyzw: FloatArray
    pose_covariance: FloatArray  # 36, row-major
    linear_velocity_flu_m_s: FloatArray
    angular_velocity_flu_rad_s: FloatArray
    twist_covariance: FloatArray  # 36, row-major


def _numbers(solution: InsSolution, rate_variance_rad2_s2: float) -> FloatArray | None:
    """The outputs' numbers of ``solution`` (core.output.output_numbers), None if not
    publishable."""
    numbers = np.empty(NUMBERS)
    valid = output_numbers(pack(solution), rate_variance_rad2_s2, numbers)
    return numbers if valid else None


def publishable(solution: InsSolution) -> bool:
    """True if every number of ``solution`` that the outputs carry is finite and every
    covariance positive semi-definite (ARCHITECTURE.md: valid or not published)."""
    return _numbers(solution, 0.0) is not None


def odometry_arrays(solution: InsSolution, rate_variance_rad2_s2: float) -> OdometryArrays:
    """Odometry numbers of ``solution``; ``rate_variance_rad2_s2``: variance of each rate axis.
    ValueError for a solution that is not ``publishable``."""
    numbers = _numbers(solution, rate_variance_rad2_s2)
    if numbers is None:
        raise ValueError("solution with a non-finite value or a covariance that is not PSD")
    odometry = numbers[ODOMETRY]
    return OdometryArrays(
        position_enu_m=odometry[0:3],
        orientation_xyzw=odometry[3:7],
        pose_covariance=odometry[7:43],
        linear_velocity_flu_m_s=odometry[43:46],
        angular_velocity_flu_rad_s=odometry[46:49],
        twist_covariance=odometry[49:85],
    )


def fill_odometry(
    msg: Any, solution: InsSolution, map_frame: str, base_frame: str, rate_variance_rad2_s2: float
) -> Any:
    """nav_msgs/Odometry of a solution (rclpy or rosbags message), stamped at its IMU stamp."""
    arrays = odometry_arrays(solution, rate_variance_rad2_s2)
    set_header(msg, stamp_ns(solution.t_s), map_frame)
    msg.child_frame_id = base_frame
    pose, twist = msg.pose, msg.twist
    p, q = pose.pose.position, pose.pose.orientation
    p.x, p.y, p.z = (float(v) for v in arrays.position_enu_m)
    q.x, q.y, q.z, q.w = (float(v) for v in arrays.orientation_xyzw)
    pose.covariance[:] = arrays.pose_covariance
    v, w = twist.twist.linear, twist.twist.angular
    v.x, v.y, v.z = (float(x) for x in arrays.linear_velocity_flu_m_s)
    w.x, w.y, w.z = (float(x) for x in arrays.angular_velocity_flu_rad_s)
    twist.covariance[:] = arrays.twist_covariance
    return msg


def fill_fused_fix(msg: Any, solution: InsSolution, base_frame: str) -> Any:
    """sensor_msgs/NavSatFix of base_link: ENU covariance, NO_FIX while the engine aligns."""
    return fill_navsatfix(
        msg,
        stamp_ns(solution.t_s),
        base_frame,
        int(NavSatStatus.NO_FIX if solution.state == "aligning" else NavSatStatus.FIX),
        SERVICE_GPS,
        solution.lat_deg,
        solution.lon_deg,
        solution.height_m,
        solution.cov_pos_enu_m2.ravel(),
        int(CovarianceType.KNOWN),
    )
