"""One replay: engine run, evaluation against the reference and against the withheld fixes,
report (shared by the single run and every run of a sweep)."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ins_fusion.core.config import FusionConfig
from ins_fusion.replay.frames import comparison_frame, is_imu_frame, moved_track
from ins_fusion.replay.inputs import ReplayInputs
from ins_fusion.replay.metrics import Evaluation, evaluate
from ins_fusion.replay.outages import Outage
from ins_fusion.replay.report import Report, build_report
from ins_fusion.replay.run import FusionRun, SolutionTrack, run_fusion
from ins_fusion.replay.settings import changed_parameters
from ins_fusion.replay.withheld import WithheldEvaluation, evaluate_withheld

#: Reference stamps are evaluated between solutions at most this many output periods apart
#: (and at least 0.5 s): interpolation does not bridge gaps in the recorded solution.
_MAX_GAP_PERIODS = 2.5


@dataclass(frozen=True)
class Replay:
    """Everything one replay produced; ``compared_track`` is the fused solution in the frame of
    the reference (``run.track`` of base_link unless the reference is of the IMU)."""

    run: FusionRun
    compared_track: SolutionTrack
    evaluation: Evaluation | None
    withheld: WithheldEvaluation | None
    report: Report


def reference_frame(inputs: ReplayInputs, config: FusionConfig) -> str | None:
    """The frame the reference is compared in (ins_fusion.replay.frames.comparison_frame): its
    frame_id when that is base_link or the IMU's, None when there is no reference or its frame
    is another (then base_link is compared as is)."""
    if inputs.reference is None:
        return None
    return comparison_frame(inputs.reference.frame_id, config.base_frame, inputs.imu_frame)


def replay(
    inputs: ReplayInputs,
    parameters: Mapping[str, Any],
    outages: Sequence[Outage],
    reference: str | None,
    progress: Callable[[int, int], None] | None = None,
) -> Replay:
    """Run the engine with the flat ``parameters`` over ``inputs``, evaluate it when the inputs
    hold a reference (``reference``: its prefix, for the report), and compare it with the GNSS
    fixes the outages withheld. A reference of the IMU (its frame_id is the IMU's) is compared
    with the solution moved to the IMU by ``imu_lever_arm`` and the mounting (the engine's estimate,
    else ``imu_mounting_rpy_deg``)
    (ins_fusion.replay.frames)."""
    run = run_fusion(inputs, parameters, outages, progress)
    evaluation = withheld = None
    max_gap_s = max(0.5, _MAX_GAP_PERIODS / run.output_rate_hz)
    frame = reference_frame(inputs, run.config)
    compared = run.track
    if is_imu_frame(frame, inputs.imu_frame):
        config = run.config
        configured = np.asarray(config.imu_mounting_rpy_rad, dtype=np.float64)
        mounting = np.array(  # the engine's estimate where it has one
            [
                configured if s.imu_mounting_rpy_rad is None else s.imu_mounting_rpy_rad
                for s in run.track.solutions
            ]
        ).reshape(-1, 3)
        compared = moved_track(run.track, config.imu_lever_arm_flu_m, mounting)
    if inputs.reference is not None and run.datum is not None:
        evaluation = evaluate(
            compared, inputs.reference, run.datum, inputs.t0_s, outages, max_gap_s
        )
    if outages and run.datum is not None:
        withheld = evaluate_withheld(
            run.track,
            run.withheld_fixes,
            run.datum,
            inputs.t0_s,
            run.config.gnss_lever_arm_flu_m,
            max_gap_s,
        )
    changed = changed_parameters(parameters)
    report = build_report(
        inputs,
        run,
        evaluation,
        outages,
        changed,
        reference,
        withheld,
        frame or run.config.base_frame,
    )
    return Replay(run, compared, evaluation, withheld, report)
