"""``gnss_ins batch``: many bags replayed on a Dask cluster, one task per bag
(ins_fusion.fleet.task), each result saved atomically as it arrives (ins_fusion.fleet.store),
then the fleet summary of every bag asked for: the table printed, ``summary.csv``,
``summary.parquet`` (with pandas and pyarrow) and ``summary.png`` in the output folder.

A bag that fails is saved with its error and the others go on. Interrupted (Ctrl-C), the bags
saved so far stay; the same command replays the rest.
"""

from __future__ import annotations

import argparse
import glob
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ins_fusion.fleet.overview import overview_png
from ins_fusion.fleet.store import BatchStore, open_store, write_atomic
from ins_fusion.fleet.summary import Row, bag_row, format_summary, to_csv, to_parquet
from ins_fusion.fleet.task import BagResult, replay_bag
from ins_fusion.runtime.cluster import cluster, completed, submit_each
from ins_fusion.runtime.progress import Progress

SUMMARY_CSV = "summary.csv"
SUMMARY_PARQUET = "summary.parquet"
SUMMARY_PNG = "summary.png"


class BatchError(Exception):
    """Bad input of a batch (bags not found, two bags of one name)."""


@dataclass(frozen=True)
class BatchPlan:
    """What to replay: ``bags`` name -> absolute path, in the order given; ``template`` the
    ``gnss_ins replay`` arguments of every bag (its bag and outputs set per task); ``options``
    the batch's options as JSON-ready values (kept in the output folder)."""

    bags: dict[str, str]
    template: argparse.Namespace
    plot: bool
    exports: tuple[str, ...]
    options: dict[str, Any]


def find_bags(patterns: Sequence[str]) -> dict[str, str]:
    """name -> absolute path of each bag (directory or storage file) a pattern names or
    matches (shell globs); a bag's folder in the output is its name."""
    bags: dict[str, str] = {}
    for pattern in patterns:
        matches = sorted(glob.glob(pattern)) if glob.has_magic(pattern) else [pattern]
        if not matches:
            raise BatchError(f"{pattern} matches no bag")
        for match in matches:
            path = Path(match).absolute()
            if not path.exists():
                raise BatchError(f"{match}: no such bag")
            if path.name in bags and bags[path.name] != str(path):
                raise BatchError(
                    f"two bags named {path.name}: {bags[path.name]} and {path} (their results"
                    " would share a folder: run them in batches of their own)"
                )
            bags[path.name] = str(path)
    return bags


def run_batch(
    plan: BatchPlan,
    out: Path,
    scheduler: str | None,
    workers: int | None,
    force: bool = False,
    retry_failed: bool = False,
) -> int:
    """Replay the plan's bags not done yet in ``out``; 0 all replayed, 1 some failed or had
    no solution, 130 interrupted. StoreError, ClusterError: the folder or cluster is unusable."""
    with open_store(out, plan.options, force) as store:
        todo = store.pending(plan.bags, force, retry_failed)
        print(f"{len(plan.bags)} bags: {len(todo)} to replay, {len(plan.bags) - len(todo)} done")
        if todo:
            try:
                _replay(store, plan, todo, scheduler, workers)
            except KeyboardInterrupt:
                left = store.pending(plan.bags, False, False)
                print(
                    f"interrupted: {len(plan.bags) - len(left)} of {len(plan.bags)} bags done;"
                    " the same command replays the other "
                    f"{len(left)}",
                    file=sys.stderr,
                )
                return 130
        rows = _rows(store, plan)
    _write_summary(out, rows)
    print(format_summary(rows))
    return 0 if all(row["status"] == "ok" for row in rows) else 1


def _replay(
    store: BatchStore, plan: BatchPlan, todo: list[str], scheduler: str | None, workers: int | None
) -> None:
    arguments = {name: (plan.template, plan.bags[name], plan.plot, plan.exports) for name in todo}
    with (
        cluster(scheduler, workers, len(todo)) as client,
        Progress("batch", total=len(todo), unit="bags") as bar,
    ):
        futures = submit_each(client, replay_bag, arguments)
        for done, (name, result, error) in enumerate(completed(futures), 1):
            if error is not None:  # the task itself failed: its worker died, or the cluster
                result = BagResult(
                    plan.bags[name], "failed", f"{type(error).__name__}: {error}", 3, 0.0, 0.0, "-"
                )
            store.save(name, result)
            line = f"{name}: {result.status} ({result.seconds:.1f} s on {result.worker})"
            bar.message(line if result.error is None else f"{line}: {result.error}")
            bar.update(done, name)


def _rows(store: BatchStore, plan: BatchPlan) -> list[Row]:
    rows = []
    for name in plan.bags:
        outcome = store.outcome(name)
        assert outcome is not None  # every bag was saved
        rows.append(bag_row(name, outcome, store.report(name)))
    return rows


def _write_summary(out: Path, rows: list[Row]) -> None:
    write_atomic(out / SUMMARY_CSV, to_csv(rows))
    parquet = to_parquet(rows)
    if parquet is not None:
        write_atomic(out / SUMMARY_PARQUET, parquet)
    failed = sum(row["status"] != "ok" for row in rows)
    title = f"gnss_ins batch {out}: {len(rows)} bags, {failed} not replayed to the end"
    write_atomic(out / SUMMARY_PNG, overview_png(rows, title))
    print(f"summary: {out / SUMMARY_CSV}, {out / SUMMARY_PNG}")
