"""One replay: engine run, evaluation against the reference and against the withheld fixes,
report (shared by the single run and every run of a sweep)."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ins_fusion.core.settings.config import FusionConfig
from ins_fusion.replay.frames import comparison_frame, is_imu_frame, moved_track
from ins_fusion.replay.inputs import ReplayInputs
from ins_fusion.replay.metrics import Evaluation, evaluate
from ins_fusion.replay.outages import Outage
from ins_fusion.replay.report import Report, build_report, smoothed_report
from ins_fusion.replay.run import FusionRun, SolutionTrack, run_fusion
from ins_fusion.replay.settings import changed_parameters
from ins_fusion.replay.withheld import WithheldEvaluation, evaluate_withheld

#: Reference stamps are evaluated between solutions at most this many output periods apart
#: (and at least 0.5 s): interpolation does not bridge gaps in the recorded solution.
_MAX_GAP_PERIODS = 2.5


@dataclass(frozen=True)
class Scored:
    """One track scored: ``compared`` is it in the frame of the reference (the track itself,
    of base_link, unless the reference is of the IMU), ``evaluation`` against the reference
    and ``withheld`` against the fixes the outages withheld (None where there is none)."""

    compared: SolutionTrack
    evaluation: Evaluation | None
    withheld: WithheldEvaluation | None


@dataclass(frozen=True)
class Replay:
    """Everything one replay produced; ``compared_track`` is the fused solution in the frame of
    the reference (``run.track`` of base_link unless the reference is of the IMU); ``smoothed``:
    the RTS-smoothed track scored the same way (None without smoothing)."""

    run: FusionRun
    compared_track: SolutionTrack
    evaluation: Evaluation | None
    withheld: WithheldEvaluation | None
    report: Report
    smoothed: Scored | None = None


def reference_frame(inputs: ReplayInputs, config: FusionConfig) -> str | None:
    """The frame the reference is compared in (ins_fusion.replay.frames.comparison_frame): its
    frame_id when that is base_link or the IMU's, None when there is no reference or its frame
    is another (then base_link is compared as is)."""
    if inputs.reference is None:
        return None
    return comparison_frame(inputs.reference.frame_id, config.base_frame, inputs.imu_frame)


def _score(
    inputs: ReplayInputs,
    run: FusionRun,
    track: SolutionTrack,
    outages: Sequence[Outage],
    max_gap_s: float,
) -> Scored:
    """Evaluate a track of the run against the reference (moved to the reference's frame
    first) and against the withheld fixes."""
    evaluation = withheld = None
    frame = reference_frame(inputs, run.config)
    compared = track
    if is_imu_frame(frame, inputs.imu_frame):
        config = run.config
        configured = np.asarray(config.imu_mounting_rpy_rad, dtype=np.float64)
        estimated = track.imu_mounting_rpy_rad  # the engine's estimate where it has one
        mounting = np.where(np.isnan(estimated), configured, estimated)
        compared = moved_track(
            track, config.imu_lever_arm_flu_m, mounting, track.cov_att_imu_enu_rad2
        )
    if inputs.reference is not None and run.datum is not None:
        evaluation = evaluate(
            compared, inputs.reference, run.datum, inputs.t0_s, outages, max_gap_s
        )
    if outages and run.datum is not None:
        withheld = evaluate_withheld(
            track,
            run.withheld_fixes,
            run.datum,
            inputs.t0_s,
            run.config.gnss_lever_arm_flu_m,
            max_gap_s,
        )
    return Scored(compared, evaluation, withheld)


def replay(
    inputs: ReplayInputs,
    parameters: Mapping[str, Any],
    outages: Sequence[Outage],
    reference: str | None,
    progress: Callable[[int, int], None] | None = None,
    smooth: bool = False,
) -> Replay:
    """Run the engine with the flat ``parameters`` over ``inputs``, evaluate it when the inputs
    hold a reference (``reference``: its prefix, for the report), and compare it with the GNSS
    fixes the outages withheld. A reference of the IMU (its frame_id is the IMU's) is compared
    with the solution moved to the IMU by ``imu_lever_arm`` and the mounting (the engine's estimate,
    else ``imu_mounting_rpy_deg``), with the IMU's own attitude covariance
    (ins_fusion.replay.frames). ``smooth``: the RTS-smoothed track too, scored the same way,
    under ``smoothed`` in the report."""
    run = run_fusion(inputs, parameters, outages, progress, smooth)
    max_gap_s = max(0.5, _MAX_GAP_PERIODS / run.output_rate_hz)
    forward = _score(inputs, run, run.track, outages, max_gap_s)
    changed = changed_parameters(parameters)
    report = build_report(
        inputs,
        run,
        forward.evaluation,
        outages,
        changed,
        reference,
        forward.withheld,
        reference_frame(inputs, run.config) or run.config.base_frame,
    )
    smoothed = None
    if run.smoothed is not None:
        # The smoothed track is at the covariance steps: bridge the interval between them.
        gap_s = max(max_gap_s, _MAX_GAP_PERIODS * run.config.covariance_interval_s)
        smoothed = _score(inputs, run, run.smoothed, outages, gap_s)
        report["smoothed"] = smoothed_report(
            run.smoothed, run.smoothing_time_s, smoothed.evaluation, outages, smoothed.withheld
        )
    return Replay(run, forward.compared, forward.evaluation, forward.withheld, report, smoothed)
