"""The replay report: one JSON-ready dict per run, and its short printed table.

Times are seconds after the first IMU stamp; errors are estimate minus reference (see
ins_fusion.replay.metrics). Keys (docs/replay.md describes each): bag, topics, parameters (those
differing from the defaults), imu_samples, duration_s, read_time_s, fusion_time_s, wall_time_s,
realtime_factor, aligned_at_s, final_state, resets, last_reset_reason, warnings (set-up problems
the engine found, e.g. a unit levelled upside down), datum, reference,
reference_frame (the frame compared in: base_link, or the IMU's for a reference of the IMU),
reference_frame_id (the reference's own), dropped_messages, measurements, evaluated_samples,
position_error_m, velocity_error_m_s, attitude_error_deg, outages, nees (position and attitude,
``_nees``), withheld_fixes (per
outage: the fused antenna against the GNSS fixes the outage withheld,
ins_fusion.replay.withheld; with or without a reference), and with smoothing ``smoothed``: the
same accuracy keys for the RTS-smoothed track, with its epochs and the backward pass's time.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ins_fusion.replay import metrics
from ins_fusion.replay.inputs import ReplayInputs
from ins_fusion.replay.metrics import Evaluation
from ins_fusion.replay.outages import Outage
from ins_fusion.replay.run import FusionRun, SolutionTrack
from ins_fusion.replay.withheld import WithheldEvaluation, withheld_stats

Report = dict[str, Any]


def build_report(
    inputs: ReplayInputs,
    run: FusionRun,
    evaluation: Evaluation | None,
    outages: Sequence[Outage],
    parameters: Mapping[str, Any],
    reference: str | None,
    withheld: WithheldEvaluation | None = None,
    reference_frame: str = "base_link",
) -> Report:
    """The report of one run (``parameters``: the settings that differ from the defaults;
    ``reference``: the reference prefix evaluated against, None for no evaluation;
    ``withheld``: the comparison with the withheld fixes, None when there was none;
    ``reference_frame``: the frame the fused solution was compared in)."""
    wall = inputs.read_time_s + run.fusion_time_s
    track = run.track
    aligned = np.flatnonzero(track.aligned)
    report: Report = {
        "bag": inputs.bag,
        "topics": inputs.roles_read(),
        "parameters": dict(parameters),
        "imu_samples": len(inputs.imu),
        "duration_s": inputs.duration_s,
        "read_time_s": inputs.read_time_s,
        "fusion_time_s": run.fusion_time_s,
        "wall_time_s": wall,
        "realtime_factor": inputs.duration_s / wall if wall > 0.0 else None,
        "aligned_at_s": float(track.t_s[aligned[0]] - inputs.t0_s) if aligned.size else None,
        "final_state": run.status.state,
        "resets": run.status.resets,
        "last_reset_reason": run.status.last_reset_reason,
        "warnings": list(run.status.warnings),
        "datum": None if run.datum is None else list(run.datum),
        "reference": reference if evaluation is not None else None,
        "reference_frame": reference_frame if evaluation is not None else None,
        "reference_frame_id": None
        if evaluation is None or inputs.reference is None
        else inputs.reference.frame_id,
        "dropped_messages": dict(run.dropped),
        "measurements": {name: dict(c) for name, c in run.status.measurements.items()},
        # The noise the engine adapted to and its self-calibration at the end
        # (InsEngine.adapted_noise, InsEngine.self_calibration; NaN -> None).
        "adapted_noise": _finite(run.status.adapted),
        "self_calibration": _finite(run.status.calibration),
    }
    report.update(_accuracy(evaluation, outages))
    scored = withheld if withheld is not None else WithheldEvaluation.empty()
    report["withheld_fixes"] = [withheld_stats(scored, o) for o in outages]
    return report


def smoothed_report(
    track: SolutionTrack,
    smoothing_time_s: float,
    evaluation: Evaluation | None,
    outages: Sequence[Outage],
    withheld: WithheldEvaluation | None,
) -> Report:
    """The ``smoothed`` section: epochs of the smoothed track, the backward pass's wall time
    [s], and the accuracy keys of the forward report (None values without a reference)."""
    scored = withheld if withheld is not None else WithheldEvaluation.empty()
    return {
        "epochs": len(track.t_s),
        "smoothing_time_s": smoothing_time_s,
        **_accuracy(evaluation, outages),
        "withheld_fixes": [withheld_stats(scored, o) for o in outages],
    }


def _accuracy(evaluation: Evaluation | None, outages: Sequence[Outage]) -> Report:
    """The error and consistency sections (None values without a reference)."""
    if evaluation is None:
        empty = metrics.Errors.empty()
        return {
            "evaluated_samples": 0,
            "position_error_m": metrics.position_stats(empty),
            "velocity_error_m_s": None,
            "attitude_error_deg": None,
            "outages": [metrics.outage_stats(empty, o) for o in outages],
            "nees": _nees(empty, None),
        }
    position = evaluation.position
    return {
        "evaluated_samples": len(position.t_rel_s),
        "position_error_m": metrics.position_stats(position),
        "velocity_error_m_s": None
        if evaluation.velocity is None
        else metrics.velocity_stats(evaluation.velocity),
        "attitude_error_deg": None
        if evaluation.attitude is None
        else metrics.attitude_stats(evaluation.attitude),
        "outages": [metrics.outage_stats(position, o) for o in outages],
        "nees": _nees(position, evaluation.attitude),
    }


def _nees(position: metrics.Errors, attitude: metrics.Errors | None) -> Report:
    """The position and attitude consistency (``_consistency``) over every stamp, and
    separately inside and outside the outages."""
    return {
        "dof": metrics.NEES_DOF,
        **_consistency(position, attitude, None),
        "in_outage": _consistency(position, attitude, True),
        "out_of_outage": _consistency(position, attitude, False),
    }


def _consistency(
    position: metrics.Errors, attitude: metrics.Errors | None, in_outage: bool | None
) -> Report:
    """position_mean (NEES), position_within_3sigma_fraction (every ENU component) and samples;
    attitude_mean (NEES of roll, pitch, yaw), attitude_within_3sigma_fraction,
    yaw_within_3sigma_fraction and attitude_samples (None and 0 without an attitude
    reference); over the stamps inside (``in_outage`` True) or outside (False) the outages, or
    all of them (None)."""

    def stats(errors: metrics.Errors) -> Report:
        select = None if in_outage is None else errors.in_outage == in_outage
        return metrics.consistency_stats(errors, select)

    pos = stats(position)
    att = stats(attitude if attitude is not None else metrics.Errors.empty())
    return {
        "position_mean": pos["mean"],
        "position_within_3sigma_fraction": pos["within_3sigma_fraction"],
        "samples": pos["samples"],
        "attitude_mean": att["mean"],
        "attitude_within_3sigma_fraction": att["within_3sigma_fraction"],
        "yaw_within_3sigma_fraction": att["axis_within_3sigma_fraction"][2],
        "attitude_samples": att["samples"],
    }


def _plain(value: Any) -> Any:
    """JSON-safe copy: numpy scalars to Python numbers, NaN and infinities to None."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def to_json(report: Report) -> str:
    """The report as indented JSON (strict: no NaN)."""
    return json.dumps(_plain(report), indent=2, allow_nan=False) + "\n"


