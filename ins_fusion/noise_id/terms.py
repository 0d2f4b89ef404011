"""Noise terms of an Allan-deviation curve: the IEEE 952 slopes fitted together, the classic
flat-minimum read-off of bias instability, and confidence intervals.

Model of the Allan variance (Oslo notes §3, (4.2)-(4.4); the Gauss-Markov part is
ins_fusion.sim.noise.allan_variance), u = rad/s (gyro) or m/s² (accelerometer):

    σ²(τ) = 3Q²/τ² + N²/τ + bias(τ) + K²τ/3

| term | Allan-deviation slope | coefficient and read-off |
|---|---|---|
| quantisation Q [u·s] | -1 | the -1 line at τ = √3 s |
| white noise N [u/√Hz] (ARW, VRW) | -1/2 | the -1/2 line at τ = 1 s |
| bias, first-order Gauss-Markov σ [u], T [s] | +1/2, hump 0.6172σ at τ ≈ 1.89T, -1/2 | fit |
| bias, flicker B [u] | 0 | (2 ln2/π) B²: the flat line / 0.664 |
| random walk K [u·√Hz] (RRW) | +1/2 | the +1/2 line at τ = 3 s |

Fit (the Allan-variance least squares of IEEE 952, annex C): for a fixed T the model is linear in
(Q², N², σ² or B², K²), solved by non-negative least squares (scipy.optimize.nnls), so a term
the data do not need comes out as zero; T is found on a grid over log T and refined by a bounded
scalar minimisation. Each point is weighted by its relative standard deviation sqrt(2/edf)
against the model, iterated three times with weights and noise types (edf) from the fitted
model. The fit starts at the first τ (in the shorter half of the curve) where the Allan deviation
falls at least as steeply as -0.475, within 0.025 of white noise: points before it are flattened
by the sensor's output filter (band-limited white noise is a Gauss-Markov process of correlation
time 1/(2B), docs/simulator.md) and would bias N.

Bias instability: both bias models are fitted. A bias term counts only when it stands out of the
scatter of the curve: somewhere its share of the Allan variance exceeds what the curve's 99.9 %
chi-squared interval allows (its 99.9 % interval excludes zero: T is searched over decades, so
a weaker test lets white noise pass for a short-T process); a Gauss-Markov term must also be
visible, with T inside the searched range and its hump inside the curve, and a flicker floor
must make at least half of the variance at an interior minimum of the curve (a flat minimum,
not the corner between white noise and a random walk, nor the end of a falling curve). Of two
such models the better fit (edf-weighted squared relative residuals) is kept; with neither the
record shows no bias instability (white noise runs into a random walk, or the curve still falls
at its end). Each model is refitted without the quantisation and random-walk terms unless they
are visible and stand out of the scatter in the same way.

Classic read-off (Oslo notes §3 slope table): B = min σ(τ)/0.664, sqrt(2 ln2/π) = 0.664 from
(4.2), at τ_min. Without a Gauss-Markov fit the node's bias is B with correlation time τ_min,
the Oslo thesis' convention (§4.1: B taken as the stationary std, T = τ at the minimum).

Confidence interval of a term: the chi-squared interval of the Allan variance at the point where
the term is best determined (largest share² · edf) is attributed to the term's share of the
variance there. Allan points are correlated, so the fit over many points is at least this good,
but the interval does not hold the trade-off between neighbouring terms (a Gauss-Markov hump
against a random walk): docs/allan.md. A term that nowhere makes 25 % of the fitted variance is
"not visible" and is bounded by the upper confidence limits of the curve instead. The
Gauss-Markov σ and T get the precision a record of the curve's length gives for the fitted
noise (whittle.expected_errors, which does hold the trade-off); with the samples at hand,
likelihood.refine replaces the bias and the random walk by their Whittle fit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import minimize_scalar, nnls
from scipy.stats import norm

from gnss_ins_common.types import FloatArray
from ins_fusion.noise_id.allan import ONE_SIGMA, AllanCurve, log_slope
from ins_fusion.noise_id.whittle import BIAS, LOG_TIME, SpectralModel, expected_errors
from ins_fusion.sim.noise import allan_variance

#: Allan deviation of flicker bias instability B is sqrt(2 ln2/π) B = 0.664 B (Oslo (4.2)).
FLICKER_ADEV_FACTOR = math.sqrt(2.0 * math.log(2.0) / math.pi)
#: A first-order Gauss-Markov process peaks in Allan deviation near τ = 1.89 T (Oslo notes §3
#: [note], Hou 2004; ins_fusion.sim.noise.allan_variance).
GM_PEAK_TAU_FACTOR = 1.89
#: The fit starts where the Allan deviation falls at least this steeply (white noise: -0.5).
WHITE_START_SLOPE = -0.475
#: A term is visible when it makes at least this share of the fitted Allan variance somewhere.
VISIBLE_SHARE = 0.25
#: A flicker floor must make at least this share of the variance at the curve's minimum.
DOMINANT_SHARE = 0.5
#: A bias term must stand out of the curve's scatter at this confidence (see the docstring).
SIGNIFICANCE = 0.999
#: Shortest Gauss-Markov time constant tried, in units of the first fitted τ (its hump must lie
#: inside the curve to be told from white noise).
_GM_MIN_TIME_FACTOR = 2.0
_GM_GRID_POINTS = 40
_ITERATIONS = 3
#: Relative distance from the ends of the T grid within which T counts as "at the bound".
_BOUND_TOLERANCE = 0.01

GAUSS_MARKOV = "gauss-markov"
FLICKER = "flicker"
NO_BIAS = "none"
#: Names of the model's terms, in the order of NoiseTerms.coefficients.
COMPONENTS = ("quantization", "white", "bias", "random_walk")


@dataclass(frozen=True)
class Term:
    """One noise coefficient [SI] with its confidence limits. A term that is not visible has
    value = its fitted value (often 0), low = 0 and high = the upper bound the curve allows."""

    value: float
    low: float
    high: float
    visible: bool


@dataclass(frozen=True)
class BiasInstability:
    """The bias instability as ins_fusion_node models it: a first-order Gauss-Markov bias of
    stationary std sigma [u] and correlation time [s] (model GAUSS_MARKOV: fitted; FLICKER:
    the flat minimum B and τ_min), read at read_tau_s [s] (the hump 1.89 T, or τ_min).
    Gauss-Markov only: time_limits_s, the confidence limits of T [s]; errors, the 1σ of log σ
    and log T (relative errors) from the Whittle likelihood's Fisher information."""

    model: str
    sigma: Term
    time_constant_s: float
    read_tau_s: float
    time_limits_s: tuple[float, float] = (math.nan, math.nan)
    errors: tuple[float, float] = (math.nan, math.nan)


