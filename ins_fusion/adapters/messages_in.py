"""Incoming ROS messages -> fusion engine inputs, for rclpy and rosbags message objects alike.

One definition of how ins_fusion_node and ``gnss_ins replay`` read their topics (the IMU, at
134 Hz, only from its bytes: ins_fusion.adapters.cdr_fields; ``ImuSample`` is its record): the
functions only read fields by attribute (rclpy messages and rosbags-deserialized ones have the
same field names) and return the engine's plain types. No ROS import.

Conventions (ARCHITECTURE.md): every time is the message's ``header.stamp`` [s since the
epoch, host clock]; REP-103 ENU world and FLU body; REP-145 IMU data; a covariance whose first
element is -1 marks a quantity the message does not carry.

| topic | type | function | InsEngine input |
|---|---|---|---|
| imu/data_raw | Imu | ``cdr_fields.imu_sample`` (bytes) into ``HeldImu`` | ``add_imu_series`` |
| gnss/fix | NavSatFix | ``fix_measurement`` | ``add_gnss_fix`` |
| gnss/vel | TwistWithCovarianceStamped (ENU) | ``velocity_measurement`` | ``add_gnss_velocity`` |
| gnss/attitude | Imu (orientation only) | ``attitude_measurement`` | ``add_attitude`` |
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np

from gnss_ins_common.navsat import CovarianceType, NavSatStatus
from gnss_ins_common.types import BoolArray, FloatArray, Vec3
from ins_fusion.core.engine.engine import InsEngine
from ins_fusion.core.filter.records import (
    AttitudeMeasurement,
    GnssFixMeasurement,
    GnssVelocityMeasurement,
    VehicleSpeedMeasurement,
)
from ins_fusion.core.output.solution_rows import RowBuffer


class ImuSample(NamedTuple):
    """One imu/data_raw sample: stamp [s], rate [rad/s] and specific force [m/s²] in imu_link
    FLU (REP-145)."""

    t_s: float
    rate_flu_rad_s: Vec3
    force_flu_m_s2: Vec3


class HeldImu:
    """IMU samples held until the engine takes them together, in arrays as
    ``InsEngine.add_imu_series`` takes a replay's: the node's way into the engine is the
    replay's. At most ``capacity`` samples."""

    def __init__(self, capacity: int) -> None:
        self._t_s = np.empty(capacity)
        self._rate = np.empty((capacity, 3))
        self._force = np.empty((capacity, 3))
        self._ticks = np.zeros(capacity, dtype=np.bool_)  # no rows: the caller builds its own
        self._rows = RowBuffer()
        self.count = 0

    @property
    def full(self) -> bool:
        """Whether no further sample can be held."""
        return self.count == len(self._t_s)

    def hold(self, sample: ImuSample) -> None:
        """Keep ``sample`` after those held (not when ``full``)."""
        n = self.count
        self._t_s[n] = sample.t_s
        self._rate[n] = sample.rate_flu_rad_s
        self._force[n] = sample.force_flu_m_s2
        self.count = n + 1

    def take(self, engine: InsEngine) -> None:
        """The held samples into ``engine`` in their order; none held after it."""
        if self.count:
            span = (0, self.count)
            engine.add_imu_series(self._t_s, self._rate, self._force, self._ticks, span, self._rows)
            self.count = 0


def stamp_s(msg: Any) -> float:
    """``msg.header.stamp`` in seconds."""
    stamp = msg.header.stamp
    return float(stamp.sec) + float(stamp.nanosec) * 1e-9


def _vec3(v: Any) -> Vec3:
    return (float(v.x), float(v.y), float(v.z))