def _num(value: Any, digits: int = 3) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


def _percent(value: Any) -> str:
    return "-" if value is None else f"{100.0 * value:.1f}%"


def _accuracy_lines(report: Report) -> list[str]:
    """Errors, consistency and outage rows of a report (or its smoothed section) with a
    reference."""
    pos, att, nees = report["position_error_m"], report["attitude_error_deg"], report["nees"]
    lines = [
        f"position error [m]    horizontal rms {_num(pos['horizontal_rms'])}"
        f"  p95 {_num(pos['horizontal_p95'])}  max {_num(pos['horizontal_max'])}"
        f"  vertical rms {_num(pos['vertical_rms'])}"
    ]
    if att is not None:
        lines.append(
            f"attitude error [deg]  roll rms {_num(att['roll_rms'])}"
            f"  pitch rms {_num(att['pitch_rms'])}  yaw rms {_num(att['yaw_rms'])}"
        )
    lines.append(
        f"position NEES (dof {nees['dof']})  mean {_num(nees['position_mean'], 2)}"
        f" ({_percent(nees['position_within_3sigma_fraction'])} within 3σ);"
        f" in outages {_num(nees['in_outage']['position_mean'], 2)}"
        f" ({_percent(nees['in_outage']['position_within_3sigma_fraction'])});"
        f" outside {_num(nees['out_of_outage']['position_mean'], 2)}"
        f" ({_percent(nees['out_of_outage']['position_within_3sigma_fraction'])})"
    )
    if att is not None:
        parts = [nees, nees["in_outage"], nees["out_of_outage"]]
        mean, within, yaw = (
            [_num(p["attitude_mean"], 2) for p in parts],
            [_percent(p["attitude_within_3sigma_fraction"]) for p in parts],
            [_percent(p["yaw_within_3sigma_fraction"]) for p in parts],
        )
        lines.append(
            f"attitude NEES (dof {nees['dof']})  mean {mean[0]} ({within[0]} within 3σ,"
            f" yaw {yaw[0]}); in outages {mean[1]} ({within[1]}, yaw {yaw[1]});"
            f" outside {mean[2]} ({within[2]}, yaw {yaw[2]})"
        )
    if report["outages"]:
        lines.append("outage  start s  length s  end horiz m  end 1σ m  max horiz m  max vert m")
        lines.extend(
            f"{i:>6}  {o['start_s']:>7.1f}  {o['duration_s']:>8.1f}"
            f"  {_num(o['horizontal_error_end_m']):>11}  {_num(o['horizontal_sigma_end_m']):>8}"
            f"  {_num(o['horizontal_error_max_m']):>11}  {_num(o['vertical_error_max_m']):>10}"
            for i, o in enumerate(report["outages"], 1)
        )
    return lines