def _normal_quantile(confidence: float) -> float:
    """z of a two-sided normal interval of probability ``confidence``."""
    return float(norm.ppf(0.5 + confidence / 2.0))


def log_normal_term(value: float, relative_error: float, confidence: float) -> Term:
    """A visible term with the interval value·exp(±z·relative_error)."""
    spread = math.exp(_normal_quantile(confidence) * relative_error)
    return Term(value, value / spread, value * spread, True)


def gauss_markov_bias(
    sigma: float, time_constant_s: float, errors: tuple[float, float], confidence: float
) -> BiasInstability:
    """A Gauss-Markov bias of σ [u] and T [s] with the 1σ relative errors (of σ, of T)."""
    time = log_normal_term(time_constant_s, errors[1], confidence)
    return BiasInstability(
        GAUSS_MARKOV,
        log_normal_term(sigma, errors[0], confidence),
        time_constant_s,
        GM_PEAK_TAU_FACTOR * time_constant_s,
        (time.low, time.high),
        errors,
    )


@dataclass(frozen=True)
class NoiseTerms:
    """The fitted terms of one axis (see the module docstring; SI units of the axis).

    curve: the measured curve with the noise types (edf, intervals) of the fitted model.
    flat_minimum: the classic read-off B at flat_minimum_tau_s, ``visible`` when the minimum is
    inside the curve (not its last point). bias: None when the record shows no bias instability.
    coefficients: Q², N², the bias term (σ² Gauss-Markov, else B² flicker), K², as fitted;
    fit_tau_s: the τ range fitted [s].
    """

    curve: AllanCurve
    quantization: Term
    white: Term
    random_walk: Term
    flat_minimum: Term
    flat_minimum_tau_s: float
    bias: BiasInstability | None
    coefficients: tuple[float, float, float, float]
    fit_tau_s: tuple[float, float]

    def components(self, tau_s: FloatArray) -> dict[str, FloatArray]:
        """Allan variance of each fitted term at tau_s [u²], keyed by COMPONENTS."""
        tau = np.asarray(tau_s, dtype=np.float64)
        parts = _columns(tau, self._bias_shape(tau)) * np.array(self.coefficients)
        return {name: parts[:, i] for i, name in enumerate(COMPONENTS)}

    def avar(self, tau_s: FloatArray) -> FloatArray:
        """Allan variance of the fitted model at tau_s [u²]."""
        tau = np.asarray(tau_s, dtype=np.float64)
        return np.asarray(_columns(tau, self._bias_shape(tau)) @ np.array(self.coefficients))

    def _bias_shape(self, tau_s: FloatArray) -> FloatArray:
        if self.bias is None:
            return _bias_shape(tau_s, NO_BIAS, math.nan)
        return _bias_shape(tau_s, self.bias.model, self.bias.time_constant_s)


