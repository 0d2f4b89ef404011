"""Accuracy and speed of `gnss_ins allan` on simulated static records; prints numbers, asserts
nothing.

1. Accuracy, per case (profile, length, rate) and per axis, over many seeds: recovered / true
   for the Gauss-Markov bias σ and T (mean and worst over the seeds), how often the 68 %
   intervals hold the truth, how many seeds identify a bias and how many the tool accepts for
   ``--terms white,bias`` (σ ±5 %, T ±10 % at 1σ; the rest it refuses, saying how long a record
   needs), the share of accepted σ within 10 % of the truth, and the bound (1σ of σ and T) the
   Whittle likelihood's Fisher information gives for the true noise and this length. Then, per
   sensor, white noise N and random walk K. The imu400cc (band-limited, quantised) at 134 Hz
   for 2 h, at 10 Hz for 24 h and at 1 Hz for 7 days; the stim300 (Oslo Table 5.1) at 500 Hz
   for 2 h, at 1 Hz for 24 h and 30 days (the densities do not depend on the rate; at 10 Hz the
   imu400cc's accelerometer counts add 3 % to its VRW, at 1 Hz more).
2. Speed: a 1 h imu400cc bag at 134 Hz (482 400 messages): reading it, the analysis of the six
   axes, the whole `gnss_ins allan`; and the analysis of a 2 h stim300 record at 500 Hz.

Runs of 1 go to a process pool over the cores.
"""

from __future__ import annotations

import math
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from contextlib import redirect_stdout
from dataclasses import dataclass
from io import StringIO
from pathlib import Path

import numpy as np

from ins_fusion.bags.imu import read_imu
from ins_fusion.noise_id.analysis import GYRO, identify, shortcomings
from ins_fusion.noise_id.record import sample_clock
from ins_fusion.noise_id.synthetic import static_record, write_static_bag
from ins_fusion.noise_id.terms import Term
from ins_fusion.noise_id.whittle import BIAS, LOG_TIME, SpectralModel, expected_errors
from ins_fusion.sim.imu_model import PROFILES, TriadErrors
from ins_fusion.tools import cli

HOUR, DAY = 3600.0, 86400.0
#: (profile, length [s], rate [Hz] or None for the profile's, seeds)
CASES = (
    ("imu400cc", 2 * HOUR, None, 6),
    ("imu400cc", DAY, 10.0, 12),
    ("imu400cc", 7 * DAY, 1.0, 12),
    ("stim300", 2 * HOUR, None, 4),
    ("stim300", DAY, 1.0, 12),
    ("stim300", 30 * DAY, 1.0, 8),
)
Case = tuple[str, float, float | None]


@dataclass(frozen=True)
class AxisResult:
    sensor: str
    axis: str
    white: float  # recovered / true
    white_covered: bool
    sigma: float | None  # None: no bias identified
    sigma_covered: bool
    time: float | None
    time_covered: bool
    walk: float | None  # None: not visible (or no true random walk)
    accepted: bool  # the tool gives the bias for this axis


def _covered(term: Term, truth: float) -> bool:
    return term.low <= truth <= term.high


def _truth(triad: TriadErrors, i: int) -> SpectralModel:
    return SpectralModel(
        triad.noise_density[i] ** 2,
        triad.bias_instability[i] ** 2,
        triad.random_walk[i] ** 2,
        triad.bias_correlation_time_s[i],
    )


def _run(job: tuple[str, float, float | None, int]) -> list[AxisResult]:
    name, duration, rate, seed = job
    profile = PROFILES[name]
    record = static_record(profile, duration, rate, seed, band_limited=True)
    report = identify(record, sample_clock(record.t_s), name)
    refused = {p.split(":")[0] for p in shortcomings(report, ("white", "bias"))}
    results = []
    for axis in report.axes:
        triad = profile.gyro if axis.sensor is GYRO else profile.accel
        truth = _truth(triad, "xyz".index(axis.axis))
        terms, bias = axis.terms, axis.terms.bias
        n, sigma, k = (math.sqrt(c) for c in (truth.white, truth.bias, truth.walk))
        results.append(
            AxisResult(
                axis.sensor.name,
                axis.axis,
                terms.white.value / n,
                _covered(terms.white, n),
                None if bias is None else bias.sigma.value / sigma,
                bias is not None and _covered(bias.sigma, sigma),
                None if bias is None else bias.time_constant_s / truth.time_constant_s,
                bias is not None
                and bias.time_limits_s[0] <= truth.time_constant_s <= bias.time_limits_s[1],
                terms.random_walk.value / k if k and terms.random_walk.visible else None,
                axis.name not in refused,
            )
        )
    return results


def _mean_worst(ratios: list[float]) -> str:
    """Mean and the ratio farthest from 1 (in log)."""
    if not ratios:
        return "-"
    worst = max(ratios, key=lambda r: abs(math.log(r)))
    return f"{np.mean(ratios):.2f} {worst:.2f}"


def _share(flags: list[bool]) -> str:
    return f"{np.mean(flags):.0%}" if flags else "-"


