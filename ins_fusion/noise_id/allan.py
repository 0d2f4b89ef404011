"""Overlapping Allan deviation of a rate or specific-force series, with the power-law noise type,
the equivalent degrees of freedom and the confidence interval of every point.

Definition (Oslo notes §3, (3.12)-(3.14), code B.12): samples y_k at the rate f_s, cluster time
τ = m/f_s, the overlapping estimator over all clusters; allantools.oadev computes it from the
samples as "frequency" data, in the unit of the samples (rad/s, m/s²).

Uncertainty: the Allan variance estimate at τ is chi-squared distributed with an equivalent number
of degrees of freedom (edf) that depends on m, the record length and the power-law noise type α
(PSD ∝ f^α) dominating at τ. Greenhall's algorithm (allantools.edf_greenhall, overlapping
estimator) gives the edf (allantools.edf_simple where it has no case), allantools
.confidence_interval the interval. The noise type follows from the local log-log slope μ of the
Allan variance: white rate noise (α = 0) has μ = -1, flicker (α = -1) μ = 0, random walk (α = -2)
μ = +1, and the quantisation of the integrated output (white "phase" noise, α = 2) μ = -2 (Oslo
notes §3, (4.2)-(4.4) and the slope table).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import lru_cache

import allantools
import numpy as np

from gnss_ins_common.types import FloatArray, IntArray

#: Probability of a ±1σ interval of a normal variable (allantools' default, 0.6827).
ONE_SIGMA = math.erf(1.0 / math.sqrt(2.0))
#: Cluster times per decade of τ.
POINTS_PER_DECADE = 10
#: Longest cluster time as a fraction of the record: at L/5 the overlapping estimator still has
#: 1.5 (random walk) to 5 (white) equivalent degrees of freedom.
MAX_TAU_FRACTION = 0.2
#: Span of the local slope of a measured curve [decades of τ].
SLOPE_SPAN_DECADES = 1.0
#: Allan-variance slope below which the noise is taken as quantisation (white phase, α = 2).
_QUANTISATION_SLOPE = -1.5


def log_slope(tau_s: FloatArray, values: FloatArray, span_decades: float = 0.0) -> FloatArray:
    """Local slope d ln(values) / d ln(tau) at each τ: the least-squares line through the points
    within ±span_decades/2 of it (and at least its neighbours)."""
    x, y = np.log10(tau_s), np.log(values) / math.log(10.0)
    slope = np.empty(len(x))
    for i in range(len(x)):
        near = np.abs(x - x[i]) <= span_decades / 2.0
        near[max(i - 1, 0) : i + 2] = True
        slope[i] = np.polyfit(x[near], y[near], 1)[0]
    return slope


def noise_type(avar_slope: FloatArray) -> IntArray:
    """Power-law exponent α of the noise dominating at each τ, from the Allan-variance slope μ:
    α = -μ - 1 rounded to white (0), flicker (-1) or random walk (-2); μ < -1.5 is quantisation
    (α = 2)."""
    slope = np.asarray(avar_slope, dtype=np.float64)
    frequency_noise = np.clip(np.rint(-slope - 1.0), -2.0, 0.0)
    return np.where(slope < _QUANTISATION_SLOPE, 2, frequency_noise).astype(np.int64)


def equivalent_dof(
    tau_s: FloatArray, alpha: IntArray, rate_hz: float, n_samples: int
) -> FloatArray:
    """Equivalent degrees of freedom of the overlapping Allan variance at each τ for the noise
    types α (Greenhall; allantools counts phase points, n_samples + 1)."""
    edf = np.empty(len(tau_s))
    for i, (tau, a) in enumerate(zip(tau_s, alpha, strict=True)):
        edf[i] = _edf(int(a), max(1, round(float(tau) * rate_hz)), n_samples + 1)
    return edf


@lru_cache(maxsize=4096)
def _edf(alpha: int, m: int, n_phase: int) -> float:
    """Greenhall's edf of the overlapping Allan variance (allantools; edf_simple where it has no
    case) for noise type alpha, averaging factor m and n_phase phase points. Cached: the fit
    asks for the same few (alpha, m) of a record many times, and Greenhall's sums are slow."""
    try:
        value = allantools.edf_greenhall(alpha=alpha, d=2, m=m, N=n_phase, overlapping=True)
    except NotImplementedError:
        value = allantools.edf_simple(n_phase, m, alpha)
    return float(value)


