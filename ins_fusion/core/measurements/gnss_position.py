"""The GNSS position update: its model, its handler and its compiled update with the covariance
step before it (the noise split of the fix's covariance is core.measurements.gnss_noise).

The model (``gnss_position``, compiled ``position_model``) is the antenna's position with the
estimated time-correlated receiver error; the handler (``PositionUpdate``) splits the fix's
covariance into white and correlated parts, builds the model, adds the IMU time-offset terms
when that state is estimated and calls Corrections.update (core.measurements.gate).

A fix is the engine's largest update and, arriving late, is applied again in every
re-propagation through its stamp. The general way (InsEngine._apply: the covariance step and
the prediction, ``PositionUpdate``: the white/correlated split of the fix's covariance
``gnss_noise._position_noise``, the model ``position_model``, diag(H P Hᵀ), Corrections.update
with the Joseph update and the injection, the white-noise monitor's push
``adaptation.white_push_fix``) is seven kernels with Python between them. ``position_apply``
runs the same kernels in the same order in one call, so the numbers are the same to the bit,
and ``PositionUpdate.fused`` keeps the books (NIS, process-noise adaptation, gated runs,
counters, the last fix used). Taken only where the general way would do nothing else: a valid
fix, the heading known, no time-offset state, no smoother, no gate recovery possible; and when
the split asks for a restart of the correlated error states, the kernel stops after the
covariance step and the general way goes on from there (a new variance of theirs it sets
itself).
"""

from __future__ import annotations

import math

import numpy as np

from gnss_ins_common.types import FloatArray
from ins_fusion.core.compiled import jit, kernel_array
from ins_fusion.core.filter.adaptation import FixUpdate, white_push_fix
from ins_fusion.core.filter.eskf import (
    ATT,
    POS,
    Columns,
    ErrorStateFilter,
    ProcessModel,
    StateLayout,
)
from ins_fusion.core.filter.records import GnssFixMeasurement, Prediction, height_measured
from ins_fusion.core.filter.state import (
    X_GNSS_ERROR,
    X_GNSS_REPORTED,
    X_GNSS_VARIANCE,
    FilterState,
)
from ins_fusion.core.filter.update_algebra import projected_variance
from ins_fusion.core.measurements.common import Model, late_imu, step_to, update_and_restart
from ins_fusion.core.measurements.gate import EngineParts, Kind, KindUpdate
from ins_fusion.core.measurements.gnss_noise import (
    NOISE_MOVED,
    NOISE_RESTART,
    _position_noise,
    shrink_correlated,
)
from ins_fusion.core.nav import earth
from ins_fusion.core.nav.rotation import skew
from ins_fusion.core.settings.config import FusionConfig

#: GNSS fixes: they adapt the process noise; a recovery widens the position.
POSITION = Kind("gnss_position", adapts=True, recovery_block=POS)
#: The IMU time offset is observed only above this speed of the antenna [m/s] (``late_imu``).
_TIME_OFFSET_MIN_SPEED_M_S = 1.0


def gnss_position(
    pred: Prediction,
    layout: StateLayout,
    meas: GnssFixMeasurement,
    lever_b: FloatArray,
    white_cov_ned: FloatArray,
    gnss_error_ned: tuple[float, float, float],
) -> Model:
    """Antenna position p + C_nb l plus the estimated time-correlated receiver error ε_g (when
    it is a state). H: δp -> I, ψ -> -[(C_nb l)×], δε_g -> I; R: the white part of the
    receiver's covariance. North and east rows only for a 2-D fix. Compiled
    (``position_model``)."""
    return position_model(
        pred,
        (math.radians(meas.lat_deg), math.radians(meas.lon_deg), meas.height_m),
        lever_b,
        white_cov_ned,
        gnss_error_ned,
        layout.size,
        layout.columns.gp,
        meas.height_known,
    )


