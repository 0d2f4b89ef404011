"""What the measurement kinds share. Their models: the form of a model, the variances that mark
a component as not measured, ENU <-> NED covariances, the residual mounting, the gyro-error
columns of H, the Euler-angle Jacobian and the IMU time-offset terms of a GNSS measurement.
Their compiled updates: the covariance step and the prediction to the stamp (``step_to``) and
the gated Joseph update with the injection (``update_and_restart``, ``update_rows``), the
kernels each ``<kind>_apply`` is made of (their books: core.measurements.gate.KindUpdate).

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
from ins_fusion.core.compiled import compilable, jit
from ins_fusion.core.filter.eskf import BG, Columns, ErrorStateFilter, ProcessModel
from ins_fusion.core.filter.propagation import covariance_step, predicted_state
from ins_fusion.core.filter.records import Prediction
from ins_fusion.core.filter.state import X_COV_DT, X_COV_VEL0, X_VEL, FilterState, inject_nominal
from ins_fusion.core.filter.update_algebra import joseph_update
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
    H: FloatArray, d_rate: FloatArray, mat_bi: FloatArray, rate_i: FloatArray, columns: Columns
) -> None:
    """H's columns of the gyro bias, scale and scale asymmetry errors (``columns``:
    StateLayout.columns, -1 when not estimated) for a measurement that depends on the body
    rate through ``d_rate`` (rows x 3, d(measured)/dω_b, base FRD): dω_b/dδb_g = -R_bi,
    dω_b/dδs_g = -R_bi diag(ω_i), dω_b/dδa_g = -R_bi diag(|ω_i|)."""
    H[:, BG : BG + 3] = d_rate @ -mat_bi
    if columns.sg >= 0:
        H[:, columns.sg : columns.sg + 3] = d_rate @ (-mat_bi * rate_i)
    if columns.sr >= 0:
        H[:, columns.sr : columns.sr + 3] = d_rate @ (-mat_bi * np.abs(rate_i))


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


@jit
def step_to(
    P: FloatArray,
    x: FloatArray,
    t_m: float,
    process: ProcessModel,
    mat_bi: FloatArray,
    columns: Columns,
    correlation_time_s: float,
) -> tuple[bool, FloatArray, FloatArray, Prediction]:
    """What InsEngine._apply does before a model (heading known, no smoother): the covariance
    step over the interval accumulated in ``x`` when there is one (``covariance_step``) and
    the prediction to ``t_m`` [s]. Returns (stepped, Φ of the step (P when none), the new P,
    the prediction)."""
    stepped = not x[X_COV_DT] <= 0.0  # as Propagator.propagate_covariance decides
    phi = P
    if stepped:
        P, phi = covariance_step(P, x, mat_bi, process, columns, correlation_time_s)
    return stepped, phi, P, predicted_state(x, t_m)


@jit
def update_and_restart(
    P: FloatArray,
    x: FloatArray,
    model: tuple[FloatArray, FloatArray, FloatArray],
    threshold: float,
    columns: Columns,
) -> tuple[bool, float, FloatArray, FloatArray]:
    """The gated Joseph update of ``model`` (z, H, R), the injection into ``x`` when accepted
    and the covariance interval going on from the corrected velocity (what Corrections.update
    and InsEngine._apply do after the model; heading known). Returns (accepted, NIS, δx (z
    when rejected), new P (P when rejected))."""
    z, H, R = model
    accepted, nis, dx, P_new = joseph_update(P, z, H, R, threshold)
    if accepted:
        inject_nominal(x, dx, columns)
    restart_interval(x)
    return accepted, nis, dx, P_new


@jit
def update_rows(
    P: FloatArray,
    x: FloatArray,
    rows: int,
    model: tuple[FloatArray, FloatArray, FloatArray],
    gates: tuple[float, float, float],
    columns: Columns,
) -> tuple[bool, float, FloatArray]:
    """``update_and_restart`` of a model of ``rows`` rows (1-3) at the gate of that many
    (``gates``: of 1, 2 and 3 rows); a model without rows (nothing measured) updates nothing,
    and the covariance interval goes on from the velocity all the same. Returns (accepted,
    NIS (NaN without rows), new P)."""
    if rows == 0:
        restart_interval(x)
        return False, math.nan, P
    accepted, nis, _, P_new = update_and_restart(P, x, model, gates[rows - 1], columns)
    return accepted, nis, P_new


@jit
def restart_interval(x: FloatArray) -> None:
    """The covariance interval in ``x`` goes on from the current velocity (after an update,
    as InsEngine._apply)."""
    for k in range(3):
        x[X_COV_VEL0 + k] = x[X_VEL + k]
