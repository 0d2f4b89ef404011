"""Unknown attitude S4 (Shin & El-Sheimy; Aalborg notes §4.1-§4.4): (5.4) |f| = g and (5.8)
|ω| = Ω per static position, by nonlinear least squares: accelerometer bias, symmetric scale and
the three non-orthogonality angles (x axis and x-y plane of the accelerometer triad fix the
frame, so A is lower triangular); gyro bias. §4.3: asymmetry and non-linearity corrupt the
accelerometer terms, g-dependent bias the gyro bias.

Observation noise (§4.4): the σ of each segment mean (``segments``), projected onto the
direction of each reading, and the bias instability (``model``). Options, the gravity check
and the χ² warning are those of the other static methods (calibration_id/static.py).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
import scipy.optimize

from gnss_ins_common.types import FloatArray
from ins_fusion.calibration_id.lsq import EstimationError
from ins_fusion.calibration_id.result import CalibrationResult, Estimate, Quantity, Residual
from ins_fusion.calibration_id.segments import Segment
from ins_fusion.calibration_id.static import AXES, GRAVITY_TOLERANCE, StaticOptions, warn_chi2
from ins_fusion.core.nav.earth import EARTH_RATE_RAD_S

#: S4 estimates 9 accelerometer parameters.
S4_MIN_POSITIONS = 9


def _norm_fit(
    sigma: FloatArray,
    covariance: Callable[[int], FloatArray],
    model: Callable[[FloatArray], FloatArray],
    x0: FloatArray,
    magnitude: float,
    names: Sequence[str],
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, float]:
    """Nonlinear least squares on |model(x)_k| = magnitude, one row per segment; ``sigma``
    (m, 3) the σ of the segment means.

    The covariance of the residuals projects each axis' covariance (``covariance(axis)``, per
    segment) onto the directions of model(x0). Returns x, its covariance, residuals, residual
    σ, χ²."""
    start = model(x0)
    directions = start / np.linalg.norm(start, axis=1, keepdims=True)
    cov = sum(np.outer(directions[:, i], directions[:, i]) * covariance(i) for i in range(3))
    cov = np.asarray(cov) + np.diag(np.sum((directions * sigma) ** 2, axis=1))
    factor = np.linalg.cholesky(cov)

    def whitened(x: FloatArray) -> FloatArray:
        r = np.linalg.norm(model(x), axis=1) - magnitude
        return np.asarray(np.linalg.solve(factor, r))

    fit = scipy.optimize.least_squares(whitened, x0, method="lm", x_scale="jac")
    jac = np.asarray(fit.jac)
    _, singular, vt = np.linalg.svd(jac, full_matrices=False)
    if singular[-1] <= 1e-8 * singular[0]:
        raise EstimationError(
            f"the positions do not determine {names[int(np.argmax(np.abs(vt[-1])))]}:"
            " spread the attitudes (faces, edges and corners)"
        )
    x = np.asarray(fit.x)
    residuals = np.linalg.norm(model(x), axis=1) - magnitude
    white = np.asarray(fit.fun)
    return x, np.linalg.inv(jac.T @ jac), residuals, np.sqrt(np.diag(cov)), float(white @ white)


def unknown_attitude(segments: Sequence[Segment], options: StaticOptions) -> CalibrationResult:
    """S4: (5.4) and (5.8) by nonlinear least squares (module docstring)."""
    if len(segments) < S4_MIN_POSITIONS:
        raise EstimationError(
            f"unknown-attitude (S4) needs at least {S4_MIN_POSITIONS} static positions,"
            f" found {len(segments)}"
        )
    g = options.site.gravity_m_s2
    for s in segments:
        up_norm = float(np.linalg.norm(s.means.force_m_s2))
        if abs(up_norm / g - 1.0) > GRAVITY_TOLERANCE:
            raise EstimationError(f"{s.where}: |f| = {up_norm:.3f} m/s² is not gravity")
    result = CalibrationResult(
        "unknown-attitude",
        list(segments),
        [f"position {k + 1}" for k in range(len(segments))],
    )
    forces = np.array([s.means.force_m_s2 for s in segments])
    lower = [(1, 0), (2, 0), (2, 1)]

    def corrected_force(x: FloatArray) -> FloatArray:
        mat = np.eye(3) + np.diag(x[3:6])
        for k, (i, j) in enumerate(lower):
            mat[i, j] = x[6 + k]
        return np.asarray(np.linalg.solve(mat, (forces - x[:3]).T).T)

    names = [f"accel bias {a}" for a in AXES] + [f"accel scale {a}" for a in AXES]
    names += [f"accel misalignment {AXES[i]}{AXES[j]}" for i, j in lower]
    x, cov, residuals, res_sigma, chi2 = _norm_fit(
        np.array([s.means.force_sigma_m_s2 for s in segments]),
        lambda i: options.instability.covariance(segments, "accel", i),
        corrected_force,
        np.zeros(9),
        g,
        names,
    )
    sx = np.sqrt(np.diag(cov))
    mis, mis_s = np.zeros((3, 3)), np.zeros((3, 3))
    for k, (i, j) in enumerate(lower):
        mis[i, j], mis_s[i, j] = x[6 + k], sx[6 + k]
    source = "S4 (5.4) |f| = g, misalignment in the accelerometer frame"
    result.estimates += [
        Estimate(Quantity.ACCEL_BIAS, x[:3], sx[:3], source),
        Estimate(Quantity.ACCEL_SCALE_POSITIVE, x[3:6], sx[3:6], source),
        Estimate(Quantity.ACCEL_SCALE_NEGATIVE, x[3:6], sx[3:6], source),
        Estimate(Quantity.ACCEL_MISALIGNMENT, mis, mis_s, source),
    ]
    warn_chi2(result, "accelerometers |f| = g", (chi2, len(segments) - 9))
    result.residuals += [
        Residual(k, "|f| - g", r / Quantity.ACCEL_BIAS.unit, "mg", r / s)
        for k, (r, s) in enumerate(zip(residuals, res_sigma, strict=True))
    ]
    _s4_gyro(segments, options, result)
    return result


def _s4_gyro(
    segments: Sequence[Segment], options: StaticOptions, result: CalibrationResult
) -> None:
    """(5.8) |ω̃ - B| = Ω, when the segment means resolve the earth rate."""
    rates = np.array([s.means.rate_rad_s for s in segments])
    sigma = np.array([s.means.rate_sigma_rad_s for s in segments])
    if float(np.median(sigma)) > EARTH_RATE_RAD_S / 3.0:
        result.notes.append(
            "gyro bias not estimated: the σ of the segment mean rates"
            f" ({math.degrees(float(np.median(sigma))) * 3600:.1f} deg/h) is not small against"
            " the earth rate (15.04 deg/h) that (5.8) relies on"
        )
        return
    x, cov, residuals, res_sigma, chi2 = _norm_fit(
        sigma,
        lambda i: options.instability.covariance(segments, "gyro", i),
        lambda b: rates - b,
        rates.mean(axis=0),
        EARTH_RATE_RAD_S,
        [f"gyro bias {a}" for a in AXES],
    )
    result.estimates.append(
        Estimate(
            Quantity.GYRO_BIAS,
            x,
            np.sqrt(np.diag(cov)),
            "S4 (5.8) |ω| = Ω (contains the g-dependent bias, §4.3)",
        )
    )
    warn_chi2(result, "gyros |ω| = Ω", (chi2, len(segments) - 3))
    result.residuals += [
        Residual(k, "|w| - Ω", r / Quantity.GYRO_BIAS.unit, "deg/s", r / s)
        for k, (r, s) in enumerate(zip(residuals, res_sigma, strict=True))
    ]
