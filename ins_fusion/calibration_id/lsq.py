"""Generalised least squares for the linear observation equations of the static methods.

y = H x + v, Cov(v) = C: x̂ = (Hᵀ C⁻¹ H)⁻¹ Hᵀ C⁻¹ y with covariance (Hᵀ C⁻¹ H)⁻¹. For the S1/S2
equations of Aalborg notes §4.2 this is exactly their closed-form solutions, and the covariance is
the law of error propagation of §4.4, (5.22)/(5.23). Solved by whitening with the Cholesky factor
of C and scipy's least squares (SVD), which also finds parameters the positions cannot separate.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from gnss_ins_common.types import FloatArray


class EstimationError(ValueError):
    """The data cannot determine the parameters (too few or badly chosen positions)."""


@dataclass(frozen=True)
class LinearFit:
    """Parameters (p,), their covariance (p, p), residuals y - H x̂ (m,), residuals divided by
    their observation σ (m,), χ² = rᵀ C⁻¹ r and its degrees of freedom m - p."""

    params: FloatArray
    covariance: FloatArray
    residuals: FloatArray
    normalized: FloatArray
    chi2: float
    dof: int

    @property
    def sigma(self) -> FloatArray:
        """1σ of each parameter."""
        return np.sqrt(np.diag(self.covariance))


def solve(
    design: FloatArray, observations: FloatArray, covariance: FloatArray, names: Sequence[str]
) -> LinearFit:
    """GLS solution; EstimationError names a parameter the design does not determine."""
    m, p = design.shape
    if m < p:
        raise EstimationError(
            f"{m} observations cannot determine {p} parameters ({', '.join(names)})"
        )
    factor = scipy.linalg.cholesky(covariance, lower=True)
    h = scipy.linalg.solve_triangular(factor, design, lower=True)
    y = scipy.linalg.solve_triangular(factor, observations, lower=True)
    _, singular, vt = np.linalg.svd(h, full_matrices=False)
    if singular[-1] <= 1e-10 * singular[0]:
        raise EstimationError(
            f"the positions do not determine {names[int(np.argmax(np.abs(vt[-1])))]}"
        )
    params, *_ = scipy.linalg.lstsq(h, y)
    covariance_x = np.linalg.inv(h.T @ h)
    residuals = observations - design @ params
    white = y - h @ params
    return LinearFit(
        np.asarray(params),
        0.5 * (covariance_x + covariance_x.T),
        residuals,
        residuals / np.sqrt(np.diag(covariance)),
        float(white @ white),
        m - p,
    )
