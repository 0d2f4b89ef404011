"""`gnss_ins batch`: many bags replayed with the same options on a Dask cluster.

Each bag (a rosbag2 directory or storage file; shell globs are expanded, also when quoted) is
one task running ``gnss_ins replay`` with the options of this command (``--params``, ``--set``,
``--outage``, ``--smooth``, ...). Its results go to ``DIR/<bag name>/``: ``report.json``
(what ``gnss_ins replay --report`` writes for that bag alone), ``plot.png`` (unless
``--no-plot``), each ``--export NAME``, ``replay.log`` (the replay's printed table and notes)
and ``outcome.json``. ``DIR/summary.csv`` (and ``.parquet`` with pandas and pyarrow installed),
``DIR/summary.png`` and the printed table summarise every bag, a failed one with its error.

A local cluster of ``--workers`` processes by default; ``--scheduler tcp://HOST:PORT`` uses the
workers of a running Dask scheduler (docs/fleet.md). A rerun skips the bags done (``--force``
redoes them, ``--retry-failed`` those that failed), so an interrupted batch completes when run
again. Exit status 0 all replayed, 1 some bag failed or had no solution, 2 bad input, 130
interrupted.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ins_fusion.tools.replay import add_arguments as add_replay_arguments
from ins_fusion.tools.replay import add_cluster_options, add_replay_options

if TYPE_CHECKING:
    from ins_fusion.fleet.batch import BatchPlan


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``gnss_ins batch``."""
    parser.add_argument(
        "bags",
        nargs="+",
        metavar="BAG_OR_GLOB",
        help="rosbag2 bags (directories or storage files) or glob patterns of them",
    )
    parser.add_argument(
        "--out", type=Path, required=True, metavar="DIR", help="folder of the results"
    )
    add_replay_options(parser)
    parser.add_argument(
        "--export",
        action="append",
        default=[],
        metavar="NAME",
        help="write each bag's solution past alignment to NAME in its folder, .csv, .gpx or "
        ".nmea by suffix (repeatable)",
    )
    parser.add_argument("--no-plot", action="store_true", help="no plot.png per bag")
    add_cluster_options(parser, "bags")
    parser.add_argument("--force", action="store_true", help="replay the bags done already too")
    parser.add_argument(
        "--retry-failed", action="store_true", help="replay the bags that failed last time again"
    )


def _plain(value: Any) -> Any:
    """JSON-ready form of an option's value."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return dataclasses.asdict(value)
    return str(value)


def _plan(args: argparse.Namespace) -> BatchPlan:
    """The BatchPlan of the command line (UsageError, BatchError on bad input)."""
    from ins_fusion.fleet.batch import BatchPlan, find_bags
    from ins_fusion.fleet.store import OUTCOME
    from ins_fusion.fleet.task import LOG, PLOT, REPORT
    from ins_fusion.replay.command import UsageError, check_options

    shared = add_replay_options(argparse.ArgumentParser())
    replay_parser = argparse.ArgumentParser()
    add_replay_arguments(replay_parser)
    template = replay_parser.parse_args(["-"])
    for dest in shared:
        setattr(template, dest, getattr(args, dest))
    if template.params is not None:  # the workers' working directory is another
        template.params = template.params.absolute()
    for name in args.export:
        if Path(name).name != name or name in (LOG, PLOT, REPORT, OUTCOME):
            raise UsageError(
                f"--export {name}: a file name of the bag's folder, not one of"
                f" {LOG}, {PLOT}, {REPORT}, {OUTCOME}, nor a path"
            )
    if args.workers is not None and args.workers < 1:
        raise UsageError("--workers must be at least 1")
    template.export = [Path(name) for name in args.export]
    check_options(template)
    template.export = []
    options = {dest: getattr(template, dest) for dest in shared}
    options.update(plot=not args.no_plot, exports=args.export)
    return BatchPlan(
        find_bags(args.bags),
        template,
        not args.no_plot,
        tuple(args.export),
        json.loads(json.dumps(options, default=_plain)),
    )


def run(args: argparse.Namespace) -> int:
    """Replay the bags; 0 all replayed, 1 some failed, 2 bad input, 130 interrupted."""
    from ins_fusion.fleet.batch import BatchError, run_batch
    from ins_fusion.fleet.store import StoreError
    from ins_fusion.replay.command import UsageError
    from ins_fusion.runtime.cluster import ClusterError

    try:
        plan = _plan(args)
        return run_batch(
            plan, args.out, args.scheduler, args.workers, args.force, args.retry_failed
        )
    except (UsageError, BatchError, StoreError, ClusterError) as exc:
        print(f"gnss_ins batch: error: {exc}", file=sys.stderr)
        return 2