@jit
def position_model(
    pred: Prediction,
    fix_rad: tuple[float, float, float],
    lever_b: FloatArray,
    white_cov_ned: FloatArray,
    gnss_error_ned: tuple[float, float, float],
    size: int,
    gp: int,
    vertical: bool,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``gnss_position``'s model from the prediction, the fix's latitude, longitude [rad] and
    height [m] and the layout's size and GNSS error column (-1: none); without ``vertical`` (a
    2-D fix) the north and east rows only."""
    lat_rad, lon_rad, height_m, mat_nb = pred.lat_rad, pred.lon_rad, pred.height_m, pred.mat_nb
    fix_lat_rad, fix_lon_rad, fix_height_m = fix_rad
    arm_n = mat_nb @ lever_b
    r_m, r_n = earth.radii_from_sin(math.sin(lat_rad))
    offset = (
        (fix_lat_rad - lat_rad) * (r_m + height_m),
        (fix_lon_rad - lon_rad) * (r_n + height_m) * math.cos(lat_rad),
        height_m - fix_height_m,
    )
    H = np.zeros((3, size))
    z = np.empty(3)
    for k in range(3):
        H[k, POS + k] = 1.0
        if gp >= 0:
            H[k, gp + k] = 1.0
        z[k] = offset[k] - arm_n[k] - gnss_error_ned[k]
    H[:, ATT : ATT + 3] = -skew(arm_n)
    rows = 3 if vertical else 2
    return z[:rows].copy(), H[:rows].copy(), white_cov_ned[:rows, :rows].copy()


class PositionUpdate(KindUpdate):
    """The engine's update of GNSS fixes (core.measurements.gate.KindUpdate): an invalid fix is
    rejected, the noise split (``GnssNoise.position_noise``) with the restart or new variance of
    the correlated error states it asks for, the model, its time-offset terms (``late_imu``),
    the gated update and the white-noise monitor's push; ``fused`` with ``position_apply``."""

    def __init__(self, config: FusionConfig, parts: EngineParts) -> None:
        super().__init__(config, parts)
        self._noise = parts.gnss_noise

    def __call__(
        self,
        s: FilterState,
        kf: ErrorStateFilter,
        pred: Prediction,
        fix: GnssFixMeasurement,
        live: bool,
    ) -> None:
        corrections = self._corrections
        if not (fix.valid and np.isfinite(fix.cov_enu_m2).all()):
            corrections.reject(POSITION, live)
            return
        if not s.heading_known and corrections.too_fast_to_align(pred, live, POSITION):
            return
        noise = self._noise
        white, correlated, reported, action = noise.position_noise(s, fix)
        if action == NOISE_RESTART:
            noise.restart_error(s, kf, correlated, reported)
        elif action == NOISE_MOVED:  # the white/correlated split moved
            noise.set_correlated_variance(s, kf, correlated)
        antenna_b = self._geometry.arms(s)[0]
        model = gnss_position(pred, kf.layout, fix, antenna_b, white, s.gnss_error)
        if kf.layout.td is not None:
            antenna_rate_n = pred.vel_ned_m_s + pred.mat_nb @ (skew(s.rate_lp) @ antenna_b)
            model = late_imu(
                s, kf, model, antenna_rate_n, _TIME_OFFSET_MIN_SPEED_M_S, np.array(s.accel_lp)
            )
        z, H, _ = model
        predicted = projected_variance(H, kf.P)
        # Until the receiver's noise is learnt, it, not the state, may be off: no recovery.
        dx = corrections.update(s, kf, POSITION, model, live, s.gnss_white.ready)
        s.gnss_white = s.gnss_white.pushed_fix(fix.t_s, z, H, dx, kf.P, predicted, reported)
        if dx is not None:
            s.last_position_t_s = max(s.last_position_t_s, fix.t_s)

    def fused(
        self,
        s: FilterState,
        kf: ErrorStateFilter,
        record: tuple[float, GnssFixMeasurement],
        live: bool,
    ) -> bool:
        """``position_apply`` where the general way would do what it does (False: the general
        way applies the fix, possibly after the covariance step the kernel made)."""
        fix = record[1]
        if kf.smoother_hooks is not None or kf.layout.td is not None or not s.heading_known:
            return False
        if not (fix.valid and np.isfinite(fix.cov_enu_m2).all()):
            return False
        recover = self._config.gate_recovery_count
        ready = s.gnss_white.ready  # else a gated fix is no reason for a recovery
        if recover and ready and s.gated_runs.get(POSITION.name, 0) + 1 >= recover:
            return False
        kf.set_white_noise(*self._propagator.white_noise(s))  # read only by a step
        geometry, corrections = self._geometry, self._corrections
        rows = 3 if fix.height_known else 2
        white = s.gnss_white.values.copy()
        stepped, phi, action, P, accepted, nis = position_apply(
            kernel_array(kf.P),
            s.x,
            (
                fix.t_s,
                math.radians(fix.lat_deg),
                math.radians(fix.lon_deg),
                fix.height_m,
                kernel_array(fix.cov_enu_m2),
            ),
            kf.process_model(),
            (geometry.mat_bi, kernel_array(geometry.arms(s)[0])),
            kf.layout.columns,
            (white, self._noise.settings(s)),
            (self._correlation_time_s, corrections.gate(rows), kf.layout.size),
        )
        self._taken(kf, stepped, phi, P)
        if action == NOISE_RESTART:
            return False
        if action == NOISE_MOVED:  # the kernel set it in the state (set_correlated_variance)
            kf.gnss_variance = s.gnss_variance
        self._booked(s, POSITION, (accepted, nis), rows, live)
        s.gnss_white = s.gnss_white.with_values(white)
        if accepted:
            s.last_position_t_s = max(s.last_position_t_s, fix.t_s)
        return True


