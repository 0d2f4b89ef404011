"""The algebra of a measurement update of the error-state filter (core.filter.eskf): the gated
Joseph update, the chi-square gate, and what a gate recovery does to the covariance (fading,
widening), with the covariance's health check.

Updates are Joseph form, (I - KH) P (I - KH)ᵀ + K R Kᵀ, with a chi-square gate on the
normalised innovation squared. The product is taken as two rank-m corrections, A = P - K (H P)
then A - (A Hᵀ) Kᵀ, which is the same formula in O(n²m) instead of the O(n³) of forming I - KH
(m = 1-3 rows, n = 15-26 states). filterpy's ``KalmanFilter.update`` is not used on the hot
path: it has no gate, builds an n×n I - KH for every scalar update and inverts S with ``inv``.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from scipy.special import gammaincinv

from gnss_ins_common.types import FloatArray
from ins_fusion.core.compiled import jit


def chi2_threshold(probability: float, dof: int) -> float:
    """Gate: normalised innovation squared accepted below this (chi-square quantile)."""
    # scipy.stats.chi2.ppf's own formula; scipy.stats itself costs ~1 s of import.
    return float(2.0 * gammaincinv(0.5 * dof, probability))


class UpdateResult(NamedTuple):
    """Outcome of one measurement update: accepted or gated, the normalised innovation
    squared, and the error-state estimate to inject (None when gated)."""

    accepted: bool
    nis: float
    dx: FloatArray | None


@jit
def joseph_update(
    P: FloatArray, z: FloatArray, H: FloatArray, R: FloatArray, threshold: float
) -> tuple[bool, float, FloatArray, FloatArray]:
    """(accepted, NIS, δx, new P) of ErrorStateFilter.update; a singular S gives NIS inf."""
    PHt = P @ H.T
    S = H @ PHt + R
    try:
        s_inv = np.linalg.inv(S)  # 1-3 rows: one inverse is cheaper than two solves
    except Exception:  # singular (numba cannot name LinAlgError)
        return False, math.inf, z, P
    nis = float(z @ s_inv @ z)
    if not nis <= threshold:  # also rejects NaN
        return False, nis, z, P
    K = PHt @ s_inv
    A = P - K @ (H @ P)  # (I - KH) P
    P_new = A - (A @ H.T) @ K.T + K @ R @ K.T  # A (I - KH)ᵀ + K R Kᵀ
    return True, nis, K @ z, 0.5 * (P_new + P_new.T)


@jit
def projected_variance(H: FloatArray, P: FloatArray) -> FloatArray:
    """diag(H P Hᵀ): the variance of each row of H δx."""
    HP = H @ P
    out = np.zeros(len(H))
    for i in range(len(H)):
        for j in range(H.shape[1]):
            out[i] += HP[i, j] * H[i, j]
    return out


def faded_covariance(P: FloatArray, factor: float, ceiling: FloatArray) -> FloatArray:
    """P faded by ``factor`` (fading memory: factor x P), as noise added to P, (factor - 1) P,
    whose rows and columns are scaled down (D A D, D diagonal <= 1) for the states whose variance
    would otherwise end above ``ceiling``: such a state ends at its ceiling, one already there
    gets nothing. The result stays positive semi-definite and never below P (what the RTS
    smoother's noise step needs).

    A fading multiplies every variance; repeated over a long run of inconsistent measurements
    (an IMU at rest under a moving antenna: issue 38) it multiplied the bias variances without
    bound until the state overflowed. A bias, a scale factor, a mounting angle cannot be less
    known than before the first measurement, so their prior variance bounds them."""
    added = P * (factor - 1.0)
    room = np.maximum(ceiling - np.diagonal(P), 0.0)
    growth = np.maximum(np.diagonal(added), np.finfo(float).tiny)
    shrink = np.sqrt(np.minimum(1.0, room / growth))
    if bool(np.all(shrink == 1.0)):
        return P * factor
    return P + shrink[:, None] * added * shrink[None, :]


def widening(P: FloatArray, z: FloatArray, H: FloatArray, R: FloatArray, start: int) -> FloatArray:
    """The 3x3 covariance to add to the block of ``P`` at ``start`` that makes the innovation z
    fit: the excess of each z_i² over S_ii, mapped into that block by the pseudo-inverse of its
    columns of H, so that the new S_ii = max(S_ii, z_i²) when they have full row rank
    (ErrorStateFilter.widen, a gate recovery's last resort)."""
    excess = np.maximum(np.square(z) - np.diagonal(H @ P @ H.T + R), 0.0)
    G = np.linalg.pinv(H[:, start : start + 3])
    added: FloatArray = (G * excess) @ G.T
    return added


@jit
def covariance_problem(P: FloatArray) -> int:
    """-1 for a usable covariance; -2 when an element is not finite, else the state of the
    most negative variance when one is negative."""
    worst, lowest = -1, 0.0
    for i in range(P.shape[0]):
        for j in range(P.shape[1]):
            if not math.isfinite(P[i, j]):
                return -2
        if P[i, i] < lowest:
            worst, lowest = i, P[i, i]
    return worst
