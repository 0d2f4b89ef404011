"""The attitude update (ADU5): its model, its handler and its compiled update with the
covariance step before it.

The model (``attitude``, compiled ``attitude_model``) is base_link's Euler angles, the angles
marked unknown left out; the handler (``AttitudeUpdate``) sets the heading from the measured
yaw while it is unknown (core.measurements.heading) and otherwise calls Corrections.update
(core.measurements.gate) with the model.

An attitude receiver's epochs arrive late like the fixes, so each is applied once on arrival
and again in every re-propagation through its stamp. The general way (InsEngine._apply: the
covariance step and the prediction, ``AttitudeUpdate`` with Geometry.measured_mat_nb and the
model ``attitude_model``, Corrections.update with the Joseph update and the injection) is five
kernels with Python between them; ``attitude_apply`` runs the same kernels in the same order in
one call, so the numbers are the same to the bit, and ``AttitudeUpdate.fused`` keeps the books (NIS,
gated runs, counters). Taken only where the general way would do nothing else: the heading
known (else the attitude sets it), no time-offset state, no smoother, and no gate recovery
possible.
"""

from __future__ import annotations

import math

import numpy as np

from gnss_ins_common.types import FloatArray, Quat
from ins_fusion.core.compiled import jit, kernel_array
from ins_fusion.core.filter.eskf import ATT, Columns, ErrorStateFilter, ProcessModel, StateLayout
from ins_fusion.core.filter.records import AttitudeMeasurement, Prediction
from ins_fusion.core.filter.state import X_MOUNTING, FilterState, base_mat_nb
from ins_fusion.core.measurements.common import (
    UNKNOWN_ANGLE_VARIANCE,
    Model,
    euler_jacobian,
    mounting_skew,
    step_to,
    update_rows,
)
from ins_fusion.core.measurements.gate import Kind, KindUpdate
from ins_fusion.core.measurements.heading import set_heading
from ins_fusion.core.nav.rotation import as_quat, euler_rad, wrap_angle

#: The attitude receiver's epochs; a recovery widens the attitude.
ATTITUDE = Kind("attitude", recovery_block=ATT)
#: FLU <-> FRD sign flips of the (roll, pitch, yaw) errors of a REP-103 orientation covariance.
_RPY_SIGN = (1.0, -1.0, -1.0)
#: Attitude measurements observe the IMU time offset only above this Euler rate [rad/s].
TIME_OFFSET_MIN_TURN_RATE = math.radians(2.0)


def attitude(
    pred: Prediction,
    layout: StateLayout,
    mat_nb_measured: FloatArray,
    cov_rpy_flu: FloatArray,
    time_offset_s: float = 0.0,
    mounting_rad: tuple[float, float] = (0.0, 0.0),
) -> Model | None:
    """Euler angles (roll, pitch, yaw) of base_link; angles marked unknown are dropped.

    The REP-103 covariance (errors about the FLU axes) becomes the covariance of the NED Euler
    angles by the sign flips of pitch and yaw (element by element: a non-finite variance of one
    angle leaves the others usable). None when no angle is measured. With a residual IMU time
    offset state, the measurement is compared with the attitude ``time_offset_s`` later on the
    IMU's timeline: the Euler angles move by their rate J C_nb ω_b (the earth and transport
    rates, < 1e-4 rad/s, left out) times it, and H gets that rate on δt_d when above
    ``TIME_OFFSET_MIN_TURN_RATE`` (a slower one is mostly gyro noise). The measured frame is
    the vehicle's: C_nb (I + [μ×]) with the residual mounting μ = (0, pitch, yaw), which is
    ψ = C_nb μ, so H gets J C_nb on (μ_y, μ_z). Compiled (``attitude_model``).
    """
    rows, z, H, R = attitude_model(
        kernel_array(pred.mat_nb),
        kernel_array(mat_nb_measured),
        kernel_array(cov_rpy_flu),
        mounting_rad,
        (kernel_array(pred.rate_b), time_offset_s),
        layout.size,
        layout.columns.mt,
        layout.columns.td,
    )
    return None if rows == 0 else (z, H, R)


