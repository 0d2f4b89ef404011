"""IMU error model per axis and the named sensor profiles.

Observation model (Aalborg notes §3.1, (2.1)-(2.2), shared/reference/imu400cc-aalborg-notes.md),
per triad in the sensor's own FLU axes, y = true rate ω or specific force f:

    ỹ = y + s±∘y + A y + b + β(t) + μ(t) + n(t)   [+ G f for the gyros]

with s± the scale-factor error chosen by the sign of each input (asymmetric scale), A the
off-diagonal misalignment, b the turn-on bias (fixed part plus a random draw per power-up), β a
first-order Gauss-Markov bias instability, μ a rate/acceleration random walk, n white noise of the
ARW/VRW density and G the g-dependent gyro bias. The output is then quantised to the device's
counts and limited to its range (saturation, or the two's-complement wrap seen in the NTNU data).

Noise is stored as densities in SI: ARW in rad/s/sqrt(Hz) (= rad/sqrt(s)), VRW in m/s²/sqrt(Hz)
(= m/s/sqrt(s)), bias instability as the Gauss-Markov stationary std, random walk in u·sqrt(Hz).
The per-sample std of the white part is density/sqrt(dt), so a profile works at any rate.
Optionally (``ImuErrorModel(band_limited=True)``) the white noise passes through a first-order
low-pass of the sensor's noise bandwidth (noise.BandLimitedNoise): the density below the corner is
kept and the per-sample std becomes density·sqrt(bandwidth), as measured on a band-limited unit.
The sensor temperature (for the driver's temperature topic) starts at a seeded power-up value and
drifts smoothly (first order) to a seeded settled value; it does not change the errors (Aalborg
notes §1.2: no measurable bias change between 5 and 27 °C).
Profiles are written in the user-facing units of the datasheets through core.nav.units.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from gnss_ins_common.axes import AxisMap
from gnss_ins_common.types import FloatArray, Mat3, Vec3
from imu400cc_driver.axes import DEFAULT_ACCEL_SIGN, DEFAULT_AXIS_SPEC
from ins_fusion.core.nav.calibration import mat3, vec3
from ins_fusion.core.nav.units import (
    DEG,
    STANDARD_GRAVITY_M_S2,
    deg_h,
    deg_s,
    deg_sqrt_h,
    m_s_sqrt_h,
    mg,
    percent,
    ppm,
)
from ins_fusion.sim.noise import BandLimitedNoise, GaussMarkov, RandomWalk, WhiteNoise

_ZERO3: Vec3 = (0.0, 0.0, 0.0)
_ZERO33: Mat3 = (_ZERO3, _ZERO3, _ZERO3)


def _each(convert: Callable[[float], float], x: float, y: float, z: float) -> Vec3:
    """Per-axis values (x, y, z) converted to SI."""
    return (convert(x), convert(y), convert(z))


def _same(value: float) -> Vec3:
    """The same value on the three axes."""
    return (value, value, value)


@dataclass(frozen=True)
class TriadErrors:
    """Errors of one sensor triad, per axis (x, y, z of the sensor's FLU frame), in SI.

    u is rad/s for gyros and m/s² for accelerometers.
    noise_density: white noise [u/sqrt(Hz)] (ARW rad/sqrt(s), VRW m/s/sqrt(s)).
    bias_instability: stationary std of the Gauss-Markov bias [u]; bias_correlation_time_s [s].
    random_walk: rate/acceleration random walk density [u·sqrt(Hz)] (u/sqrt(s)).
    bias, bias_sigma: turn-on bias, fixed part and std of the per-power-up draw [u].
    scale_pos, scale_neg: scale-factor error for positive/negative input [fraction];
    scale_sigma: std of a per-power-up draw added to both [fraction].
    scale_large_pos, scale_large_neg, large_input: the scale factors for inputs of magnitude
    at least large_input [u] (Aalborg report §9.1.1: one value at ±0.2 g, another at ±1 g;
    inf: one range), with the same draw.
    misalignment_rad: off-diagonal A[i][j] = sensitivity of axis i to input j [rad];
    misalignment_sigma_rad: std of a per-power-up draw of every off-diagonal element.
    resolution: one output count [u] (0 = no quantisation); full_scale: largest magnitude [u];
    wrap: beyond full scale the output wraps around (two's complement) instead of saturating.
    bandwidth_hz: noise-equivalent bandwidth of the sensor's output filter [Hz] (inf: the white
    noise is not band-limited), used when the model is band-limited.
    """

    noise_density: Vec3 = _ZERO3
    bias_instability: Vec3 = _ZERO3
    bias_correlation_time_s: Vec3 = (1.0, 1.0, 1.0)
    random_walk: Vec3 = _ZERO3
    bias: Vec3 = _ZERO3
    bias_sigma: Vec3 = _ZERO3
    scale_pos: Vec3 = _ZERO3
    scale_neg: Vec3 = _ZERO3
    scale_sigma: Vec3 = _ZERO3
    scale_large_pos: Vec3 = _ZERO3
    scale_large_neg: Vec3 = _ZERO3
    large_input: float = math.inf
    misalignment_rad: Mat3 = _ZERO33
    misalignment_sigma_rad: float = 0.0
    resolution: float = 0.0
    full_scale: float = math.inf
    wrap: bool = False
    bandwidth_hz: float = math.inf

    def in_flu(self, axes: AxisMap, sign: float) -> TriadErrors:
        """These errors, given per device axis of a triad whose output is ``sign`` (±1) times
        ``axes.to_flu`` of the device output, per FLU axis: the same carry-over as a device-axis
        calibration file (core.nav.calibration, ``axes: device``)."""
        scale_pos, scale_neg = axes.scale_pair_to_flu(self.scale_pos, self.scale_neg, sign)
        large_pos, large_neg = axes.scale_pair_to_flu(
            self.scale_large_pos, self.scale_large_neg, sign
        )
        return replace(
            self,
            scale_large_pos=vec3(large_pos),
            scale_large_neg=vec3(large_neg),
            noise_density=vec3(axes.permute_to_flu(self.noise_density)),
            bias_instability=vec3(axes.permute_to_flu(self.bias_instability)),
            bias_correlation_time_s=vec3(axes.permute_to_flu(self.bias_correlation_time_s)),
            random_walk=vec3(axes.permute_to_flu(self.random_walk)),
            bias=vec3(sign * axes.to_flu(self.bias)),
            bias_sigma=vec3(axes.permute_to_flu(self.bias_sigma)),
            scale_pos=vec3(scale_pos),
            scale_neg=vec3(scale_neg),
            scale_sigma=vec3(axes.permute_to_flu(self.scale_sigma)),
            misalignment_rad=mat3(axes.matrix_to_flu(self.misalignment_rad)),
        )


@dataclass(frozen=True)
class TemperatureSpec:
    """Sensor temperature [°C]: the power-up value is mean + N(0, turn_on_sigma²); it drifts as
    a first-order lag with time constant drift_time_s [s] to a settled value mean +
    N(0, drift_sigma²)."""

    mean_c: float = 25.0
    turn_on_sigma_c: float = 0.0
    drift_sigma_c: float = 0.0
    drift_time_s: float = 1800.0


@dataclass(frozen=True)
class ImuProfile:
    """A named IMU: nominal output rate, gyro and accelerometer errors, g-dependent gyro bias
    G[i][j] = rate error of gyro i per m/s² of specific force on axis j [rad/s per m/s²]."""

    name: str
    rate_hz: float
    gyro: TriadErrors
    accel: TriadErrors
    gyro_g_sensitivity: Mat3 = _ZERO33
    temperature: TemperatureSpec = TemperatureSpec()
    source: str = ""


def _deg_s_per_g(value: float) -> float:
    """g-dependent gyro bias: (deg/s)/g -> (rad/s)/(m/s²)."""
    return deg_s(value) / STANDARD_GRAVITY_M_S2


#: Crossbow IMU400CC-100 (Aalborg notes). Datasheet §1.2: range ±100 °/s / ±2 g, RW < 2.25 °/√h,
#: < 0.1 m/s/√h. Measured: white noise from the per-axis σ of (7.14) with the bandwidths of §1.3
#: (independent samples at 25 Hz gyro / 75 Hz accelerometer) as in (5.21), RW = 60σ/√BW, which
#: gives the report's 2.98 °/√h on average; turn-on biases and their day-to-day std from §3.3
#: (Fig. 5-36 gyro, Fig. 5-34 accelerometer, both S2); asymmetric scale factors Fig. 5-30 (gyro D2,
#: ±15 °/s) and Fig. 5-33 (accelerometer S1 mod, ±0.2 g); g-dependent gyro bias Fig. 5-37 (rows =
#: gyro axis, units (°/s)/g; both readings of the garbled header are within their σ). Bias
#: instability: no datasheet value; the std of the six field standstill means (Fig. 9-9) for the
#: gyros and of the 30-min tube-level setups (Fig. 5-28) for the accelerometers, with an assumed
#: 300 s correlation time (the drives were 4 min apart). Counts and range from §2.4: 150/32768 °/s
#: and 3/32768 g per count, ±150 °/s and ±3 g readable. Misalignment was not measured (§3.4: ignored
#: for MEMS). Noise bandwidths 25 Hz / 75 Hz (§1.2, the bandwidths (5.21) divides by, §1.3).
#: Temperature about 28 °C on the drives (§7.1.3, Fig. 8-3); the ±0.5 °C power-up spread and the
#: drift to within ±1 °C over 30 min are assumptions (the unit stayed within 24-28 °C, §4).
#: The report's values are per device axis; they are carried into FLU with the imu400cc_node
#: defaults (axis_map, accel_sign), as config/imu400cc_calibration.yaml says for the fusion node.
_IMU400CC_AXES = AxisMap.from_spec(DEFAULT_AXIS_SPEC)
#: Input size [mg] from which the IMU400CC's accelerometers take their ±1 g scale: the report
#: corrects by input size (§9.1.1) without stating where it switches; the project takes the
#: middle of its two calibration inputs, 0.2 g and 1 g.
IMU400CC_LARGE_INPUT_MG = 600.0
IMU400CC = ImuProfile(
    name="imu400cc",
    rate_hz=134.0,
    gyro=TriadErrors(
        noise_density=_each(deg_sqrt_h, *(60.0 * s / DEG / 5.0 for s in (0.0041, 0.0040, 0.0048))),
        bias_instability=_each(deg_s, 0.0030, 0.0019, 0.0051),
        bias_correlation_time_s=_same(300.0),
        bias=_each(deg_s, 0.0246, -0.0343, -0.0153),
        bias_sigma=_each(deg_s, 0.010, 0.0089, 0.0140),
        scale_pos=_each(percent, 0.0921, 0.8286, 0.2637),
        scale_neg=_each(percent, -0.1304, -0.8199, -0.1811),
        resolution=deg_s(150.0 / 32768.0),
        full_scale=deg_s(150.0),
        bandwidth_hz=25.0,
    ).in_flu(_IMU400CC_AXES, 1.0),
    accel=TriadErrors(
        noise_density=_each(
            m_s_sqrt_h, *(60.0 * s / math.sqrt(75.0) for s in (0.0029, 0.0038, 0.0036))
        ),
        bias_instability=_same(mg(0.4)),
        bias_correlation_time_s=_same(300.0),
        bias=_each(mg, 5.4, -3.1, 7.1),
        bias_sigma=_each(mg, 0.2, 0.3, 0.2),
        scale_pos=_each(percent, 0.0652, 0.0309, -0.0202),
        scale_neg=_each(percent, 0.0172, 0.0340, 0.0846),
        scale_large_pos=_each(percent, -0.2953, -0.0803, -0.0002),
        scale_large_neg=_each(percent, -0.2953, -0.0803, -0.0002),
        large_input=mg(IMU400CC_LARGE_INPUT_MG),
        resolution=mg(3000.0 / 32768.0),
        full_scale=mg(3000.0),
        bandwidth_hz=75.0,
    ).in_flu(_IMU400CC_AXES, DEFAULT_ACCEL_SIGN),
    gyro_g_sensitivity=mat3(
        DEFAULT_ACCEL_SIGN
        * _IMU400CC_AXES.matrix_to_flu(
            [
                _each(_deg_s_per_g, -0.0003, -0.0002, 0.0006),
                _each(_deg_s_per_g, -0.0005, 0.0021, -0.0001),
                _each(_deg_s_per_g, -0.0076, -0.0004, 0.0030),
            ]
        )
    ),
    temperature=TemperatureSpec(
        mean_c=28.0, turn_on_sigma_c=0.5, drift_sigma_c=1.0, drift_time_s=1800.0
    ),
    source="shared/reference/imu400cc-aalborg-notes.md §1.2, §1.3, §2.4, §3.3, §7.1.3",
)

#: Sensonor STIM300 (Oslo notes §4.5 Table 5.1, identified at 500 Hz, converted to densities:
#: white density = per-sample std × sqrt(0.002 s), random-walk density = driving std ×
#: sqrt(0.002 s), bias instability = the Allan read-off B as stationary std; notes §4.1-§4.4).
#: Datasheet (§5): bias error over temperature ±10 °/h and ±2 mg rms (turn-on draws), scale
#: ±500 / ±300 ppm, misalignment 1 mrad, resolution 0.22 °/h and 1.9 µg, range ±480 °/s
#: (output cap) and ±10 g.
_STIM_DT_SQRT = math.sqrt(0.002)
STIM300 = ImuProfile(
    name="stim300",
    rate_hz=500.0,
    gyro=TriadErrors(
        noise_density=_same(deg_s(3.779e-2) * _STIM_DT_SQRT),
        bias_instability=_same(deg_s(1.613e-4)),
        bias_correlation_time_s=_same(800.0),
        random_walk=_same(deg_s(9.764e-5) * _STIM_DT_SQRT),
        bias_sigma=_same(deg_h(10.0)),
        scale_sigma=_same(ppm(500.0)),
        misalignment_sigma_rad=1e-3,
        resolution=deg_h(0.22),
        full_scale=deg_s(480.0),
    ),
    accel=TriadErrors(
        noise_density=_same(1.797e-2 * _STIM_DT_SQRT),
        bias_instability=_same(2.385e-4),
        bias_correlation_time_s=_same(150.0),
        random_walk=_same(2.040e-4 * _STIM_DT_SQRT),
        bias_sigma=_same(mg(2.0)),
        scale_sigma=_same(ppm(300.0)),
        misalignment_sigma_rad=1e-3,
        resolution=mg(1.9e-3),
        full_scale=mg(10000.0),
    ),
    source="shared/reference/mems-noise-oslo-notes.md §4.1-§4.5 (Table 5.1), §5",
)

#: ST L3G4200D gyro + LIS331DLH accelerometer in the Q-Free OBU, 50 Hz (NTNU notes §3).
#: White noise from the bench variances of Tables 4.4/4.5 at 50 Hz (density = σ/sqrt(50 Hz));
#: gyro turn-on bias = mean and std of the four standstills of Table 4.6 (two power cycles);
#: accelerometer bias and symmetric scale from the six-position test of Table 4.7 (notes §5:
#: offsets +0.021, +0.1046, -0.017 m/s², scale (|a+| + |a-|)/2 / 9.82171 - 1); output in mdps and
#: mg (1 count each) with the signed 16-bit wrap at 32.768 °/s the notes found in sharp turns (§11).
#: Bias instability is not characterised. Accelerometer range ±2 g is the LIS331DLH's smallest
#: setting (external; the thesis does not give the configuration).
_NTNU_G = 9.82171
L3G4200D_LIS331DLH = ImuProfile(
    name="l3g4200d_lis331dlh",
    rate_hz=50.0,
    gyro=TriadErrors(
        noise_density=_each(lambda v: math.sqrt(v / 50.0), 7.02e-6, 5.14e-6, 7.36e-6),
        bias=(-0.0028775, 0.0031975, -0.002615),
        bias_sigma=(0.0013937, 0.0000801, 0.0010792),
        resolution=deg_s(1e-3),
        full_scale=deg_s(32.768),
        wrap=True,
    ),
    accel=TriadErrors(
        noise_density=_each(lambda v: math.sqrt(v / 50.0), 1.877e-4, 2.189e-4, 3.517e-4),
        bias=(0.021, 0.1046, -0.017),
        scale_pos=_each(lambda a: a / _NTNU_G - 1.0, 10.026, 10.0995, 10.18),
        scale_neg=_each(lambda a: a / _NTNU_G - 1.0, 10.026, 10.0995, 10.18),
        resolution=mg(1.0),
        full_scale=mg(2000.0),
    ),
    source="shared/reference/gnss-ins-ntnu-notes.md §3, §5, §11 (Tables 4.4-4.7)",
)

#: Error-free IMU (exact truth, no quantisation, unlimited range).
IDEAL = ImuProfile(name="ideal", rate_hz=134.0, gyro=TriadErrors(), accel=TriadErrors())

PROFILES: dict[str, ImuProfile] = {
    p.name: p for p in (IMU400CC, STIM300, L3G4200D_LIS331DLH, IDEAL)
}


class _TriadModel:
    """Turn-on draws and running noise processes of one triad."""

    def __init__(
        self, errors: TriadErrors, seed: np.random.SeedSequence, band_limited: bool
    ) -> None:
        turn_on, white, gm, walk = (np.random.default_rng(s) for s in seed.spawn(4))
        e = errors
        self.errors = e
        self.bias = np.array(e.bias) + np.array(e.bias_sigma) * turn_on.standard_normal(3)
        scale_draw = np.array(e.scale_sigma) * turn_on.standard_normal(3)
        self.scale_pos = np.array(e.scale_pos) + scale_draw
        self.scale_neg = np.array(e.scale_neg) + scale_draw
        self.scale_large_pos = np.array(e.scale_large_pos) + scale_draw
        self.scale_large_neg = np.array(e.scale_large_neg) + scale_draw
        off_diagonal = 1.0 - np.eye(3)
        self.misalignment = (
            np.array(e.misalignment_rad)
            + e.misalignment_sigma_rad * turn_on.standard_normal((3, 3))
        ) * off_diagonal
        self.bandwidth_hz = e.bandwidth_hz if band_limited else math.inf
        self.white: WhiteNoise | BandLimitedNoise = (
            BandLimitedNoise(np.array(e.noise_density), self.bandwidth_hz, white)
            if math.isfinite(self.bandwidth_hz)
            else WhiteNoise(np.array(e.noise_density), white)
        )
        self.instability = GaussMarkov(
            np.array(e.bias_instability), np.array(e.bias_correlation_time_s), gm
        )
        self.walk = RandomWalk(np.array(e.random_walk), walk)

    def noise_sigma(self, dt_s: float) -> FloatArray:
        """Per-sample std of the white (or band-limited) noise at spacing dt_s, per axis [u]."""
        bandwidth = min(self.bandwidth_hz, 1.0 / dt_s)
        return np.array(self.errors.noise_density) * math.sqrt(bandwidth)

    def apply(self, truth: FloatArray, dt_s: FloatArray, extra: FloatArray) -> FloatArray:
        """Measured values (n, 3) for true inputs (n, 3); extra is added before quantisation."""
        scale = np.where(
            np.abs(truth) >= self.errors.large_input,
            np.where(truth >= 0.0, self.scale_large_pos, self.scale_large_neg),
            np.where(truth >= 0.0, self.scale_pos, self.scale_neg),
        )
        out = (
            truth * (1.0 + scale)
            + truth @ self.misalignment.T
            + self.bias
            + self.instability.sample(dt_s)
            + self.walk.sample(dt_s)
            + self.white.sample(dt_s)
            + extra
        )
        e = self.errors
        if e.resolution > 0.0:
            out = np.round(out / e.resolution) * e.resolution
        if e.wrap:
            return np.asarray(
                np.mod(out + e.full_scale, 2.0 * e.full_scale) - e.full_scale, dtype=np.float64
            )
        return np.clip(out, -e.full_scale, e.full_scale)


class _TemperatureModel:
    """Seeded sensor temperature of one power-up (see TemperatureSpec)."""

    def __init__(self, spec: TemperatureSpec, seed: np.random.SeedSequence) -> None:
        start, settled = np.random.default_rng(seed).standard_normal(2)
        self._start_c = spec.mean_c + spec.turn_on_sigma_c * start
        self._settled_c = spec.mean_c + spec.drift_sigma_c * settled
        self._time_constant_s = spec.drift_time_s

    def sample(self, t_s: FloatArray) -> FloatArray:
        """Temperature [°C] at times t_s [s] since power-up."""
        decay = np.exp(-np.asarray(t_s, dtype=np.float64) / self._time_constant_s)
        return np.asarray(self._settled_c + (self._start_c - self._settled_c) * decay)


class ImuErrorModel:
    """A powered-up IMU of a profile: seeded turn-on errors and running noise processes.

    Feed it consecutive blocks of true samples (any block size, any spacing); the output only
    depends on the seed and the sample times, not on how the record is split. ``band_limited``
    low-passes the white noise with the profile's noise bandwidths (TriadErrors.bandwidth_hz).
    """

    def __init__(self, profile: ImuProfile, seed: int, band_limited: bool = False) -> None:
        self.profile = profile
        gyro_seed, accel_seed, temperature_seed = np.random.SeedSequence(seed).spawn(3)
        self.gyro = _TriadModel(profile.gyro, gyro_seed, band_limited)
        self.accel = _TriadModel(profile.accel, accel_seed, band_limited)
        self._temperature = _TemperatureModel(profile.temperature, temperature_seed)
        self._g_sensitivity = np.array(profile.gyro_g_sensitivity)
        self._last_t_s: float | None = None

    def noise_sigma(self) -> tuple[FloatArray, FloatArray]:
        """Per-sample std of the white noise at the profile's rate: (gyro [rad/s], accel
        [m/s²]) per axis, what the driver's covariances state."""
        dt = 1.0 / self.profile.rate_hz
        return self.gyro.noise_sigma(dt), self.accel.noise_sigma(dt)

    def temperature_c(self, t_s: FloatArray) -> FloatArray:
        """Sensor temperature [°C] at times t_s [s] (its own random draws)."""
        return self._temperature.sample(t_s)

    def apply(
        self, t_s: FloatArray, rate_flu_rad_s: FloatArray, specific_force_flu_m_s2: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """Measured (rate, specific force) in the sensor's FLU axes for true samples at t_s.

        t_s: increasing sample times (n,) [s]; true inputs (n, 3) [rad/s], [m/s²]. The first
        sample of the first block is taken one nominal period after the previous (virtual) one.
        """
        t = np.atleast_1d(np.asarray(t_s, dtype=np.float64))
        previous = t[0] - 1.0 / self.profile.rate_hz if self._last_t_s is None else self._last_t_s
        dt = np.diff(t, prepend=previous)
        if np.any(dt <= 0.0):
            raise ValueError("IMU sample times must increase")
        self._last_t_s = float(t[-1])
        rate = np.atleast_2d(rate_flu_rad_s)
        force = np.atleast_2d(specific_force_flu_m_s2)
        measured_force = self.accel.apply(force, dt, np.zeros_like(force))
        measured_rate = self.gyro.apply(rate, dt, force @ self._g_sensitivity.T)
        return measured_rate, measured_force
