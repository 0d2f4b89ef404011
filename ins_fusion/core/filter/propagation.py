"""Time update of the engine: one IMU increment through the strapdown (with the filter's sensor
error estimates and the mounting), the error covariance every ``covariance_interval``, the
prediction of the nominal state to a measurement's stamp, and the increment that bridges
missing samples.

Frames: imu FRD increments, base_link FRD body, NED navigation (core.nav.strapdown,
core.filter.eskf).
"""

from __future__ import annotations

import math

import numpy as np

from gnss_ins_common.types import FloatArray, Vec3
from ins_fusion.core.compiled import compilable, jit, kernel_array
from ins_fusion.core.filter.adaptation import B_MEAN, B_VERSION, ImuNoiseMonitor
from ins_fusion.core.filter.eskf import (
    ATT,
    VEL,
    Columns,
    ErrorStateFilter,
    Motion,
    ProcessModel,
    propagate_kernel,
)
from ins_fusion.core.filter.records import Prediction
from ins_fusion.core.filter.state import (
    X_ACCEL_LP,
    X_ACCEL_N,
    X_BA,
    X_BG,
    X_COV_DT,
    X_COV_DTH,
    X_COV_DV,
    X_COV_VEL0,
    X_GNSS_ERROR,
    X_HAS_PREV,
    X_HEIGHT,
    X_LAT,
    X_LON,
    X_NAV,
    X_PREV,
    X_QUAT,
    X_RATE_B,
    X_RATE_I,
    X_RATE_LP,
    X_SA,
    X_SG,
    X_SR,
    X_T,
    X_VEL,
    FilterState,
    Geometry,
    decouple_yaw,
)
from ins_fusion.core.filter.timeline import Gap
from ins_fusion.core.nav import earth
from ins_fusion.core.nav.rotation import mat_from_quat
from ins_fusion.core.nav.strapdown import (
    INC_ANGLE,
    INC_DT,
    INC_VEL,
    INCREMENT_SIZE,
    NAV_SIZE,
    increment,
    mechanize,
)
from ins_fusion.core.settings.config import FusionConfig

#: Time constant of the smoothed acceleration and rate of the time-offset model [s].
_ACCEL_SMOOTHING_S = 0.1


class ImuDensities:
    """IMU white-noise densities (gyro, accelerometer) [rad²/s, m²/s³] per imu axis: the user's
    (``floor``) or the measured ones (core.filter.adaptation.ImuNoiseMonitor) where above them."""

    def __init__(self, gyro_psd: FloatArray, accel_psd: FloatArray) -> None:
        self.floor = (gyro_psd, accel_psd)
        self.monitor = ImuNoiseMonitor()
        self._measured: tuple[FloatArray, FloatArray] | None = None
        self._effective = self.floor

    def current(self) -> tuple[FloatArray, FloatArray] | None:
        """The densities in force; None before a measurement (then the floor applies)."""
        measured = self.monitor.psd
        return None if measured is None else self._effective_of(measured)

    def adopt(self, version: float, means: FloatArray) -> tuple[FloatArray, FloatArray]:
        """The densities in force when the monitor was at ``version`` with ``means``
        (ImuNoiseMonitor.adopt); ``current`` gives them until the version changes."""
        return self._effective_of(self.monitor.adopt(version, means))

    def _effective_of(
        self, measured: tuple[FloatArray, FloatArray]
    ) -> tuple[FloatArray, FloatArray]:
        """The floor, raised where ``measured`` (the monitor's psd) is above it."""
        if measured is not self._measured:
            self._measured = measured
            self._effective = densities_in_force(self.floor, measured[0], measured[1])
        return self._effective


@compilable
def corrected_gyro(measured: float, bias: float, scale: float, asymmetry: float) -> float:
    """One gyro axis's rate [rad/s] or angle increment [rad] with its ``bias`` (in the same
    unit), scale factor and scale asymmetry [fraction] removed: the sensor model
    ω̃ = (1 + s)ω + a|ω| + b (core.filter.eskf), that is (1 + s ± a)ω + b for either sign of ω,
    inverted (ω has the sign of ω̃ - b while |a| < 1 + s)."""
    unbiased = measured - bias
    return unbiased / (1.0 + scale + asymmetry * math.copysign(1.0, unbiased))


