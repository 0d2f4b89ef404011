"""Stochastic processes of the sensor error models, sampled at arbitrary times, and their Allan
variance.

Discretisation is exact for any sample spacing (shared/reference/mems-noise-oslo-notes.md,
"Implications" R2): white noise of density N averaged over an interval dt has standard deviation
N/sqrt(dt); a first-order Gauss-Markov process with stationary std sigma and correlation time T
moves by x_k = exp(-dt/T) x_{k-1} + sigma sqrt(1 - exp(-2dt/T)) n_k (Oslo notes §4.1, (4.8)-(4.13)
with B = sigma); a random walk of density K moves by K sqrt(dt) n_k (Oslo notes §4.2). Every
process draws from its own generator, one normal per sample and axis in time order, so the output
does not depend on how a record is split into blocks.

Band-limited white noise (a sensor whose output filter is slower than its sample rate, Aalborg
notes §1.3) is the interval-averaged white noise x_k through the discrete first-order low-pass
y_k = a_k y_{k-1} + (1 - a_k) x_k with a_k = (1 - B dt_k) / (1 + B dt_k): unit gain at zero
frequency keeps the density N below the corner (Allan deviation N/sqrt(tau) for tau >> 1/B), and
the stationary variance N²/dt (1 - a)/(1 + a) = N² B is the per-sample σ = N sqrt(B) of Aalborg
(5.21), with B the noise-equivalent bandwidth. a is the bilinear-transform pole of a continuous
first-order filter with time constant 1/(2B) (-3 dB at B/π); samples slower than B (B dt >= 1)
stay plain white noise.
"""

from __future__ import annotations

import math

import numpy as np

from gnss_ins_common.types import FloatArray

#: Longest span, in correlation times, handled in one vectorised Gauss-Markov chunk (bounds the
#: growth of exp(t/T) in the closed-form sum).
_GM_CHUNK_TIME_CONSTANTS = 20.0
#: Largest growth exp(...) of the closed-form first-order recursion within one chunk.
_RECURSION_CHUNK_LOG_GROWTH = 200.0


class WhiteNoise:
    """White noise with density [u/sqrt(Hz)] per axis, averaged over each sample interval."""

    def __init__(self, density: FloatArray, rng: np.random.Generator) -> None:
        self.density = np.asarray(density, dtype=np.float64)
        self._rng = rng

    def sample(self, dt_s: FloatArray) -> FloatArray:
        """Values for intervals dt_s (n,) -> (n, axes)."""
        draws = self._rng.standard_normal((len(dt_s), len(self.density)))
        return draws * self.density / np.sqrt(dt_s)[:, None]


class BandLimitedNoise:
    """White noise of density [u/sqrt(Hz)] per axis through a first-order low-pass of
    noise-equivalent bandwidth [Hz] (see the module docstring); starts stationary."""

    def __init__(self, density: FloatArray, bandwidth_hz: float, rng: np.random.Generator) -> None:
        if not bandwidth_hz > 0.0:
            raise ValueError("the noise bandwidth must be positive")
        self.bandwidth_hz = bandwidth_hz
        self.value = (
            np.asarray(density, dtype=np.float64)
            * math.sqrt(bandwidth_hz)
            * rng.standard_normal(len(density))
        )
        self._white = WhiteNoise(density, rng)

    def sample(self, dt_s: FloatArray) -> FloatArray:
        """Values for intervals dt_s (n,) -> (n, axes)."""
        white = self._white.sample(dt_s)
        b_dt = self.bandwidth_hz * np.asarray(dt_s, dtype=np.float64)
        pole = np.clip((1.0 - b_dt) / (1.0 + b_dt), 0.0, None)
        out = _first_order_recursion(pole, (1.0 - pole)[:, None] * white, self.value)
        if len(out):
            self.value = out[-1].copy()
        return out


def _first_order_recursion(pole: FloatArray, drive: FloatArray, start: FloatArray) -> FloatArray:
    """y_k = pole_k y_{k-1} + drive_k from y_{-1} = start; pole (n,) in [0, 1), drive (n, axes).

    Closed form per chunk, y_k = P_k (y_start + sum_{j<=k} drive_j / P_j) with P_k the product of
    the poles, in chunks that bound 1/P_k (as GaussMarkov does).
    """
    if not np.any(pole):
        return drive.copy()
    neg_log = -np.log(np.maximum(pole, np.finfo(np.float64).tiny))
    cumulative = np.cumsum(neg_log)
    out = np.empty_like(drive)
    value = start
    begin = 0
    while begin < len(pole):
        base = cumulative[begin - 1] if begin else 0.0
        stop = int(np.searchsorted(cumulative, base + _RECURSION_CHUNK_LOG_GROWTH, side="right"))
        stop = max(stop, begin + 1)
        growth = np.exp(cumulative[begin:stop] - base)[:, None]
        out[begin:stop] = (value + np.cumsum(drive[begin:stop] * growth, axis=0)) / growth
        value = out[stop - 1]
        begin = stop
    return out


