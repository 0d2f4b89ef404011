"""What the measurement models of several kinds share: the form of a model, the variances that
mark a component as not measured, ENU <-> NED covariances, the residual mounting, the gyro-error
columns of H, the Euler-angle Jacobian and the IMU time-offset terms of a GNSS measurement.

Every model returns (z, H, R) with the innovation z = measured - predicted, so that
z ≈ H δx + v for the error state of core.filter.eskf (x_true = x_nominal + δx, C_true = (I + [ψ×])
C). The prediction is the nominal state at the measurement's own stamp (``Prediction``). Frames:
NED/FRD inside; the ROS-facing records (core.filter.records) use ENU/FLU (REP-103) like the messages
they come from. Lever arms are base_link FRD vectors from the IMU (the mechanised point) to
the point measured. Each kind's model is in its own module (gnss_position, gnss_velocity,
attitude, stationary, nhc, vehicle_speed).
"""

from __future__ import annotations

import math

import numpy as np

from gnss_ins_common.types import FloatArray
from ins_fusion.core.compiled import compilable
from ins_fusion.core.filter.eskf import BG, ErrorStateFilter
from ins_fusion.core.filter.state import FilterState
from ins_fusion.core.nav.rotation import skew

#: A variance at or above this marks a component as not measured: GNSS vertical velocity [m²/s²]
#: (the contract of gnss/vel) and attitude angles [rad²].
UNKNOWN_VELOCITY_VARIANCE = 1.0e4
UNKNOWN_ANGLE_VARIANCE = 1.0
#: ENU <-> NED: the axis each NED axis is read from and its sign (rotation.MAT_ENU_NED).
_AXIS = (1, 0, 2)
_SIGN = (1.0, 1.0, -1.0)

#: A measurement's model: innovation z, Jacobian H (rows x state size) and noise covariance R.
Model = tuple[FloatArray, FloatArray, FloatArray]


@compilable
def mounting_skew(mounting_rad: tuple[float, float]) -> FloatArray:
    """[μ×] of a residual mounting μ = (0, pitch, yaw) about base_link FRD y, z [rad]: the
    vehicle frame v is the engine's body frame b turned by it, C_bv = I + [μ×]."""
    return skew((0.0, mounting_rad[0], mounting_rad[1]))


@compilable
def ned_cov(cov_enu: FloatArray) -> FloatArray:
    """ENU covariance -> NED (and back: the axis swap is its own inverse), element by element
    (a product with MAT_ENU_NED would spread a non-finite vertical variance into the
    horizontal block)."""
    out = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            out[i, j] = _SIGN[i] * _SIGN[j] * cov_enu[_AXIS[i], _AXIS[j]]
    return out


@compilable
def gyro_error_columns(
    H: FloatArray, d_rate: FloatArray, mat_bi: FloatArray, rate_i: FloatArray, sg: int
) -> None:
    """H's columns of the gyro bias and scale errors (``sg``: the scale's first column, -1
    when not estimated) for a measurement that depends on the body rate through ``d_rate``
    (rows x 3, d(measured)/dω_b, base FRD): dω_b/dδb_g = -R_bi, dω_b/dδs_g = -R_bi diag(ω_i)."""
    H[:, BG : BG + 3] = d_rate @ -mat_bi
    if sg >= 0:
        H[:, sg : sg + 3] = d_rate @ (-mat_bi * rate_i)


@compilable
def euler_jacobian(mat_nb: FloatArray) -> FloatArray:
    """d(roll, pitch, yaw)/dψ for C_true = (I + [ψ×]) C (rows roll, pitch, yaw)."""
    c = mat_nb
    d_roll = c[2, 1] ** 2 + c[2, 2] ** 2
    d_yaw = c[0, 0] ** 2 + c[1, 0] ** 2
    cos_pitch = math.sqrt(d_yaw)
    return np.array(
        (
            (
                (c[2, 2] * c[1, 1] - c[2, 1] * c[1, 2]) / d_roll,
                (c[2, 1] * c[0, 2] - c[2, 2] * c[0, 1]) / d_roll,
                0.0,
            ),
            (-c[1, 0] / cos_pitch, c[0, 0] / cos_pitch, 0.0),
            (-c[0, 0] * c[2, 0] / d_yaw, -c[1, 0] * c[2, 0] / d_yaw, 1.0),
        )
    )


def late_imu(
    s: FilterState,
    kf: ErrorStateFilter,
    model: Model,
    rate_n: FloatArray,
    min_rate: float,
    second_n: FloatArray | None = None,
) -> Model:
    """A GNSS measurement at its epoch t compared with the state at t + t̂_d, the estimated
    residual IMU time offset (the IMU timeline runs late by it): the prediction moves by
    rate·t̂_d (+ second·t̂_d²/2 when the second derivative is given) and H gets the rate
    at t + t̂_d on δt_d (rate, second: first and second time derivative of the measured
    quantity, NED). Below ``min_rate`` the offset is frozen (H stays 0): the rate is then
    mostly noise, and a noisy H would move the estimate without cause. Only with the time
    offset state (the attitude's terms are in its compiled model)."""
    td = kf.layout.td
    assert td is not None
    z, H, R = model
    rows = len(z)
    offset = s.time_offset
    shift = rate_n[:rows] * offset
    if second_n is not None:
        shift = shift + second_n[:rows] * (0.5 * offset * offset)
        rate_n = rate_n + second_n * offset
    if float(np.linalg.norm(rate_n[:rows])) >= min_rate:
        H[:, td] = rate_n[:rows]
    return z - shift, H, R
