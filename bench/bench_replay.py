"""Replay speed and accuracy of the fusion core on simulated bags; prints numbers, asserts nothing.

1. Speed: `gnss_ins replay` of a 240 s seed test pattern bag (imu400cc at 134 Hz, Leica RTK 1 Hz,
   ADU5 5 Hz, truth 50 Hz) on one core: bag reading, fusion, wall time and real-time factor.
2. The acceptance scenario of issue 5: the same bag, 20 s GNSS outages (fix, velocity and attitude
   dropped) starting 50, 85 and 145 s after the drive starts (the drive starts 60 s after the
   first IMU stamp), with and without the ADU5 attitude: horizontal error at the end of each
   outage (the reference design had 10, 15 and 60 m), RMS errors, position NEES in and out of
   the outages.
3. Outages of 10, 20, 30 and 60 s at the same places, with and without NHC and ZUPT/ZARU
   (outages that would overlap are replayed one at a time).
4. Noise-free IMU (profile ``ideal``), no outage, 600 s: error after ten minutes.

Runs of 2-4 go to a process pool over the cores; each run is timed on its own core.
"""

from __future__ import annotations

import itertools
import multiprocessing
import tempfile
from concurrent.futures import ProcessPoolExecutor
from contextlib import redirect_stdout
from io import StringIO
from pathlib import Path
from typing import Any

from ins_fusion.replay.inputs import ReplayInputs, load_bag
from ins_fusion.replay.outages import Outage
from ins_fusion.replay.pipeline import replay
from ins_fusion.replay.report import Report
from ins_fusion.sim.topics import SimulationConfig
from ins_fusion.tools.simulate import write_bag

DRIVE_START_S = 60.0
OUTAGE_STARTS_S = (50.0, 85.0, 145.0)
REFERENCE_DESIGN_M = (10.0, 15.0, 60.0)
VARIANTS: dict[str, dict[str, Any]] = {
    "NHC+ZUPT": {},
    "no NHC": {"use_nhc": False},
    "no ZUPT/ZARU": {"use_zupt": False, "use_zaru": False},
    "neither": {"use_nhc": False, "use_zupt": False, "use_zaru": False},
}

#: Inputs by bag name, read before the pool forks (workers inherit them).
INPUTS: dict[str, ReplayInputs] = {}


def _outages(length_s: float, starts: tuple[float, ...] = OUTAGE_STARTS_S) -> list[Outage]:
    return [Outage(DRIVE_START_S + start, length_s) for start in starts]


def _run(job: tuple[str, dict[str, Any], list[Outage]]) -> Report:
    bag, parameters, outages = job
    return replay(INPUTS[bag], parameters, outages, "/ground_truth").report


def _simulate(directory: Path, name: str, **config: Any) -> None:
    with redirect_stdout(StringIO()):
        write_bag(SimulationConfig(**config), directory / name)
    INPUTS[name] = load_bag(directory / name)


def _fmt(value: float | None, digits: int = 3) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


def bench_speed() -> None:
    inputs = INPUTS["test_pattern"]
    report = _run(("test_pattern", {}, []))
    print(
        f"1. speed, 240 s test pattern at 134 Hz ({report['imu_samples']} IMU samples): read "
        f"{report['read_time_s']:.2f} s + fusion {report['fusion_time_s']:.2f} s = "
        f"{report['wall_time_s']:.2f} s -> {report['realtime_factor']:.0f}x real time "
        f"(fusion alone {inputs.duration_s / report['fusion_time_s']:.0f}x)"
    )


