"""Engine and road vibration of a car body as a MEMS IMU senses it (simulator only).

In a moving car the IMU output carries vibration 10-100x its datasheet white noise: band-limited
(engine, road and suspension), zero-mean, growing with speed. Modelled here per axis of imu_link
(REP-103 FLU, the sensor's frame) as band-limited Gaussian noise added to the true specific force
[m/s²] and angular rate [rad/s] before the sensor's errors (a real input: scale factors,
misalignment and g-sensitivity act on it, then noise, quantisation and range limits follow).

Spectrum: two independent components per axis, each unit white noise on a uniform grid at the
IMU rate through a 4th-order Butterworth band-pass (scipy.signal, second-order sections),
normalised to unit variance and mixed by a variance fraction:

- road / suspension: 0.5-5 Hz, ``road_fraction`` of the variance (accel 0.15, gyro 0.4);
- engine / body: 5-40 Hz, the rest.

Band edges above 0.45x the IMU rate are lowered to it (the per-sample σ is kept). Outside
0.25-50 Hz lies < 0.1 % of the power at 134 Hz.

Amplitude: per-sample σ of each axis = profile σ (at ``reference_speed_m_s``) x
``speed_factor`` = idle + (1 - idle) |v| / v_ref, with idle = 0.1 (engine idling at a standstill,
assumed); no upper cap.

Profiles (σ at 15 m/s, x forward, y left, z up):

| name | accel σ [m/s²] | gyro σ [rad/s] |
|---|---|---|
| none | 0 | 0 |
| car | 0.58, 0.37, 0.52 | 0.0072, 0.0186, 0.0029 |
| rough | 1.16, 0.74, 1.04 | 0.0144, 0.0372, 0.0058 |

Source: the comma2k19 segment (test/fixtures/comma2k19/README.md, `/imu/data_raw`): a phone
IMU on a car windshield mount at 104 Hz, driving 8-20 m/s, per-sample σ of the high-passed
signal accel (0.58, 0.37, 0.52) m/s², gyro (0.0072, 0.0186, 0.0029) rad/s; ``car`` takes these
measured values as they are (the only real vibration record the project has). Road
fractions: in that record 0.5-5 Hz holds 13-19 % (accel) and 29-74 % (gyro) of the power above
0.5 Hz, an upper bound since it includes the car's own manoeuvres. Idle fraction, reference speed
and the 2x of ``rough`` are assumed.

Sampling: the filters run on the grid k / rate_hz (integer k) of the time axis, from the grid
point at or before the first requested time on; a requested time between grid points is
interpolated linearly (exact for the simulator's k / rate stamps and the emulator's device
times; between points the high-frequency part is slightly attenuated). One normal per grid point
and channel is drawn in time order after a 20 s warm-up (stationary start), so the output
depends only on the seed and the sample times, not on how a record is split into blocks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy import signal

from gnss_ins_common.types import FloatArray, Vec3

Band = tuple[float, float]
_ZERO3: Vec3 = (0.0, 0.0, 0.0)
#: Butterworth order of each band-pass (2 x order poles).
FILTER_ORDER = 4
#: Highest band edge as a fraction of the sample rate (below Nyquist with a margin).
_MAX_EDGE_FRACTION = 0.45
#: Warm-up of the filters before the first sample [s] (the slowest pole decays in ~1 s).
_WARM_UP_S = 20.0
#: Length of the impulse response used to normalise the filters [s].
_IMPULSE_S = 60.0
#: Requested times within this many grid steps of a grid point take its value.
_SNAP = 1e-6


@dataclass(frozen=True)
class VibrationProfile:
    """A named vibration environment of the IMU, per axis of imu_link (FLU).

    gyro_sigma_rad_s, accel_sigma_m_s2: per-sample σ at reference_speed_m_s [rad/s], [m/s²];
    idle_fraction: σ at a standstill as a fraction of that [-]; road_band_hz, body_band_hz:
    band-pass edges of the two components [Hz]; gyro_road_fraction, accel_road_fraction: share of
    the variance in the road band [-]; source: where the numbers come from.
    """

    name: str
    gyro_sigma_rad_s: Vec3 = _ZERO3
    accel_sigma_m_s2: Vec3 = _ZERO3
    reference_speed_m_s: float = 15.0
    idle_fraction: float = 0.1
    road_band_hz: Band = (0.5, 5.0)
    body_band_hz: Band = (5.0, 40.0)
    gyro_road_fraction: float = 0.4
    accel_road_fraction: float = 0.15
    source: str = ""

    @property
    def silent(self) -> bool:
        """True when the profile adds nothing."""
        return not any(self.gyro_sigma_rad_s) and not any(self.accel_sigma_m_s2)


_SOURCE = (
    "comma2k19 segment (test/fixtures/comma2k19/README.md, /imu/data_raw: windshield phone "
    "IMU, 8-20 m/s, per-sample σ of the high-passed signal accel 0.58/0.37/0.52 m/s², gyro "
    "0.0072/0.0186/0.0029 rad/s, x forward, y left, z up)"
)
NONE = VibrationProfile(name="none")
CAR = VibrationProfile(
    name="car",
    gyro_sigma_rad_s=(0.0072, 0.0186, 0.0029),
    accel_sigma_m_s2=(0.58, 0.37, 0.52),
    source=_SOURCE,
)
ROUGH = VibrationProfile(
    name="rough",
    gyro_sigma_rad_s=(0.0144, 0.0372, 0.0058),
    accel_sigma_m_s2=(1.16, 0.74, 1.04),
    source="car x 2 (assumed: rough road surface)",
)
PROFILES: dict[str, VibrationProfile] = {p.name: p for p in (NONE, CAR, ROUGH)}


def profile(name: str) -> VibrationProfile:
    """The profile called ``name``; ValueError naming the known ones otherwise."""
    try:
        return PROFILES[name]
    except KeyError:
        known = ", ".join(sorted(PROFILES))
        raise ValueError(f"unknown vibration profile {name!r} (known: {known})") from None


def speed_factor(vib: VibrationProfile, speed_m_s: ArrayLike) -> FloatArray:
    """σ at speed |speed_m_s| [m/s] relative to σ at the reference speed [-]:
    idle + (1 - idle) |v| / v_ref."""
    speed = np.abs(np.asarray(speed_m_s, dtype=np.float64))
    idle = vib.idle_fraction
    return np.asarray(idle + (1.0 - idle) * speed / vib.reference_speed_m_s, dtype=np.float64)


def vibration_sigma(vib: VibrationProfile, speed_m_s: float) -> tuple[FloatArray, FloatArray]:
    """Per-sample σ per axis at a speed [m/s]: (gyro [rad/s], accel [m/s²]), shape (3,) each."""
    factor = float(speed_factor(vib, speed_m_s))
    return (
        np.array(vib.gyro_sigma_rad_s) * factor,
        np.array(vib.accel_sigma_m_s2) * factor,
    )


@dataclass(frozen=True)
class _BandPass:
    """One band-pass at a sample rate: sections, unit-variance gain, noise-equivalent bandwidth."""

    sos: FloatArray
    gain: float
    bandwidth_hz: float

    @classmethod
    def design(cls, band_hz: Band, rate_hz: float) -> _BandPass:
        low, high = band_hz[0], min(band_hz[1], _MAX_EDGE_FRACTION * rate_hz)
        if not 0.0 < low < high:
            raise ValueError(
                f"vibration band {band_hz[0]:g}-{band_hz[1]:g} Hz does not fit a {rate_hz:g} Hz "
                "sample rate"
            )
        sos = np.asarray(
            signal.butter(FILTER_ORDER, (low, high), btype="bandpass", fs=rate_hz, output="sos"),
            dtype=np.float64,
        )
        impulse = np.zeros(max(round(_IMPULSE_S * rate_hz), 64))
        impulse[0] = 1.0
        energy = float(np.sum(signal.sosfilt(sos, impulse) ** 2))
        _, response = signal.sosfreqz(sos, worN=8192, fs=rate_hz)
        peak = float(np.max(np.abs(response)))
        # Two-sided convention of noise.py (σ² = N² B): B = fs Σh² / |H|²max.
        return cls(sos, 1.0 / math.sqrt(energy), rate_hz * energy / peak**2)


def _bands(vib: VibrationProfile, rate_hz: float) -> tuple[_BandPass, _BandPass]:
    return _BandPass.design(vib.road_band_hz, rate_hz), _BandPass.design(vib.body_band_hz, rate_hz)


def _road_fractions(vib: VibrationProfile) -> FloatArray:
    """Road-band variance fraction of the six channels (gyro x, y, z, accel x, y, z)."""
    return np.repeat([vib.gyro_road_fraction, vib.accel_road_fraction], 3)


def equivalent_density(
    vib: VibrationProfile, speed_m_s: float, rate_hz: float
) -> tuple[FloatArray, FloatArray]:
    """White-noise density equivalent to the vibration at a speed [m/s], sampled at rate_hz [Hz]:
    (gyro [rad/s/sqrt(Hz)], accel [m/s²/sqrt(Hz)]) per axis.

    The vibration's mean PSD level over its band (two-sided, the ARW/VRW convention of
    noise.py, σ² = N² B): N = σ / sqrt(B_road + B_body), with B the noise-equivalent bandwidths
    of the two band-passes (≈ 2 x 4.5 Hz and 2 x 35 Hz); for one flat band, σ / sqrt(B). It is
    the low-frequency-equivalent level: white noise of density N carries the vibration's power
    within its band, i.e. what a filter treating the vibration as white noise should add to the
    sensor's density. It is not the per-sample level: white noise of density N sampled at
    rate_hz has σ = N sqrt(rate_hz), more than the vibration's σ (that would be σ sqrt(dt)).
    The road band holds a higher level than the body band when its fraction exceeds its share
    of the bandwidth (gyro: about 5x), so this is an average, not a flat spectrum.
    """
    gyro_sigma, accel_sigma = vibration_sigma(vib, speed_m_s)
    if vib.silent:
        return np.zeros(3), np.zeros(3)
    road, body = _bands(vib, rate_hz)
    bandwidth = road.bandwidth_hz + body.bandwidth_hz
    return gyro_sigma / math.sqrt(bandwidth), accel_sigma / math.sqrt(bandwidth)


class Vibration:
    """Seeded vibration of one drive: ``sample(t_s, speed_m_s)`` gives (rate [rad/s], specific
    force [m/s²]) to add to the truth in imu_link FLU, shape (n, 3) each.

    rate_hz: the IMU's nominal rate (the filters' grid) [Hz]; seed: int or SeedSequence. Feed
    non-decreasing times (any spacing, any block size); ``none`` gives exact zeros without
    drawing.
    """

    def __init__(
        self, vib: VibrationProfile, rate_hz: float, seed: int | np.random.SeedSequence
    ) -> None:
        if not rate_hz > 0.0:
            raise ValueError("the IMU rate must be positive")
        self.profile = vib
        self.rate_hz = rate_hz
        self._sigma = np.concatenate([vib.gyro_sigma_rad_s, vib.accel_sigma_m_s2])
        self._last_t = -math.inf
        self._next: int | None = None  # grid index of the next point to generate
        self._tail = np.zeros((2, 6))  # unit-σ values at grid points next - 2, next - 1
        if vib.silent:
            return
        self._rng = np.random.default_rng(seed)
        self._road, self._body = _bands(vib, rate_hz)
        road_fraction = _road_fractions(vib)
        self._road_weight = np.sqrt(road_fraction) * self._road.gain
        self._body_weight = np.sqrt(1.0 - road_fraction) * self._body.gain
        self._zi_road = np.zeros((self._road.sos.shape[0], 2, 6))
        self._zi_body = np.zeros((self._body.sos.shape[0], 2, 6))
        self._grid(round(_WARM_UP_S * rate_hz))

    def _grid(self, count: int) -> FloatArray:
        """The next ``count`` grid values, unit σ per channel (gyro x, y, z, accel x, y, z)."""
        if count == 0:  # scipy's sosfilt refuses an empty block
            return np.zeros((0, 6))
        draws = self._rng.standard_normal((count, 2, 6))
        road, self._zi_road = signal.sosfilt(self._road.sos, draws[:, 0], axis=0, zi=self._zi_road)
        body, self._zi_body = signal.sosfilt(self._body.sos, draws[:, 1], axis=0, zi=self._zi_body)
        return np.asarray(road * self._road_weight + body * self._body_weight, dtype=np.float64)

    def sample(self, t_s: ArrayLike, speed_m_s: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Vibration at sample times t_s (n,) [s] with vehicle speeds speed_m_s (n,) or scalar
        [m/s]: (angular rate [rad/s], specific force [m/s²]) in imu_link FLU, (n, 3) each."""
        t = np.atleast_1d(np.asarray(t_s, dtype=np.float64))
        speed = np.broadcast_to(np.asarray(speed_m_s, dtype=np.float64), t.shape)
        if t.ndim != 1:
            raise ValueError("sample times must be one-dimensional")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(speed))):
            raise ValueError("sample times and speeds must be finite")
        if len(t) and (t[0] < self._last_t or np.any(np.diff(t) < 0.0)):
            raise ValueError("vibration sample times must not decrease")
        if self.profile.silent or not len(t):
            return np.zeros((len(t), 3)), np.zeros((len(t), 3))
        self._last_t = float(t[-1])
        position = t * self.rate_hz
        nearest = np.rint(position)
        position = np.where(np.abs(position - nearest) < _SNAP, nearest, position)
        lower = np.floor(position).astype(np.int64)
        if self._next is None:
            self._next = int(lower[0])
        needed = max(int(np.ceil(position[-1])) + 1 - self._next, 0)
        base = self._next - 2
        values = np.concatenate([self._tail, self._grid(needed)])
        self._next += needed
        self._tail = values[-2:].copy()
        index = lower - base
        upper = np.minimum(index + 1, len(values) - 1)
        weight = (position - lower)[:, None]
        unit = values[index] * (1.0 - weight) + values[upper] * weight
        out = unit * self._sigma * speed_factor(self.profile, speed)[:, None]
        return out[:, :3].copy(), out[:, 3:].copy()
