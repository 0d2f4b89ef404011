"""Error-state Kalman filter: state layout, error dynamics, discretisation, the filter object.

Error state (closed loop: estimated, injected into the nominal state and reset to zero after each
update), with x_true = x_nominal + δx:

    δp   position error, NED [m]            δv  velocity error, NED [m/s]
    ψ    attitude error, NED [rad]: C_nb,true = (I + [ψ×]) C_nb,nominal
    δb_g gyro bias error, imu FRD [rad/s]   δb_a accelerometer bias error, imu FRD [m/s²]
    δs_g, δs_a optional scale-factor errors [fraction] (imu FRD)
    δa_g optional gyro scale asymmetry [fraction] (imu FRD): an error per unit of |rate|
    ε_g  optional time-correlated GNSS position error, NED [m] (first-order Gauss-Markov)
    δμ   optional residual IMU-to-vehicle mounting, pitch and yaw about base_link FRD y, z [rad]
    δt_d optional residual IMU time offset [s]: how much later than the GNSS the IMU is stamped
    δk_s optional scale error of the vehicle speed [fraction]: measured = (1 + k_s) true

Sensor model (imu FRD axes i): ω̃ = (1 + s_g)∘ω + a_g∘|ω| + b_g + n_g,
f̃ = (1 + s_a)∘f + b_a + n_a, with b, s and a first-order Gauss-Markov processes (Oslo notes §2
(3.15)/(3.16), §7 F1/G1; shared/reference/mems-noise-oslo-notes.md). The mechanization body
frame b is base_link FRD, C_ni = C_nb R_bi with R_bi the imu -> base_link mounting. Linearised
error dynamics (the "phi-angle" form of Shin 2001 / KF-GINS; the position terms of order v/R,
Ω v/R and ∂g/∂φ, below 5e-6 s⁻¹ at car speeds, are left out: they change a position error of
1 m by < 0.1 mm in a 20 s outage; test/core/filter/test_eskf.py checks every block against
finite differences of the strapdown):

    δṗ = δv
    δv̇ = -[f_n×]ψ + F_vv δv + (2g/(R+h)) δp_D e_D - C_ni (δb_a + diag(f_i) δs_a) - C_ni n_a
    ψ̇ = -[ω_in×]ψ - ∂ω_en/∂v δv - C_ni (δb_g + diag(ω_i) δs_g + diag(|ω_i|) δa_g) - C_ni n_g
    δḃ = -δb/T + w_b,   E[w_b²] = 2σ_b²/T (and the same for the scale factors)
    ε̇_g = -ε_g/T_g + w_g, E[w_g²] = 2σ_g²/T_g with σ_g² from the latest fix (gnss_variance)
    δμ̇ = w_μ, δṫ_d = w_t, δk̇_s = w_k: random constants with a small random walk
    (``CALIBRATION_WALK``)

The gyro's misalignment m (σ_m per off-diagonal element, from a datasheet or a calibration),
which has no states, adds a turn-rate-dependent white noise to n_g, per imu axis i:

    E[n_m,i²] = T_m σ_m² Σ_{j≠i} ω_j²    [rad²/s], T_m = ``AXIS_ERROR_TIME_S``

m is a constant, so the attitude error it makes in a turn grows as σ_m ω t; white noise of this
density grows as σ_m ω √(T_m t): the two agree after T_m = 10 s, about a car's turn (a corner at
10 °/s), and the GNSS corrects the attitude within that. Without it a tactical IMU's 1 mrad
misalignment at 14 °/s (50 °/h) turns the attitude by several times its σ and the position
leaves its fixes (docs/accuracy.md). Scale factors are states instead (δs_g): as noise of this
kind they hid the gyro bias's signature in turns and lengthened outage drifts several times.
The asymmetry a_g is the part of a scale factor that depends on the sign of the rate
(S± = s_g ± a_g for positive / negative input): the IMU400CC's is its largest scale error
(Aalborg §3.3: y +0.83 % / -0.82 %, a rate-independent offset while turning either way), which
symmetric states cannot follow (docs/fusion.md).

Discretisation over an interval Δt: Φ = I + FΔt + (FΔt)²/2 and Q_d = (Φ Q_c Φᵀ + Q_c)Δt/2, both
second-order accurate; propagated in steps of 1/134 s or 0.1 s for 10 s they agree with Van Loan's
exact form to 0.5 % (test/core/filter/test_eskf.py; Oslo notes "Implications" R2). The engine
propagates P every ``covariance_interval`` (0.1 s, the pseudo-measurement period) with the
interval's mean specific force, and always up to the stamp of a measurement before updating;
per IMU sample instead gives the same errors and NEES at 1.6 times the CPU time
(bench/bench_fusion_engine.py). The gated update and its algebra: core.filter.update_algebra.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from gnss_ins_common.types import FloatArray, IntArray
from ins_fusion.core.compiled import compilable, jit, kernel_array
from ins_fusion.core.filter.update_algebra import (
    UpdateResult,
    covariance_problem,
    faded_covariance,
    joseph_update,
    widening,
)
from ins_fusion.core.nav import earth
from ins_fusion.core.nav.calibration import TriadCalibration
from ins_fusion.core.settings.config import ImuNoise
from ins_fusion.core.smoother.rts import SmootherHooks

#: First index of each always-present block of the error state.
POS, VEL, ATT, BG, BA = 0, 3, 6, 9, 12
_CORE_SIZE = 15
#: Random-walk densities of the self-calibration states: mounting [rad²/s] (0.01°/√s: a
#: mounting that settles by a few hundredths of a degree per minute), time offset [s²/s]
#: (0.1 ms/√s: a clock mapping that wanders by about a millisecond per minute) and speed scale
#: [1/s] (1e-5/√s: a tyre whose radius changes by 0.01 % in 100 s as it warms).
CALIBRATION_WALK = {
    "mounting": math.radians(0.01) ** 2,
    "time_offset": 1e-4**2,
    "speed_scale": 1e-5**2,
}


class Columns(NamedTuple):
    """StateLayout.columns: the first column of each optional block (-1: absent), for
    compiled code."""

    #: Gyro scale factors.
    sg: int
    #: Accelerometer scale factors.
    sa: int
    #: Gyro scale asymmetry.
    sr: int
    #: Correlated GNSS position error.
    gp: int
    #: Residual mounting (pitch, yaw).
    mt: int
    #: Residual IMU time offset.
    td: int
    #: Vehicle speed scale.
    ks: int


#: Time [s] over which the white noise standing for the gyro's misalignment matches its effect
#: in a steady turn (module docstring).
AXIS_ERROR_TIME_S = 10.0


@dataclass(frozen=True)
class StateLayout:
    """Named indices of the error state: the 15 core states, then the optional gyro and
    accelerometer scale factors, the gyro scale asymmetry, the GNSS position error (NED [m],
    time-correlated part of the receiver's error), the residual mounting (pitch, yaw [rad]),
    the residual IMU time offset [s] and the vehicle speed's scale error [fraction]. An absent
    block has index None."""

    gyro_scale: bool = False
    accel_scale: bool = False
    gnss_error: bool = False
    mounting: bool = False
    time_offset: bool = False
    speed_scale: bool = False
    gyro_asymmetry: bool = False
    sg: int | None = field(init=False)
    sa: int | None = field(init=False)
    sr: int | None = field(init=False)
    gp: int | None = field(init=False)
    mt: int | None = field(init=False)
    td: int | None = field(init=False)
    ks: int | None = field(init=False)
    size: int = field(init=False)
    #: (sg, sa, sr, gp, mt, td, ks) for compiled code: -1 for an absent block.
    columns: Columns = field(init=False)

    def __post_init__(self) -> None:
        next_index = _CORE_SIZE
        columns: dict[str, int] = {}
        for name, present, width in (
            ("sg", self.gyro_scale, 3),
            ("sa", self.accel_scale, 3),
            ("sr", self.gyro_asymmetry, 3),
            ("gp", self.gnss_error, 3),
            ("mt", self.mounting, 2),
            ("td", self.time_offset, 1),
            ("ks", self.speed_scale, 1),
        ):
            object.__setattr__(self, name, next_index if present else None)
            columns[name] = next_index if present else -1
            next_index += width * present
        object.__setattr__(self, "size", next_index)
        object.__setattr__(self, "columns", Columns(**columns))


def gyro_misalignment_variance(
    noise: ImuNoise, calibration: TriadCalibration | None = None
) -> FloatArray:
    """Variance [rad²] of each off-diagonal element of the gyro's misalignment (row: sensing
    axis, column: input axis; zero diagonal), which no state estimates (module docstring): a
    calibration's own σ when it corrects a misalignment, else the datasheet's
    ``gyro_misalignment``. Axis signs do not matter (squares): FLU and FRD give the same."""
    if calibration is not None and np.any(calibration.misalignment_rad):
        variance = np.square(calibration.misalignment_sigma_rad)
    else:
        variance = np.full((3, 3), noise.gyro_misalignment**2)
    np.fill_diagonal(variance, 0.0)
    return variance


def gyro_asymmetry_sigma(
    noise: ImuNoise, calibration: TriadCalibration | None = None
) -> FloatArray:
    """σ of the gyro scale asymmetry per imu axis [fraction] (module docstring): what a
    calibration that corrects sign-dependent scale factors leaves, sqrt(σ₊² + σ₋²) / 2 from its
    own σ of S₊ and S₋ (a = (S₊ - S₋) / 2), else the datasheet's ``gyro_asymmetry_sigma``."""
    if calibration is not None and calibration.scale_positive != calibration.scale_negative:
        return 0.5 * np.hypot(calibration.scale_positive_sigma, calibration.scale_negative_sigma)
    return np.full(3, noise.gyro_asymmetry_sigma)