def _gauss_markov_shape(tau_s: FloatArray, time_constant_s: float) -> FloatArray:
    """Allan variance of a unit-σ first-order Gauss-Markov process."""
    return allan_variance(tau_s, gm_sigma=1.0, gm_time_constant_s=time_constant_s)


def _bias_shape(tau_s: FloatArray, bias_model: str, time_constant_s: float) -> FloatArray:
    """Allan variance of a unit bias term: Gauss-Markov, flicker (also the unused column of a
    model without bias)."""
    if bias_model == GAUSS_MARKOV:
        return _gauss_markov_shape(tau_s, time_constant_s)
    return np.full_like(tau_s, FLICKER_ADEV_FACTOR**2)


def _columns(tau_s: FloatArray, bias_shape: FloatArray) -> FloatArray:
    """Allan variance per unit squared coefficient of each term: 3/τ², 1/τ, bias, τ/3."""
    return np.stack([3.0 / tau_s**2, 1.0 / tau_s, bias_shape, tau_s / 3.0], axis=1)


def _nnls(
    columns: FloatArray, avar: FloatArray, weight: FloatArray, used: NDArray[np.bool_]
) -> tuple[FloatArray, float]:
    """Non-negative weighted least squares on the used columns (scaled to unit norm for
    conditioning; the others get 0): coefficients and the weighted sum of squared residuals."""
    a = columns[:, used] * weight[:, None]
    scale = np.linalg.norm(a, axis=0)
    scale[scale == 0.0] = 1.0
    solution, residual = nnls(a / scale, avar * weight)
    coefficients = np.zeros(columns.shape[1])
    coefficients[used] = solution / scale
    return coefficients, float(residual) ** 2


@dataclass(frozen=True)
class _Fit:
    """One bias model fitted to the fitted range of a curve."""

    coefficients: FloatArray
    time_constant_s: float  # nan for flicker
    curve: AllanCurve  # the fitted range, noise types from the model
    columns: FloatArray  # _columns on curve.tau_s
    model: FloatArray  # fitted Allan variance on curve.tau_s

    def share(self, index: int) -> FloatArray:
        """Share of the fitted Allan variance of one term on the fitted range."""
        return np.asarray(self.columns[:, index] * self.coefficients[index] / self.model)

    @property
    def misfit(self) -> float:
        """Sum of squared relative residuals, each weighted by its edf/2 (a chi-square if the
        points were independent)."""
        residual = (self.model - self.curve.avar) / self.model
        return float(np.sum(residual**2 * self.curve.edf / 2.0))


