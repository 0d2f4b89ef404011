"""One replay: engine run, evaluation against the reference, report (shared by the single run
and every run of a sweep)."""

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

#: Reference stamps are evaluated between solutions at most this many output periods apart
#: (and at least 0.5 s): interpolation does not bridge gaps in the recorded solution.
_MAX_GAP_PERIODS = 2.5


@dataclass(frozen=True)
class Replay:
    """Everything one replay produced."""

    run: FusionRun
    evaluation: Evaluation | None
    report: Report


def replay(
    inputs: ReplayInputs,
    parameters: Mapping[str, Any],
    outages: Sequence[Outage],
    reference: str | None,
    progress: Callable[[int, int], None] | None = None,
) -> Replay:
    """Run the engine with the flat ``parameters`` over ``inputs`` and evaluate it when the
    inputs hold a reference (``reference``: its prefix, for the report)."""
    run = run_fusion(inputs, parameters, outages, progress)
    evaluation = None
    if inputs.reference is not None and run.datum is not None:
        max_gap_s = max(0.5, _MAX_GAP_PERIODS / run.output_rate_hz)
        evaluation = evaluate(
            run.track, inputs.reference, run.datum, inputs.t0_s, outages, max_gap_s
        )
    changed = changed_parameters(parameters)
    report = build_report(inputs, run, evaluation, outages, changed, reference)
    return Replay(run, evaluation, report)
