"""White noise, Gauss-Markov bias and random walk fitted to the raw samples by the debiased
Whittle likelihood of their block means, with Fisher-information intervals.

Why not the Allan curve: its points are strongly correlated and a hump of a Gauss-Markov bias
overlaps the white noise and the random walk, so a least-squares fit of the curve has no honest
interval for σ and T (chi-squared limits of single points do not hold the trade-off between the
terms). The likelihood of the data's spectrum uses every frequency with its exact weight and
its Fisher information gives the errors; allantools computes Allan statistics only, so this
module is our own.

Data (u = rad/s or m/s²): means y_j of blocks of Δ seconds (whole samples; a first pass with
Δ ≥ MIN_BLOCK_S, well above a MEMS output filter's time constant, finds T, a second uses
Δ = T/BLOCKS_PER_TIME), then first differences d_j = y_{j+1} - y_j, which make the random walk
stationary. Autocovariance of d per unit coefficient (exact for block means of continuous-time
processes; the simulator's processes, ins_fusion.sim.noise):

- white noise of density N: Var y = N²/Δ, so c_d(0) = 2N²/Δ, c_d(1) = -N²/Δ;
- Gauss-Markov bias, stationary σ, correlation time T, a = Δ/T: c_y(0) = 2σ²(a - 1 + e^-a)/a²,
  c_y(k ≥ 1) = σ²(1 - e^-a)² e^-(k-1)a / a², c_d(k) = 2c_y(k) - c_y(k-1) - c_y(k+1);
- random walk of density K: c_d(0) = 2K²Δ/3, c_d(1) = K²Δ/6 (its Allan variance K²τ/3 at τ = Δ).

Debiased Whittle likelihood (Sykulski et al., Biometrika 2019): with the tapered periodogram
I_k = |Σ h_j d_j e^(-iω_k j)|² (h: TAPER_FRACTION cosine taper, Σ h² = 1) at the Fourier
frequencies 0 < ω_k < π and its exact expectation S_k = Σ_|τ|<n ρ_h(τ) c_d(τ) e^(-iω_k τ),
ρ_h(τ) = Σ_j h_j h_(j+τ) (one FFT), -log L = Σ_k log S_k + I_k/S_k. For a fixed T, S is
linear in (N², σ², K²): the maximum is found by Fisher scoring (weighted least squares with
weights 1/S_k², non-negative), T on a log grid refined by a bounded scalar search.
Uncertainty: the inverse Fisher information Σ_k ∂S_k ∂S_kᵀ / S_k² in (log N², log σ², log K²,
log T), divided by the taper's variance inflation n Σ h⁴; σ and T with log-normal intervals.
Computed for a model and a record length without data (expected_errors), it tells how long a
record must be.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.fft import next_fast_len
from scipy.optimize import minimize_scalar, nnls
from scipy.signal import windows
from scipy.stats import chi2

from gnss_ins_common.types import FloatArray

#: Most blocks of the first pass (the FFT length).
MAX_BLOCKS = 2**16
#: Shortest block [s]: the correlation of block means left by the sensor's output filter
#: (time constant 1/(2B), 20 ms for the IMU400CC's gyros) is then about 1 %.
MIN_BLOCK_S = 1.0
#: Blocks per correlation time of the second pass. Longer blocks lift the random walk and the
#: Gauss-Markov bias above the leakage of white noise into the lowest frequencies (the
#: periodogram of a finite record), which otherwise hides them: on 24 h of an IMU400CC gyro
#: the bound on σ falls from 40 % to 18 % (the exact likelihood's: 17 %).
BLOCKS_PER_TIME = 10.0
#: Share of the record cosine-tapered at its ends: without a taper, the difference of the last
#: and first block means (one random number) leaks into every frequency of the periodogram and,
#: where the spectrum of the differences is low (white noise at low frequencies), hundreds of
#: ordinates share it; the likelihood then counts it many times (a spurious random walk).
TAPER_FRACTION = 0.2
#: Fewest blocks of the second pass.
MIN_BLOCKS = 1000
#: Correlation times searched, in blocks (low end) and in records (high end).
_MIN_TIME_BLOCKS = 2.0
_MAX_TIME_RECORDS = 0.5
_TIME_GRID_POINTS = 30
_REWEIGHTINGS = 50
_CONVERGED = 1e-7
#: Relative ridge keeping the normal equations of nearly equal columns positive definite.
_RIDGE = 1e-12
#: Relative distance from the ends of the T range within which T counts as "at the bound".
_BOUND_TOLERANCE = 0.01
#: Likelihood-ratio statistics a term must reach, chi-squared at 0.999 with 2 (σ², T) and 1
#: (K²) degrees of freedom.
BIAS_EVIDENCE = float(chi2.ppf(0.999, 2))
WALK_EVIDENCE = float(chi2.ppf(0.999, 1))
#: Step of the numerical derivative of the Gauss-Markov column in log T.
_LOG_STEP = 1e-4
#: Indices of the model's coefficients (N², σ², K²) and of log T in the Fisher information.
WHITE, BIAS, WALK, LOG_TIME = 0, 1, 2, 3


@dataclass(frozen=True)
class Blocks:
    """Differences of block means [u] and the periodogram of them at 0 < ω_k < π."""

    block_s: float
    record_s: float
    periodogram: FloatArray

    @property
    def n(self) -> int:
        """Number of differences."""
        return round(self.record_s / self.block_s) - 1


def block_samples(n_samples: int, rate_hz: float, time_constant_s: float = math.nan) -> int:
    """Samples per block: at least MIN_BLOCK_S and 1/MAX_BLOCKS of the record; for a
    correlation time T [s], T/BLOCKS_PER_TIME but at most 1/MIN_BLOCKS of the record."""
    shortest = max(1, math.ceil(MIN_BLOCK_S * rate_hz), math.ceil(n_samples / MAX_BLOCKS))
    if not math.isfinite(time_constant_s):
        return shortest
    wanted = round(time_constant_s / BLOCKS_PER_TIME * rate_hz)
    return max(shortest, min(wanted, n_samples // MIN_BLOCKS))


def _fast_length(n: int) -> int:
    """The longest length ≤ n that the FFT handles fast (a product of small primes; a long
    prime length is many times slower)."""
    while next_fast_len(n, real=True) != n:
        n -= 1
    return n


def blocks(values: FloatArray, rate_hz: float, samples: int) -> Blocks:
    """Means of blocks of ``samples`` evenly spaced samples [u] at rate_hz, differenced (the
    first _fast_length of them), and their periodogram."""
    count = _fast_length(len(values) // samples - 1) + 1
    means = np.asarray(values[: count * samples], dtype=np.float64)
    d = np.diff(means.reshape(count, samples).mean(axis=1))
    spectrum = np.abs(np.fft.rfft(taper(len(d)) * d)) ** 2
    return Blocks(samples / rate_hz, count * samples / rate_hz, spectrum[1 : (len(d) - 1) // 2 + 1])


def taper(n: int) -> FloatArray:
    """Data taper of n points with unit energy (TAPER_FRACTION cosine-tapered)."""
    h = windows.tukey(n, TAPER_FRACTION)
    return np.asarray(h / np.sqrt(np.sum(h**2)), dtype=np.float64)


def _taper_correlation(n: int) -> FloatArray:
    """Σ_t h_t h_(t+τ) of the taper at lags 0..n-1."""
    spectrum = np.abs(np.fft.rfft(taper(n), 2 * n)) ** 2
    return np.asarray(np.fft.irfft(spectrum, 2 * n)[:n])


def _expected_periodogram(acov: FloatArray, correlation: FloatArray) -> FloatArray:
    """Expected tapered periodogram at 0 < ω_k < π of a series with autocovariance acov
    (lags 0..n-1) and taper correlation ``correlation``."""
    n = len(acov)
    weighted = correlation * acov
    spectrum = 2.0 * np.fft.rfft(weighted).real - weighted[0]
    return np.asarray(spectrum[1 : (n - 1) // 2 + 1])


def _ma1(n: int, lag0: float, lag1: float) -> FloatArray:
    acov = np.zeros(n)
    acov[0], acov[1] = lag0, lag1
    return acov


def _gauss_markov_column(
    block_s: float, time_constant_s: float, correlation: FloatArray
) -> FloatArray:
    """Expected periodogram of differenced block means of a unit-σ Gauss-Markov process."""
    n = len(correlation)
    a = block_s / time_constant_s
    lags = np.arange(n + 1)
    c_y = np.expm1(-a) ** 2 * np.exp(-np.maximum(lags - 1, 0) * a) / a**2
    c_y[0] = 2.0 * (a + math.expm1(-a)) / a**2
    below = np.concatenate(([c_y[1]], c_y[:-2]))
    return _expected_periodogram(2.0 * c_y[:-1] - below - c_y[1:], correlation)


@dataclass(frozen=True)
class SpectralModel:
    """Coefficients N² [u²/Hz], σ² [u²], K² [u²·Hz] and T [s] (σ² = 0: no Gauss-Markov term)."""

    white: float
    bias: float
    walk: float
    time_constant_s: float

    @property
    def coefficients(self) -> FloatArray:
        """(N², σ², K²)."""
        return np.array([self.white, self.bias, self.walk])


class _Columns:
    """Expected periodogram per unit coefficient, for a record of n differences of Δ blocks."""

    def __init__(self, n: int, block_s: float) -> None:
        self.block_s = block_s
        self._correlation = _taper_correlation(n)
        # Variance inflation of tapered periodogram ordinates (n Σ h⁴, 1.12 for the taper).
        self._inflation = n * float(np.sum(taper(n) ** 4))
        self._white = _expected_periodogram(
            _ma1(n, 2.0 / block_s, -1.0 / block_s), self._correlation
        )
        self._walk = _expected_periodogram(
            _ma1(n, 2.0 * block_s / 3.0, block_s / 6.0), self._correlation
        )
        # The bias column of each T asked for: the fits with and without a random walk search
        # the same grid of T, and each fit solves again at the T it found.
        self._bias: dict[float, FloatArray] = {}

    def at(self, time_constant_s: float) -> FloatArray:
        """Columns (white, bias, walk) for the correlation time T [s]."""
        if (bias := self._bias.get(time_constant_s)) is None:
            bias = _gauss_markov_column(self.block_s, time_constant_s, self._correlation)
            self._bias[time_constant_s] = bias
        return np.stack([self._white, bias, self._walk], axis=1)

    def fisher(self, model: SpectralModel) -> FloatArray:
        """Fisher information in (log N², log σ², log K², log T) (rows of absent terms: 0)."""
        columns = self.at(model.time_constant_s)
        step = math.exp(_LOG_STEP)
        d_log_time = (
            self.at(model.time_constant_s * step)[:, BIAS]
            - self.at(model.time_constant_s / step)[:, BIAS]
        ) * (model.bias / (2.0 * _LOG_STEP))
        gradient = np.column_stack([columns * model.coefficients, d_log_time])
        gradient /= (columns @ model.coefficients)[:, None]
        return np.asarray(gradient.T @ gradient) / self._inflation


def _negative_log_likelihood(spectrum: FloatArray, periodogram: FloatArray) -> float:
    return float(np.sum(np.log(spectrum) + periodogram / spectrum))


def _solve(
    columns: FloatArray, periodogram: FloatArray, used: NDArray[np.bool_]
) -> tuple[FloatArray, float]:
    """Whittle maximum over the used non-negative coefficients: (coefficients, -log L).

    Fisher scoring: weighted least squares of I_k on the columns with weights 1/S_k², S_k from
    the previous step, through the small normal equations (G = L Lᵀ, nnls of Lᵀ x = L⁻¹ r)."""
    a = columns[:, used]
    scale = np.linalg.norm(a, axis=0)
    # One row per column (the transposed layout halves the time of the products below).
    rows = np.ascontiguousarray((a / scale).T)
    spectrum = np.full(len(periodogram), float(np.mean(periodogram)))
    solution = np.zeros(len(rows))
    for _ in range(_REWEIGHTINGS):
        previous = solution
        weighted = rows / spectrum
        gram = weighted @ weighted.T
        lower = np.linalg.cholesky(gram + np.eye(len(gram)) * _RIDGE * np.trace(gram))
        solution = nnls(lower.T, np.linalg.solve(lower, weighted @ (periodogram / spectrum)))[0]
        # A zero solution (a constant series) keeps a floor under the spectrum.
        spectrum = np.maximum(solution @ rows, np.finfo(np.float64).tiny)
        # np.allclose(solution, previous, rtol=_CONVERGED, atol=0.0) without its overhead.
        if np.all(np.abs(solution - previous) <= _CONVERGED * np.abs(previous)):
            break
    coefficients = np.zeros(columns.shape[1])
    coefficients[used] = solution / scale
    return coefficients, _negative_log_likelihood(spectrum, periodogram)


def _model(
    columns: _Columns, periodogram: FloatArray, used: NDArray[np.bool_], time_constant_s: float
) -> tuple[SpectralModel, float]:
    """Whittle maximum for a fixed T: the model and its -log L."""
    (white, bias, walk), nll = _solve(columns.at(time_constant_s), periodogram, used)
    return SpectralModel(float(white), float(bias), float(walk), time_constant_s), nll


def _fit_time(
    columns: _Columns, periodogram: FloatArray, used: NDArray[np.bool_], bounds: tuple[float, float]
) -> tuple[SpectralModel, float]:
    """Best model with a Gauss-Markov term and its -log L: T on a log grid, then refined."""

    def profile(log_time: float) -> float:
        return _solve(columns.at(math.exp(log_time)), periodogram, used)[1]

    grid = np.linspace(math.log(bounds[0]), math.log(bounds[1]), _TIME_GRID_POINTS)
    best = int(np.argmin([profile(float(x)) for x in grid]))
    low, high = grid[max(best - 1, 0)], grid[min(best + 1, len(grid) - 1)]
    result = minimize_scalar(profile, bounds=(float(low), float(high)), method="bounded")
    return _model(columns, periodogram, used, math.exp(float(result.x)))


def _time_bounds(block_s: float, record_s: float) -> tuple[float, float]:
    """Correlation times searched [s]."""
    return _MIN_TIME_BLOCKS * block_s, _MAX_TIME_RECORDS * record_s


@dataclass(frozen=True)
class WhittleFit:
    """The selected model (σ² = 0: no Gauss-Markov term stands out; K² = 0: no random walk),
    the 1σ relative errors of its terms (relative_errors) and the T [s] of the best model with
    a Gauss-Markov term (kept or not)."""

    model: SpectralModel
    errors: dict[int, float]
    candidate_time_s: float


def _terms(*indices: int) -> NDArray[np.bool_]:
    used = np.zeros(3, dtype=bool)
    used[list(indices)] = True
    return used


def _select(data: Blocks) -> WhittleFit:
    """White noise + Gauss-Markov + random walk by the debiased Whittle likelihood. A term is
    kept when its likelihood ratio stands out (BIAS_EVIDENCE, WALK_EVIDENCE), a Gauss-Markov
    term also with T inside the searched range (at its ends it is white noise or a random
    walk)."""
    columns = _Columns(data.n, data.block_s)
    bounds = _time_bounds(data.block_s, data.record_s)
    i = data.periodogram
    full = _fit_time(columns, i, _terms(WHITE, BIAS, WALK), bounds)
    no_walk = _fit_time(columns, i, _terms(WHITE, BIAS), bounds)
    walk_only = _model(columns, i, _terms(WHITE, WALK), bounds[0])
    white_only = _model(columns, i, _terms(WHITE), bounds[0])
    low, high = bounds[0] * (1.0 + _BOUND_TOLERANCE), bounds[1] * (1.0 - _BOUND_TOLERANCE)

    def inside(fit: tuple[SpectralModel, float]) -> bool:
        return low < fit[0].time_constant_s < high

    # A random walk must stand out also against a Gauss-Markov bias (which it would otherwise
    # stand in for), unless that bias sits at the longest T, where it is a random walk itself.
    walk_alone = 2.0 * (white_only[1] - walk_only[1])
    walk_evidence = 2.0 * (no_walk[1] - full[1]) if inside(no_walk) else walk_alone
    has_walk = walk_evidence >= WALK_EVIDENCE and walk_alone >= WALK_EVIDENCE
    with_bias, without = (full, walk_only) if has_walk else (no_walk, white_only)
    bias_evidence = 2.0 * (without[1] - with_bias[1])
    has_bias = bias_evidence >= BIAS_EVIDENCE and inside(with_bias)
    model = with_bias[0] if has_bias else without[0]
    return WhittleFit(
        model, relative_errors(columns.fisher(model), model), with_bias[0].time_constant_s
    )


def fit_whittle(values: FloatArray, rate_hz: float) -> WhittleFit:
    """_select on blocks of MIN_BLOCK_S, then again on blocks of a tenth of the correlation
    time found (BLOCKS_PER_TIME)."""
    finest = block_samples(len(values), rate_hz)
    first = _select(blocks(values, rate_hz, finest))
    samples = block_samples(len(values), rate_hz, first.candidate_time_s)
    return first if samples == finest else _select(blocks(values, rate_hz, samples))


def relative_errors(fisher: FloatArray, model: SpectralModel) -> dict[int, float]:
    """1σ of log N, log σ, log K and log T from the inverse Fisher information, over the terms
    the model has (an absent term: nan)."""
    present = np.array([model.white > 0.0, model.bias > 0.0, model.walk > 0.0, model.bias > 0.0])
    errors = dict.fromkeys((WHITE, BIAS, WALK, LOG_TIME), math.nan)
    if not present.any():
        return errors
    try:
        covariance = np.linalg.inv(fisher[np.ix_(present, present)])
    except np.linalg.LinAlgError:  # terms the data cannot tell apart
        return {index: math.inf for index in errors}
    for row, index in enumerate(np.flatnonzero(present)):
        # log c = log(c²) / 2 for a coefficient, log T itself.
        half = 1.0 if index == LOG_TIME else 0.5
        errors[int(index)] = half * math.sqrt(max(float(covariance[row, row]), 0.0))
    return errors


def expected_errors(model: SpectralModel, rate_hz: float, n_samples: int) -> dict[int, float]:
    """relative_errors expected from a record of n_samples at rate_hz with this noise (the
    Cramér-Rao bound of the Whittle likelihood; no data needed)."""
    m = block_samples(n_samples, rate_hz, model.time_constant_s)
    columns = _Columns(_fast_length(n_samples // m - 1), m / rate_hz)
    return relative_errors(columns.fisher(model), model)
