"""Fusion engine: speed, accuracy in GNSS outages, consistency; prints numbers, asserts nothing.

Simulated drives in-process (test/support/drives.py harness: simulator IMU400CC profile on the
survey car, Leica RTK 1 Hz with its 0.053 s latency, optional ADU5 attitude 5 Hz). Sections:

1. speed: CPU time of the engine alone per IMU sample (best of 3) for covariance intervals 0
   (every sample), 0.04 and 0.1 s, with the accuracy and NEES each gives; the cost of late
   measurements (0.053 s Leica latency, and RTK delivered 1.24 s late like the NTNU OBU);
2. the Aalborg outages (20 s at 50, 85, 145 s after the drive starts): horizontal error at the
   end of each outage over several seeds, with and without NHC / ZUPT+ZARU;
3. outage lengths 10, 20, 30, 60 s at the same starts, with and without NHC / ZUPT+ZARU;
4. consistency over seeds: position NEES (3 dof) and 3σ containment in and out of outages;
5. yaw RMS with and without the ADU5, and without it when the heading became known;
6. the noise-free IMU over 10 minutes, seeds 1-6 (an in-process cross-check of
   bench_replay.py section 4, which gives the acceptance numbers).

Usage: python bench/bench_fusion_engine.py [--quick] [--section N ...]
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "test"))

from support.drives import (
    AALBORG_OUTAGES,
    CALIBRATION,
    DRIVE_START_S,
    Drive,
    RunResult,
    config,
    feed,
    run,
    simulate,
)

from ins_fusion.core.engine.engine import InsEngine
from ins_fusion.core.engine.warm_up import warm_up
from ins_fusion.core.nav.calibration import ImuCalibration

CAL = ImuCalibration.from_yaml(CALIBRATION)
#: The heading counts as known once the filter's yaw σ is below this [deg] (unknown: 90°).
HEADING_KNOWN_SIGMA_DEG = 10.0
AIDS = {
    "NHC + ZUPT/ZARU": {},
    "no NHC": {"use_nhc": False},
    "no ZUPT/ZARU": {"use_zupt": False, "use_zaru": False},
    "neither": {"use_nhc": False, "use_zupt": False, "use_zaru": False},
}


def cpu_per_sample(drive: Drive, overrides: dict[str, Any], repeats: int = 3) -> float:
    """Best CPU time of the engine alone per IMU sample [s]."""
    best = np.inf
    for _ in range(repeats):
        engine = InsEngine(config(**overrides), CAL)
        start = time.process_time()
        feed(engine, drive)
        best = min(best, time.process_time() - start)
    return best / len(drive.imu_t)


def consistency(result: RunResult, outages: Sequence[tuple[float, float]]) -> str:
    parts = []
    for inside in (True, False):
        mask = result.mask(outages, inside)
        nees = result.nees(mask).mean()
        within = result.within_3_sigma(mask).min()
        parts.append(f"{'in' if inside else 'out'}: NEES {nees:5.2f} 3σ {within * 100:5.1f} %")
    return ", ".join(parts)


def section_speed(quick: bool) -> None:
    print("\n== 1. speed (engine only, CPU time, best of 3; 134 Hz IMU)")
    drive = simulate(outages=AALBORG_OUTAGES, seed=1)
    duration = float(drive.imu_t[-1] - drive.imu_t[0])
    print("covariance interval | µs/sample | real-time factor | outage-end errors [m] | NEES")
    for interval in (0.0, 0.04, 0.1):
        per_sample = cpu_per_sample(drive, {"covariance_interval": interval}, 1 if quick else 3)
        result = run(drive, config(covariance_interval=interval), CAL)
        errors = " ".join(f"{e:5.2f}" for e in result.outage_end_errors(AALBORG_OUTAGES))
        print(
            f"{interval:19.2f} | {per_sample * 1e6:9.1f} | {1.0 / (per_sample * 134.0):14.0f}x"
            f" | {errors} | {consistency(result, AALBORG_OUTAGES)}"
        )
    engine = InsEngine(config(), CAL)
    feed(engine, drive)
    status = engine.status()
    fixes = (
        status.measurements["gnss_position"]["used"]
        + status.measurements["gnss_position"]["rejected"]
    )
    print(
        f"late measurements (Leica 0.053 s): {status.rollbacks} rollbacks, "
        f"{status.replayed_samples / max(status.rollbacks, 1):.1f} samples re-propagated each, "
        f"{status.replayed_samples / len(drive.imu_t) * 100:.1f} % extra steps ({fixes} fixes)"
    )
    delayed = Drive(
        drive.truth,
        drive.imu_t,
        drive.imu_rate,
        drive.imu_force,
        sorted(((t + 1.24, m) for t, m in drive.events), key=lambda e: e[0]),
    )
    slow = cpu_per_sample(delayed, {}, 1)
    fast = cpu_per_sample(drive, {}, 1)
    print(
        f"RTK delivered 1.24 s late (NTNU OBU latency): {slow * 1e6:.1f} µs/sample vs "
        f"{fast * 1e6:.1f} ({1.0 / (slow * 134.0):.0f}x real time), {duration:.0f} s drive"
    )


def section_aalborg(seeds: Sequence[int]) -> None:
    print("\n== 2. Aalborg outages: horizontal error at the end of each 20 s outage [m]")
    print("(outages at 50, 85, 145 s after the drive starts; the Aalborg design: 10, 15, 60 m)")
    drives = {seed: simulate(outages=AALBORG_OUTAGES, seed=seed) for seed in seeds}
    for name, overrides in AIDS.items():
        errors = np.array(
            [
                run(d, config(**overrides), CAL).outage_end_errors(AALBORG_OUTAGES)
                for d in drives.values()
            ]
        )
        per_outage = " | ".join(
            f"{errors[:, k].mean():5.2f} mean {errors[:, k].max():5.2f} max" for k in range(3)
        )
        print(f"{name:16s} | {per_outage} | worst {errors.max():5.2f} ({len(seeds)} seeds)")


def section_lengths(seeds: Sequence[int]) -> None:
    print("\n== 3. outage length: horizontal error at the end [m], mean (max) over seeds and the")
    print("   three starts (50, 85, 145 s after the drive starts)")
    starts = [DRIVE_START_S + s for s in (50.0, 85.0, 145.0)]
    print("aids             | " + " | ".join(f"{length:>12.0f} s" for length in (10, 20, 30, 60)))
    for name, overrides in AIDS.items():
        cells = []
        for length in (10.0, 20.0, 30.0, 60.0):
            groups = (
                [tuple((s, length) for s in starts)]
                if length < 35.0
                else [((s, length),) for s in starts]
            )
            errors = []
            for seed in seeds:
                for outages in groups:
                    drive = simulate(300.0, outages=outages, seed=seed)
                    errors += run(drive, config(**overrides), CAL, 2.0).outage_end_errors(outages)
            cells.append(f"{np.mean(errors):6.2f} ({np.max(errors):6.2f})")
        print(f"{name:16s} | " + " | ".join(cells))


def section_consistency(seeds: Sequence[int]) -> None:
    print("\n== 4. consistency over seeds (position NEES, 3 dof: ideal 3; 3σ containment)")
    nees_in, nees_out, within_in, within_out = [], [], [], []
    for seed in seeds:
        result = run(simulate(outages=AALBORG_OUTAGES, seed=seed), config(), CAL)
        inside, outside = result.mask(AALBORG_OUTAGES, True), result.mask(AALBORG_OUTAGES, False)
        nees_in.append(result.nees(inside).mean())
        nees_out.append(result.nees(outside).mean())
        within_in.append(result.within_3_sigma(inside))
        within_out.append(result.within_3_sigma(outside))
        print(f"seed {seed}: {consistency(result, AALBORG_OUTAGES)}")
    print(
        f"mean over {len(seeds)} seeds: in outages NEES {np.mean(nees_in):.2f}, 3σ (E,N,U) "
        f"{np.round(np.mean(within_in, axis=0) * 100, 1)} %; out of outages NEES "
        f"{np.mean(nees_out):.2f}, 3σ {np.round(np.mean(within_out, axis=0) * 100, 1)} %"
    )


def heading_known_at(drive: Drive) -> float:
    """First time [s] the filter's yaw σ is below HEADING_KNOWN_SIGMA_DEG (inf: never), checked
    every 0.1 s."""
    engine = InsEngine(config(), CAL)
    known = [np.inf]
    limit = np.radians(HEADING_KNOWN_SIGMA_DEG) ** 2

    def check(i: int) -> None:
        if i % 13 or np.isfinite(known[0]):
            return
        solution = engine.solution()
        if solution is not None and solution.cov_att_enu_rad2[2, 2] < limit:
            known[0] = float(drive.imu_t[i])

    feed(engine, drive, after_sample=check)
    return known[0]


def section_yaw(seeds: Sequence[int]) -> None:
    print(
        f"\n== 5. yaw error while driving [deg]: RMS from the drive start or, if later, the"
        f" heading being known (yaw σ < {HEADING_KNOWN_SIGMA_DEG:.0f}°); RMS of the last 60 s; max"
    )
    for with_attitude in (True, False):
        rms, last, worst, known = [], [], [], []
        for seed in seeds:
            drive = simulate(seed=seed, with_attitude=with_attitude)
            result = run(drive, config(), CAL)
            known.append(heading_known_at(drive))
            yaw = result.yaw_err_deg[result.t >= max(known[-1], DRIVE_START_S)]
            rms.append(np.sqrt(np.mean(yaw**2)))
            late = result.yaw_err_deg[result.t >= result.t[-1] - 60.0]
            last.append(np.sqrt(np.mean(late**2)))
            worst.append(np.abs(yaw).max())
        label = "with ADU5   " if with_attitude else "without ADU5"
        print(
            f"{label}: heading known at {np.round(np.subtract(known, DRIVE_START_S), 1)} s after"
            f" the drive starts; RMS {np.mean(rms):.3f} (seeds {np.round(rms, 3)}), last 60 s"
            f" {np.mean(last):.3f}, max {np.max(worst):.3f}"
        )


def section_ideal(seeds: Sequence[int]) -> None:
    print("\n== 6. noise-free IMU, RTK 1 Hz, no outage, 10 minutes: horizontal error [cm]")
    rms = []
    for seed in seeds:
        result = run(simulate(600.0, imu_profile="ideal", seed=seed), config(), None, 1.0)
        late = result.horizontal[result.t >= result.t[-1] - 60.0] * 100.0
        rms.append(np.sqrt(np.mean(late**2)))
        print(
            f"seed {seed}: at 10 min {result.horizontal[-1] * 100:5.2f}; last 60 s: RMS "
            f"{rms[-1]:5.2f}, p95 {np.percentile(late, 95):5.2f}, "
            f"max {late.max():5.2f}"
        )
    print(f"RMS over the seeds' last 60 s: {np.sqrt(np.mean(np.square(rms))):.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer seeds")
    parser.add_argument("--section", type=int, nargs="*", default=[1, 2, 3, 4, 5, 6])
    args = parser.parse_args()
    seeds = [1, 2, 3] if args.quick else [1, 2, 3, 4, 5, 6, 7, 8]
    warm_up()  # no kernel compiled inside a timed part
    start = time.perf_counter()
    sections = {
        1: lambda: section_speed(args.quick),
        2: lambda: section_aalborg(seeds),
        3: lambda: section_lengths(seeds[:3]),
        4: lambda: section_consistency(seeds),
        5: lambda: section_yaw(seeds[:4]),
        6: lambda: section_ideal(seeds[:6]),
    }
    for number in args.section:
        sections[number]()
    print(f"\n(bench wall time {time.perf_counter() - start:.0f} s)")


if __name__ == "__main__":
    main()
