"""The GNSS velocity update: its model, its handler and its compiled update with the covariance
step before it.

The model (``gnss_velocity``, compiled ``velocity_model``) is the antenna's velocity, the
vertical row only when it is measured; the handler (``VelocityUpdate``) sets the heading from
the course while it is unknown (core.measurements.heading), builds the model, adds the IMU
time-offset terms when that state is estimated and calls Corrections.update
(core.measurements.gate).

Every fix comes with a velocity, and both arrive late: each is applied once when it arrives
and again in every re-propagation through its stamp. The general way (InsEngine._apply:
Propagator.propagate_covariance and predict, ``VelocityUpdate`` with the model
``velocity_model``, Corrections.update with the Joseph update and the injection) is five
kernels with Python between them; ``velocity_apply`` runs the same kernels in the same order in
one call (``step_to`` and ``update_rows`` of core.measurements.common), so the numbers are the
same to the bit, and ``VelocityUpdate.fused`` keeps the books (NIS, process-noise adaptation, gated
runs, counters). Taken only where the general way would do nothing else: the heading known, velocity
updates on, no time-offset state (its terms), no smoother (its history hears each step), and
no gate recovery possible (fewer gated updates in a row than the recovery needs).
"""

from __future__ import annotations

import math

import numpy as np

from gnss_ins_common.types import FloatArray
from ins_fusion.core.compiled import jit, kernel_array
from ins_fusion.core.filter.eskf import (
    ATT,
    VEL,
    Columns,
    ErrorStateFilter,
    ProcessModel,
    StateLayout,
)
from ins_fusion.core.filter.records import GnssVelocityMeasurement, Prediction
from ins_fusion.core.filter.state import FilterState
from ins_fusion.core.measurements.common import (
    UNKNOWN_VELOCITY_VARIANCE,
    Model,
    gyro_error_columns,
    late_imu,
    ned_cov,
    step_to,
    update_rows,
)
from ins_fusion.core.measurements.gate import EngineParts, Kind, KindUpdate
from ins_fusion.core.measurements.heading import fast_enough, heading_from_course
from ins_fusion.core.nav.rotation import skew
from ins_fusion.core.settings.config import FusionConfig

#: GNSS velocities: they adapt the process noise; a recovery widens the velocity.
VELOCITY = Kind("gnss_velocity", adapts=True, recovery_block=VEL)
#: A velocity that set the unknown heading from the course (counted, no update of its own).
COURSE_HEADING = Kind("course_heading")
#: The IMU time offset is observed only above this acceleration [m/s²] (``late_imu``).
_TIME_OFFSET_MIN_ACCEL_M_S2 = 0.3


def gnss_velocity(
    pred: Prediction,
    layout: StateLayout,
    meas: GnssVelocityMeasurement,
    lever_b: FloatArray,
    mat_bi: FloatArray,
) -> Model | None:
    """Antenna velocity v + C_nb (ω_b × l) (the ω_in × C l term, < 2e-4 m/s, is left out);
    horizontal rows only when the vertical is unknown (its velocity or variance not finite, or
    the variance at least UNKNOWN_VELOCITY_VARIANCE). None when the horizontal is unusable.
    Compiled (``velocity_model``)."""
    rows, z, H, R = velocity_model(
        pred,
        lever_b,
        mat_bi,
        kernel_array(meas.vel_enu_m_s),
        kernel_array(meas.cov_enu_m2_s2),
        layout.size,
        layout.columns,
    )
    return None if rows == 0 else (z, H, R)


@jit
def velocity_model(
    pred: Prediction,
    lever_b: FloatArray,
    mat_bi: FloatArray,
    vel_enu: FloatArray,
    cov_enu: FloatArray,
    size: int,
    columns: Columns,
) -> tuple[int, FloatArray, FloatArray, FloatArray]:
    """``gnss_velocity``'s model (rows, z, H, R; 0 rows: unusable) from the prediction, the
    measured ENU velocity and covariance, the layout's size and columns (-1: not estimated)."""
    mat_nb, vel, rate_b, rate_i = pred.mat_nb, pred.vel_ned_m_s, pred.rate_b, pred.rate_i
    measured = np.array((vel_enu[1], vel_enu[0], -vel_enu[2]))
    cov = ned_cov(cov_enu)
    if not np.isfinite(measured[:2]).all() or not np.isfinite(cov[:2, :2]).all():
        return 0, measured[:0], np.zeros((0, size)), cov[:0, :0].copy()
    vertical = math.isfinite(measured[2]) and cov[2, 2] < UNKNOWN_VELOCITY_VARIANCE
    rows = 3 if vertical else 2
    rot_n = mat_nb @ (skew(rate_b) @ lever_b)
    H = np.zeros((3, size))
    for k in range(3):
        H[k, VEL + k] = 1.0
    H[:, ATT : ATT + 3] = -skew(rot_n)
    gyro_error_columns(H, -(mat_nb @ skew(lever_b)), mat_bi, rate_i, columns)
    z = measured - vel - rot_n
    return rows, z[:rows].copy(), H[:rows].copy(), cov[:rows, :rows].copy()


