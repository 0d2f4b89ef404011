"""Parameter sweeps: replay every setting of a grid and rank the settings by one metric.

One task per setting on a Dask cluster (ins_fusion.runtime.cluster: a LocalCluster of one
process per core, at most one per setting, or the scheduler given); the inputs are read once
and sent to every worker. Scores: ins_fusion.replay.ranking.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from ins_fusion.replay.inputs import ReplayInputs
from ins_fusion.replay.outages import Outage
from ins_fusion.replay.pipeline import replay
from ins_fusion.replay.ranking import RANK_METRICS
from ins_fusion.replay.report import Report
from ins_fusion.runtime.cluster import cluster, completed, submit_each


@dataclass(frozen=True)
class SweepResult:
    """One setting of the grid, its report and its score (None: not measurable)."""

    setting: dict[str, Any]
    report: Report
    score: float | None


def _run_setting(
    inputs: ReplayInputs,
    parameters: dict[str, Any],
    outages: tuple[Outage, ...],
    reference: str | None,
) -> Report:
    return replay(inputs, parameters, outages, reference).report


def run_sweep(
    inputs: ReplayInputs,
    base: Mapping[str, Any],
    settings: Sequence[dict[str, Any]],
    outages: Sequence[Outage],
    reference: str | None,
    rank_by: str,
    workers: int | None = None,
    progress: Callable[[int, int], None] | None = None,
    scheduler: str | None = None,
) -> list[SweepResult]:
    """Replay ``base`` updated with each setting; results best first (unscored last).

    ``scheduler``: a Dask scheduler's address, None for a LocalCluster of ``workers`` processes
    (default: one per core, at most one per setting). A run that raises raises here.
    """
    score = RANK_METRICS[rank_by][0]
    count = len(settings)
    results: list[SweepResult] = []
    with cluster(scheduler, workers, count) as client:
        shared = client.scatter(inputs, broadcast=True)
        arguments = {
            index: (shared, {**base, **setting}, tuple(outages), reference)
            for index, setting in enumerate(settings)
        }
        futures = submit_each(client, _run_setting, arguments)
        for done, (index, report, error) in enumerate(completed(futures), 1):
            if error is not None:
                raise error
            results.append(SweepResult(settings[index], report, score(report)))
            if progress is not None:
                progress(done, count)
    return sorted(results, key=lambda r: (r.score is None, r.score or 0.0))


def _value(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, list):
        return "[" + ",".join(_value(v) for v in value) + "]"
    return str(value)


def _cell(value: float | None) -> str:
    return "-" if value is None else f"{value:.4g}"


#: Metrics shown next to the score in the sweep table: (column title, RANK_METRICS name).
_HEADLINES = (
    ("horiz rms m", "horizontal_rms"),
    ("yaw rms deg", "yaw_rms"),
    ("outage end m", "outage_end_max"),
    ("withheld end m", "withheld_end_max"),
)


def format_sweep(results: Sequence[SweepResult], rank_by: str) -> str:
    """Ranked table: setting, score, a few headline metrics and the NEES mean per run."""
    if not results:
        return "no runs"
    names = list(results[0].setting)
    header = ["rank", *names, "score", *(title for title, _ in _HEADLINES), "NEES mean"]
    rows = [header]
    for rank, result in enumerate(results, 1):
        report = result.report
        rows.append(
            [
                str(rank),
                *(_value(result.setting[name]) for name in names),
                _cell(result.score),
                *(_cell(RANK_METRICS[key][0](report)) for _, key in _HEADLINES),
                _cell(report["nees"]["position_mean"]),
            ]
        )
    widths = [max(len(row[i]) for row in rows) for i in range(len(header))]
    lines = [f"ranked by {rank_by}: {RANK_METRICS[rank_by][1]} (lower is better)"]
    lines += ["  ".join(c.rjust(w) for c, w in zip(row, widths, strict=True)) for row in rows]
    return "\n".join(lines)