def _length(duration: float, rate: float | None) -> str:
    text = f"{duration / DAY:g} d" if duration >= DAY else f"{duration / HOUR:g} h"
    return text + (f" {rate:g} Hz" if rate else "")


def _bias_rows(case: Case, rows: list[AxisResult]) -> None:
    name, duration, rate = case
    profile = PROFILES[name]
    for sensor, triad in (("gyro", profile.gyro), ("accel", profile.accel)):
        for i, axis in enumerate("xyz"):
            mine = [r for r in rows if r.sensor == sensor and r.axis == axis]
            found = [r for r in mine if r.sigma is not None and r.time is not None]
            ok = [r for r in found if r.accepted]
            sample_rate = rate or profile.rate_hz
            bound = expected_errors(_truth(triad, i), sample_rate, round(duration * sample_rate))
            print(
                f"{name:<9} {_length(duration, rate):>10} {sensor:<5} {axis} "
                f"{len(found):>3}/{len(ok):<2}/{len(mine):<3} "
                f"{bound[BIAS]:>6.1%} {bound[LOG_TIME]:>6.1%}  "
                f"{_mean_worst([r.sigma for r in found if r.sigma]):<10} "
                f"{_share([r.sigma_covered for r in found]):>5} "
                f"{_mean_worst([r.time for r in found if r.time]):<10} "
                f"{_share([r.time_covered for r in found]):>5}  "
                f"{_mean_worst([r.sigma for r in ok if r.sigma]):<10} "
                f"{_share([abs((r.sigma or 0.0) - 1.0) <= 0.1 for r in ok]):>5} "
                f"{_mean_worst([r.time for r in ok if r.time]):<10} "
                f"{_share([r.sigma_covered for r in ok]):>5} "
                f"{_share([r.time_covered for r in ok]):>5}"
            )


def _accuracy() -> None:
    jobs = [
        (name, duration, rate, seed)
        for name, duration, rate, seeds in CASES
        for seed in range(seeds)
    ]
    with ProcessPoolExecutor() as pool:
        results = list(pool.map(_run, jobs))
    by_case: dict[Case, list[AxisResult]] = {}
    for job, result in zip(jobs, results, strict=True):
        by_case.setdefault(job[:3], []).extend(result)
    print(
        "Gauss-Markov bias, recovered / true: mean and worst over the seeds; cover: share of "
        "68 % intervals holding the truth.\nid/ok/n: seeds with a bias identified / accepted "
        "(σ ±5 %, T ±10 % at 1σ) / seeds; bound: 1σ of σ and T for the true noise and length"
    )
    print(
        f"{'profile':<9} {'length':>10} {'axis':<7} {'id/ok/n':<9} {'bound σ':>6} {'T':>6}  "
        f"{'σ (id)':<10} {'cover':>5} {'T (id)':<10} {'cover':>5}  {'σ (ok)':<10} "
        f"{'≤10%':>5} {'T (ok)':<10} {'cov σ':>5} {'cov T':>5}"
    )
    for case, rows in by_case.items():
        _bias_rows(case, rows)
    print("\nwhite noise N and random walk K, recovered / true: mean and worst; cover as above")
    for (name, duration, rate), rows in by_case.items():
        for sensor in ("gyro", "accel"):
            mine = [r for r in rows if r.sensor == sensor]
            print(
                f"{name:<9} {_length(duration, rate):>10} {sensor:<5} "
                f"N {_mean_worst([r.white for r in mine]):<10} "
                f"cover {_share([r.white_covered for r in mine]):>5}  "
                f"K {_mean_worst([r.walk for r in mine if r.walk]):<10} "
                f"(seen on {sum(r.walk is not None for r in mine)}/{len(mine)})"
            )


def _speed() -> None:
    with tempfile.TemporaryDirectory() as directory:
        bag = Path(directory) / "static"
        start = time.perf_counter()
        write_static_bag(
            bag, static_record(PROFILES["imu400cc"], 3600.0, seed=1, band_limited=True)
        )
        written = time.perf_counter() - start
        start = time.perf_counter()
        record = read_imu(bag, temperature_topic=None, relative=True)
        read = time.perf_counter() - start
        start = time.perf_counter()
        identify(record, sample_clock(record.t_s), "speed")
        analysis = time.perf_counter() - start
        start = time.perf_counter()
        with redirect_stdout(StringIO()):
            code = cli.main(["allan", str(bag), "--terms", "white", "-o", f"{directory}/n.yaml"])
        total = time.perf_counter() - start
    messages = len(record.t_s)
    print(
        f"imu400cc 1 h at 134 Hz ({messages} messages): bag written in {written:.1f} s; "
        f"read {read:.1f} s ({messages / read:.0f} messages/s), analysis of the six axes "
        f"{analysis:.1f} s; the whole gnss_ins allan {total:.1f} s (exit {code})"
    )
    record = static_record(PROFILES["stim300"], 7200.0, seed=1)
    start = time.perf_counter()
    identify(record, sample_clock(record.t_s), "speed")
    print(
        f"stim300 2 h at 500 Hz ({len(record.t_s)} samples per axis): analysis "
        f"{time.perf_counter() - start:.1f} s"
    )


if __name__ == "__main__":
    _speed()
    _accuracy()
