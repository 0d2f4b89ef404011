"""Static methods (Aalborg notes §4.1-§4.4): six-position S2, Salychev, known attitude S3,
unknown attitude S4.

Observation model (2.1)/(2.2) in imu_link FLU for a unit at rest with known up direction u
(unit vector) and known earth rate e (both in imu_link): the true specific force is f = g u, so
per accelerometer axis i and gyro axis i

    f̃_i = B_f,i + (1 + S±_i) f_i + Σ_j≠i A_ij f_j            (2.1), S± by the sign of f_i
    ω̃_i = B_ω,i + Σ_j G_ij f_j + e_i                          (2.2), scale × earth rate dropped

(the gyro scale and misalignment multiply the earth rate only, §4.3: "too weak"). Each method
writes one such equation per static segment and solves per axis by least squares (``lsq``):

- **six-position S2**: each axis once up and once down. Accelerometer, symmetric scale:
  (5.2)/(5.3) on the two vertical readings, B = (f̃₁ + f̃₂)/2, S = (f̃₁ - f̃₂)/(2g) - 1;
  asymmetric scale: B from the four positions where the axis is horizontal (S1, (5.1)), then
  (5.5)/(5.6) with α = 90° each on its own (S1 mod: S+ up, S- down). Gyro (5.9)-(5.18): with
  the axis vertical the earth rate is ±Ω sin φ and the g-dependent bias ±g G_ii, so the pair
  sum gives B and the difference G_ii without knowing the heading; a pair with axis j vertical
  gives G_ij from its difference and another B from its sum. The heading is unknown, so the
  horizontal earth rate on a horizontal axis (Ω cos φ times the cosine of its azimuth) is noise
  of variance (Ω cos φ)²/2.
- **Salychev** (§4.6 as executed): the same six positions with the horizontal positive axes
  pointing south-east and south-west, so every horizontal axis sees -Ω cos φ/√2 and the earth
  rate is known on every axis ((5.17)/(5.18) for this geometry). Accelerometer scale symmetric
  by default, as the report chose (Fig. 5-35).
- **known attitude S3** (Titterton): any positions with known roll, pitch and yaw; adds the
  accelerometer misalignment A_ij; the gyro rows subtract the full earth rate.
- **unknown attitude S4** (Shin & El-Sheimy): by the norms of the readings, not per axis
  (calibration_id/unknown_attitude.py; it shares this module's options and checks).

Observation noise (§4.4): the σ of each segment mean (``segments``); the attitude (level) error
σ_θ, which moves a horizontal axis by g σ_θ and a vertical one only to second order (§4.4
neglects it), i.e. variance σ_θ² (g² - f_i²); the bias instability (``model``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from enum import StrEnum

import numpy as np
import scipy.stats
from scipy.spatial.transform import Rotation

from gnss_ins_common.types import FloatArray
from ins_fusion.calibration_id.lsq import EstimationError, LinearFit, solve
from ins_fusion.calibration_id.model import BiasInstability, Site
from ins_fusion.calibration_id.result import (
    CalibrationResult,
    Estimate,
    FitSummary,
    Quantity,
    Residual,
)
from ins_fusion.calibration_id.segments import Segment
from ins_fusion.core.nav.earth import EARTH_RATE_RAD_S

AXES = "xyz"
#: An axis counts as vertical within this angle [deg]; a six-position segment must be.
MAX_TILT_DEG = 10.0
#: |mean specific force| of a static segment within this fraction of g.
GRAVITY_TOLERANCE = 0.1
#: A fit whose χ² has a smaller probability gets a warning in the report.
CHI2_WARNING_P = 1e-3


class Scale(StrEnum):
    """Accelerometer scale-factor model."""

    ASYMMETRIC = "asymmetric"
    SYMMETRIC = "symmetric"


@dataclass(frozen=True)
class StaticOptions:
    """Site, attitude (level) σ of the positions [rad], bias instability, scale model, and
    the input size [m/s²] from which the accelerometer scale is a second, large-range term
    (inf: one range; Aalborg report §9.1.1, ImuCalibration's scale_large_*)."""

    site: Site
    level_sigma_rad: float = math.radians(0.1)
    instability: BiasInstability = field(default_factory=BiasInstability)
    accel_scale: Scale = Scale.ASYMMETRIC
    large_input_m_s2: float = math.inf


#: The calibration terms of the accelerometer scale by (large range, positive input).
_SCALES = {
    (False, True): Quantity.ACCEL_SCALE_POSITIVE,
    (False, False): Quantity.ACCEL_SCALE_NEGATIVE,
    (True, True): Quantity.ACCEL_SCALE_LARGE_POSITIVE,
    (True, False): Quantity.ACCEL_SCALE_LARGE_NEGATIVE,
}
#: Scale-factor terms of an accelerometer axis: (range is large, sign or None for symmetric).
_ScaleTerm = tuple[bool, float | None]


def _scale_columns(
    f: FloatArray, symmetric: bool, large_input: float
) -> list[tuple[_ScaleTerm, FloatArray]]:
    """Design columns of the scale terms for true inputs f [m/s²] of one axis: per range (one,
    or small and large) one symmetric column or one per sign; terms no input reaches are left
    out (not estimated)."""
    columns = []
    for large in (False, True) if math.isfinite(large_input) else (False,):
        in_range = (np.abs(f) >= large_input) == large
        part = np.where(in_range, f, 0.0)
        signs: tuple[float | None, ...] = (None,) if symmetric else (1.0, -1.0)
        for sign in signs:
            column = part if sign is None else np.where(part * sign > 0.0, part, 0.0)
            if np.any(column != 0.0):
                columns.append(((large, sign), column))
    return columns


@dataclass(frozen=True)
class Position:
    """A static segment with its known attitude: ``up`` unit vector, known earth rate [rad/s]
    and variance of its unknown part [(rad/s)²] per axis, all in imu_link."""

    segment: Segment
    label: str
    up: FloatArray
    earth_rate_rad_s: FloatArray
    earth_rate_var: FloatArray


def axis_label(axis: int, sign: float) -> str:
    """``+x``, ``-z``..."""
    return f"{'+' if sign > 0 else '-'}{AXES[axis]}"


def up_axis(segment: Segment, gravity_m_s2: float) -> tuple[int, float]:
    """The imu_link axis (index, sign) pointing up in a static segment; EstimationError when
    the reading is not gravity or no axis is within MAX_TILT_DEG of vertical."""
    f = segment.means.force_m_s2
    norm = float(np.linalg.norm(f))
    if abs(norm / gravity_m_s2 - 1.0) > GRAVITY_TOLERANCE:
        raise EstimationError(
            f"{segment.where}: |f| = {norm:.3f} m/s² is not gravity ({gravity_m_s2:.4f} m/s²);"
            " not a static reading in m/s²"
        )
    axis = int(np.argmax(np.abs(f)))
    sign = math.copysign(1.0, float(f[axis]))
    tilt = math.degrees(math.acos(min(1.0, abs(float(f[axis])) / norm)))
    if tilt > MAX_TILT_DEG:
        raise EstimationError(
            f"{segment.where}: the up direction is {tilt:.0f}° from the nearest axis"
            f" ({axis_label(axis, sign)}); every position needs an axis vertical"
        )
    return axis, sign


def six_positions(segments: Sequence[Segment], site: Site, salychev: bool) -> list[Position]:
    """The segments as six-position setups: the axis up in each (from gravity), earth rate
    known vertically (heading unknown) or on every axis (Salychev: horizontal axes SE/SW).
    EstimationError when a position is missing."""
    omega_v = EARTH_RATE_RAD_S * math.sin(site.latitude_rad)
    omega_h = EARTH_RATE_RAD_S * math.cos(site.latitude_rad)
    positions = []
    for s in segments:
        axis, sign = up_axis(s, site.gravity_m_s2)
        up = np.zeros(3)
        up[axis] = sign
        horizontal = 1.0 - np.abs(up)
        if salychev:
            earth, var = omega_v * up - omega_h / math.sqrt(2.0) * horizontal, np.zeros(3)
        else:
            earth, var = omega_v * up, 0.5 * omega_h * omega_h * horizontal
        positions.append(Position(s, axis_label(axis, sign), up, earth, var))
    found = [p.label for p in positions]
    missing = [axis_label(a, s) for a in range(3) for s in (1.0, -1.0)]
    missing = [m for m in missing if m not in found]
    if missing:
        counts = ", ".join(f"{label} ×{found.count(label)}" for label in sorted(set(found)))
        raise EstimationError(
            f"six-position needs every axis up and down: missing {', '.join(missing)} up"
            f" (static segments found: {counts or 'none'})"
        )
    return positions


def attitude_positions(
    segments: Sequence[Segment], rpy_rad: Sequence[tuple[float, float, float]], site: Site
) -> list[Position]:
    """Segments with given roll, pitch, yaw [rad] of imu_link in ENU (REP-103: yaw 0 = x east,
    counter-clockwise positive), in order. EstimationError when the counts differ or gravity
    in the data is more than MAX_TILT_DEG from the attitude's up."""
    if len(rpy_rad) != len(segments):
        raise EstimationError(f"{len(rpy_rad)} attitudes given for {len(segments)} static segments")
    positions = []
    for s, (roll, pitch, yaw) in zip(segments, rpy_rad, strict=True):
        to_body = Rotation.from_euler("ZYX", [yaw, pitch, roll]).inv()
        up = to_body.apply([0.0, 0.0, 1.0])
        f = s.means.force_m_s2
        angle = math.degrees(math.acos(np.clip(up @ f / np.linalg.norm(f), -1.0, 1.0)))
        label = "/".join(f"{math.degrees(a):.0f}" for a in (roll, pitch, yaw))
        if angle > MAX_TILT_DEG:
            raise EstimationError(
                f"{s.where}: attitude {label} deg puts up {angle:.0f}° from gravity in the data"
            )
        earth = to_body.apply(site.earth_rate_enu_rad_s)
        positions.append(Position(s, label, up, earth, np.zeros(3)))
    return positions


def _covariance(
    positions: Sequence[Position], triad: str, axis: int, extra: FloatArray, options: StaticOptions
) -> FloatArray:
    segments = [p.segment for p in positions]
    sigma = np.array(
        [
            (
                p.segment.means.rate_sigma_rad_s
                if triad == "gyro"
                else p.segment.means.force_sigma_m_s2
            )[axis]
            for p in positions
        ]
    )
    return np.diag(sigma * sigma + extra) + options.instability.covariance(segments, triad, axis)


def warn_chi2(result: CalibrationResult, name: str, fit: LinearFit | tuple[float, int]) -> None:
    """Add the χ² of a fit (its degrees of freedom) to ``result``, and a note when its probability
    is below CHI2_WARNING_P."""
    chi2, dof = (fit.chi2, fit.dof) if isinstance(fit, LinearFit) else fit
    result.fits.append(FitSummary(name, chi2, dof))
    if dof > 0 and scipy.stats.chi2.sf(chi2, dof) < CHI2_WARNING_P:
        result.notes.append(
            f"{name}: residuals larger than their σ (χ² = {chi2:.1f} for {dof} degrees of"
            " freedom): motion, level errors or errors the method does not model; the stated"
            " σ are optimistic"
        )


def fit_accel(
    positions: Sequence[Position],
    options: StaticOptions,
    result: CalibrationResult,
    misalignment: bool,
    written: bool,
) -> None:
    """Accelerometer bias, scale (options.accel_scale) and optionally misalignment, per axis.

    Symmetric without misalignment uses the vertical readings only ((5.2)/(5.3)); otherwise
    every position ((5.1), (5.5)/(5.6) at α = 90°, S3)."""
    g = options.site.gravity_m_s2
    symmetric = options.accel_scale is Scale.SYMMETRIC
    vertical_only = symmetric and not misalignment
    source = (
        "S2 (5.2)/(5.3), vertical axes"
        if vertical_only
        else ("S3 least squares" if misalignment else "S1 (5.1) + S1 mod (5.5)/(5.6), α = 90°")
    )
    bias, bias_s = np.full(3, math.nan), np.full(3, math.nan)
    # (large range, positive) -> value and σ per axis; NaN: not estimated
    scales = {
        (large, positive): (np.full(3, math.nan), np.full(3, math.nan))
        for large in (False, True)
        for positive in (True, False)
    }
    mis, mis_s = np.zeros((3, 3)), np.zeros((3, 3))
    for i in range(3):
        rows = [
            k
            for k, p in enumerate(positions)
            if not vertical_only or abs(p.up[i]) > math.cos(math.radians(MAX_TILT_DEG))
        ]
        used = [positions[k] for k in rows]
        f = np.array([g * p.up for p in used])
        others = [j for j in range(3) if j != i]
        columns = [np.ones(len(used))]
        names = [f"accel bias {AXES[i]}"]
        terms = _scale_columns(f[:, i], symmetric, options.large_input_m_s2)
        for (large, sign), column in terms:
            columns.append(column)
            names.append(
                f"accel scale{' large' if large else ''}"
                + ("" if sign is None else (" +" if sign > 0 else " -"))
                + f" {AXES[i]}"
            )
        if misalignment:
            columns += [f[:, j] for j in others]
            names += [f"accel misalignment {AXES[i]}{AXES[j]}" for j in others]
        level = options.level_sigma_rad**2 * np.maximum(g * g - f[:, i] ** 2, 0.0)
        fit = solve(
            np.stack(columns, axis=1),
            np.array([p.segment.means.force_m_s2[i] for p in used]),
            _covariance(used, "accel", i, level, options),
            names,
        )
        x, sx = fit.params, fit.sigma
        bias[i], bias_s[i] = x[0], sx[0]
        for k, ((large, sign), _) in enumerate(terms, start=1):
            for positive in (True, False) if sign is None else (sign > 0,):
                value, sigma = scales[large, positive]
                value[i], sigma[i] = x[k] - 1.0, sx[k]
        if misalignment:
            mis[i, others], mis_s[i, others] = x[-2:], sx[-2:]
        if written:
            warn_chi2(result, f"accelerometer {AXES[i]}", fit)
            result.residuals += [
                Residual(k, f"f_{AXES[i]}", r / Quantity.ACCEL_BIAS.unit, "mg", n)
                for k, r, n in zip(rows, fit.residuals, fit.normalized, strict=True)
            ]
    label = f"{source}, {options.accel_scale.value} scale"
    result.estimates.append(Estimate(Quantity.ACCEL_BIAS, bias, bias_s, label, written))
    ranged = math.isfinite(options.large_input_m_s2)
    for (large, positive), (value, sigma) in scales.items():
        # Two ranges: a term no position reaches is left out (kept from a base file).
        if not np.all(np.isnan(value)) if ranged else not large:
            result.estimates.append(
                Estimate(_SCALES[large, positive], value, sigma, label, written)
            )
    if ranged:
        result.accel_large_input_m_s2 = options.large_input_m_s2
    if misalignment:
        result.estimates.append(Estimate(Quantity.ACCEL_MISALIGNMENT, mis, mis_s, label, written))


def fit_gyro(
    positions: Sequence[Position], options: StaticOptions, result: CalibrationResult, source: str
) -> None:
    """Gyro bias and g-dependent bias G per axis: ω̃_i - e_i = B_i + Σ_j G_ij g u_j."""
    g = options.site.gravity_m_s2
    f = np.array([g * p.up for p in positions])
    bias, bias_s = np.zeros(3), np.zeros(3)
    gsens, gsens_s = np.zeros((3, 3)), np.zeros((3, 3))
    for i in range(3):
        names = [f"gyro bias {AXES[i]}"] + [
            f"g-dependent bias {AXES[i]}{AXES[j]}" for j in range(3)
        ]
        fit = solve(
            np.hstack((np.ones((len(positions), 1)), f)),
            np.array([p.segment.means.rate_rad_s[i] - p.earth_rate_rad_s[i] for p in positions]),
            _covariance(
                positions, "gyro", i, np.array([p.earth_rate_var[i] for p in positions]), options
            ),
            names,
        )
        bias[i], bias_s[i] = fit.params[0], fit.sigma[0]
        gsens[i], gsens_s[i] = fit.params[1:], fit.sigma[1:]
        warn_chi2(result, f"gyro {AXES[i]}", fit)
        result.residuals += [
            Residual(k, f"w_{AXES[i]}", r / Quantity.GYRO_BIAS.unit, "deg/s", n)
            for k, (r, n) in enumerate(zip(fit.residuals, fit.normalized, strict=True))
        ]
    result.estimates += [
        Estimate(Quantity.GYRO_BIAS, bias, bias_s, source),
        Estimate(Quantity.GYRO_G_SENSITIVITY, gsens, gsens_s, source),
    ]


def six_position(
    segments: Sequence[Segment], options: StaticOptions, salychev: bool = False
) -> CalibrationResult:
    """S2 (or the Salychev procedure): accelerometer bias and scale (both scale models; the
    chosen one is written), gyro bias and g-dependent bias (module docstring)."""
    positions = six_positions(segments, options.site, salychev)
    result = CalibrationResult(
        "salychev" if salychev else "six-position",
        [p.segment for p in positions],
        [f"{p.label} up" for p in positions],
    )
    other = Scale.SYMMETRIC if options.accel_scale is Scale.ASYMMETRIC else Scale.ASYMMETRIC
    fit_accel(positions, options, result, misalignment=False, written=True)
    fit_accel(
        positions,
        replace(options, accel_scale=other),
        result,
        misalignment=False,
        written=False,
    )
    heading = (
        "horizontal axes SE/SW, earth rate known on every axis"
        if salychev
        else "heading unknown, horizontal earth rate as noise"
    )
    fit_gyro(positions, options, result, f"S2 (5.9)-(5.18), {heading}")
    return result


def known_attitude(
    segments: Sequence[Segment],
    rpy_rad: Sequence[tuple[float, float, float]],
    options: StaticOptions,
) -> CalibrationResult:
    """S3: accelerometer bias, scale and misalignment; gyro bias and g-dependent bias."""
    positions = attitude_positions(segments, rpy_rad, options.site)
    result = CalibrationResult(
        "known-attitude", [p.segment for p in positions], [p.label for p in positions]
    )
    fit_accel(positions, options, result, misalignment=True, written=True)
    fit_gyro(positions, options, result, "S3 least squares, full earth rate from the attitude")
    return result