def _solve_gauss_markov(
    tau: FloatArray, avar: FloatArray, weight: FloatArray, used: NDArray[np.bool_]
) -> tuple[FloatArray, float]:
    """Best T on a log grid, refined between its neighbours; coefficients and T."""
    grid = np.log(np.geomspace(_GM_MIN_TIME_FACTOR * tau[0], tau[-1], _GM_GRID_POINTS))

    def misfit(log_t: float) -> float:
        columns = _columns(tau, _gauss_markov_shape(tau, math.exp(log_t)))
        return _nnls(columns, avar, weight, used)[1]

    best = int(np.argmin([misfit(float(x)) for x in grid]))
    low, high = grid[max(best - 1, 0)], grid[min(best + 1, len(grid) - 1)]
    result = minimize_scalar(misfit, bounds=(float(low), float(high)), method="bounded")
    time_constant = math.exp(float(result.x))
    columns = _columns(tau, _gauss_markov_shape(tau, time_constant))
    return _nnls(columns, avar, weight, used)[0], time_constant


def _fit(curve: AllanCurve, bias_model: str, used: NDArray[np.bool_] | None = None) -> _Fit:
    """Iteratively re-weighted fit of one bias model (NO_BIAS: without a bias term) to the
    curve, with the terms ``used`` (default all)."""
    tau, avar = curve.tau_s, curve.avar
    used = np.ones(4, dtype=bool) if used is None else used.copy()
    used[2] &= bias_model != NO_BIAS
    reference = avar
    time_constant = math.nan
    columns = _columns(tau, _bias_shape(tau, bias_model, time_constant))
    coefficients = np.zeros(4)
    for _ in range(_ITERATIONS):
        weight = np.sqrt(curve.edf / 2.0) / reference
        if bias_model == GAUSS_MARKOV:
            coefficients, time_constant = _solve_gauss_markov(tau, avar, weight, used)
            columns = _columns(tau, _gauss_markov_shape(tau, time_constant))
        else:
            coefficients = _nnls(columns, avar, weight, used)[0]
        model = columns @ coefficients
        # A zero model (a constant series) keeps the data as its own reference.
        reference = np.where(model > 0.0, model, avar)
        curve = curve.with_noise_types(log_slope(tau, reference))
    return _Fit(coefficients, time_constant, curve, columns, reference)


