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
from ins_fusion.core.engine import InsSolution
from ins_fusion.core.rotation import mat_from_quat


@dataclass(frozen=True)
class OdometryArrays:
    """The numbers of one nav_msgs/Odometry (positions in m, angles in rad, rates in rad/s)."""

    position_enu_m: FloatArray
    orientation_xyzw: FloatArray
    pose_covariance: FloatArray  # 36, row-major
    linear_velocity_flu_m_s: FloatArray
    angular_velocity_flu_rad_s: FloatArray
    twist_covariance: FloatArray  # 36, row-major


#: Relative tolerance on negative covariance eigenvalues (rounding in a PSD matrix).
_PSD_TOLERANCE = 1e-9


def _psd(covs: FloatArray) -> bool:
    """True for a stack of finite, symmetric, positive semi-definite matrices (up to rounding),
    shape (k, n, n); one batched eigen-decomposition for all."""
    if not np.isfinite(covs).all():
        return False
    transposed = covs.transpose(0, 2, 1)
    if (np.abs(covs - transposed) > 1e-9 * np.abs(transposed)).any():
        return False
    eigenvalues = np.linalg.eigvalsh(covs)
    tolerance = _PSD_TOLERANCE * np.maximum(1.0, eigenvalues.max(axis=1))
    return bool((eigenvalues.min(axis=1) >= -tolerance).all())


def publishable(solution: InsSolution) -> bool:
    """True if every number of ``solution`` that the outputs carry is finite and every
    covariance positive semi-definite (ARCHITECTURE.md: valid or not published)."""
    vectors = (
        [solution.lat_deg, solution.lon_deg, solution.height_m],
        solution.pos_enu_m,
        solution.vel_enu_m_s,
        solution.quat_enu_flu_xyzw,
        solution.rate_flu_rad_s,
    )
    if not all(np.isfinite(v).all() for v in vectors):
        return False
    covariances = (solution.cov_pos_enu_m2, solution.cov_vel_enu, solution.cov_att_enu_rad2)
    return _psd(np.array(covariances, dtype=np.float64))


def odometry_arrays(solution: InsSolution, rate_variance_rad2_s2: float) -> OdometryArrays:
    """Odometry numbers of ``solution``; ``rate_variance_rad2_s2``: variance of each rate axis."""
    mat_enu_flu = mat_from_quat(*solution.quat_enu_flu_xyzw.tolist())  # FLU -> ENU
    pose_cov = np.zeros((6, 6))
    pose_cov[:3, :3] = solution.cov_pos_enu_m2
    pose_cov[3:, 3:] = solution.cov_att_enu_rad2
    twist_cov = np.zeros((6, 6))
    twist_cov[:3, :3] = mat_enu_flu.T @ solution.cov_vel_enu @ mat_enu_flu
    twist_cov[3:, 3:] = np.eye(3) * rate_variance_rad2_s2
    return OdometryArrays(
        position_enu_m=np.asarray(solution.pos_enu_m, dtype=float),
        orientation_xyzw=np.asarray(solution.quat_enu_flu_xyzw, dtype=float),
        pose_covariance=pose_cov.ravel(),
        linear_velocity_flu_m_s=mat_enu_flu.T @ solution.vel_enu_m_s,
        angular_velocity_flu_rad_s=np.asarray(solution.rate_flu_rad_s, dtype=float),
        twist_covariance=twist_cov.ravel(),
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