@jit
def attitude_model(
    mat_nb: FloatArray,
    mat_nb_measured: FloatArray,
    cov_rpy_flu: FloatArray,
    mounting_rad: tuple[float, float],
    late: tuple[FloatArray, float],
    size: int,
    mt: int,
    td: int,
) -> tuple[int, FloatArray, FloatArray, FloatArray]:
    """``attitude``'s model (rows, z, H, R; 0 rows: no angle measured) from the predicted and
    the measured body -> NED rotation, the REP-103 covariance [rad²], the residual mounting
    (pitch, yaw) [rad], ``late`` = (the corrected body rate [rad/s], base FRD, the IMU time
    offset estimate [s]), the layout's size and its mounting and time-offset columns (-1: not
    estimated)."""
    cov = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            cov[i, j] = _RPY_SIGN[i] * _RPY_SIGN[j] * cov_rpy_flu[i, j]
    keep = np.empty(3, dtype=np.int64)
    rows = 0
    for k in range(3):
        if math.isfinite(cov[k, k]) and cov[k, k] < UNKNOWN_ANGLE_VARIANCE:
            keep[rows] = k
            rows += 1
    if rows == 0:
        return 0, np.zeros(0), np.zeros((0, size)), np.zeros((0, 0))
    mat_nv = mat_nb
    if mounting_rad[0] != 0.0 or mounting_rad[1] != 0.0:
        mat_nv = mat_nb @ (np.eye(3) + mounting_skew(mounting_rad))
    z = wrap_angle(euler_rad(mat_nb_measured) - euler_rad(mat_nv))
    H = np.zeros((3, size))
    jacobian = euler_jacobian(mat_nv)
    H[:, ATT : ATT + 3] = jacobian
    if mt >= 0:
        H[:, mt : mt + 2] = (jacobian @ mat_nb)[:, 1:3]
    if td >= 0:
        rate_b, time_offset_s = late
        euler_rate = jacobian @ (mat_nb @ rate_b)
        z = z - euler_rate * time_offset_s
        if math.sqrt(euler_rate @ euler_rate) >= TIME_OFFSET_MIN_TURN_RATE:
            H[:, td] = euler_rate
    keep = keep[:rows]
    R = np.empty((rows, rows))
    for a in range(rows):
        for b in range(rows):
            R[a, b] = cov[keep[a], keep[b]]
    return rows, z[keep], H[keep], R


class AttitudeUpdate(KindUpdate):
    """The engine's update of attitude epochs (core.measurements.gate.KindUpdate): while the
    heading is unknown, a measured yaw sets it (counted used); else the model and the gated
    update (an epoch without a measured angle rejected); ``fused`` with ``attitude_apply``."""

    def __call__(
        self,
        s: FilterState,
        kf: ErrorStateFilter,
        pred: Prediction,
        att: AttitudeMeasurement,
        live: bool,
    ) -> None:
        corrections = self._corrections
        mat_nb = self._geometry.measured_mat_nb(att)
        if not s.heading_known:
            yaw_variance = float(att.cov_rpy_rad2[2, 2])
            if math.isfinite(yaw_variance) and yaw_variance < UNKNOWN_ANGLE_VARIANCE:
                set_heading(s, kf, self._geometry, float(euler_rad(mat_nb)[2]), yaw_variance)
                corrections.count_used(ATTITUDE, live)
            return
        model = attitude(pred, kf.layout, mat_nb, att.cov_rpy_rad2, s.time_offset, s.mounting)
        if model is None:
            corrections.reject(ATTITUDE, live)
            return
        corrections.update(s, kf, ATTITUDE, model, live)

    def fused(
        self,
        s: FilterState,
        kf: ErrorStateFilter,
        record: tuple[float, AttitudeMeasurement],
        live: bool,
    ) -> bool:
        if not self._sensor_usable(s, kf, ATTITUDE):
            return False
        att, geometry = record[1], self._geometry
        result = self._kernel(
            attitude_apply,
            (s, kf),
            (att.t_s, as_quat(att.quat_enu_flu_xyzw), kernel_array(att.cov_rpy_rad2)),
            (geometry.mat_bi, geometry.q_a_base),
            (self._correlation_time_s, self._gates, kf.layout.size),
        )
        self._sensor_taken((s, kf), ATTITUDE, result, live)
        return True


@jit
def attitude_apply(
    P: FloatArray,
    x: FloatArray,
    measured: tuple[float, Quat, FloatArray],
    process: ProcessModel,
    geometry: tuple[FloatArray, Quat],
    columns: Columns,
    constants: tuple[float, tuple[float, float, float], int],
) -> tuple[bool, FloatArray, int, bool, float, FloatArray]:
    """The attitude ``measured`` = (stamp [s], REP-103 orientation (x, y, z, w) of the
    receiver's frame, covariance of its roll, pitch, yaw [rad²]) on the error covariance ``P``
    and the nominal state ``x`` (X_* layout, changed in place; heading known): ``step_to`` the
    stamp, the model of base_link's Euler angles (``geometry``: rotation imu -> body, rotation
    of base_link in the receiver's frame) and ``update_rows``.
    ``constants``: GNSS correlation time [s], the gates of 1, 2 and 3 rows, state size.
    Returns (stepped, Φ of the step (P when none), rows of the model (0: no angle measured),
    accepted, NIS, the new P)."""
    t_m, quat_a, cov_rpy = measured
    mat_bi, q_a_base = geometry
    correlation_time_s, gates, size = constants
    stepped, phi, P, prediction = step_to(P, x, t_m, process, mat_bi, columns, correlation_time_s)
    rows, z, H, R = attitude_model(
        prediction.mat_nb,
        base_mat_nb(quat_a, q_a_base),
        cov_rpy,
        (x[X_MOUNTING], x[X_MOUNTING + 1]),
        (prediction.rate_b, 0.0),
        size,
        columns.mt,
        -1,
    )
    accepted, nis, P_new = update_rows(P, x, rows, (z, H, R), gates, columns)
    return stepped, phi, rows, accepted, nis, P_new