def positive_definite(cov: FloatArray) -> BoolArray:
    """Whether each 3x3 matrix of ``cov`` (..., 3, 3) is finite, symmetric and positive
    definite (...)."""
    turned = np.swapaxes(cov, -1, -2)
    with np.errstate(invalid="ignore", over="ignore"):  # a non-finite matrix is refused anyway
        # np.allclose's default tolerances, without its cost per matrix.
        asymmetric = (np.abs(cov - turned) > 1e-8 + 1e-5 * np.abs(turned)).any(axis=(-2, -1))
        # Sylvester's criterion on the lower triangle (what np.linalg.eigvalsh reads): the
        # leading principal minors are positive. Closed form: eigvalsh costs ~100 µs a matrix.
        a, d, b = cov[..., 0, 0], cov[..., 1, 0], cov[..., 1, 1]
        e, f, c = cov[..., 2, 0], cov[..., 2, 1], cov[..., 2, 2]
        minor2 = a * b - d * d
        minor3 = c * minor2 - a * f * f + 2.0 * d * e * f - b * e * e
        positive = (a > 0.0) & (minor2 > 0.0) & (minor3 > 0.0)
    result: BoolArray = np.isfinite(cov).all(axis=(-2, -1)) & ~asymmetric & positive
    return result


def fix_measurement(msg: Any) -> GnssFixMeasurement:
    """sensor_msgs/NavSatFix -> antenna position with its ENU covariance [m²]
    (``fixes_from_fields``)."""
    (fix,) = fixes_from_fields(
        np.array([stamp_s(msg)]),
        np.array([[msg.latitude, msg.longitude, msg.altitude]], dtype=np.float64),
        [int(msg.status.status)],
        [int(msg.position_covariance_type)],
        np.asarray(msg.position_covariance, dtype=np.float64).reshape(1, 3, 3),
    )
    return fix


def fixes_from_fields(
    t_s: FloatArray,
    lla: FloatArray,
    status: Sequence[int],
    covariance_type: Sequence[int],
    cov: FloatArray,
) -> list[GnssFixMeasurement]:
    """The fields of n NavSatFix messages -> antenna positions: stamps [s] (n,), (latitude
    [deg], longitude [deg], altitude [m]) (n, 3), status.status (n), position_covariance_type
    (n), covariances ENU [m²] (n, 3, 3).

    Valid only with a fix (status >= FIX; NO_FIX and UNKNOWN carry no position), finite
    latitude and longitude, and a known, finite, positive definite covariance (type not
    UNKNOWN; a zero or negative variance is no accuracy either): a position without an
    accuracy cannot be weighted. A NaN altitude or a vertical variance of at least
    HEIGHT_UNKNOWN_VARIANCE_M2 (gnss_ins_common.navsat) is a 2-D fix: valid on its horizontal
    part (``GnssFixMeasurement`` marks its height unknown); else the altitude is above the
    WGS-84 ellipsoid (ARCHITECTURE.md). Invalid fixes are still handed to the engine, which
    ignores and counts them.
    """
    fixes = [
        GnssFixMeasurement(t, lat, lon, alt, matrix)
        for t, (lat, lon, alt), matrix in zip(t_s.tolist(), lla.tolist(), cov, strict=True)
    ]
    marked = np.array([f.cov_enu_m2 for f in fixes]).reshape(-1, 3, 3)
    valid = (
        (np.asarray(status, dtype=np.int64) >= NavSatStatus.FIX)
        & (np.asarray(covariance_type, dtype=np.int64) != CovarianceType.UNKNOWN)
        & np.isfinite(lla[:, :2]).all(axis=1)
        & positive_definite(marked)
    )
    return [
        fix if ok else dataclasses.replace(fix, valid=False)
        for fix, ok in zip(fixes, valid.tolist(), strict=True)
    ]


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


def speed_measurement(msg: Any) -> VehicleSpeedMeasurement:
    """geometry_msgs/TwistWithCovarianceStamped (vehicle/speed) or nav_msgs/Odometry (wheel
    odometry, its twist in base_link) -> the forward speed twist.linear.x [m/s] and its variance
    covariance[0] [m²/s²] (<= 0 or NaN: not given)."""
    twist = msg.twist
    return speed_from_fields(stamp_s(msg), _vec3(twist.twist.linear), twist.covariance)


def speed_from_fields(
    t_s: float, linear: Sequence[float], covariance: Sequence[float]
) -> VehicleSpeedMeasurement:
    """A twist's fields -> the vehicle speed: stamp [s], the forward speed linear.x [m/s] and
    its variance, the first element of the row-major 6x6 covariance [m²/s²]."""
    return VehicleSpeedMeasurement(t_s, float(linear[0]), float(covariance[0]))


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