def _withheld_lines(report: Report) -> list[str]:
    """Per outage: the fused antenna against the withheld GNSS fixes (NEES with P + R_fix)."""
    rows = report.get("withheld_fixes") or []
    if not rows:
        return []
    lines = [
        "withheld fixes (fused antenna - fix; the fixes carry their own error)",
        "outage  start s  length s    fixes  end horiz m  end 1σ m  max horiz m  max vert m"
        "  NEES (3)   in 3σ",
    ]
    lines.extend(
        f"{i:>6}  {o['start_s']:>7.1f}  {o['duration_s']:>8.1f}"
        f"  {str(o['evaluated_fixes']) + '/' + str(o['withheld_fixes']):>7}"
        f"  {_num(o['horizontal_error_end_m']):>11}  {_num(o['horizontal_sigma_end_m']):>8}"
        f"  {_num(o['horizontal_error_max_m']):>11}  {_num(o['vertical_error_max_m']):>10}"
        f"  {_num(o['nees']['mean'], 2):>8}  {_percent(o['nees']['within_3sigma_fraction']):>7}"
        for i, o in enumerate(rows, 1)
    )
    return lines


def format_table(report: Report) -> str:
    """A short human-readable summary of a report."""
    lines = [
        f"replay {report['bag']}: {report['imu_samples']} IMU samples, "
        f"{report['duration_s']:.1f} s in {report['wall_time_s']:.2f} s "
        f"({_num(report['realtime_factor'], 0)}x real time); aligned at "
        f"{_num(report['aligned_at_s'], 1)} s, final state {report['final_state']}, "
        f"{report['resets']} resets",
    ]
    lines += [f"WARNING: {warning}" for warning in report.get("warnings", ())]
    withheld = _withheld_lines(report)
    if report["reference"] is None:
        note = " (withheld fixes below)" if withheld else ""
        lines.append(f"no reference: accuracy not evaluated{note}")
    else:
        frame, frame_id = report.get("reference_frame"), report.get("reference_frame_id")
        if frame != "base_link" or frame_id != frame:
            lines.append(
                f"reference {report['reference']}: frame_id {frame_id!r}, compared in {frame}"
            )
        lines += _accuracy_lines(report)
    lines += withheld
    smoothed = report.get("smoothed")
    if smoothed is not None:
        lines.append(
            f"smoothed (RTS, backward pass over {smoothed['epochs']} epochs in"
            f" {smoothed['smoothing_time_s']:.2f} s):"
        )
        if report["reference"] is not None:
            lines += ["  " + line for line in _accuracy_lines(smoothed)]
        lines += ["  " + line for line in _withheld_lines(smoothed)]
    lines += _adapted_lines(report)
    lines += _calibration_lines(report)
    counters = report["measurements"]
    width = max(len("measurement"), *(len(n) for n in counters)) if counters else 11
    lines.append(f"{'measurement':<{width}}  {'used':>7}  {'rejected':>8}")
    lines.extend(
        f"{name:<{width}}  {c.get('used', 0):>7}  {c.get('rejected', 0):>8}"
        for name, c in counters.items()
    )
    return "\n".join(lines)


