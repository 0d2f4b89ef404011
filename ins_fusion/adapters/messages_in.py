"""Incoming ROS messages -> fusion engine inputs, for rclpy and rosbags message objects alike.

One definition of how ins_fusion_node and ``gnss_ins replay`` read their topics (the IMU, at
134 Hz, straight from its bytes with the same fields: ins_fusion.adapters.cdr_fields): the functions
only read fields by attribute (rclpy messages and rosbags-deserialized ones have the same field
names) and return the engine's plain types. No ROS import.

Conventions (shared/ARCHITECTURE.md): every time is the message's ``header.stamp`` [s since the
epoch, host clock]; REP-103 ENU world and FLU body; REP-145 IMU data; a covariance whose first
element is -1 marks a quantity the message does not carry.

| topic | type | function | InsEngine input |
|---|---|---|---|
| imu/data_raw | Imu | ``imu_sample`` (or ``cdr_fields.imu_sample``) | ``add_imu(*sample)`` |
| gnss/fix | NavSatFix | ``fix_measurement`` | ``add_gnss_fix`` |
| gnss/vel | TwistWithCovarianceStamped (ENU) | ``velocity_measurement`` | ``add_gnss_velocity`` |
| gnss/attitude | Imu (orientation only) | ``attitude_measurement`` | ``add_attitude`` |
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np

from gnss_ins_common.navsat import CovarianceType, NavSatStatus
from gnss_ins_common.types import Vec3
from ins_fusion.core.measurements import (
    AttitudeMeasurement,
    GnssFixMeasurement,
    GnssVelocityMeasurement,
)


class ImuSample(NamedTuple):
    """One imu/data_raw sample: stamp [s], rate [rad/s] and specific force [m/s²] in imu_link
    FLU (REP-145)."""

    t_s: float
    rate_flu_rad_s: Vec3
    force_flu_m_s2: Vec3


def stamp_s(msg: Any) -> float:
    """``msg.header.stamp`` in seconds."""
    stamp = msg.header.stamp
    return float(stamp.sec) + float(stamp.nanosec) * 1e-9


def _vec3(v: Any) -> Vec3:
    return (float(v.x), float(v.y), float(v.z))


def positive_definite(cov: np.ndarray) -> bool:
    """True for a finite, symmetric, positive definite 3x3 matrix."""
    # np.allclose's default tolerances, without its cost per fix.
    if not np.isfinite(cov).all() or (np.abs(cov - cov.T) > 1e-8 + 1e-5 * np.abs(cov.T)).any():
        return False
    # Sylvester's criterion on the lower triangle (what np.linalg.eigvalsh reads): the leading
    # principal minors are positive. Closed form: eigvalsh cost ~100 us per fix of a replay.
    rows: list[list[float]] = cov.tolist()
    (a, _, _), (d, b, _), (e, f, c) = rows
    minor2 = a * b - d * d
    return a > 0.0 and minor2 > 0.0 and c * minor2 - a * f * f + 2.0 * d * e * f - b * e * e > 0.0


def imu_sample(msg: Any) -> ImuSample:
    """sensor_msgs/Imu of imu/data_raw -> ``ImuSample`` (angular_velocity, linear_acceleration)."""
    return ImuSample(stamp_s(msg), _vec3(msg.angular_velocity), _vec3(msg.linear_acceleration))


def fix_measurement(msg: Any) -> GnssFixMeasurement:
    """sensor_msgs/NavSatFix -> antenna position with its ENU covariance [m²]
    (``fix_from_fields``)."""
    return fix_from_fields(
        stamp_s(msg),
        (float(msg.latitude), float(msg.longitude), float(msg.altitude)),
        int(msg.status.status),
        int(msg.position_covariance_type),
        np.asarray(msg.position_covariance, dtype=np.float64).reshape(3, 3),
    )


def fix_from_fields(
    t_s: float, position: Vec3, status: int, covariance_type: int, cov: np.ndarray
) -> GnssFixMeasurement:
    """A NavSatFix's fields -> antenna position: stamp [s], (latitude [deg], longitude [deg],
    altitude [m]), status.status, position_covariance_type, covariance ENU [m²] (3, 3).

    Valid only with a fix (status >= FIX; NO_FIX and UNKNOWN carry no position), finite
    latitude, longitude and altitude (altitude above the WGS-84 ellipsoid, ARCHITECTURE.md),
    and a known, finite, positive definite covariance (type not UNKNOWN; a zero or negative
    variance is no accuracy either): a position without an accuracy cannot be weighted. Invalid
    fixes are still handed to the engine, which ignores and counts them.
    """
    valid = (
        status >= NavSatStatus.FIX
        and covariance_type != CovarianceType.UNKNOWN
        and all(map(math.isfinite, position))
        and positive_definite(cov)
    )
    return GnssFixMeasurement(t_s, *position, cov, valid)


def velocity_measurement(msg: Any) -> GnssVelocityMeasurement:
    """geometry_msgs/TwistWithCovarianceStamped (ENU) -> velocity (``velocity_from_fields``)."""
    twist = msg.twist
    return velocity_from_fields(
        stamp_s(msg),
        _vec3(twist.twist.linear),
        np.asarray(twist.covariance, dtype=np.float64).reshape(6, 6),
    )


def velocity_from_fields(
    t_s: float, linear: Vec3, covariance: np.ndarray
) -> GnssVelocityMeasurement:
    """A TwistWithCovarianceStamped's fields -> antenna velocity: stamp [s], ENU velocity
    [m/s] and the linear 3x3 block of the 6x6 covariance [m²/s²] (a huge vertical variance =
    vertical not measured)."""
    return GnssVelocityMeasurement(t_s, np.array(linear), covariance[:3, :3])


def attitude_measurement(msg: Any) -> AttitudeMeasurement:
    """sensor_msgs/Imu of gnss/attitude -> orientation of FLU in ENU (x, y, z, w) and its
    roll/pitch/yaw covariance [rad²]. A message without an orientation
    (orientation_covariance[0] == -1, REP-145) gives infinite variances: no angle measured
    (the engine counts it as rejected)."""
    cov = np.asarray(msg.orientation_covariance, dtype=np.float64).reshape(3, 3)
    if cov[0, 0] == -1.0:
        cov = np.diag([math.inf] * 3)
    q = msg.orientation
    quat = np.array([float(q.x), float(q.y), float(q.z), float(q.w)])
    return AttitudeMeasurement(stamp_s(msg), quat, cov)
