"""`gnss_ins batch` on a LocalCluster against the same bags replayed one after the other;
prints numbers, asserts nothing.

Eight simulated drives (test pattern, imu400cc, Leica RTK 1 Hz, ADU5 5 Hz, seeds 1-8, ``--duration``
s each, kept in ``--bags``) get the same per-bag work three ways, each a command started cold:

1. one after the other in one process: ``replay_bag`` (the batch's own task, ins_fusion.fleet.task)
   for each bag in a loop, start-up paid once;
2. ``gnss_ins replay`` once per bag (what a shell loop does today), for reference;
3. ``gnss_ins batch --workers N`` (default 2): a LocalCluster of N single-threaded processes.

The work per bag: an outage of 20 s at 100 s, the RTS smoother, the plot and a CSV export.
Then the per-task overhead of the engine: N x the batch's wall time minus the tasks' own
seconds (outcome.json), per task; the start of the LocalCluster alone; the round trip of an
empty task. The load averages before and after are printed: the machine may be shared.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from contextlib import redirect_stdout
from io import StringIO
from pathlib import Path

SEEDS = tuple(range(1, 9))
#: The replay options of every bag.
OPTIONS = ("--outage", "100:20", "--smooth")
EXPORT = "track.csv"


def _bags(root: Path, duration_s: float) -> list[Path]:
    """The eight bags (written when missing)."""
    from ins_fusion.sim.drive import SimulationConfig
    from ins_fusion.sim.simulated_bag import write_bag

    bags = []
    for seed in SEEDS:
        path = root / f"drive_{seed}_{duration_s:g}s"
        if not (path / "metadata.yaml").exists():
            with redirect_stdout(StringIO()):
                write_bag(SimulationConfig(duration_s=duration_s, seed=seed), path)
        bags.append(path)
    return bags


def _sequential(bags: list[str]) -> None:
    """Child mode: replay_bag for each bag, one after the other; prints each task's seconds."""
    from ins_fusion.fleet.task import replay_bag
    from ins_fusion.tools.replay import add_arguments

    parser = argparse.ArgumentParser()
    add_arguments(parser)
    template = parser.parse_args(["-", *OPTIONS])
    for bag in bags:
        result = replay_bag(template, bag, True, (EXPORT,))
        assert result.status == "ok", result.error
        print(f"{result.seconds:.3f} {result.cpu_seconds:.3f}")


def _timed(command: list[str]) -> tuple[float, str]:
    start = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(command)} failed:\n{done.stderr}")
    return wall, done.stdout


def _noop() -> None:
    return None


def _cluster_overhead(workers: int, tasks: int = 200) -> tuple[float, float, float]:
    """(seconds to start and stop the LocalCluster, round trip of one empty task, seconds per
    empty task when ``tasks`` are submitted at once)."""
    from ins_fusion.runtime.cluster import cluster, completed, submit_each

    start = time.perf_counter()
    with cluster(None, workers, workers) as client:
        started = time.perf_counter() - start
        client.submit(_noop, pure=False).result()
        one = time.perf_counter()
        for _ in range(20):
            client.submit(_noop, pure=False).result()
        round_trip = (time.perf_counter() - one) / 20
        many = time.perf_counter()
        for _ in completed(submit_each(client, _noop, {i: () for i in range(tasks)})):
            pass
        bulk = (time.perf_counter() - many) / tasks
        stopping = time.perf_counter()
    return started + time.perf_counter() - stopping, round_trip, bulk


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=300.0, help="seconds per drive")
    parser.add_argument("--workers", type=int, default=2, help="LocalCluster processes")
    parser.add_argument("--bags", type=Path, help="folder of the bags (default: temporary)")
    parser.add_argument("--sequential", nargs="+", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.sequential:
        _sequential(args.sequential)
        return
    with tempfile.TemporaryDirectory() as scratch:
        root = args.bags or Path(scratch) / "bags"
        root.mkdir(parents=True, exist_ok=True)
        bags = [str(p) for p in _bags(root, args.duration)]
        print(
            f"{len(bags)} bags of {args.duration:g} s, {os.cpu_count()} cores, load averages"
            f" before {' '.join(f'{x:.2f}' for x in os.getloadavg())}"
        )
        cli = [sys.executable, "-m", "ins_fusion.tools.cli"]
        sequential, out = _timed([sys.executable, __file__, "--sequential", *bags])
        task_s = [float(line.split()[0]) for line in out.splitlines()]
        cpu_s = sum(float(line.split()[1]) for line in out.splitlines())
        print(
            f"one after the other, one process:  {sequential:6.1f} s  (tasks {sum(task_s):.1f} s,"
            f" first {task_s[0]:.1f} s, the others {sum(task_s[1:]) / 7:.2f} s each)"
        )
        commands = 0.0
        for bag in bags:
            wall, _ = _timed(
                [
                    *cli,
                    "replay",
                    bag,
                    *OPTIONS,
                    "--report",
                    f"{scratch}/r.json",
                    "--plot",
                    f"{scratch}/p.png",
                    "--export",
                    f"{scratch}/{EXPORT}",
                ]
            )
            commands += wall
        print(f"gnss_ins replay per bag, in turn:   {commands:6.1f} s")
        out_dir = Path(scratch) / "batch"
        batch, _ = _timed(
            [
                *cli,
                "batch",
                *bags,
                "--out",
                str(out_dir),
                *OPTIONS,
                "--export",
                EXPORT,
                "--workers",
                str(args.workers),
            ]
        )
        outcomes = [json.loads((out_dir / Path(b).name / "outcome.json").read_text()) for b in bags]
        seconds = sum(o["seconds"] for o in outcomes)
        cpu_batch = sum(o["cpu_seconds"] for o in outcomes)
        print(
            f"gnss_ins batch --workers {args.workers}:         {batch:6.1f} s  (tasks "
            f"{seconds:.1f} s): {sequential / batch:.2f}x one process,"
            f" {commands / batch:.2f}x the replay commands"
        )
        print(
            f"the tasks' CPU: {cpu_s:.1f} s one after the other, {cpu_batch:.1f} s in the batch;"
            f" cores obtained over the wall time: {cpu_s / sequential:.2f} and"
            f" {cpu_batch / batch:.2f} (of {args.workers}: the rest went to the machine's other"
            " load)"
        )
        overhead = (args.workers * batch - seconds) / len(bags)
        print(
            f"per-task overhead of the batch: {overhead:.2f} s ({args.workers} x wall - tasks,"
            " per bag: cluster start, the workers' imports, summary, idle tail)"
        )
        start_stop, round_trip, bulk = _cluster_overhead(args.workers)
        print(
            f"LocalCluster of {args.workers}: start + stop {start_stop:.2f} s; an empty task"
            f" {1e3 * round_trip:.1f} ms round trip, {1e3 * bulk:.2f} ms each when 200 are"
            " submitted at once"
        )
        print(f"load averages after {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":  # the LocalCluster's workers are spawned: they import this module
    main()