class ProcessModel(NamedTuple):
    """ErrorStateFilter.process_model: the F and Q buffers (filled in place), the white-noise
    densities per imu axis (gyro [rad²/s], accelerometer [m²/s³]), the gyro misalignment's
    noise and the Gauss-Markov states' indices and densities."""

    F: FloatArray
    Q: FloatArray
    gyro_psd: FloatArray
    misalignment_q: FloatArray
    accel_psd: FloatArray
    markov_idx: IntArray
    markov_q: FloatArray


class Motion(NamedTuple):
    """What the error dynamics F depend on over a covariance interval (frames: imu FRD, NED)."""

    mat_ni: FloatArray  #: rotation imu -> NED
    force_n: FloatArray  #: mean specific force, NED [m/s²]
    force_i: FloatArray  #: mean specific force, imu FRD [m/s²]
    rate_i: FloatArray  #: mean corrected rate, imu FRD [rad/s]
    lat_rad: float  #: latitude [rad]
    height_m: float  #: height [m]
    vel_ned_m_s: tuple[float, float, float]  #: NED velocity [m/s]


@compilable
def with_white_noise(
    process: ProcessModel, gyro_psd: FloatArray, accel_psd: FloatArray
) -> ProcessModel:
    """``process`` with other white-noise densities (gyro [rad²/s], accelerometer [m²/s³] per
    imu axis: the monitored ones a compiled sample run uses)."""
    return ProcessModel(
        process.F,
        process.Q,
        gyro_psd,
        process.misalignment_q,
        accel_psd,
        process.markov_idx,
        process.markov_q,
    )


