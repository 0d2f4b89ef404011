"""Rauch–Tung–Striebel smoother for the closed-loop error-state filter: the backward pass on the
error states (pure math; the records come from core.smoother.history).

Forward filter (core.filter.eskf, core.engine.engine). Between two covariance steps the nominal
state is mechanised sample by sample; at each *transition* j the error covariance goes from the
posterior of step j-1 to the prior of step j,

    P_j⁻ = Φ_j P_{j-1}⁺ Φ_jᵀ + Q_j,

where a transition is a covariance propagation over an interval (Φ from core.filter.eskf), or a jump
of the model at one instant: a restarted state (Φ = I with that state's rows zeroed, Q its new
variance) or noise added outside the propagation (Φ = I: a gate recovery's fading, a bridged IMU
gap). The updates of step j follow; each feeds its estimate dx back into the nominal state and
resets the error mean to zero (closed loop). c_j = Σ dx is what step j fed back, so the nominal
after it is x̂_j⁺ = x̂_j⁻ ⊕ c_j (⊕: the engine's injection; to first order an addition, for the
attitude too: exp([ψ₂×]) exp([ψ₁×]) = exp([(ψ₁ + ψ₂)×]) up to ψ₂ × ψ₁ / 2, below 1e-6 rad for
the corrections of one step).

Derivation (closed loop). Let s_j be the true error relative to x̂_j⁺ and δ_j the one relative
to the nominal mechanised from x̂_{j-1}⁺, which is x̂_j⁻ at step j: δ_j = Φ_j s_{j-1} + w_j and
s_j = δ_j − c_j. This is a linear-Gaussian system with a known input (−c_j, a function of the
data), on which the forward filter is the Kalman filter: the filtered mean of s_{j-1} is 0 with
covariance P_{j-1}⁺, the predicted mean of δ_j is Φ_j·0 = 0 with covariance P_j⁻. The RTS
recursion (Rauch, Tung, Striebel, "Maximum likelihood estimates of linear dynamic systems",
AIAA Journal 3(8), 1965) with these zero means, and E[δ_j | all] = E[s_j | all] + c_j, gives,
with e_j = E[s_j | all data] the smoothed error relative to x̂_j⁺ and P_j^s its covariance:

    A_{j-1} = P_{j-1}⁺ Φ_jᵀ (P_j⁻)⁻¹
    e_{j-1} = A_{j-1} (e_j + c_j)
    P_{j-1}^s = P_{j-1}⁺ + A_{j-1} (P_j^s − P_j⁻) A_{j-1}ᵀ

from e_N = 0 and P_N^s = P_N⁺ at the last step of a segment (the forward filter's answer there).
The smoothed state of step j is x̂_j⁺ ⊕ e_j = x̂_j⁻ ⊕ (e_j + c_j). Attitude: ψ (C_true =
(I + [ψ×]) C, NED) is one more additive error of the linear model; the smoothed attitude is
exp([e_ψ×]) C, the same small rotation the forward filter injects, never an addition of Euler
angles. A segment ends where the engine re-initialises rather than estimates (a reset; the
heading set at alignment): no information crosses it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
import scipy.linalg

from gnss_ins_common.types import FloatArray


class SmootherHooks(Protocol):
    """What the engine tells the smoother's history (core.smoother.history); P arrays are the
    engine's, never modified in place after the call. Every hook runs on the engine's current
    timeline: a rollback (``on_rollback``) undoes what followed the checkpoint."""

    def on_transition(self, P_before: FloatArray, phi: FloatArray, P_after: FloatArray) -> None:
        """Covariance propagated over an interval: P_after = Φ P_before Φᵀ + Q."""

    def on_restart(self, P_before: FloatArray, P_after: FloatArray, states: range) -> None:
        """``states`` restarted: uncorrelated, at a new variance, their nominal estimate reset."""

    def on_noise(self, P_before: FloatArray, P_after: FloatArray) -> None:
        """Noise added to P outside the propagation (P_after - P_before >= 0)."""

    def on_correction(self, dx: FloatArray) -> None:
        """An update's error estimate fed back into the nominal state."""

    def on_checkpoint(self, t_s: float) -> None:
        """The engine saved a checkpoint at the IMU stamp t_s [s]."""

    def on_rollback(self, t_s: float) -> None:
        """The engine went back to its checkpoint at t_s [s]."""

    def on_break(self, P: FloatArray | None) -> None:
        """The state is re-initialised (the heading set at alignment); P before it."""

    def on_reset(self, P: FloatArray | None) -> None:
        """The engine starts again (reset): a break, and no rollback before it."""


def smoother_gain(P_post: FloatArray, phi: FloatArray, P_prior: FloatArray) -> FloatArray:
    """A = P⁺ Φᵀ (P⁻)⁻¹ by a Cholesky solve; by the pseudo-inverse when P⁻ is only
    semi-definite (a state without variance, e.g. a GNSS error state restarted at zero)."""
    rhs = phi @ P_post  # (P⁺ Φᵀ)ᵀ: A = (P⁻⁻¹ Φ P⁺)ᵀ as both P are symmetric
    try:
        factor = scipy.linalg.cho_factor(P_prior, check_finite=False)
        solved = scipy.linalg.cho_solve(factor, rhs, check_finite=False)
    except np.linalg.LinAlgError:
        solved = np.linalg.pinv(P_prior, hermitian=True) @ rhs
    gain: FloatArray = np.asarray(solved.T, dtype=np.float64)
    return gain


@dataclass(frozen=True)
class Smoothed:
    """Smoothed error of one step relative to its posterior nominal (e_j) and its covariance."""

    error: FloatArray
    cov: FloatArray


def backward_step(
    later: Smoothed,
    correction: FloatArray,
    P_post: FloatArray,
    phi: FloatArray,
    P_prior: FloatArray,
) -> Smoothed:
    """One RTS step back from step j (``later``: e_j, P_j^s; ``correction``: c_j; ``phi``,
    ``P_prior``: Φ_j, P_j⁻ of the transition into step j) to step j-1 (``P_post``: P_{j-1}⁺)."""
    gain = smoother_gain(P_post, phi, P_prior)
    error = gain @ (later.error + correction)
    cov = P_post + gain @ (later.cov - P_prior) @ gain.T
    return Smoothed(error, 0.5 * (cov + cov.T))