def tau_grid(n_samples: int, rate_hz: float) -> FloatArray:
    """Cluster times [s]: whole multiples of the sample period, POINTS_PER_DECADE per decade,
    from one period to MAX_TAU_FRACTION of the record."""
    m_max = max(1, math.floor(MAX_TAU_FRACTION * n_samples))
    decades = math.log10(m_max)
    count = max(2, math.ceil(decades * POINTS_PER_DECADE) + 1)
    m = np.unique(np.rint(np.logspace(0.0, decades, count)).astype(np.int64))
    return np.asarray(m / rate_hz, dtype=np.float64)


@dataclass(frozen=True)
class AllanCurve:
    """Overlapping Allan deviation adev [u] at cluster times tau_s [s] of n_samples at rate_hz,
    with the noise type alpha and the equivalent degrees of freedom edf of every point."""

    tau_s: FloatArray
    adev: FloatArray
    alpha: IntArray
    edf: FloatArray
    rate_hz: float
    n_samples: int

    @property
    def avar(self) -> FloatArray:
        """Allan variance [u²]."""
        return np.asarray(self.adev**2, dtype=np.float64)

    @property
    def record_s(self) -> float:
        """Length of the record [s]."""
        return self.n_samples / self.rate_hz

    def with_noise_types(self, avar_slope: FloatArray) -> AllanCurve:
        """The same curve with noise types and edf from another Allan-variance slope (e.g. of a
        fitted model, smoother than the data's own at long τ)."""
        alpha = noise_type(avar_slope)
        edf = equivalent_dof(self.tau_s, alpha, self.rate_hz, self.n_samples)
        return replace(self, alpha=alpha, edf=edf)

    def interval(self, confidence: float = ONE_SIGMA) -> tuple[FloatArray, FloatArray]:
        """Lower and upper confidence limits of the Allan deviation [u] (chi-squared, edf)."""
        limits = [
            allantools.confidence_interval(float(dev), float(edf), ci=confidence)
            for dev, edf in zip(self.adev, self.edf, strict=True)
        ]
        low, high = np.array(limits, dtype=np.float64).reshape(-1, 2).T
        return low, high


def allan_curve(tau_s: FloatArray, adev: FloatArray, rate_hz: float, n_samples: int) -> AllanCurve:
    """An Allan-deviation curve of a record of n_samples at rate_hz (measured or theoretical),
    with noise types and edf from its own slope over SLOPE_SPAN_DECADES (a first guess for a
    measured curve, whose slope is noisy at long τ; the fit replaces it with its model's)."""
    tau = np.asarray(tau_s, dtype=np.float64)
    dev = np.asarray(adev, dtype=np.float64)
    alpha = noise_type(log_slope(tau, dev**2, SLOPE_SPAN_DECADES))
    edf = equivalent_dof(tau, alpha, rate_hz, n_samples)
    return AllanCurve(tau, dev, alpha, edf, rate_hz, n_samples)


def overlapping_adev(values: FloatArray, rate_hz: float) -> AllanCurve:
    """Overlapping Allan deviation of evenly spaced samples [u] at rate_hz on tau_grid
    (allantools integrates them after removing their mean)."""
    series = np.asarray(values, dtype=np.float64)
    taus = tau_grid(len(series), rate_hz)
    tau, adev, _, _ = allantools.oadev(series, rate=rate_hz, data_type="freq", taus=taus)
    return allan_curve(tau, adev, rate_hz, len(series))