class ErrorStateFilter:
    """Covariance of the error state and its propagation and update (the mean is always zero
    between updates: closed loop)."""

    def __init__(
        self,
        layout: StateLayout,
        noise: ImuNoise,
        gnss_correlation_time_s: float = 60.0,
        gyro_misalignment_var: FloatArray | None = None,
        asymmetry_sigma: FloatArray | None = None,
    ) -> None:
        """P starts at zero; set it before use. P arrays are replaced, never modified in place,
        so a reference to ``P`` is a snapshot. ``gyro_misalignment_var``, ``asymmetry_sigma``:
        from ``gyro_misalignment_variance`` and ``gyro_asymmetry_sigma`` (None: from ``noise``
        alone)."""
        n = layout.size
        self.layout = layout
        self.P: FloatArray = np.zeros((n, n))
        #: Largest variance of each error state after a fading (``scale``), inf: none; set by
        #: the start to what is known of the state before any measurement (faded_covariance).
        self.variance_ceiling: FloatArray = np.full(n, math.inf)
        #: Transition matrix Φ of the last covariance step (a new array per step).
        self.phi: FloatArray = np.eye(n)
        #: Observer of the covariance's changes (the RTS smoother's history), set by the engine.
        self.smoother_hooks: SmootherHooks | None = None
        # F and Q are rebuilt block by block through views; constant blocks are set once.
        F = self._F = np.zeros((n, n))
        F[POS : POS + 3, VEL : VEL + 3] = np.eye(3)
        Q = self._Q = np.zeros((n, n))
        #: Columns of the gyro and accelerometer scale factors and of the gyro scale asymmetry
        #: (-1: not estimated).
        self.scale_columns = (layout.columns.sg, layout.columns.sa, layout.columns.sr)
        # Gauss-Markov states: F = -1/T, continuous noise 2σ²/T.
        t_b = noise.bias_correlation_time_s
        markov = [(BG, t_b, noise.gyro_bias_instability), (BA, t_b, noise.accel_bias_instability)]
        if asymmetry_sigma is None:
            asymmetry_sigma = gyro_asymmetry_sigma(noise)
        for start, sigma in (
            (layout.sg, np.full(3, noise.gyro_scale_sigma)),
            (layout.sa, np.full(3, noise.accel_scale_sigma)),
            (layout.sr, asymmetry_sigma),
        ):
            if start is not None:
                markov.append((start, t_b, (float(sigma[0]), float(sigma[1]), float(sigma[2]))))
        if layout.gp is not None:
            markov.append((layout.gp, gnss_correlation_time_s, (0.0, 0.0, 0.0)))
        walks = [(layout.mt, 2, CALIBRATION_WALK["mounting"])]
        walks.append((layout.td, 1, CALIBRATION_WALK["time_offset"]))
        walks.append((layout.ks, 1, CALIBRATION_WALK["speed_scale"]))
        for start, width, density in walks:
            if start is not None:
                Q[start : start + width, start : start + width] = np.eye(width) * density
        self._markov_idx = np.concatenate([np.arange(m[0], m[0] + 3) for m in markov])
        self._markov_q = np.array([2.0 * s * s / m[1] for m in markov for s in m[2]])
        self._F[self._markov_idx, self._markov_idx] = np.repeat([-1.0 / m[1] for m in markov], 3)
        # No GNSS error states (correlation time 0 = all white): no rate either.
        self._gnss_rate = 2.0 / gnss_correlation_time_s if layout.gp is not None else 0.0
        self._accel_psd = noise.accel_psd
        self._gyro_psd = noise.gyro_psd
        # Turn-rate-dependent gyro noise of the misalignment (module docstring).
        if gyro_misalignment_var is None:
            gyro_misalignment_var = gyro_misalignment_variance(noise)
        self._gyro_misalignment_q = gyro_misalignment_var * AXIS_ERROR_TIME_S
        self._gnss_variance: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @property
    def gnss_variance(self) -> tuple[float, float, float]:
        """Stationary variance of the GNSS position error states per NED axis [m²]."""
        return self._gnss_variance

    @gnss_variance.setter
    def gnss_variance(self, variance: tuple[float, float, float]) -> None:
        self._gnss_variance = variance
        if self.layout.gp is not None:
            self._markov_q[-3:] = np.array(variance) * self._gnss_rate

    def dynamics(
        self,
        mat_ni: FloatArray,
        force_n: FloatArray,
        force_i: FloatArray,
        rate_i: FloatArray,
        lat_rad: float,
        height_m: float,
        vel_ned_m_s: tuple[float, float, float],
    ) -> FloatArray:
        """The error-state matrix F (module docstring) for a rotation imu FRD -> NED, the
        specific force in NED and the corrected force/rate in imu FRD [m/s², rad/s], position
        and NED velocity. Returns an internal array, valid until the next call."""
        motion = Motion(mat_ni, force_n, force_i, rate_i, lat_rad, height_m, vel_ned_m_s)
        _fill_dynamics(self._F, motion, *self.scale_columns)
        return self._F

    def noise_density(self, mat_ni: FloatArray, rate_i: FloatArray) -> FloatArray:
        """Continuous process noise Q_c = G Q Gᵀ [per second] for the rotation imu -> NED
        and the corrected angular rate in imu FRD [rad/s]."""
        _fill_noise(
            self._Q,
            mat_ni,
            rate_i,
            self._gyro_psd,
            self._gyro_misalignment_q,
            self._accel_psd,
            self._markov_idx,
            self._markov_q,
        )
        return self._Q

    def process_model(self) -> ProcessModel:
        """What a covariance step hands its kernel besides P and the interval: the F and Q buffers
        (filled in place), the white-noise densities in force, the gyro misalignment's noise
        and the Gauss-Markov states' indices and densities (propagation.covariance_step)."""
        return ProcessModel(
            self._F,
            self._Q,
            self._gyro_psd,
            self._gyro_misalignment_q,
            self._accel_psd,
            self._markov_idx,
            self._markov_q,
        )

    def set_white_noise(self, gyro_psd: FloatArray, accel_psd: FloatArray) -> None:
        """White-noise power densities per imu axis from now on: gyro [rad²/s] (ARW²),
        accelerometer [m²/s³] (VRW²)."""
        self._gyro_psd = gyro_psd
        self._accel_psd = accel_psd

    def scale(self, factor: float) -> None:
        """Multiply the covariance by ``factor`` (fading memory: every state less certain), no
        state's variance beyond its ``variance_ceiling`` (``faded_covariance``)."""
        self.P = faded_covariance(self.P, factor, self.variance_ceiling)

    def add_noise(self, start: int, cov: FloatArray) -> None:
        """Add a 3x3 covariance to the diagonal block of the states at ``start`` (noise the
        continuous model does not hold, e.g. a bridged IMU gap). P is replaced, not changed in
        place: the engine's history holds references to earlier P."""
        P = self.P.copy()
        P[start : start + 3, start : start + 3] += cov
        self.P = P

    def widen(self, z: FloatArray, H: FloatArray, R: FloatArray, start: int) -> None:
        """Add to the 3x3 block of P at ``start`` what makes the innovation z fit: the excess
        of each z_i² over S_ii, mapped into that block by the pseudo-inverse of its columns of
        H, so that the new S_ii = max(S_ii, z_i²) when they have full row rank."""
        self.add_noise(start, widening(self.P, z, H, R, start))

    def update(self, z: FloatArray, H: FloatArray, R: FloatArray, threshold: float) -> UpdateResult:
        """Gated Joseph-form update with innovation z = measured - predicted, z ≈ H δx + v."""
        accepted, nis, dx, P = joseph_update(
            kernel_array(self.P),
            kernel_array(z),
            kernel_array(H),
            kernel_array(R),
            float(threshold),
        )
        if not accepted:
            return UpdateResult(False, nis, None)
        self.P = P
        return UpdateResult(True, nis, dx)

    def problem(self) -> str | None:
        """Why the covariance is unusable (non-finite, negative variance), or None."""
        return problem_text(covariance_problem(kernel_array(self.P)))