def _adapted_lines(report: Report) -> list[str]:
    """The adapted noise next to nothing else: what the filter ended up believing."""
    adapted = report.get("adapted_noise")
    if not adapted:
        return []

    def axes(prefix: str, suffix: str, names: str) -> str:
        return "/".join(_num(adapted.get(f"{prefix}_{a}_{suffix}"), 3) for a in names)

    return [
        f"adapted noise  gyro ARW {axes('gyro_arw', 'deg_sqrt_h', 'xyz')} deg/√h  "
        f"accel VRW {axes('accel_vrw', 'm_s_sqrt_h', 'xyz')} m/s/√h  "
        f"GNSS white σ {axes('gnss_white_sigma', 'm', 'enu')} m"
    ]


def _finite(values: dict[str, float]) -> dict[str, float | None]:
    return {name: value if math.isfinite(value) else None for name, value in values.items()}


def _calibration_lines(report: Report) -> list[str]:
    """The self-calibration, and the parameters that hold it, for the user to copy."""
    cal = report.get("self_calibration") or {}
    lines = []
    if cal.get("time_offset_s") is not None:
        lines.append(
            f"IMU time offset  {1e3 * cal['time_offset_s']:.1f} ms (residual "
            f"{1e3 * cal['time_offset_residual_s']:.1f} ± {1e3 * cal['time_offset_sigma_s']:.1f}"
            f" ms 1σ)  ->  imu_time_offset: {cal['time_offset_s']:.4f}"
        )
    if cal.get("speed_scale_error_pct") is not None:
        lines.append(
            f"vehicle speed scale error  {cal['speed_scale_error_pct']:.2f} ± "
            f"{cal['speed_scale_sigma_pct']:.2f} % (1σ; measured / true - 1)"
        )
    if cal.get("imu_mounting_pitch_deg") is not None:
        rpy = ", ".join(f"{cal[f'imu_mounting_{a}_deg']:.2f}" for a in ("roll", "pitch", "yaw"))
        lines.append(
            f"IMU mounting residual  pitch {cal['mounting_pitch_residual_deg']:.2f} ± "
            f"{cal['mounting_pitch_sigma_deg']:.2f}°  yaw {cal['mounting_yaw_residual_deg']:.2f}"
            f" ± {cal['mounting_yaw_sigma_deg']:.2f}° (1σ)  ->  imu_mounting_rpy_deg: [{rpy}]"
        )
    return lines
