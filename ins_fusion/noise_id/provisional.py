"""A provisional bias instability for a record too short to pin it (``gnss_ins allan`` without
``--terms``).

A static record of half an hour to a few hours gives white noise to a few per cent but a
Gauss-Markov bias σ and T only to tens of per cent, or not at all when the bias hardly rises
above the white noise within the record (the IMU400CC's gyros in 40 min). Rather than write
nothing, the tool writes what the record supports, marked as provisional:

- the IEEE 952 bias instability B = (minimum of the Allan deviation) / 0.664 with its
  chi-squared interval (an upper bound when the minimum is the curve's last point: the curve
  still falls);
- one correlation time for the node, T_node: the geometric mean of the accepted axes' fitted T
  and, for every provisional axis, T_c = τ_max / 1.89, the time whose Allan-deviation hump lies
  at the longest cluster time τ_max the record gives (a longer T cannot be told from a random
  walk within the record);
- per provisional axis, σ_fit: the Gauss-Markov σ of time T_node that, with white noise, fits
  the Allan curve best (weighted non-negative least squares over the fitted τ range, weights
  sqrt(edf/2)/model as in terms.py), with the interval of σ² from the least-squares covariance
  (``visible`` when it excludes 0); Allan points are correlated, so that interval is narrower
  than the truth, and
- the node's σ: the larger of B and σ_fit's upper limit, a Gauss-Markov bias that covers both
  the floor of the curve (a Gauss-Markov hump peaks at 0.617 σ, the floor reads 0.664 B) and
  the fit's interval. On 40 min of the simulated IMU400CC (bench/bench_allan_provisional.py,
  docs/allan.md §6) that is 0.5-3.7 times the true σ for the gyros (median 1.0-1.9) and
  0.86-1.05 for the accelerometers;
- the record length that would pin σ and T (analysis.needed_record_s for the node's noise).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import nnls
from scipy.stats import norm

from ins_fusion.noise_id.analysis import AxisNoise, NoiseReport, bias_shortcoming, needed_record_s
from ins_fusion.noise_id.terms import GM_PEAK_TAU_FACTOR, Term
from ins_fusion.noise_id.whittle import BIAS, LOG_TIME, SpectralModel, expected_errors
from ins_fusion.sim.noise import allan_variance

_ITERATIONS = 3


@dataclass(frozen=True)
class ProvisionalBias:
    """The provisional bias of one axis [SI]: the floor read-off B, the σ of time T_node
    fitted to the curve, the node's σ (the larger of B and σ_fit.high) and the record length
    [s] that would pin σ and T (inf: no length the model can tell)."""

    axis: AxisNoise
    floor: Term
    sigma_fit: Term
    sigma: float
    needed_s: float

    @property
    def sigma_from_floor(self) -> bool:
        """The node's σ is the floor read-off (not σ_fit's upper limit)."""
        return self.sigma == self.floor.value


@dataclass(frozen=True)
class ProvisionalBiases:
    """The provisional axes and the node's one correlation time [s] for every axis."""

    axes: tuple[ProvisionalBias, ...]
    time_constant_s: float

    def of(self, axis: AxisNoise) -> ProvisionalBias | None:
        """The provisional bias of ``axis`` (None: the axis's own fit is accepted)."""
        return next((p for p in self.axes if p.axis is axis), None)


def cover_time_s(report: NoiseReport) -> float:
    """T_c [s]: the Gauss-Markov time whose hump lies at the record's longest cluster time."""
    return max(float(a.curve.tau_s[-1]) for a in report.axes) / GM_PEAK_TAU_FACTOR


def fit_at_time(axis: AxisNoise, time_constant_s: float, confidence: float) -> Term:
    """σ [u] of a Gauss-Markov bias of time_constant_s fitted with white noise to the axis's
    Allan curve over its fitted τ range, with the least-squares interval at ``confidence``."""
    curve = axis.curve
    fitted = curve.tau_s >= axis.terms.fit_tau_s[0]
    tau, avar, edf = curve.tau_s[fitted], curve.avar[fitted], curve.edf[fitted]
    columns = np.stack(
        [1.0 / tau, allan_variance(tau, gm_sigma=1.0, gm_time_constant_s=time_constant_s)], axis=1
    )
    model = avar
    for _ in range(_ITERATIONS):
        weighted = columns * (np.sqrt(edf / 2.0) / model)[:, None]
        coefficients, _ = nnls(weighted, avar * np.sqrt(edf / 2.0) / model)
        model = np.where(columns @ coefficients > 0.0, columns @ coefficients, avar)
    variance = float(coefficients[1])
    spread = float(norm.ppf(0.5 + confidence / 2.0)) * math.sqrt(
        float(np.linalg.inv(weighted.T @ weighted)[1, 1])
    )
    return Term(
        math.sqrt(variance),
        math.sqrt(max(variance - spread, 0.0)),
        math.sqrt(variance + spread),
        variance > spread,
    )


def provisional_biases(report: NoiseReport) -> ProvisionalBiases:
    """The provisional bias of every axis whose bias instability the record does not pin, and
    the node's correlation time (module docstring)."""
    short = [a for a in report.axes if bias_shortcoming(a) is not None]
    pinned = [a.terms.bias for a in report.axes if all(a is not s for s in short)]
    times = [b.time_constant_s for b in pinned if b is not None]
    times += [cover_time_s(report)] * len(short)
    time_constant = math.exp(sum(math.log(t) for t in times) / len(times)) if times else math.nan
    axes = []
    for axis in short:
        floor = axis.terms.flat_minimum
        sigma_fit = fit_at_time(axis, time_constant, report.confidence)
        sigma = max(floor.value, sigma_fit.high)
        model = SpectralModel(axis.terms.coefficients[1], sigma**2, 0.0, time_constant)
        n = axis.curve.n_samples
        expected = expected_errors(model, axis.curve.rate_hz, n)
        needed = needed_record_s(model, axis.curve, (expected[BIAS], expected[LOG_TIME]))
        axes.append(ProvisionalBias(axis, floor, sigma_fit, sigma, needed))
    return ProvisionalBiases(tuple(axes), time_constant)