def _fit_start(curve: AllanCurve) -> int:
    """Index of the first point fitted (see the module docstring)."""
    slope = log_slope(curve.tau_s, curve.adev)
    half = slope[: max(1, len(slope) // 2)]
    steep = np.flatnonzero(half <= WHITE_START_SLOPE)
    return int(steep[0]) if len(steep) else int(np.argmin(half))


def _restrict(curve: AllanCurve, start: int) -> AllanCurve:
    return AllanCurve(
        curve.tau_s[start:],
        curve.adev[start:],
        curve.alpha[start:],
        curve.edf[start:],
        curve.rate_hz,
        curve.n_samples,
    )


def _significant(fit: _Fit, index: int) -> bool:
    """Term ``index``'s share exceeds, somewhere, the room the SIGNIFICANCE interval of the
    Allan variance leaves below the fitted value (its lower limit is above zero)."""
    low, _ = fit.curve.interval(SIGNIFICANCE)
    room = 1.0 - (low / fit.curve.adev) ** 2
    return bool(np.any(fit.share(index) > room))


def _gauss_markov_identified(fit: _Fit) -> bool:
    tau, time_constant = fit.curve.tau_s, fit.time_constant_s
    inside = (
        _GM_MIN_TIME_FACTOR * tau[0] * (1.0 + _BOUND_TOLERANCE)
        < time_constant
        < tau[-1] * (1.0 - _BOUND_TOLERANCE)
    )
    visible = bool(np.any(fit.share(2) >= VISIBLE_SHARE))
    return (
        inside
        and GM_PEAK_TAU_FACTOR * time_constant <= tau[-1]
        and visible
        and _significant(fit, 2)
    )


def _flicker_identified(fit: _Fit) -> bool:
    lowest = int(np.argmin(fit.curve.adev))
    interior = lowest < len(fit.curve.tau_s) - 1
    return interior and bool(fit.share(2)[lowest] >= DOMINANT_SHARE) and _significant(fit, 2)


def _term(fit: _Fit, index: int, limits: tuple[FloatArray, FloatArray], bound: FloatArray) -> Term:
    """Term ``index`` of the fit, with the confidence limits of the fitted curve; ``bound``:
    the coefficient each point's upper limit would allow alone (for a term that is not
    visible)."""
    share = fit.share(index)
    variance = float(fit.coefficients[index])
    if not np.any(share >= VISIBLE_SHARE):
        return Term(math.sqrt(variance), 0.0, float(np.min(bound)), False)
    best = int(np.argmax(share**2 * fit.curve.edf))
    ratios = (np.array([limits[0][best], limits[1][best]]) / fit.curve.adev[best]) ** 2
    interval = variance * np.maximum(0.0, 1.0 + (ratios - 1.0) / share[best])
    return Term(math.sqrt(variance), math.sqrt(interval[0]), math.sqrt(interval[1]), True)


def _fit_model(curve: AllanCurve, bias_model: str) -> _Fit:
    """Fit a bias model, then refit it without the quantisation and random-walk terms unless
    they are visible and stand out of the scatter: a small one would bend the white-noise line
    (and take N with it), a random walk made of the last few noisy clusters would take the
    place of the bias's own rise."""
    first = _fit(curve, bias_model)
    used = np.array(
        [
            i in (1, 2) or (np.any(first.share(i) >= VISIBLE_SHARE) and _significant(first, i))
            for i in range(4)
        ]
    )
    return first if used.all() else _fit(curve, bias_model, used)


def fit_noise_terms(curve: AllanCurve, confidence: float = ONE_SIGMA) -> NoiseTerms:
    """The noise terms of a measured (or theoretical) Allan-deviation curve."""
    start = _fit_start(curve)
    fitted = _restrict(curve, start)
    gauss_markov = _fit_model(fitted, GAUSS_MARKOV)
    flicker = _fit_model(fitted, FLICKER)
    has_gm = _gauss_markov_identified(gauss_markov)
    has_flicker = _flicker_identified(flicker)
    if has_gm and (not has_flicker or gauss_markov.misfit <= flicker.misfit):
        bias_model, fit = GAUSS_MARKOV, gauss_markov
    elif has_flicker:
        bias_model, fit = FLICKER, flicker
    else:
        bias_model, fit = NO_BIAS, _fit_model(fitted, NO_BIAS)
    # The whole curve with the noise types of the fitted model (for its intervals and edf).
    shape = _bias_shape(curve.tau_s, bias_model, fit.time_constant_s)
    typed = curve.with_noise_types(
        log_slope(curve.tau_s, _columns(curve.tau_s, shape) @ fit.coefficients)
    )
    low, high = typed.interval(confidence)
    fit = _Fit(
        fit.coefficients, fit.time_constant_s, _restrict(typed, start), fit.columns, fit.model
    )
    limits = (low[start:], high[start:])
    # Classic read-off on the measured curve (fitted range), chi-squared interval at τ_min.
    lowest = start + int(np.argmin(fit.curve.adev))
    flat = Term(
        float(typed.adev[lowest]) / FLICKER_ADEV_FACTOR,
        float(low[lowest]) / FLICKER_ADEV_FACTOR,
        float(high[lowest]) / FLICKER_ADEV_FACTOR,
        lowest < len(typed.tau_s) - 1,
    )
    tau_min = float(typed.tau_s[lowest])
    q2, n2, bias2, k2 = (float(c) for c in fit.coefficients)
    bias: BiasInstability | None = None
    if bias_model == GAUSS_MARKOV:
        # What a record of this length gives (the curve alone has no better interval).
        model = SpectralModel(n2, bias2, k2, fit.time_constant_s)
        errors = expected_errors(model, curve.rate_hz, curve.n_samples)
        bias = gauss_markov_bias(
            math.sqrt(bias2), fit.time_constant_s, (errors[BIAS], errors[LOG_TIME]), confidence
        )
    elif bias_model == FLICKER:
        bias = BiasInstability(FLICKER, flat, tau_min, tau_min)
    return NoiseTerms(
        curve=typed,
        quantization=_term(fit, 0, limits, high * typed.tau_s / math.sqrt(3.0)),
        white=_term(fit, 1, limits, high * np.sqrt(typed.tau_s)),
        random_walk=_term(fit, 3, limits, high * np.sqrt(3.0 / typed.tau_s)),
        flat_minimum=flat,
        flat_minimum_tau_s=tau_min,
        bias=bias,
        coefficients=(q2, n2, bias2, k2),
        fit_tau_s=(float(fit.curve.tau_s[0]), float(fit.curve.tau_s[-1])),
    )