class RandomWalk:
    """Random walk (rate or acceleration random walk) of density [u·sqrt(Hz)] per axis, from 0."""

    def __init__(self, density: FloatArray, rng: np.random.Generator) -> None:
        self.density = np.asarray(density, dtype=np.float64)
        self.value = np.zeros_like(self.density)
        self._rng = rng

    def sample(self, dt_s: FloatArray) -> FloatArray:
        """Values at the ends of intervals dt_s (n,) -> (n, axes)."""
        draws = self._rng.standard_normal((len(dt_s), len(self.density)))
        out = self.value + np.cumsum(draws * self.density * np.sqrt(dt_s)[:, None], axis=0)
        if len(out):
            self.value = out[-1].copy()
        return out


class GaussMarkov:
    """First-order Gauss-Markov process per axis: stationary std sigma, correlation time T.

    Starts from a draw of the stationary distribution. Axes with sigma = 0 stay at 0.
    """

    def __init__(
        self, sigma: FloatArray, time_constant_s: FloatArray, rng: np.random.Generator
    ) -> None:
        self.sigma = np.asarray(sigma, dtype=np.float64)
        self.time_constant_s = np.broadcast_to(
            np.asarray(time_constant_s, dtype=np.float64), self.sigma.shape
        ).copy()
        if np.any(self.time_constant_s <= 0.0):
            raise ValueError("Gauss-Markov correlation times must be positive")
        self._rng = rng
        self.value = self.sigma * rng.standard_normal(self.sigma.shape)

    def sample(self, dt_s: FloatArray) -> FloatArray:
        """Values at the ends of intervals dt_s (n,) -> (n, axes)."""
        draws = self._rng.standard_normal((len(dt_s), len(self.sigma)))
        out = np.empty_like(draws)
        t_end = np.cumsum(dt_s)
        chunk = _GM_CHUNK_TIME_CONSTANTS * float(self.time_constant_s.min())
        start = 0
        while start < len(dt_s):
            t0 = t_end[start - 1] if start else 0.0
            stop = int(np.searchsorted(t_end, t0 + chunk, side="right"))
            stop = max(stop, start + 1)
            out[start:stop] = self._chunk(
                t_end[start:stop] - t0, dt_s[start:stop], draws[start:stop]
            )
            self.value = out[stop - 1].copy()
            start = stop
        return out

    def _chunk(self, t_rel: FloatArray, dt_s: FloatArray, draws: FloatArray) -> FloatArray:
        # x_k = e^{-t_k/T} (x_0 + sum_{j<=k} e^{t_j/T} q_j) with q_j the driving noise of step j.
        rel = t_rel[:, None] / self.time_constant_s
        step_std = self.sigma * np.sqrt(-np.expm1(-2.0 * dt_s[:, None] / self.time_constant_s))
        growth = np.exp(rel)
        return (self.value + np.cumsum(draws * step_std * growth, axis=0)) / growth


def allan_variance(
    tau_s: FloatArray,
    white_density: float = 0.0,
    gm_sigma: float = 0.0,
    gm_time_constant_s: float = 1.0,
    random_walk_density: float = 0.0,
) -> FloatArray:
    """Theoretical Allan variance [u²] of white noise + first-order Gauss-Markov + random walk.

    White: N²/τ; random walk: K²τ/3 (Oslo notes §3, (4.3)-(4.4)); Gauss-Markov with q = 2σ²/T:
    (qT²/τ)(1 - (T/2τ)(3 - 4e^{-τ/T} + e^{-2τ/T})), which behaves as a random walk of density
    sqrt(q) for τ << T and as white noise of density sqrt(q)T for τ >> T, with its maximum
    0.6172σ (Allan deviation) near τ = 1.89 T.
    """
    tau = np.asarray(tau_s, dtype=np.float64)
    x = tau / gm_time_constant_s
    gm = 2.0 * gm_sigma**2 / x * (1.0 - (3.0 - 4.0 * np.exp(-x) + np.exp(-2.0 * x)) / (2.0 * x))
    return np.asarray(
        white_density**2 / tau + gm + random_walk_density**2 * tau / 3.0, dtype=np.float64
    )