@compilable
def densities_in_force(
    floor: tuple[FloatArray, FloatArray], gyro_psd: FloatArray, accel_psd: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """The user's white-noise densities ``floor`` (gyro [rad²/s], accelerometer [m²/s³] per imu
    axis) raised where the measured ones ``gyro_psd``, ``accel_psd`` are above them."""
    return np.maximum(floor[0], gyro_psd), np.maximum(floor[1], accel_psd)


@compilable
def white_noise(
    densities: tuple[FloatArray, FloatArray], q_scale: float
) -> tuple[FloatArray, FloatArray]:
    """The IMU white-noise densities of a covariance step (gyro [rad²/s], accelerometer
    [m²/s³] per imu axis): ``densities`` (those in force) times the process-noise scale."""
    return densities[0] * q_scale, densities[1] * q_scale


@compilable
def monitored_white_noise(
    block: FloatArray, floor: tuple[FloatArray, FloatArray], q_scale: float
) -> tuple[FloatArray, FloatArray]:
    """``white_noise`` of the densities in force while the IMU noise monitor's ``block``
    (core.filter.adaptation B_* layout) holds its latest estimate: ``floor`` raised to it
    (ImuDensities.current; the floor before its first estimate), inside compiled runs."""
    if block[B_VERSION] == 0.0:
        return white_noise(floor, q_scale)
    measured = densities_in_force(floor, block[B_MEAN : B_MEAN + 3], block[B_MEAN + 3 : B_MEAN + 6])
    return white_noise(measured, q_scale)


def bridge(
    dt: float, last_sample: tuple[Vec3, Vec3], rate_i: Vec3, force_i: Vec3
) -> tuple[FloatArray, Gap]:
    """Trapezoidal increment (core.nav.strapdown.increment) over a gap of ``dt`` [s] from the last
    sample (rate, force; imu FRD) to this one, and its uncertainty. The trapezoid is exact for
    a rate and force that change linearly; for a change at an unknown instant inside the gap (a
    turn starting) it errs by Δ·dt·(1/2 - τ/dt), of RMS Δ·dt/√12, with Δ the change from the
    last sample to this one."""
    rate0, force0 = last_sample
    h = 0.5 * dt
    inc = increment(
        dt,
        (h * (rate0[0] + rate_i[0]), h * (rate0[1] + rate_i[1]), h * (rate0[2] + rate_i[2])),
        (
            h * (force0[0] + force_i[0]),
            h * (force0[1] + force_i[1]),
            h * (force0[2] + force_i[2]),
        ),
    )
    k = dt * dt / 12.0
    gap = Gap(
        tuple(k * (a - b) ** 2 for a, b in zip(rate_i, rate0, strict=True)),
        tuple(k * (a - b) ** 2 for a, b in zip(force_i, force0, strict=True)),
    )
    return inc, gap


@jit
def advance(x: FloatArray, inc: FloatArray, r_bi: FloatArray, bridged: bool, t: float) -> None:
    """The time update of the nominal state ``x`` (core.filter.state X_* layout) over one increment
    ``inc`` (imu FRD; ``bridged``: it spans missing samples, no coning/sculling history):
    correct it with the estimated biases, scale factors and gyro scale asymmetry, turn it into
    base_link FRD with ``r_bi`` (row-major imu -> body), mechanize, and update the derived
    rates, the low-passed acceleration and rate and the covariance interval; stamp ``t`` [s]."""
    dt = inc[INC_DT]
    ti0 = corrected_gyro(inc[INC_ANGLE], x[X_BG] * dt, x[X_SG], x[X_SR])
    ti1 = corrected_gyro(inc[INC_ANGLE + 1], x[X_BG + 1] * dt, x[X_SG + 1], x[X_SR + 1])
    ti2 = corrected_gyro(inc[INC_ANGLE + 2], x[X_BG + 2] * dt, x[X_SG + 2], x[X_SR + 2])
    vi0 = (inc[INC_VEL] - x[X_BA] * dt) / (1.0 + x[X_SA])
    vi1 = (inc[INC_VEL + 1] - x[X_BA + 1] * dt) / (1.0 + x[X_SA + 1])
    vi2 = (inc[INC_VEL + 2] - x[X_BA + 2] * dt) / (1.0 + x[X_SA + 2])
    inc_b = np.empty(INCREMENT_SIZE)
    inc_b[INC_DT] = dt
    for row in range(3):
        r0, r1, r2 = r_bi[3 * row], r_bi[3 * row + 1], r_bi[3 * row + 2]
        inc_b[INC_ANGLE + row] = r0 * ti0 + r1 * ti1 + r2 * ti2
        inc_b[INC_VEL + row] = r0 * vi0 + r1 * vi1 + r2 * vi2
    v0 = x[X_VEL : X_VEL + 3].copy()
    use_prev = not bridged and x[X_HAS_PREV] != 0.0
    mechanize(x[X_NAV : X_NAV + NAV_SIZE], inc_b, x[X_PREV : X_PREV + INCREMENT_SIZE], use_prev)
    inv_dt = 1.0 / dt
    # Acceleration and rate low-passed over ~0.1 s (vibration out) for the time-offset
    # model: their noise would otherwise make H noisy and the estimate wander.
    k = min(1.0, dt / _ACCEL_SMOOTHING_S)
    for axis in range(3):
        an = (x[X_VEL + axis] - v0[axis]) * inv_dt
        rb = inc_b[INC_ANGLE + axis] * inv_dt
        x[X_ACCEL_N + axis] = an
        x[X_RATE_B + axis] = rb
        lp = x[X_ACCEL_LP + axis]
        x[X_ACCEL_LP + axis] = lp + k * (an - lp)
        rl = x[X_RATE_LP + axis]
        x[X_RATE_LP + axis] = rl + k * (rb - rl)
    x[X_RATE_I], x[X_RATE_I + 1], x[X_RATE_I + 2] = ti0 * inv_dt, ti1 * inv_dt, ti2 * inv_dt
    x[X_PREV : X_PREV + INCREMENT_SIZE] = inc_b
    x[X_HAS_PREV] = 1.0
    x[X_T] = t
    x[X_COV_DTH] += ti0
    x[X_COV_DTH + 1] += ti1
    x[X_COV_DTH + 2] += ti2
    x[X_COV_DV] += vi0
    x[X_COV_DV + 1] += vi1
    x[X_COV_DV + 2] += vi2
    x[X_COV_DT] += dt


@jit
def covariance_interval(x: FloatArray, mat_bi: FloatArray) -> tuple[float, Motion]:
    """The interval accumulated in ``x`` (X_COV_* of core.filter.state; ``mat_bi`` imu ->
    body) as eskf.propagate_kernel takes it: its length [s] and its ``Motion`` (the mean
    specific force in NED from the velocity change and normal gravity; latitude, height and
    NED velocity at its end); the interval restarts (accumulators zero, its start velocity the
    current one)."""
    dt = x[X_COV_DT]
    inv_dt = 1.0 / dt
    lat, height = x[X_LAT], x[X_HEIGHT]
    vel = x[X_VEL : X_VEL + 3].copy()
    force_n = (vel - x[X_COV_VEL0 : X_COV_VEL0 + 3]) * inv_dt
    force_n[2] -= earth.normal_gravity_from_sin_cos(math.sin(lat), math.cos(lat), height)
    mat_nb = mat_from_quat(x[X_QUAT], x[X_QUAT + 1], x[X_QUAT + 2], x[X_QUAT + 3])
    force_i = x[X_COV_DV : X_COV_DV + 3] * inv_dt
    rate_i = x[X_COV_DTH : X_COV_DTH + 3] * inv_dt
    x[X_COV_DT] = 0.0
    x[X_COV_DTH : X_COV_DTH + 3] = 0.0
    x[X_COV_DV : X_COV_DV + 3] = 0.0
    x[X_COV_VEL0 : X_COV_VEL0 + 3] = vel
    velocity = (vel[0], vel[1], vel[2])
    return dt, Motion(mat_nb @ mat_bi, force_n, force_i, rate_i, lat, height, velocity)


@jit
def covariance_step(
    P: FloatArray,
    x: FloatArray,
    mat_bi: FloatArray,
    process: ProcessModel,
    columns: Columns,
    correlation_time_s: float,
) -> tuple[FloatArray, FloatArray]:
    """(P, Φ) over the interval accumulated in ``x`` (``covariance_interval``, which restarts
    it; ``process``: ErrorStateFilter.process_model), and the estimate of the correlated GNSS
    error in ``x`` decayed over it when ``columns`` (StateLayout.columns) hold that block
    (``correlation_time_s``: its correlation time [s])."""
    dt, motion = covariance_interval(x, mat_bi)
    P_new, phi = propagate_kernel(P, process, dt, motion, columns.sg, columns.sa, columns.sr)
    if columns.gp >= 0:
        decay = math.exp(-dt / correlation_time_s)
        for k in range(3):
            x[X_GNSS_ERROR + k] = x[X_GNSS_ERROR + k] * decay
    return P_new, phi


class Propagator:
    """Strapdown and covariance propagation of the nominal state (see the module docstring)."""

    def __init__(self, config: FusionConfig, geometry: Geometry, densities: ImuDensities) -> None:
        self._covariance_interval_s = config.covariance_interval_s
        self._gnss_correlation_time_s = config.gnss_correlation_time_s
        self._geometry = geometry
        self._densities = densities

    def step(
        self,
        s: FilterState,
        kf: ErrorStateFilter,
        inc: FloatArray,
        gap: Gap | None,
        t: float,
        noise: tuple[FloatArray, FloatArray] | None,
    ) -> None:
        """Correct an increment with the filter's sensor errors and mechanize (``advance``),
        then ``advanced``."""
        advance(s.x, inc, self._geometry.r_bi, gap is not None, t)
        self.advanced(s, kf, gap, noise)

    def advanced(
        self,
        s: FilterState,
        kf: ErrorStateFilter,
        gap: Gap | None,
        noise: tuple[FloatArray, FloatArray] | None,
    ) -> None:
        """What follows ``advance`` of ``s.x``: ``gap``: the increment bridged missing samples
        (its uncertainty goes into P); ``noise``: the IMU white-noise densities from now on
        (None = the user's); the covariance follows every ``covariance_interval`` seconds."""
        s.imu_psd = noise
        s.changed()
        if gap is not None:
            mat_ni = s.mat_nb @ self._geometry.mat_bi
            P_before = kf.P
            kf.add_noise(ATT, (mat_ni * gap.angle_var_rad2) @ mat_ni.T)
            kf.add_noise(VEL, (mat_ni * gap.velocity_var_m2_s2) @ mat_ni.T)
            if kf.smoother_hooks is not None:  # smoother hook: the gap's noise
                kf.smoother_hooks.on_noise(P_before, kf.P)
        if s.x[X_COV_DT] >= self._covariance_interval_s:
            self.propagate_covariance(s, kf)

    def propagate_covariance(self, s: FilterState, kf: ErrorStateFilter) -> None:
        """Propagate P over the accumulated interval with its mean specific force (NED from the
        velocity change; Coriolis, < 3e-3 m/s², left out of F)."""
        if s.x[X_COV_DT] <= 0.0:
            return
        kf.set_white_noise(*self.white_noise(s))
        P_before = kf.P
        kf.P, kf.phi = covariance_step(
            kernel_array(kf.P),
            s.x,
            self._geometry.mat_bi,
            kf.process_model(),
            kf.layout.columns,
            self._gnss_correlation_time_s,
        )
        if kf.smoother_hooks is not None:  # smoother hook: a covariance step
            kf.smoother_hooks.on_transition(P_before, kf.phi, kf.P)
        if not s.heading_known:
            decouple_yaw(kf)

    def white_noise(self, s: FilterState) -> tuple[FloatArray, FloatArray]:
        """``white_noise`` of a covariance step from ``s``: the densities in force at it (the
        user's when none was measured) [rad²/s, m²/s³]."""
        return white_noise(s.imu_psd or self._densities.floor, s.q_scale)

    @staticmethod
    def predict(s: FilterState, kf: ErrorStateFilter, t_m: float) -> Prediction:
        """The nominal state carried from the current state to t_m (< one IMU interval;
        ``predicted_state``)."""
        return predicted_state(s.x, t_m)


@jit
def predicted_state(x: FloatArray, t_m: float) -> Prediction:
    """The nominal state of ``x`` (X_* layout) carried to t_m [s] with its NED acceleration
    and body rate (constant over less than an IMU interval): latitude, longitude [rad],
    height [m], NED velocity [m/s], body -> NED rotation, corrected rate in body and imu FRD
    [rad/s]."""
    dt = t_m - x[X_T]
    mat_nb = mat_from_quat(x[X_QUAT], x[X_QUAT + 1], x[X_QUAT + 2], x[X_QUAT + 3])
    vel = x[X_VEL : X_VEL + 3].copy()
    rate_b = x[X_RATE_B : X_RATE_B + 3].copy()
    rate_i = x[X_RATE_I : X_RATE_I + 3].copy()
    if dt == 0.0:
        return Prediction(x[X_LAT], x[X_LON], x[X_HEIGHT], vel, mat_nb, rate_b, rate_i)
    vel_m = vel + x[X_ACCEL_N : X_ACCEL_N + 3] * dt
    mean_vel = 0.5 * (vel + vel_m)
    lat, lon, height = earth.displace(
        x[X_LAT], x[X_LON], x[X_HEIGHT], mean_vel[0] * dt, mean_vel[1] * dt, mean_vel[2] * dt
    )
    r = rate_b * dt
    rotation = np.array(((0.0, -r[2], r[1]), (r[2], 0.0, -r[0]), (-r[1], r[0], 0.0)))  # [r×]
    turn = np.eye(3) + rotation + 0.5 * rotation @ rotation
    return Prediction(lat, lon, height, vel_m, mat_nb @ turn, rate_b, rate_i)