class VelocityUpdate(KindUpdate):
    """The engine's update of GNSS velocities (core.measurements.gate.KindUpdate): while the
    heading is unknown, the heading from the course when fast enough (counted as a
    ``course_heading`` used) or nothing when too fast to align; else, with velocity updates on,
    the model, its time-offset terms (``late_imu``) and the gated update; ``fused`` with
    ``velocity_apply``."""

    def __init__(self, config: FusionConfig, parts: EngineParts) -> None:
        super().__init__(config, parts)
        self._gnss_noise, self._latest = parts.gnss_noise, parts.latest

    def __call__(
        self,
        s: FilterState,
        kf: ErrorStateFilter,
        pred: Prediction,
        vel: GnssVelocityMeasurement,
        live: bool,
    ) -> None:
        config, corrections = self._config, self._corrections
        if not s.heading_known:
            if config.use_course_heading and fast_enough(vel, config.course_speed_m_s):
                applied = heading_from_course(
                    s, kf, self._geometry, self._gnss_noise, self._latest.fix, vel
                )
                if applied:
                    corrections.count_used(COURSE_HEADING, live)
                return
            if corrections.too_fast_to_align(pred, live, VELOCITY):
                return
        if not config.use_gnss_velocity:
            return
        geometry = self._geometry
        model = gnss_velocity(pred, kf.layout, vel, geometry.arms(s)[0], geometry.mat_bi)
        if model is None:
            corrections.reject(VELOCITY, live)
            return
        if kf.layout.td is not None:
            model = late_imu(s, kf, model, np.array(s.accel_lp), _TIME_OFFSET_MIN_ACCEL_M_S2)
        corrections.update(s, kf, VELOCITY, model, live)

    def fused(
        self,
        s: FilterState,
        kf: ErrorStateFilter,
        record: tuple[float, GnssVelocityMeasurement],
        live: bool,
    ) -> bool:
        if not (self._config.use_gnss_velocity and self._sensor_usable(s, kf, VELOCITY)):
            return False
        vel, geometry = record[1], self._geometry
        result = self._kernel(
            velocity_apply,
            (s, kf),
            (vel.t_s, kernel_array(vel.vel_enu_m_s), kernel_array(vel.cov_enu_m2_s2)),
            (geometry.mat_bi, kernel_array(geometry.arms(s)[0])),
            (self._correlation_time_s, self._gates, kf.layout.size),
        )
        self._sensor_taken((s, kf), VELOCITY, result, live)
        return True


@jit
def velocity_apply(
    P: FloatArray,
    x: FloatArray,
    measured: tuple[float, FloatArray, FloatArray],
    process: ProcessModel,
    geometry: tuple[FloatArray, FloatArray],
    columns: Columns,
    constants: tuple[float, tuple[float, float, float], int],
) -> tuple[bool, FloatArray, int, bool, float, FloatArray]:
    """The GNSS velocity ``measured`` = (stamp [s], ENU velocity [m/s], its covariance
    [m²/s²]) on the error covariance ``P`` and the nominal state ``x`` (X_* layout, changed in
    place; heading known): ``step_to`` the stamp, the model of the antenna (``geometry``:
    rotation imu -> body, lever arm of the antenna from the IMU [m], body FRD) and
    ``update_rows``. ``constants``: GNSS correlation time [s], the gates of 1, 2 and 3 rows,
    state size. Returns (stepped, Φ of the step (P when none), rows of the model
    (0: unusable), accepted, NIS, the new P)."""
    t_m, vel_enu, cov_enu = measured
    mat_bi, arm_b = geometry
    correlation_time_s, gates, size = constants
    stepped, phi, P, prediction = step_to(P, x, t_m, process, mat_bi, columns, correlation_time_s)
    rows, z, H, R = velocity_model(
        prediction,
        arm_b,
        mat_bi,
        vel_enu,
        cov_enu,
        size,
        columns,
    )
    accepted, nis, P_new = update_rows(P, x, rows, (z, H, R), gates, columns)
    return stepped, phi, rows, accepted, nis, P_new