#: What makes a filter unusable besides a negative variance (whose state index the checks
#: return): nothing (usable), a non-finite covariance (update_algebra.covariance_problem), a
#: non-finite navigation state (core.filter.state.filter_problem).
USABLE, NONFINITE_COVARIANCE, NONFINITE_NAVIGATION = -1, -2, -3


def problem_text(code: int) -> str | None:
    """A health check's ``code`` (above) in words; None: usable."""
    if code == USABLE:
        return None
    if code == NONFINITE_COVARIANCE:
        return "non-finite covariance"
    if code == NONFINITE_NAVIGATION:
        return "non-finite navigation state"
    return f"negative variance in state {code}"


@jit
def _fill_dynamics(F: FloatArray, motion: Motion, sg: int, sa: int, sr: int) -> None:
    """The state-dependent blocks of F (ErrorStateFilter.dynamics; ``sg``, ``sa``, ``sr``:
    columns of the scale factors and the gyro scale asymmetry, -1 when not estimated)."""
    mat_ni, force_n, force_i, rate_i, lat_rad, height_m, vel_ned_m_s = motion
    vn, ve, vd = vel_ned_m_s
    sin_lat = math.sin(lat_rad)
    r_m, r_n = earth.radii_from_sin(sin_lat)
    rmh, rnh = r_m + height_m, r_n + height_m
    tan_lat = math.tan(lat_rad)
    cos_lat = math.cos(lat_rad)
    w_ie_n, w_ie_d = earth.EARTH_RATE_RAD_S * cos_lat, -earth.EARTH_RATE_RAD_S * sin_lat
    # ω_en = (a v_E, b v_N, c v_E): ∂ω_en/∂v = [[0, a, 0], [b, 0, 0], [0, c, 0]].
    a, b, c = 1.0 / rnh, -1.0 / rmh, -tan_lat / rnh
    wx, wy, wz = w_ie_n + a * ve, b * vn, w_ie_d + c * ve  # ω_in
    cx, cy, cz = wx + w_ie_n, wy, wz + w_ie_d  # 2ω_ie + ω_en
    fx, fy, fz = force_n[0], force_n[1], force_n[2]
    # δv̇: [v×] ∂ω_en/∂v - [(2ω_ie + ω_en)×]; -[f_n×]; ψ̇: -∂ω_en/∂v; -[ω_in×].
    blocks = (
        (VEL, VEL, ((-vd * b, ve * c + cz, -cy), (-cz, vd * a - vn * c, cx))),
        (VEL, ATT, ((0.0, fz, -fy), (-fz, 0.0, fx))),
        (ATT, VEL, ((0.0, -a, 0.0), (-b, 0.0, 0.0))),
        (ATT, ATT, ((0.0, wz, -wy), (-wz, 0.0, wx))),
    )
    for row, col, (first, second) in blocks:
        for j in range(3):
            F[row, col + j] = first[j]
            F[row + 1, col + j] = second[j]
    F[VEL + 2, VEL], F[VEL + 2, VEL + 1], F[VEL + 2, VEL + 2] = vn * b + cy, -ve * a - cx, 0.0
    F[VEL + 2, ATT], F[VEL + 2, ATT + 1], F[VEL + 2, ATT + 2] = fy, -fx, 0.0
    F[ATT + 2, VEL], F[ATT + 2, VEL + 1], F[ATT + 2, VEL + 2] = 0.0, -c, 0.0
    F[ATT + 2, ATT], F[ATT + 2, ATT + 1], F[ATT + 2, ATT + 2] = wy, -wx, 0.0
    F[VEL + 2, POS + 2] = (
        2.0 * earth.normal_gravity_from_sin_cos(sin_lat, cos_lat, height_m) / math.sqrt(rmh * rnh)
    )
    for i in range(3):
        for j in range(3):
            F[VEL + i, BA + j] = -mat_ni[i, j]
            F[ATT + i, BG + j] = -mat_ni[i, j]
            if sg >= 0:
                F[ATT + i, sg + j] = mat_ni[i, j] * -rate_i[j]
            if sa >= 0:
                F[VEL + i, sa + j] = mat_ni[i, j] * -force_i[j]
            if sr >= 0:
                F[ATT + i, sr + j] = mat_ni[i, j] * -abs(rate_i[j])