@jit
def position_apply(
    P: FloatArray,
    x: FloatArray,
    measured: tuple[float, float, float, float, FloatArray],
    process: ProcessModel,
    geometry: tuple[FloatArray, FloatArray],
    columns: Columns,
    noise: tuple[FloatArray, tuple[float, FloatArray, float, FloatArray]],
    constants: tuple[float, float, int],
) -> tuple[bool, FloatArray, int, FloatArray, bool, float]:
    """The fix ``measured`` = (stamp [s], latitude, longitude [rad], height [m], ENU
    covariance [m²]) on the error covariance ``P`` and the nominal state ``x`` (X_* layout,
    changed in place; heading known): ``step_to`` the stamp, the white/correlated split
    (``noise``: the white-noise monitor's values, GnssNoise.settings) with the new variance of
    the correlated error states when it moved (``shrink_correlated``), the model of the antenna
    (``geometry``: rotation imu -> body, lever arm of the antenna from the IMU [m], body FRD),
    diag(H P Hᵀ), ``update_and_restart`` and the push of the white-noise monitor's values (in
    place). ``constants``: GNSS correlation time [s], the gate of the fix's rows (3, a 2-D fix
    2: ``height_measured``), state size.
    Returns (stepped, Φ of the step (P when none), what the split asked of the correlated
    error states (gnss_noise.NOISE_*), the new P, accepted, NIS); NOISE_RESTART: nothing
    after the covariance step was made."""
    t_m, fix_lat, fix_lon, fix_height, cov_enu = measured
    mat_bi, arm_b = geometry
    white, (scale_sq, white_var_ned, white_fraction, share) = noise
    correlation_time_s, threshold, size = constants
    stepped, phi, P, prediction = step_to(P, x, t_m, process, mat_bi, columns, correlation_time_s)
    gp = columns.gp
    vertical = height_measured(fix_height, cov_enu[2, 2])
    R, correlated, reported, action = _position_noise(
        cov_enu,
        scale_sq,
        white_var_ned,
        white_fraction,
        share,
        (gp >= 0, vertical),
        (x[X_GNSS_REPORTED], x[X_GNSS_REPORTED + 1], x[X_GNSS_REPORTED + 2]),
        (x[X_GNSS_VARIANCE], x[X_GNSS_VARIANCE + 1], x[X_GNSS_VARIANCE + 2]),
    )
    if action == NOISE_RESTART:
        return stepped, phi, action, P, False, math.nan
    if action == NOISE_MOVED:
        _, P, _ = shrink_correlated(P, x, correlated, gp)
    error = (x[X_GNSS_ERROR], x[X_GNSS_ERROR + 1], x[X_GNSS_ERROR + 2])
    z, H, R = position_model(
        prediction,
        (fix_lat, fix_lon, fix_height),
        arm_b,
        R,
        error,
        size,
        gp,
        vertical,
    )
    predicted = projected_variance(H, P)
    accepted, nis, dx, P_new = update_and_restart(P, x, (z, H, R), threshold, columns)
    white_push_fix(white, t_m, FixUpdate(z, H, dx, accepted, P_new), predicted, reported)
    return stepped, phi, action, P_new, accepted, nis
