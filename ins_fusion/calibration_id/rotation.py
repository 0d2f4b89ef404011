"""Gyro scale factors from known rotations (Aalborg notes §4.2, §4.4, §4.6 "Turn table").

- **D1, rate table** (5.19): ω̃ = ω + S ω + B. For every steady rotation segment the bias B is
  the mean of the static segment just before it (S1, (5.7)), so earth rate and the gravity part
  of the g-dependent bias cancel (the spin axis is vertical and stays so); S = (ω̃ - B)/ω - 1 with
  ω the table rate, its sign from the data (S+ / S- per direction). The other axes' rate gives
  their sensitivity to the spun axis (misalignment plus the mounting of the unit on the table,
  σ 0.5° in §4.4; the same for D2): reported, not written.
- **D2, known angle** (5.20): Δγ̃ = Δγ + S Δγ + t B. The gyro is integrated (trapezoid on the
  stamps) over the motion between two static segments, t its duration, B the mean of the static
  segment before it; S = (Δγ̃ - t B)/Δγ - 1.

σ (§4.4, law of error propagation): the two means (D1) or the integrated white noise N²t with
N² = σ_B² T_static and t σ_B (D2); the bias instability between the static segment and the
rotation; the table rate σ (D1, common to every run at that rate, added after averaging the
runs) or the angle σ (D2, per run: the stop at the forced centring). The centrifugal g-dependent
bias during rotation is not modelled (§4.2). Several runs of one axis and direction are averaged
with weights 1/σ²; their scatter against σ is the χ² of the report.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.integrate import trapezoid

from gnss_ins_common.types import FloatArray
from ins_fusion.bags.imu import ImuRecord
from ins_fusion.calibration_id.lsq import EstimationError
from ins_fusion.calibration_id.model import BiasInstability
from ins_fusion.calibration_id.result import (
    CalibrationResult,
    Estimate,
    FitSummary,
    Quantity,
    Residual,
)
from ins_fusion.calibration_id.segments import Kind, Segment, means
from ins_fusion.calibration_id.static import AXES, axis_label

#: The other axes may see at most this fraction of the rotation (rotation about one axis).
MAX_CROSS_AXIS = 0.1
#: A run's rate (D1) or angle (D2) within this fraction of the given one.
TOLERANCE = 0.2


@dataclass(frozen=True)
class Run:
    """One rotation: the static segment before it, the rotation (a segment of the record),
    axis and sign, scale error S and its random σ, cross-axis ratios and their σ."""

    static: Segment
    rotation: Segment
    axis: int
    sign: float
    scale: float
    sigma: float
    cross: FloatArray
    cross_sigma: FloatArray


def _rotation_axis(change: FloatArray, expected: float, what: str) -> tuple[int, float] | str:
    """(axis, sign) of a rotation change (3,) of about ``expected``, or why it is not one."""
    axis = int(np.argmax(np.abs(change)))
    size = abs(float(change[axis]))
    cross = max(abs(float(change[j])) for j in range(3) if j != axis) / size
    if cross > MAX_CROSS_AXIS:
        return f"not about one axis (other axes {100 * cross:.0f} % of {AXES[axis]})"
    if abs(size / expected - 1.0) > TOLERANCE:
        return f"{what} {size / expected:.2f} times the given one"
    return axis, math.copysign(1.0, float(change[axis]))


def _last_static_before(statics: Sequence[Segment], segment: Segment) -> Segment | None:
    before = [s for s in statics if s.record == segment.record and s.t_end_s <= segment.t_start_s]
    return max(before, key=lambda s: s.t_end_s, default=None)


def rate_table(
    segments: Sequence[Segment],
    rate_rad_s: float,
    rate_sigma_rad_s: float,
    mount_sigma_rad: float,
    instability: BiasInstability,
) -> CalibrationResult:
    """D1 from static and rotation segments (module docstring)."""
    statics = [s for s in segments if s.kind is Kind.STATIC]
    runs, skipped = [], []
    for r in (s for s in segments if s.kind is Kind.ROTATION):
        s = _last_static_before(statics, r)
        if s is None:
            skipped.append(f"{r.where}: no static segment before it for the bias")
            continue
        change = r.means.rate_rad_s - s.means.rate_rad_s
        found = _rotation_axis(change, rate_rad_s, "rate")
        if isinstance(found, str):
            skipped.append(f"{r.where}: {found}")
            continue
        axis, sign = found
        gm = 2.0 * (1.0 - instability.gyro_correlation(s, r)) * np.square(instability.gyro_rad_s)
        var = np.square(r.means.rate_sigma_rad_s) + np.square(s.means.rate_sigma_rad_s) + gm
        var /= rate_rad_s**2
        cross = change / (sign * rate_rad_s)
        runs.append(
            Run(
                s,
                r,
                axis,
                sign,
                abs(float(change[axis])) / rate_rad_s - 1.0,
                math.sqrt(var[axis]),
                cross,
                np.sqrt(var + mount_sigma_rad**2),
            )
        )
    return _combine(
        "rate-table",
        runs,
        skipped,
        f"D1 (5.19), S1 bias (5.7) just before, {math.degrees(rate_rad_s):g} deg/s",
        rate_sigma_rad_s / rate_rad_s,
        "rotation at the given --rate",
    )


def known_angle(
    records: Sequence[ImuRecord],
    statics: Sequence[Segment],
    angle_rad: float,
    angle_sigma_rad: float,
    mount_sigma_rad: float,
    instability: BiasInstability,
) -> CalibrationResult:
    """D2 from the motions between consecutive static segments (module docstring)."""
    runs, skipped = [], []
    ordered = sorted(statics, key=lambda s: (s.record, s.t_start_s))
    for a, b in itertools.pairwise(ordered):
        if a.record != b.record:
            continue
        record = records[a.record]
        start, stop = a.stop - 1, b.start + 1
        t = record.t_s[start:stop]
        duration = float(t[-1] - t[0])
        motion = Segment(
            a.record,
            start,
            stop,
            float(t[0]),
            float(t[-1]),
            Kind.ROTATION,
            means(record, start, stop),
            float(record.t_s[0]),
        )
        change = trapezoid(record.rate_flu_rad_s[start:stop], t, axis=0)
        change = change - duration * a.means.rate_rad_s
        found = _rotation_axis(change, angle_rad, "angle")
        if isinstance(found, str):
            skipped.append(f"{motion.where}: {found}")
            continue
        axis, sign = found
        scale = abs(float(change[axis])) / angle_rad - 1.0
        sigma_b = a.means.rate_sigma_rad_s
        gm = (
            2.0
            * (1.0 - instability.gyro_correlation(a, motion))
            * np.square(instability.gyro_rad_s)
        )
        var = (
            sigma_b**2 * a.duration_s * duration + duration**2 * (sigma_b**2 + gm)
        ) / angle_rad**2
        var_axis = float(var[axis]) + ((1.0 + scale) * angle_sigma_rad / angle_rad) ** 2
        runs.append(
            Run(
                a,
                motion,
                axis,
                sign,
                scale,
                math.sqrt(var_axis),
                change / (sign * angle_rad),
                np.sqrt(var + mount_sigma_rad**2),
            )
        )
    return _combine(
        "known-angle",
        runs,
        skipped,
        f"D2 (5.20), S1 bias (5.7) just before, {math.degrees(angle_rad):g} deg",
        0.0,
        "rotation by the given --angle between static segments",
    )


def _combine(
    method: str,
    runs: Sequence[Run],
    skipped: Sequence[str],
    source: str,
    common_relative_sigma: float,
    wanted: str,
) -> CalibrationResult:
    """Per axis and direction: the weighted mean of the runs' S, plus the common σ."""
    if not runs:
        detail = "; ".join(skipped) or "no motion between static segments"
        raise EstimationError(f"{method}: no {wanted} found ({detail})")
    segments: list[Segment] = []
    labels: list[str] = []
    for run in runs:
        name = axis_label(run.axis, run.sign)
        segments += [run.static, run.rotation]
        labels += [f"bias {name}", f"turn {name}"]
    result = CalibrationResult(method, segments, labels)
    result.notes += [f"ignored {text}" for text in skipped]
    scale = {1.0: np.full(3, math.nan), -1.0: np.full(3, math.nan)}
    sigma = {1.0: np.full(3, math.nan), -1.0: np.full(3, math.nan)}
    cross_sum, cross_weight = np.zeros((3, 3)), np.zeros((3, 3))
    for axis in range(3):
        for sign in (1.0, -1.0):
            group = [(k, r) for k, r in enumerate(runs) if r.axis == axis and r.sign == sign]
            if not group:
                continue
            weights = np.array([1.0 / r.sigma**2 for _, r in group])
            values = np.array([r.scale for _, r in group])
            mean = float(weights @ values / weights.sum())
            scale[sign][axis] = mean
            sigma[sign][axis] = math.sqrt(
                1.0 / weights.sum() + ((1.0 + mean) * common_relative_sigma) ** 2
            )
            result.residuals += [
                Residual(
                    2 * k + 1,
                    f"S{'+' if sign > 0 else '-'} {AXES[axis]}",
                    100.0 * (r.scale - mean),
                    "%",
                    (r.scale - mean) / r.sigma,
                )
                for k, r in group
            ]
            chi2 = float(weights @ np.square(values - mean))
            result.fits.append(
                FitSummary(f"S{'+' if sign > 0 else '-'} {AXES[axis]}", chi2, len(group) - 1)
            )
    for run in runs:
        w = 1.0 / np.square(run.cross_sigma)
        for j in range(3):
            if j != run.axis:
                cross_sum[j, run.axis] += w[j] * run.cross[j]
                cross_weight[j, run.axis] += w[j]
    with np.errstate(divide="ignore", invalid="ignore"):
        cross = np.where(cross_weight > 0, cross_sum / cross_weight, math.nan)
        cross_sigma = np.where(cross_weight > 0, 1.0 / np.sqrt(cross_weight), math.nan)
    np.fill_diagonal(cross, 0.0)
    np.fill_diagonal(cross_sigma, 0.0)
    result.estimates += [
        Estimate(Quantity.GYRO_SCALE_POSITIVE, scale[1.0], sigma[1.0], source),
        Estimate(Quantity.GYRO_SCALE_NEGATIVE, scale[-1.0], sigma[-1.0], source),
        Estimate(
            Quantity.GYRO_MISALIGNMENT,
            cross,
            cross_sigma,
            f"{source}; includes the mounting on the table (not written)",
            written=False,
        ),
    ]
    return result
