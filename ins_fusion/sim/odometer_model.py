"""Odometer (vehicle speed) error model: a wheel pulse counter read at a fixed rate.

The wheel at the measuring point rolls the distance W(t) = ∫ v_P (1 + s)(1 − λ) dt, with v_P
the true forward speed (base_link x) at the measuring point, s the scale error (tyre radius,
load, pressure: 0.5–3 %) and λ the braking slip ratio. A counter with k pulses per
metre holds N(t) = floor(k·W(t)); every output period T it reports

    speed = (N(t_i) − N(t_{i−1})) / (k·T) + n,   n white, σ = ``noise_sigma_m_s``,

the mean speed over the period, quantised in steps of 1/(k·T) (k = 0: no quantisation). The
quantisation error of one output is the difference of two fractional pulse counts: triangular,
variance (1/(k·T))²/6, and consecutive errors cancel in the sum (the distance is kept to one
pulse). Slip: while base_link decelerates harder than ``slip_threshold_m_s2`` the wheels turn
slower than the car rolls, λ = ``slip_per_m_s2`` × (deceleration − threshold), at most 1 (a locked
wheel); a negative ``slip_per_m_s2`` over-reads instead. Slip grows with the braking force in
any real tyre; a threshold keeps normal braking clean and makes hard braking an episode a
filter's gate has to catch (assumed model, no source document measures it).

Numbers of ``DMI`` are assumptions, typical of a survey distance measuring instrument on a
rear wheel: 1024 pulses per revolution of a 2 m tyre (≈ 500 pulses/m), 20 Hz output (step
0.04 m/s), 2 % scale error, 0.01 m/s of white noise.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from gnss_ins_common.types import FloatArray

#: Gauss-Legendre nodes and weights on [0, 1] for the distance over one output period.
_GL_X, _GL_W = np.polynomial.legendre.leggauss(4)
_GL_NODES, _GL_WEIGHTS = 0.5 * (_GL_X + 1.0), 0.5 * _GL_W

#: Truth the model needs at times t_s [s]: forward speed at the measuring point (base_link x
#: axis) [m/s] and base_link's acceleration along its path [m/s²] (negative when braking).
SpeedTruth = Callable[[FloatArray], tuple[FloatArray, FloatArray]]


@dataclass(frozen=True)
class OdometerProfile:
    """An odometer: output rate [Hz], scale error (measured/true − 1), pulses per metre of
    wheel travel (0: no quantisation), white noise σ [m/s], braking slip (threshold
    deceleration [m/s²] and slip ratio per m/s² beyond it)."""

    name: str
    rate_hz: float = 20.0
    scale_error: float = 0.02
    pulses_per_m: float = 500.0
    noise_sigma_m_s: float = 0.01
    slip_threshold_m_s2: float = 3.0
    slip_per_m_s2: float = 0.05

    def __post_init__(self) -> None:
        numbers = (
            *(self.rate_hz, self.scale_error, self.pulses_per_m, self.noise_sigma_m_s),
            *(self.slip_threshold_m_s2, self.slip_per_m_s2),
        )
        valid = all(map(math.isfinite, numbers)) and self.rate_hz > 0.0
        valid = valid and self.scale_error > -1.0 and min(numbers[2:5]) >= 0.0
        if not valid:
            raise ValueError(
                f"odometer {self.name}: needs finite numbers, rate_hz > 0, scale_error > -1 and"
                " pulses_per_m, noise_sigma_m_s, slip_threshold_m_s2 >= 0"
            )

    @property
    def step_m_s(self) -> float:
        """Quantisation step of one output [m/s] (0 without quantisation)."""
        return 0.0 if self.pulses_per_m == 0.0 else self.rate_hz / self.pulses_per_m

    @property
    def reported_sigma_m_s(self) -> float:
        """σ the odometer states for one output [m/s]: white noise and quantisation."""
        return math.sqrt(self.noise_sigma_m_s**2 + self.step_m_s**2 / 6.0)

    def slip_ratio(self, accel_m_s2: FloatArray) -> FloatArray:
        """Slip ratio λ at base_link path accelerations [m/s²] (0 below the threshold)."""
        excess = np.maximum(-np.asarray(accel_m_s2) - self.slip_threshold_m_s2, 0.0)
        return np.asarray(np.minimum(self.slip_per_m_s2 * excess, 1.0), dtype=np.float64)


#: A survey DMI on a rear wheel (assumed numbers, module docstring).
DMI = OdometerProfile("dmi")
#: The truth: no scale error, quantisation, noise or slip.
IDEAL = OdometerProfile(
    "ideal", scale_error=0.0, pulses_per_m=0.0, noise_sigma_m_s=0.0, slip_per_m_s2=0.0
)
PROFILES = {p.name: p for p in (DMI, IDEAL)}


@dataclass(frozen=True)
class SpeedOutputs:
    """Outputs at the ends t_s of their counting periods [s]: the period's start [s] (its middle
    is the time of validity of the mean speed), the measured speed [m/s] and, for tests, the
    true mean forward speed over the period [m/s]."""

    t_s: FloatArray
    period_start_s: FloatArray
    speed_m_s: FloatArray
    true_mean_speed_m_s: FloatArray

    @property
    def mid_s(self) -> FloatArray:
        """Middle of each counting period [s]."""
        return np.asarray(0.5 * (self.t_s + self.period_start_s), dtype=np.float64)


class OdometerModel:
    """A seeded odometer on a vehicle's truth. ``measure(t_s)`` reads the counter at times t_s
    (increasing, after every earlier call's; the counter starts at zero at ``start_s``): the
    outputs depend only on the seed and the times, not on how they are split into calls."""

    def __init__(
        self, profile: OdometerProfile, truth: SpeedTruth, seed: int, start_s: float = 0.0
    ) -> None:
        self.profile = profile
        self._truth = truth
        self._rng = np.random.default_rng(seed)
        self._last_t_s = start_s
        self._wheel_m = 0.0
        self._true_m = 0.0

    def measure(self, t_s: FloatArray) -> SpeedOutputs:
        """The outputs read at times t_s [s]."""
        t = np.asarray(t_s, dtype=np.float64)
        if not len(t):
            return SpeedOutputs(t, t, t, t)
        starts = np.concatenate(([self._last_t_s], t[:-1]))
        spans = t - starts
        if not np.all(spans > 0.0):
            raise ValueError("odometer times must increase, after the last output")
        nodes = starts[:, None] + spans[:, None] * _GL_NODES
        speed, accel = (x.reshape(nodes.shape) for x in self._truth(nodes.ravel()))
        p = self.profile
        wheel_speed = speed * (1.0 + p.scale_error) * (1.0 - p.slip_ratio(accel))
        # Running sums from the counter's state, so that any split of the times adds alike.
        wheel = np.cumsum(np.concatenate(([self._wheel_m], wheel_speed @ _GL_WEIGHTS * spans)))
        true = np.cumsum(np.concatenate(([self._true_m], speed @ _GL_WEIGHTS * spans)))
        if p.pulses_per_m > 0.0:
            travelled = np.diff(np.floor(wheel * p.pulses_per_m)) / p.pulses_per_m
        else:
            travelled = np.diff(wheel)
        noise = self._rng.standard_normal(len(t)) * p.noise_sigma_m_s
        self._last_t_s, self._wheel_m, self._true_m = (
            float(t[-1]),
            float(wheel[-1]),
            float(true[-1]),
        )
        return SpeedOutputs(t, starts, travelled / spans + noise, np.diff(true) / spans)
