"""The RTS smoother (`gnss_ins replay --smooth`): accuracy, consistency, memory and time; prints
numbers, asserts nothing (issue 17).

1. Simulated IMU400CC drives as a user makes them (`gnss_ins simulate`: seed test pattern, 240 s,
   imu400cc with band-limited noise and car vibration, Leica RTK 1 Hz, ADU5 5 Hz, truth 50 Hz)
   replayed with the default parameters (the imu400cc datasheet/report noise, not the
   simulator's true values) and 20 s GNSS outages (fix, velocity and attitude cut) 50, 85 and
   145 s after the drive starts, seeds 1-4, with and without the ADU5: per outage the largest
   horizontal error of the forward filter and of the smoothed solution and their ratio
   (acceptance: <= 0.3), and the smoothed position NEES (3 dof; acceptance: within [1.5, 6])
   over the run, in and out of the outages.
2. The real comma2k19 segment (test/fixtures/comma2k19, docs/accuracy.md): forward against
   smoothed, against its reference, with the default and the phone's datasheet parameters and
   the outage sets of bench_real_drive.py.
3. A 3-hour drive (the test pattern repeated, 134 Hz; `gnss_ins simulate --duration 10800`):
   `gnss_ins replay BAG --smooth` in a child process: its peak memory (ru_maxrss), wall time,
   forward and backward passes; and the same replay without --smooth.

    .venv/bin/python bench/bench_smoother.py [--section N ...] [--workdir DIR] [--seeds N]

The bags are written to --workdir (default: a temporary directory) and reused when present
(the 3-hour one is 2 GB and takes about 3 min to simulate on an idle core, 20 on a busy one).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

from bench_real_drive import BAG as REAL_BAG
from bench_real_drive import FIXTURE, OUTAGE_SETS

from gnss_ins_common.params import load_yaml, validate_all
from ins_fusion.core.settings.config import NODE_NAME
from ins_fusion.core.settings.params import PARAMETERS
from ins_fusion.replay.inputs import load_bag
from ins_fusion.replay.outages import Outage
from ins_fusion.replay.pipeline import replay
from ins_fusion.replay.report import Report

DRIVE_START_S = 60.0
OUTAGES = [Outage(DRIVE_START_S + start, 20.0) for start in (50.0, 85.0, 145.0)]
LONG_DURATION_S = 10_800.0
GNSS_INS = Path(sys.executable).with_name("gnss_ins")


def _simulate(path: Path, *options: str) -> Path:
    """A bag from `gnss_ins simulate` as a user runs it (kept when it exists)."""
    if not path.exists():
        command = [str(GNSS_INS), "simulate", "--scenario", "test_pattern", "--imu", "imu400cc"]
        subprocess.run([*command, *options, "-o", str(path)], check=True, capture_output=True)
    return path


def _f(value: Any, digits: int = 3) -> str:
    return "-" if value is None or not math.isfinite(value) else f"{value:.{digits}f}"


def _simulated_run(job: tuple[Path, dict[str, Any]]) -> Report:
    path, parameters = job
    return replay(load_bag(path), parameters, OUTAGES, "/ground_truth", smooth=True).report


def bench_simulated(workdir: Path, seeds: int) -> None:
    """Section 1."""
    print("## 1. Simulated imu400cc drives, RTK, 20 s outages at 50/85/145 s, default parameters")
    bags = [
        _simulate(workdir / f"tp240_seed{seed}", "--duration", "240", "--seed", str(seed))
        for seed in range(1, seeds + 1)
    ]
    defaults = validate_all(PARAMETERS, {})
    variants = {"ADU5": defaults, "no ADU5": {**defaults, "use_attitude": False}}
    jobs = [(bag, params) for params in variants.values() for bag in bags]
    with ProcessPoolExecutor(max_workers=2) as pool:
        reports = list(pool.map(_simulated_run, jobs))
    print(
        "| aiding | seed | outage max forward m (3) | smoothed m | ratio | worst ratio"
        " | smoothed NEES all / in / out | in 3σ | forward NEES all | backward pass s |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    worst: dict[str, float] = {}
    for (bag, _), report, name in zip(
        jobs, reports, [n for n in variants for _ in bags], strict=True
    ):
        smoothed = report["smoothed"]
        fwd = [o["horizontal_error_max_m"] for o in report["outages"]]
        smo = [o["horizontal_error_max_m"] for o in smoothed["outages"]]
        ratios = [s / f for s, f in zip(smo, fwd, strict=True)]
        worst[name] = max(worst.get(name, 0.0), *ratios)
        nees = smoothed["nees"]
        print(
            f"| {name} | {bag.name[-1]} | {' / '.join(_f(v, 2) for v in fwd)}"
            f" | {' / '.join(_f(v, 3) for v in smo)} | {' / '.join(_f(r, 2) for r in ratios)}"
            f" | {_f(max(ratios), 2)} | {_f(nees['position_mean'], 2)} /"
            f" {_f(nees['in_outage']['position_mean'], 2)} /"
            f" {_f(nees['out_of_outage']['position_mean'], 2)}"
            f" | {100 * nees['position_within_3sigma_fraction']:.1f} %"
            f" | {_f(report['nees']['position_mean'], 2)} | {_f(smoothed['smoothing_time_s'], 1)} |"
        )
    for name, ratio in worst.items():
        print(f"{name}: worst smoothed/forward ratio of the outage maxima {ratio:.2f}")


def bench_real(_: Path, __: int) -> None:
    """Section 2."""
    print("\n## 2. Real comma2k19 segment, forward vs smoothed against the reference")
    inputs = load_bag(REAL_BAG)
    sets = {
        "defaults": validate_all(PARAMETERS, {}),
        "datasheet": load_yaml(FIXTURE / "ins_fusion_phone.yaml", NODE_NAME, PARAMETERS),
    }
    print(
        "| parameters | outages | horiz RMS m fwd / smoothed | vert RMS m | roll/pitch/yaw RMS °"
        " fwd / smoothed | NEES fwd / smoothed | outage max m fwd / smoothed |"
    )
    print("|---|---|---|---|---|---|---|")
    for name, params in sets.items():
        for label, outages in OUTAGE_SETS.items():
            rep = replay(inputs, params, outages, "/ground_truth", smooth=True).report
            smo = rep["smoothed"]

            def att(r: Report) -> str:
                a = r["attitude_error_deg"]
                return "/".join(_f(a[k], 2) for k in ("roll_rms", "pitch_rms", "yaw_rms"))

            maxima = ", ".join(
                f"{_f(f['horizontal_error_max_m'], 2)} / {_f(s['horizontal_error_max_m'], 2)}"
                for f, s in zip(rep["outages"], smo["outages"], strict=True)
            )
            print(
                f"| {name} | {label} | {_f(rep['position_error_m']['horizontal_rms'])} /"
                f" {_f(smo['position_error_m']['horizontal_rms'])}"
                f" | {_f(rep['position_error_m']['vertical_rms'])} /"
                f" {_f(smo['position_error_m']['vertical_rms'])} | {att(rep)} / {att(smo)}"
                f" | {_f(rep['nees']['position_mean'], 2)} / {_f(smo['nees']['position_mean'], 2)}"
                f" | {maxima or '-'} |"
            )


def _child(argv: list[str]) -> tuple[float, float]:
    """Run a command; its wall time [s] and peak resident memory [MiB] (its own rusage)."""
    start = time.perf_counter()
    process = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(process.pid, 0)
    wall = time.perf_counter() - start
    if status != 0:
        raise RuntimeError(
            f"{argv} failed: {process.stderr.read().decode() if process.stderr else ''}"
        )
    return wall, usage.ru_maxrss / 1024.0  # kB on Linux


def bench_long(workdir: Path, _: int) -> None:
    """Section 3."""
    print(f"\n## 3. {LONG_DURATION_S / 3600:g}-hour drive at 134 Hz, one replay per child process")
    start = time.perf_counter()
    bag = workdir / f"long_{LONG_DURATION_S:.0f}s"
    existed = bag.exists()
    _simulate(bag, "--duration", f"{LONG_DURATION_S:g}", "--seed", "1")
    if not existed:
        print(f"simulated in {time.perf_counter() - start:.0f} s")
    size = sum(f.stat().st_size for f in bag.iterdir()) / 2**30
    print(f"bag {bag.name}: {size:.2f} GiB")
    print(
        "| replay | wall s | read s | forward s | backward pass s | smoothed epochs"
        " | peak memory MiB |"
    )
    print("|---|---|---|---|---|---|---|")
    for label, extra in (("forward only", []), ("--smooth", ["--smooth"])):
        report_path = workdir / f"long_report{'_smooth' if extra else ''}.json"
        wall, peak = _child(
            [str(GNSS_INS), "replay", str(bag), "--report", str(report_path), *extra]
        )
        report = json.loads(report_path.read_text())
        smoothed = report.get("smoothed") or {}
        print(
            f"| {label} | {wall:.0f} | {report['read_time_s']:.0f} | {report['fusion_time_s']:.0f}"
            f" | {_f(smoothed.get('smoothing_time_s'), 0)} | {smoothed.get('epochs', '-')}"
            f" | {peak:.0f} |"
        )
    print(f"(this process: {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MiB)")


SECTIONS = {1: bench_simulated, 2: bench_real, 3: bench_long}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--section", type=int, action="append", choices=sorted(SECTIONS))
    parser.add_argument("--workdir", type=Path, help="where the simulated bags are kept")
    parser.add_argument("--seeds", type=int, default=4, help="seeds of section 1")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        workdir = args.workdir or Path(tmp)
        workdir.mkdir(parents=True, exist_ok=True)
        for section in args.section or sorted(SECTIONS):
            SECTIONS[section](workdir, args.seeds)
    return 0


if __name__ == "__main__":
    sys.exit(main())
