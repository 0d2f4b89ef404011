"""One replay: engine run, evaluation against the reference and against the withheld fixes,
report (shared by the single run and every run of a sweep)."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from ins_fusion.replay.inputs import ReplayInputs
from ins_fusion.replay.metrics import Evaluation, evaluate
from ins_fusion.replay.outages import Outage
from ins_fusion.replay.report import Report, build_report
from ins_fusion.replay.run import FusionRun, run_fusion
from ins_fusion.replay.settings import changed_parameters
from ins_fusion.replay.withheld import WithheldEvaluation, evaluate_withheld

#: Reference stamps are evaluated between solutions at most this many output periods apart
#: (and at least 0.5 s): interpolation does not bridge gaps in the recorded solution.
_MAX_GAP_PERIODS = 2.5


@dataclass(frozen=True)
class Replay:
    """Everything one replay produced."""

    run: FusionRun
    evaluation: Evaluation | None
    withheld: WithheldEvaluation | None
    report: Report


def replay(
    inputs: ReplayInputs,
    parameters: Mapping[str, Any],
    outages: Sequence[Outage],
    reference: str | None,
    progress: Callable[[int, int], None] | None = None,
) -> Replay:
    """Run the engine with the flat ``parameters`` over ``inputs``, evaluate it when the inputs
    hold a reference (``reference``: its prefix, for the report), and compare it with the GNSS
    fixes the outages withheld."""
    run = run_fusion(inputs, parameters, outages, progress)
    evaluation = withheld = None
    max_gap_s = max(0.5, _MAX_GAP_PERIODS / run.output_rate_hz)
    if inputs.reference is not None and run.datum is not None:
        evaluation = evaluate(
            run.track, inputs.reference, run.datum, inputs.t0_s, outages, max_gap_s
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
    report = build_report(inputs, run, evaluation, outages, changed, reference, withheld)
    return Replay(run, evaluation, withheld, report)
