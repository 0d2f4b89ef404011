"""The markdown report of ``gnss_ins calibrate``: settings, estimates ± σ, segments, residuals.

Values are printed with the decimals that show two significant digits of their σ.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ins_fusion.bags.imu import ImuRecord
from ins_fusion.calibration_id.axes import AxisCheck
from ins_fusion.calibration_id.result import CalibrationResult, Estimate, Quantity
from ins_fusion.calibration_id.static import AXES

_MG = Quantity.ACCEL_BIAS.unit
_DEG = 180.0 / math.pi
#: What each method is, for the report's heading.
METHOD_TITLES = {
    "six-position": "six-position (S2, Aalborg notes §4.2)",
    "salychev": "Salychev procedure (S2 with compass-aligned setups, Aalborg notes §4.6)",
    "known-attitude": "multi-position with known attitude (S3, Aalborg notes §4.1)",
    "unknown-attitude": "multi-position with unknown attitude (S4, Aalborg notes §4.2)",
    "rate-table": "rate table (D1, Aalborg notes §4.2 (5.19))",
    "known-angle": "known rotation angle (D2, Aalborg notes §4.2 (5.20))",
    "axes": "axis and sign mapping from a six-position record",
}


def decimals(sigma: float) -> int:
    """Decimals that show two significant digits of sigma (0 to 8)."""
    if not math.isfinite(sigma) or sigma <= 0.0:
        return 4
    return int(min(8, max(0, 1 - math.floor(math.log10(sigma)))))


def _value(value: float, sigma: float) -> tuple[str, str]:
    if math.isnan(value):
        return "not estimated", ""
    d = decimals(sigma)
    return f"{value:.{d}f}", f"{sigma:.{d}f}"


def _estimate_rows(e: Estimate) -> list[str]:
    value, sigma = e.user()
    written = "yes" if e.written else "no"
    rows = []
    if value.ndim == 1:
        cells = [(AXES[i], value[i], sigma[i]) for i in range(3)]
    else:
        cells = [
            (AXES[i] + AXES[j], value[i, j], sigma[i, j])
            for i in range(3)
            for j in range(3)
            if i != j or e.quantity.key.startswith("g_sensitivity")
        ]
    for axis, v, s in cells:
        text, sigma_text = _value(float(v), float(s))
        rows.append(
            f"| {e.quantity.label} | {axis} | {text} | {sigma_text} | {e.quantity.unit_text}"
            f" | {written} | {e.source} |"
        )
    return rows


def _vector(values: np.ndarray, scale: float, digits: int) -> str:
    return ", ".join(f"{v * scale:.{digits}f}" for v in values)


def segment_rows(result: CalibrationResult, records: Sequence[ImuRecord]) -> list[str]:
    """The segments table."""
    lines = [
        "| # | bag | from [s] | to [s] | duration [s] | kind | label | mean f x, y, z [m/s²]"
        " | σ of mean f [mg] | mean ω x, y, z [deg/s] | σ of mean ω [deg/h] | temperature [°C] |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for k, (s, label) in enumerate(zip(result.segments, result.labels, strict=True)):
        record = records[s.record]
        t0 = s.t_start_s - s.record_start_s
        t1 = s.t_end_s - s.record_start_s
        temperature = record.temperature_range(s.t_start_s, s.t_end_s)
        temp = "—" if temperature is None else f"{temperature[0]:.1f}-{temperature[1]:.1f}"
        m = s.means
        lines.append(
            f"| {k + 1} | {record.name} | {t0:.1f} | {t1:.1f} | {s.duration_s:.1f} | {s.kind.value}"
            f" | {label} | {_vector(m.force_m_s2, 1.0, 4)}"
            f" | {_vector(m.force_sigma_m_s2, 1.0 / _MG, 3)} | {_vector(m.rate_rad_s, _DEG, 4)}"
            f" | {_vector(m.rate_sigma_rad_s, _DEG * 3600.0, 1)} | {temp} |"
        )
    return lines


def _axes_section(check: AxisCheck) -> list[str]:
    verdict = "agree" if check.agrees else "**disagree**"
    lines = [
        "## Axis mapping",
        "",
        f"- found: `axis_map: {list(check.found.spec)}`, `accel_sign: {check.found_accel_sign:g}`",
        f"- driver: `axis_map: {list(check.driver.spec)}`,"
        f" `accel_sign: {check.driver_accel_sign:g}` — they {verdict}",
        "- published accelerometer axes from the case axes (P_a):"
        f" {check.accel_matrix.astype(int).tolist()}",
        f"- handedness of the gyro axes against the driver's from {check.evidence}:"
        f" {'mirrored' if check.gyro_mirrored else 'same'}",
    ]
    if not check.found.proper:
        lines.append("- the found mapping is a mirror image (left-handed device frame)")
    if check.turns:
        lines += [
            "",
            "| after segment | turn [deg] | mismatch, same handedness [deg]"
            " | mismatch, mirrored [deg] |",
            "|---|---|---|---|",
        ]
        lines += [
            f"| {t.before + 1} | {t.angle_deg:.1f} | {t.mismatch_same_deg:.1f}"
            f" | {t.mismatch_mirror_deg:.1f} |"
            for t in check.turns
        ]
    return [*lines, ""]


def write_report(
    result: CalibrationResult,
    records: Sequence[ImuRecord],
    settings: Sequence[tuple[str, str]],
    axes: AxisCheck | None = None,
    plot_name: str | None = None,
) -> str:
    """The report as markdown text; ``settings`` are (name, text) rows for its top table."""
    lines = [f"# IMU calibration: {METHOD_TITLES[result.method]}", "", "| | |", "|---|---|"]
    lines += [f"| {name} | {text} |" for name, text in settings]
    lines.append("")
    if axes is not None:
        lines += _axes_section(axes)
    if result.estimates:
        lines += [
            "## Estimates (value ± 1σ, imu_link FLU)",
            "",
            "| term | axis | value | σ | unit | written | method, equations |",
            "|---|---|---|---|---|---|---|",
        ]
        for e in result.estimates:
            lines += _estimate_rows(e)
        lines.append("")
    lines += ["## Segments used", "", *segment_rows(result, records), ""]
    if plot_name:
        lines += [f"![segments]({plot_name})", ""]
    if result.residuals:
        lines += [
            "## Residuals",
            "",
            "| segment | label | observed | residual | unit | residual/σ |",
            "|---|---|---|---|---|---|",
        ]
        lines += [
            f"| {r.segment + 1} | {result.labels[r.segment]} | {r.observed}"
            f" | {r.value if abs(r.normalized) > 1e-6 else 0.0:.4g} | {r.unit}"
            f" | {r.normalized:+.2f} |"
            for r in result.residuals
        ]
        lines.append("")
    if result.fits:
        lines += ["| fit | χ² | degrees of freedom |", "|---|---|---|"]
        lines += [f"| {f.name} | {f.chi2:.2f} | {f.dof} |" for f in result.fits]
        lines.append("")
    if result.notes:
        lines += ["## Notes", "", *[f"- {note}" for note in result.notes], ""]
    return "\n".join(lines)