@jit
def _fill_noise(
    Q: FloatArray,
    mat_ni: FloatArray,
    rate_i: FloatArray,
    gyro_psd: FloatArray,
    gyro_misalignment_q: FloatArray,
    accel_psd: FloatArray,
    markov_idx: IntArray,
    markov_q: FloatArray,
) -> None:
    """The state-dependent blocks of Q_c (ErrorStateFilter.noise_density)."""
    Q[VEL : VEL + 3, VEL : VEL + 3] = (mat_ni * accel_psd) @ mat_ni.T
    turn_psd = gyro_misalignment_q @ (rate_i * rate_i)
    Q[ATT : ATT + 3, ATT : ATT + 3] = (mat_ni * (gyro_psd + turn_psd)) @ mat_ni.T
    for k in range(len(markov_idx)):
        Q[markov_idx[k], markov_idx[k]] = markov_q[k]


@jit
def propagate_kernel(
    P: FloatArray, process: ProcessModel, dt_s: float, motion: Motion, sg: int, sa: int, sr: int
) -> tuple[FloatArray, FloatArray]:
    """(P, Φ) after an interval of ``dt_s`` [s] with ``motion`` (propagation.covariance_step;
    ``sg``, ``sa``, ``sr``: as ``_fill_dynamics``); F and Q of ``process`` are filled in place."""
    F, Q, gyro_psd, gyro_misalignment_q, accel_psd, markov_idx, markov_q = process
    _fill_dynamics(F, motion, sg, sa, sr)
    mat_ni, rate_i = motion.mat_ni, motion.rate_i
    _fill_noise(Q, mat_ni, rate_i, gyro_psd, gyro_misalignment_q, accel_psd, markov_idx, markov_q)
    f_dt = F * dt_s
    phi = np.eye(len(P)) + f_dt + 0.5 * (f_dt @ f_dt)
    q = Q * (0.5 * dt_s)
    # Φ P Φᵀ + (Φ Q_c Φᵀ + Q_c)Δt/2 = Φ (P + Q_cΔt/2) Φᵀ + Q_cΔt/2.
    P_new = phi @ (P + q) @ phi.T
    P_new += q
    return P_new, phi
