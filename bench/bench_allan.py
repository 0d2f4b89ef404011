"""Accuracy and speed of `gnss_ins allan` on simulated static records; prints numbers, asserts
nothing.

1. Accuracy on 1 h and 2 h static records of the imu400cc (134 Hz, band-limited, quantised) and
   stim300 (500 Hz, Oslo Table 5.1) profiles, several seeds: recovered / true for the white noise
   N (ARW/VRW), the bias instability (Gauss-Markov σ and T) and the random walk K, how many axes
   identify a bias and how many the tool accepts for ``--terms white,bias`` (the rest it refuses
   as too short), the classic B = min/0.664 against σ, and how often the 68 % interval holds the
   true value.
2. The same for 24 h records, imu400cc at 10 Hz and stim300 at 1 Hz (the densities do not depend
   on the rate; at 10 Hz the imu400cc's accelerometer counts add 3 % to its VRW).
3. Speed: a 1 h imu400cc bag at 134 Hz (482 400 messages): reading it, the analysis of the six
   axes, the whole `gnss_ins allan`; and the analysis of a 2 h stim300 record at 500 Hz.

Runs of 1-2 go to a process pool over the cores.
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

from ins_fusion.noise_id.analysis import GYRO, identify, shortcomings
from ins_fusion.noise_id.record import sample_clock
from ins_fusion.noise_id.synthetic import static_record, write_imu_bag
from ins_fusion.noise_id.terms import Term
from ins_fusion.sim.imu_model import PROFILES
from ins_fusion.tools import cli
from ins_fusion.tools.allan import read_imu

SEEDS = (1, 2, 3)
CASES = (
    ("imu400cc", 3600.0, None),
    ("imu400cc", 7200.0, None),
    ("imu400cc", 86400.0, 10.0),
    ("stim300", 3600.0, None),
    ("stim300", 7200.0, None),
    ("stim300", 86400.0, 1.0),
)


@dataclass(frozen=True)
class AxisResult:
    sensor: str
    white: float  # recovered / true
    white_covered: bool
    sigma: float | None  # None: no bias identified
    sigma_covered: bool
    time: float | None
    walk: float | None  # None: not visible (or no true random walk)
    flat: float  # B = min/0.664 over the true σ
    accepted: bool  # the tool gives the bias for this axis


def _covered(term: Term, truth: float) -> bool:
    return term.low <= truth <= term.high


def _run(job: tuple[str, float, float | None, int]) -> list[AxisResult]:
    name, duration, rate, seed = job
    profile = PROFILES[name]
    record = static_record(profile, duration, rate, seed, band_limited=True)
    report = identify(record, sample_clock(record.t_s), name)
    refused = {p.split(":")[0] for p in shortcomings(report, ("white", "bias"))}
    results = []
    for axis in report.axes:
        triad = profile.gyro if axis.sensor is GYRO else profile.accel
        i = "xyz".index(axis.axis)
        truth_n, truth_b = triad.noise_density[i], triad.bias_instability[i]
        truth_t, truth_k = triad.bias_correlation_time_s[i], triad.random_walk[i]
        terms, bias = axis.terms, axis.terms.bias
        results.append(
            AxisResult(
                axis.sensor.name,
                terms.white.value / truth_n,
                _covered(terms.white, truth_n),
                None if bias is None else bias.sigma.value / truth_b,
                bias is not None and _covered(bias.sigma, truth_b),
                None if bias is None else bias.time_constant_s / truth_t,
                terms.random_walk.value / truth_k
                if truth_k and terms.random_walk.visible
                else None,
                terms.flat_minimum.value / truth_b,
                axis.name not in refused,
            )
        )
    return results


def _span(values: list[float]) -> str:
    if not values:
        return "-"
    return f"{np.median(values):.2f} ({min(values):.2f}-{max(values):.2f})"


def _accuracy() -> None:
    jobs = [(name, duration, rate, seed) for name, duration, rate in CASES for seed in SEEDS]
    with ProcessPoolExecutor() as pool:
        results = list(pool.map(_run, jobs))
    print("recovered / true: median (min-max) over axes and seeds; coverage of the 68 % interval")
    header = (
        f"{'profile':<9} {'length':>10} {'sensor':<6} {'N':<18} {'cover':>5} {'bias id/ok':>10} "
        f"{'sigma':<18} {'cover':>5} {'T':<18} {'K':<18} {'B=min/0.664':<18}"
    )
    print(header)
    for name, duration, rate in CASES:
        rows = [
            r
            for job, result in zip(jobs, results, strict=True)
            if job[:3] == (name, duration, rate)
            for r in result
        ]
        for sensor in ("gyro", "accel"):
            axes = [r for r in rows if r.sensor == sensor]
            with_bias = [r for r in axes if r.sigma is not None]
            accepted = [r for r in with_bias if r.accepted]
            length = f"{duration / 3600.0:g} h" + (f" {rate:g} Hz" if rate else "")
            print(
                f"{name:<9} {length:>10} {sensor:<6} {_span([r.white for r in axes]):<18} "
                f"{np.mean([r.white_covered for r in axes]):>5.0%} "
                f"{len(with_bias):>4}/{len(accepted):<2}/{len(axes):<2} "
                f"{_span([r.sigma for r in accepted if r.sigma is not None]):<18} "
                f"{np.mean([r.sigma_covered for r in accepted]) if accepted else math.nan:>5.0%} "
                f"{_span([r.time for r in accepted if r.time is not None]):<18} "
                f"{_span([r.walk for r in axes if r.walk is not None]):<18} "
                f"{_span([r.flat for r in axes]):<18}"
            )
    print(
        "bias id/ok/n: axes with a bias term identified / of those accepted (enough degrees of "
        "freedom) / axes; sigma, T, cover over the accepted ones"
    )


def _speed() -> None:
    with tempfile.TemporaryDirectory() as directory:
        bag = Path(directory) / "static"
        start = time.perf_counter()
        write_imu_bag(bag, static_record(PROFILES["imu400cc"], 3600.0, seed=1, band_limited=True))
        written = time.perf_counter() - start
        start = time.perf_counter()
        record, _ = read_imu(bag, "/imu/data_raw")
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
