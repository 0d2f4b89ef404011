"""Allan analysis of every gyro and accelerometer axis of a static record, the user-facing units
of the terms, and what a record or a report lacks for the requested terms.

Terms a user can require (``gnss_ins allan --terms``): ``white`` (ARW/VRW, read at τ = 1 s),
``bias`` (bias instability and its correlation time) and ``rrw`` (rate/acceleration random
walk). Quantisation is reported where visible and never required. What "enough" means:

- white: the Allan variance at τ = 1 s needs MIN_WHITE_EDF = 200 equivalent degrees of freedom
  (Allan deviation 1σ ≈ 5 %); white noise has ≈ 1.5 L/τ of them in the overlapping estimator
  (Greenhall), so L ≥ 134 s;
- bias, Gauss-Markov: the 1σ relative error of σ at most MAX_SIGMA_ERROR = 5 % and of T at
  most MAX_TIME_ERROR = 10 % (Fisher information of the Whittle likelihood, whittle.py), so
  that σ is within 10 % and T within 20 % of the truth at 95 %; the errors fall as
  1/sqrt(length), which gives the length a record needs: a day to weeks for MEMS (the bias must
  be told from the white noise and the random walk in the few frequencies below 1/(2πT));
- bias, flicker floor: MIN_BIAS_EDF = 200 equivalent degrees of freedom at the minimum of the
  Allan curve (Allan deviation 1σ ≈ 5 %, the same 10 % at 95 % as a Gauss-Markov σ), about
  150 τ_min of record;
- rrw: its +1/2 slope must be visible.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ins_fusion.bags.imu import ImuRecord
from ins_fusion.core.nav.units import DEG, mg, to_deg_h, to_deg_sqrt_h, to_m_s_sqrt_h
from ins_fusion.noise_id.allan import ONE_SIGMA, AllanCurve, equivalent_dof, overlapping_adev
from ins_fusion.noise_id.likelihood import refine
from ins_fusion.noise_id.record import RecordError, SampleClock
from ins_fusion.noise_id.terms import GAUSS_MARKOV, BiasInstability, NoiseTerms, fit_noise_terms
from ins_fusion.noise_id.whittle import BIAS, LOG_TIME, SpectralModel, expected_errors

#: Terms ``--terms`` accepts, with their names in messages.
TERMS: dict[str, str] = {
    "white": "white noise (ARW/VRW)",
    "bias": "bias instability",
    "rrw": "random walk (RRW)",
}
DEFAULT_TERMS = ("white", "bias")
#: Where white noise is read [s] (Oslo notes §3 slope table).
WHITE_TAU_S = 1.0
#: Equivalent degrees of freedom of the overlapping Allan variance of white noise per cluster
#: time of record (Greenhall: edf ≈ 1.5 L/τ - 2 for L >> τ).
WHITE_EDF_PER_CLUSTER = 1.5
MIN_WHITE_EDF = 200.0
MIN_BIAS_EDF = 200.0
MAX_SIGMA_ERROR = 0.05
MAX_TIME_ERROR = 0.10
_LENGTH_ITERATIONS = 3
#: Power-law exponent of flicker noise, the noise type where the bias is read.
_FLICKER_ALPHA = -1


@dataclass(frozen=True)
class Unit:
    """A user-facing unit: its label and the number of it in one SI unit."""

    label: str
    per_si: float


@dataclass(frozen=True)
class Sensor:
    """A triad and the units its terms are shown in (KF-GINS / datasheet style, the units of
    ins_fusion_node's imu_noise parameters)."""

    name: str
    adev: Unit
    white: Unit
    bias: Unit
    random_walk: Unit
    quantization: Unit


GYRO = Sensor(
    "gyro",
    adev=Unit("deg/h", to_deg_h(1.0)),
    white=Unit("deg/sqrt(h)", to_deg_sqrt_h(1.0)),
    bias=Unit("deg/h", to_deg_h(1.0)),
    random_walk=Unit("deg/h/sqrt(h)", to_deg_h(1.0) * 60.0),
    quantization=Unit("deg", 1.0 / DEG),
)
ACCEL = Sensor(
    "accel",
    adev=Unit("mg", 1.0 / mg(1.0)),
    white=Unit("m/s/sqrt(h)", to_m_s_sqrt_h(1.0)),
    bias=Unit("mg", 1.0 / mg(1.0)),
    random_walk=Unit("m/s^2/sqrt(h)", 60.0),
    quantization=Unit("m/s", 1.0),
)
SENSORS = (GYRO, ACCEL)
AXES = ("x", "y", "z")


@dataclass(frozen=True)
class AxisNoise:
    """The fitted terms of one axis (SI units) and its Allan curve."""

    sensor: Sensor
    axis: str
    terms: NoiseTerms

    @property
    def curve(self) -> AllanCurve:
        """The measured Allan deviation, noise types and edf from the fitted model."""
        return self.terms.curve

    @property
    def name(self) -> str:
        """``gyro x`` etc."""
        return f"{self.sensor.name} {self.axis}"


@dataclass(frozen=True)
class NoiseReport:
    """Every axis of one record (gyro x, y, z, then accelerometer x, y, z), where the record
    came from (free text) and how it was sampled."""

    axes: tuple[AxisNoise, ...]
    clock: SampleClock
    n_samples: int
    duration_s: float
    confidence: float
    source: str

    def of(self, sensor: Sensor) -> tuple[AxisNoise, ...]:
        """The three axes of a sensor."""
        return tuple(a for a in self.axes if a.sensor is sensor)


def identify(
    record: ImuRecord,
    clock: SampleClock,
    source: str,
    confidence: float = ONE_SIGMA,
    on_axis: Callable[[int], None] | None = None,
) -> NoiseReport:
    """Allan curve and terms of the six axes; ``on_axis(k)`` after the k-th (progress)."""
    axes = []
    for sensor, values in (
        (GYRO, record.rate_flu_rad_s),
        (ACCEL, record.force_flu_m_s2),
    ):
        for i, axis in enumerate(AXES):
            curve = overlapping_adev(values[:, i], clock.rate_hz)
            terms = fit_noise_terms(curve, confidence)
            terms = refine(terms, values[:, i], clock.rate_hz, confidence)
            axes.append(AxisNoise(sensor, axis, terms))
            if on_axis is not None:
                on_axis(len(axes))
    return NoiseReport(tuple(axes), clock, len(record.t_s), record.duration_s, confidence, source)


def hours(seconds: float) -> str:
    """A duration for messages: seconds below an hour, hours below 3 days, else days."""
    if seconds < 3600.0:
        return f"{seconds:.0f} s"
    return f"{seconds / 3600.0:.1f} h" if seconds < 72 * 3600.0 else f"{seconds / 86400.0:.1f} days"


def check_length(duration_s: float, terms: Sequence[str]) -> None:
    """RecordError, saying how long is needed, if the record is too short for white noise (the
    least any requested term needs)."""
    needed = MIN_WHITE_EDF / WHITE_EDF_PER_CLUSTER * WHITE_TAU_S
    if duration_s >= needed:
        return
    lines = [f"the record is {duration_s:.1f} s; white noise (τ = 1 s) needs ≥ {needed:.0f} s"]
    if "bias" in terms:
        lines.append("bias instability needs days for a MEMS unit")
    if "rrw" in terms:
        lines.append("random walk needs its +1/2 slope, usually many hours")
    raise RecordError("too short: " + "; ".join(lines))


def _flicker_dof(tau_s: float, curve: AllanCurve) -> float:
    """Equivalent degrees of freedom of flicker noise at tau_s in the curve's record (0 beyond
    a third of the record, where the estimator has none to speak of)."""
    if 3 * round(tau_s * curve.rate_hz) >= curve.n_samples:
        return 0.0
    alpha = np.array([_FLICKER_ALPHA])
    return float(equivalent_dof(np.array([tau_s]), alpha, curve.rate_hz, curve.n_samples)[0])


def _shortfall(errors: tuple[float, float]) -> float:
    """How far the relative errors (σ, T) are from MAX_SIGMA_ERROR, MAX_TIME_ERROR (≤ 1: ok)."""
    return max(errors[0] / MAX_SIGMA_ERROR, errors[1] / MAX_TIME_ERROR)


def needed_record_s(model: SpectralModel, curve: AllanCurve, errors: tuple[float, float]) -> float:
    """Record length [s] at which noise ``model`` would give a Gauss-Markov bias σ within
    MAX_SIGMA_ERROR and T within MAX_TIME_ERROR (1σ), from the relative errors (σ, T) of the
    curve's record: the errors fall about as 1/sqrt(length), refined with the expected errors
    of the longer record; inf when the bias cannot be told from the other terms at all."""
    rate = curve.rate_hz
    length = curve.record_s * _shortfall(errors) ** 2
    for _ in range(_LENGTH_ITERATIONS):
        if not math.isfinite(length):
            return math.inf
        expected = expected_errors(model, rate, round(length * rate))
        length *= _shortfall((expected[BIAS], expected[LOG_TIME])) ** 2
    return length


def _gauss_markov_shortcoming(axis: AxisNoise, bias: BiasInstability) -> str | None:
    if _shortfall(bias.errors) <= 1.0:
        return None
    record_s = axis.curve.record_s
    _, white, sigma2, walk = axis.terms.coefficients
    model = SpectralModel(white, sigma2, walk, bias.time_constant_s)
    needed = needed_record_s(model, axis.curve, bias.errors)
    return (
        f"{axis.name}: bias instability σ ±{bias.errors[0]:.1%}, T ±{bias.errors[1]:.1%} (1σ) "
        f"from this {hours(record_s)} record; σ within {2 * MAX_SIGMA_ERROR:.0%} and T within "
        f"{2 * MAX_TIME_ERROR:.0%} (95 %) needs "
        + (f"≥ {hours(needed)} of record" if math.isfinite(needed) else "a far longer record")
    )


def bias_shortcoming(axis: AxisNoise) -> str | None:
    """Why the axis's bias instability falls short of the wanted precision (None: it does not)."""
    bias, curve = axis.terms.bias, axis.curve
    if bias is None:
        return (
            f"{axis.name}: no bias instability stands out of the scatter up to τ = "
            f"{curve.tau_s[-1]:.0f} s (the longest a {hours(curve.record_s)} record gives): "
            "neither a flat floor nor a Gauss-Markov hump; record at least twice as long"
        )
    if bias.model == GAUSS_MARKOV:
        return _gauss_markov_shortcoming(axis, bias)
    edf = _flicker_dof(bias.read_tau_s, curve)
    if edf >= MIN_BIAS_EDF:
        return None
    needed = curve.record_s * MIN_BIAS_EDF / edf if edf > 0.0 else MIN_BIAS_EDF * bias.read_tau_s
    return (
        f"{axis.name}: bias instability ({bias.model}) is read at τ = {bias.read_tau_s:.0f} s "
        f"with {edf:.1f} degrees of freedom (≥ {MIN_BIAS_EDF:g} wanted, Allan deviation 1σ ≈ "
        f"{100.0 / math.sqrt(2.0 * MIN_BIAS_EDF):.0f} %); that needs ≥ {hours(needed)} of "
        f"record, this one has {hours(curve.record_s)}"
    )


def shortcomings(report: NoiseReport, terms: Sequence[str]) -> list[str]:
    """Why the report does not give the requested terms (empty: it does)."""
    problems: list[str] = []
    for axis in report.axes:
        if "white" in terms and not axis.terms.white.visible:
            problems.append(f"{axis.name}: no white-noise (-1/2) slope in the Allan deviation")
        if "bias" in terms and (problem := bias_shortcoming(axis)) is not None:
            problems.append(problem)
        if "rrw" in terms and not axis.terms.random_walk.visible:
            bound = axis.terms.random_walk.high * axis.sensor.random_walk.per_si
            problems.append(
                f"{axis.name}: no random-walk (+1/2) slope up to τ = "
                f"{axis.curve.tau_s[-1]:.0f} s (K < {bound:.3g} "
                f"{axis.sensor.random_walk.label}); record at least twice as long or leave rrw "
                "out of --terms"
            )
    return problems