def bench_acceptance(pool: ProcessPoolExecutor) -> None:
    outages = _outages(20.0)
    jobs = [
        ("test_pattern", {}, outages),
        ("test_pattern", {"use_attitude": False}, outages),
    ]
    print(
        "\n2. acceptance: imu400cc, test pattern, RTK 1 Hz,"
        " 20 s outages at 50/85/145 s of the drive"
    )
    for (_, parameters, _), report in zip(jobs, pool.map(_run, jobs), strict=True):
        pos, att, nees = report["position_error_m"], report["attitude_error_deg"], report["nees"]
        label = "without ADU5 attitude" if parameters else "with ADU5 attitude (dropped in outages)"
        print(f"  {label}:")
        for outage, reference in zip(report["outages"], REFERENCE_DESIGN_M, strict=True):
            print(
                f"    outage at {outage['start_s'] - DRIVE_START_S:.0f} s of the drive: end "
                f"{_fmt(outage['horizontal_error_end_m'])} m (filter 1σ "
                f"{_fmt(outage['horizontal_sigma_end_m'])} m), max "
                f"{_fmt(outage['horizontal_error_max_m'])} m, vertical max "
                f"{_fmt(outage['vertical_error_max_m'])} m; reference design {reference:.0f} m"
            )
        print(
            f"    horizontal rms {_fmt(pos['horizontal_rms'])} m, p95 {_fmt(pos['horizontal_p95'])}"
            f" m, max {_fmt(pos['horizontal_max'])} m; vertical rms {_fmt(pos['vertical_rms'])} m"
        )
        print(
            f"    roll/pitch/yaw rms {_fmt(att['roll_rms'])}/{_fmt(att['pitch_rms'])}/"
            f"{_fmt(att['yaw_rms'])} deg, yaw max {_fmt(att['yaw_max'])} deg"
        )
        for part, title in (("in_outage", "in outages"), ("out_of_outage", "outside")):
            stats = nees[part]
            fraction = stats["position_within_3sigma_fraction"]
            print(
                f"    position NEES {title}: mean {_fmt(stats['position_mean'], 2)} (dof 3),"
                f" {_fmt(None if fraction is None else 100 * fraction, 1)} % within 3σ"
            )


def bench_outage_lengths(pool: ProcessPoolExecutor) -> None:
    jobs: list[tuple[str, dict[str, Any], list[Outage]]] = []
    keys: list[tuple[float, str]] = []
    for length in (10.0, 20.0, 30.0, 60.0):
        separate = length > min(b - a for a, b in itertools.pairwise(OUTAGE_STARTS_S))
        groups = [(s,) for s in OUTAGE_STARTS_S] if separate else [OUTAGE_STARTS_S]
        for variant, parameters in VARIANTS.items():
            for starts in groups:
                jobs.append(("test_pattern", parameters, _outages(length, starts)))
                keys.append((length, variant))
    ends: dict[tuple[float, str], list[float | None]] = {key: [] for key in keys}
    nees: dict[tuple[float, str], list[float | None]] = {key: [] for key in keys}
    for key, report in zip(keys, pool.map(_run, jobs), strict=True):
        ends[key] += [o["horizontal_error_end_m"] for o in report["outages"]]
        nees[key].append(report["nees"]["in_outage"]["position_mean"])
    print("\n3. horizontal error [m] at the end of outages at 50/85/145 s of the drive")
    print(f"  {'length':>6}  {'variant':<13}  {'ends':<24}  NEES in outages")
    for key, values in ends.items():
        cells = "/".join(_fmt(v, 2) for v in values)
        means = ", ".join(_fmt(v, 2) for v in nees[key])
        print(f"  {key[0]:>5.0f}s  {key[1]:<13}  {cells:<24}  {means}")


def bench_noise_free() -> None:
    report = _run(("ideal", {}, []))
    pos, yaw_rms = report["position_error_m"], report["attitude_error_deg"]["yaw_rms"]
    print(
        f"\n4. noise-free IMU, no outage, 600 s: error at the end horizontal"
        f" {_fmt(pos['horizontal_final'], 4)} m, vertical {_fmt(pos['vertical_final'], 4)} m;"
        f" horizontal rms {_fmt(pos['horizontal_rms'], 4)} m, max {_fmt(pos['horizontal_max'], 4)}"
        f" m, vertical rms {_fmt(pos['vertical_rms'], 4)} m; yaw rms {_fmt(yaw_rms)}"
        f" deg; {report['realtime_factor']:.0f}x real time"
    )


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        directory = Path(tmp)
        _simulate(directory, "test_pattern", duration_s=240.0, seed=1)
        _simulate(directory, "ideal", imu="ideal", duration_s=600.0, seed=1)
    bench_speed()
    context = multiprocessing.get_context("fork")
    with ProcessPoolExecutor(mp_context=context) as pool:
        bench_acceptance(pool)
        bench_outage_lengths(pool)
    bench_noise_free()


if __name__ == "__main__":
    main()
