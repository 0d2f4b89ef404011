"""Where a whole `gnss_ins replay` spends its time; prints numbers, asserts nothing.

1. Without a profiler: CPU seconds of ``gnss_ins replay BAG --report FILE`` as a child process
   (resource.getrusage), and the read and fusion times its report gives (wall, one core).
2. cProfile of the same command in this process (``ins_fusion.tools.cli.main``): the cumulative
   time of each phase (read: load_bag; filter: run_fusion, with the engine's IMU step, its
   measurement updates, the solution rows and appending them to the track; metrics:
   evaluate and evaluate_withheld; report: build_report, the printed table and the JSON) and
   the rest (imports of the replay modules, parameter checks), then the functions with the most
   own time. The profiler's overhead per call inflates the filter, which makes many small
   calls, more than the vectorised phases: compare fractions with section 1.
3. A sampled profile of the same command (``--sample``): SIGPROF every millisecond of CPU
   (delivered at most every few ms by the kernel's timer), the Python stack at each signal;
   prints the share of the samples in which each engine function was on the stack (inclusive)
   and at its top (own). Nothing is added per call, so small functions are not inflated. A
   signal arriving in compiled code is taken when the kernel returns: kernel time shows as the
   caller's own time, or as numba's ``_numba_unpickle`` for kernels that return arrays.

Bag: bench/speed_bag.py (437 s test pattern, imu400cc 200 Hz, GNSS fix + velocity 5 Hz, truth
50 Hz) or ``--bag``. ``--profile FILE`` keeps the pstats file (e.g. for snakeviz).
"""

from __future__ import annotations

import argparse
import collections
import cProfile
import io
import json
import pstats
import resource
import signal
import subprocess
import tempfile
from contextlib import redirect_stdout
from pathlib import Path
from types import FrameType

from speed_bag import gnss_ins_command, simulated_bag

from ins_fusion.tools import cli

#: Phases: label -> (part of the module path, function name) whose cumulative time they are.
PHASES: dict[str, list[tuple[str, str]]] = {
    "read (load_bag)": [("replay/inputs.py", "load_bag")],
    "filter (run_fusion)": [("replay/run.py", "run_fusion")],
    "metrics (evaluate, withheld)": [
        ("replay/metrics.py", "evaluate"),
        ("replay/withheld.py", "evaluate_withheld"),
    ],
    "report (build, table, JSON)": [
        ("replay/report.py", "build_report"),
        ("replay/report.py", "format_table"),
        ("replay/command.py", "_write_report"),
    ],
}
#: Parts of the filter phase.
FILTER_PARTS: dict[str, list[tuple[str, str]]] = {
    "engine.add_imu": [("ins_fusion/core/", "add_imu")],
    "engine GNSS updates": [
        ("ins_fusion/core/", "add_gnss_fix"),
        ("ins_fusion/core/", "add_gnss_velocity"),
    ],
    "engine.solution_row": [("ins_fusion/core/", "solution_row")],
    "track rows (RowBuffer.append)": [("core/output/solution_rows.py", "append")],
}


def cumulative(stats: pstats.Stats, functions: list[tuple[str, str]]) -> float:
    """Sum of the cumulative times [s] of the functions named (part of the path, name)."""
    table = stats.stats  # type: ignore[attr-defined]
    return sum(
        entry[3]
        for (path, _, name), entry in table.items()
        if any(part in path and name == wanted for part, wanted in functions)
    )


def unprofiled(bag: Path, workdir: Path) -> None:
    report = workdir / "plain.json"
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    command = [*gnss_ins_command(), "replay", str(bag), f"--report={report}"]
    subprocess.run(command, check=True, stdout=subprocess.DEVNULL)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    data = json.loads(report.read_text())
    print(
        f"1. gnss_ins replay, no profiler: CPU {cpu:.2f} s; report: read {data['read_time_s']:.2f}"
        f" s, fusion {data['fusion_time_s']:.2f} s (wall), {data['imu_samples']} IMU samples"
    )


def profiled(bag: Path, workdir: Path, top: int, keep: Path | None) -> None:
    profiler = cProfile.Profile()
    with redirect_stdout(io.StringIO()):
        profiler.runcall(cli.main, ["replay", str(bag), f"--report={workdir / 'profiled.json'}"])
    stats = pstats.Stats(profiler)
    if keep is not None:
        stats.dump_stats(keep)
    total = stats.total_tt  # type: ignore[attr-defined]
    print(f"2. cProfile, total {total:.2f} s")
    rest = total
    for label, functions in PHASES.items():
        seconds = cumulative(stats, functions)
        rest -= seconds
        print(f"   {label:<34} {seconds:7.2f} s  {seconds / total:6.1%}")
        if label.startswith("filter"):
            for part, names in FILTER_PARTS.items():
                part_s = cumulative(stats, names)
                print(f"     {part:<32} {part_s:7.2f} s  {part_s / total:6.1%}")
    print(f"   {'start-up, parameters, other':<34} {rest:7.2f} s  {rest / total:6.1%}")
    print(f"   top {top} by own time:")
    out = io.StringIO()
    pstats.Stats(profiler, stream=out).sort_stats("tottime").print_stats(top)
    lines = out.getvalue().splitlines()
    start = next(i for i, line in enumerate(lines) if line.strip().startswith("ncalls"))
    print("\n".join("   " + line for line in lines[start : start + top + 1]))


def sampled(bag: Path, workdir: Path, top: int) -> None:
    inclusive: collections.Counter[str] = collections.Counter()
    own: collections.Counter[str] = collections.Counter()
    samples = 0

    def record(_: int, frame: FrameType | None) -> None:
        nonlocal samples
        samples += 1
        seen = set()
        first = True
        while frame is not None:
            code = frame.f_code
            name = f"{Path(code.co_filename).name}:{code.co_name}"
            if first:
                own[name] += 1
                first = False
            if name not in seen:
                inclusive[name] += 1
                seen.add(name)
            frame = frame.f_back

    signal.signal(signal.SIGPROF, record)
    signal.setitimer(signal.ITIMER_PROF, 0.001, 0.001)
    try:
        with redirect_stdout(io.StringIO()):
            cli.main(["replay", str(bag), f"--report={workdir / 'sampled.json'}"])
    finally:
        signal.setitimer(signal.ITIMER_PROF, 0.0, 0.0)
        signal.signal(signal.SIGPROF, signal.SIG_DFL)
    print(f"3. sampled profile, {samples} samples; on the stack (inclusive) / at its top (own):")
    below_outer = [item for item in inclusive.most_common() if item[1] < 0.95 * samples]
    for name, count in below_outer[: 2 * top]:  # the command's outer frames left out
        print(f"   {count / samples:6.1%} {name}")
    print("   own:")
    for name, count in own.most_common(top):
        print(f"   {count / samples:6.1%} {name}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bag", type=Path, help="bag to replay (default: bench/speed_bag.py)")
    parser.add_argument("--top", type=int, default=15, help="functions listed (default 15)")
    parser.add_argument("--profile", type=Path, help="write the pstats file here")
    parser.add_argument("--workdir", type=Path, help="keep the bag and reports here")
    parser.add_argument("--sample", action="store_true", help="also a sampled profile (3.)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="replay_profile_") as temporary:
        workdir = args.workdir or Path(temporary)
        workdir.mkdir(parents=True, exist_ok=True)
        bag = args.bag or simulated_bag(workdir)
        unprofiled(bag, workdir)
        profiled(bag, workdir, args.top, args.profile)
        if args.sample:
            sampled(bag, workdir, args.top)


if __name__ == "__main__":
    main()
