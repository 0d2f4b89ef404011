"""Replay speed and accuracy of the fusion core on simulated bags; prints numbers, asserts nothing.

1. Speed: `gnss_ins replay` of a 240 s seed test pattern bag (imu400cc at 134 Hz, Leica RTK 1 Hz,
   ADU5 5 Hz, truth 50 Hz) on one core: bag reading, fusion, wall time and real-time factor.
2. The acceptance scenario of issue 5: the same bag, 20 s GNSS outages (fix, velocity and attitude
   dropped) starting 50, 85 and 145 s after the drive starts (the drive starts 60 s after the
   first IMU stamp), with and without the ADU5 attitude: horizontal error at the end of each
   outage (the reference design had 10, 15 and 60 m), RMS errors, yaw (and, without the ADU5,
   when the heading became known and the yaw RMS from then on), position NEES and 3σ
   containment in and out of the outages.
3. Outages of 10, 20, 30 and 60 s at the same places, with and without NHC and ZUPT/ZARU
   (outages that would overlap are replayed one at a time).
4. Noise-free IMU (profile ``ideal``), 600 s test pattern, no outage, seeds 1-6: horizontal error
   at the end and over the last minute (RMS, p95, max) and the RTK fixes' own error on the same
   bag; with the default filter parameters and with the filter told its IMU is perfect; on the
   simulated RTK noise and on error-free GNSS (``SimulationConfig.gnss_noise_scale = 0``).

Bags are simulated in parallel; the runs of 2-4 go to a process pool over the cores, each timed
on its own core.
"""

from __future__ import annotations

import itertools
import math
import multiprocessing
import tempfile
from concurrent.futures import ProcessPoolExecutor
from contextlib import redirect_stdout
from dataclasses import dataclass
from io import StringIO
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from ins_fusion.core.filter.records import GnssFixMeasurement
from ins_fusion.core.nav import earth
from ins_fusion.core.settings.params import PARAMETERS
from ins_fusion.replay.inputs import ReplayInputs, load_bag
from ins_fusion.replay.metrics import horizontal
from ins_fusion.replay.outages import Outage
from ins_fusion.replay.pipeline import replay
from ins_fusion.replay.report import Report
from ins_fusion.sim.drive import SimulationConfig
from ins_fusion.sim.scenarios import SURVEY_CAR
from ins_fusion.sim.simulated_bag import write_bag

DRIVE_START_S = 60.0
OUTAGE_STARTS_S = (50.0, 85.0, 145.0)
REFERENCE_DESIGN_M = (10.0, 15.0, 60.0)
VARIANTS: dict[str, dict[str, Any]] = {
    "NHC+ZUPT": {},
    "no NHC": {"use_nhc": False},
    "no ZUPT/ZARU": {"use_zupt": False, "use_zaru": False},
    "neither": {"use_nhc": False, "use_zupt": False, "use_zaru": False},
}

NOISE_FREE_SEEDS = (1, 2, 3, 4, 5, 6)
#: The filter told its IMU is perfect: the imu_noise densities at this fraction of their defaults
#: (gyro ARW 0.003 deg/sqrt(h), bias instability 0.007-0.018 deg/h). Zero, which the parameter
#: ranges allow, or 1e-4 let the covariance collapse on the noisy RTK and the fixes get gated.
PERFECT_IMU_FRACTION = 1e-3
_DEFAULTS: dict[str, Any] = {p.name: p.default for p in PARAMETERS}
PERFECT_IMU: dict[str, Any] = {
    name: [v * PERFECT_IMU_FRACTION for v in _DEFAULTS[name]]
    for name in (
        "imu_noise.gyro_arw",
        "imu_noise.accel_vrw",
        "imu_noise.gyro_bias_instability",
        "imu_noise.accel_bias_instability",
    )
}
#: Window of the noise-free statistics: the last minute of the run [s].
LAST_MINUTE_S = 60.0
#: The heading counts as known once the filter's yaw σ is below this [deg] (unknown: 90°).
HEADING_KNOWN_SIGMA_DEG = 10.0

Job = tuple[str, dict[str, Any], list[Outage]]

#: Inputs by bag name, read before the replay pool forks (workers inherit them).
INPUTS: dict[str, ReplayInputs] = {}


@dataclass(frozen=True)
class Summary:
    """A replay's report and what the bench derives from its track and errors: when the heading
    became known [s after the first IMU stamp] and the yaw RMS from then on [deg] (None: never),
    and the horizontal error over the last minute: final, rms, p95, max [m]."""

    report: Report
    heading_known_s: float | None
    yaw_rms_known_deg: float | None
    last_minute_m: dict[str, float]


def _outages(length_s: float, starts: tuple[float, ...] = OUTAGE_STARTS_S) -> list[Outage]:
    return [Outage(DRIVE_START_S + start, length_s) for start in starts]


def _rms(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(values))))


def _run(job: Job) -> Summary:
    bag, parameters, outages = job
    inputs = INPUTS[bag]
    result = replay(inputs, parameters, outages, "/ground_truth")
    assert result.evaluation is not None and result.evaluation.attitude is not None
    track, position, attitude = (
        result.run.track,
        result.evaluation.position,
        result.evaluation.attitude,
    )
    yaw_sigma_deg = np.degrees(np.sqrt(track.cov_att_enu_rad2[:, 2, 2]))
    known = np.flatnonzero(track.aligned & (yaw_sigma_deg < HEADING_KNOWN_SIGMA_DEG))
    heading_known_s = float(track.t_s[known[0]] - inputs.t0_s) if known.size else None
    yaw_rms = None
    if heading_known_s is not None:
        yaw_rms = _rms(attitude.error[attitude.t_rel_s >= heading_known_s, 2])
    h = horizontal(position)
    last = h[position.t_rel_s >= position.t_rel_s[-1] - LAST_MINUTE_S]
    last_minute = {
        "final": float(h[-1]),
        "rms": _rms(last),
        "p95": float(np.percentile(last, 95.0)),
        "max": float(last.max()),
    }
    return Summary(result.report, heading_known_s, yaw_rms, last_minute)


def _simulate(job: tuple[Path, SimulationConfig]) -> ReplayInputs:
    path, config = job
    with redirect_stdout(StringIO()):
        write_bag(config, path)
    return load_bag(path)


def _fix_errors(inputs: ReplayInputs) -> tuple[np.ndarray, np.ndarray]:
    """The bag's GNSS fixes against the true antenna (base_link truth plus the survey car's
    antenna lever arm, rotated by the true attitude): times [s after the first IMU stamp] and
    horizontal errors [m]."""
    reference = inputs.reference
    assert reference is not None and reference.attitude is not None
    fixes = [m for _, _, m in inputs.measurements if isinstance(m, GnssFixMeasurement) and m.valid]
    t = np.array([m.t_s for m in fixes])
    at = np.clip(np.searchsorted(reference.position.t_s, t), 0, len(reference.position.t_s) - 1)
    assert np.allclose(reference.position.t_s[at], t, atol=1e-6), "fixes off the truth grid"
    truth = reference.position.values[at]
    lat0, lon0 = np.radians(truth[0, :2])
    fix_geodetic = np.array([[m.lat_deg, m.lon_deg, m.height_m] for m in fixes])

    def enu(geodetic: np.ndarray) -> np.ndarray:
        lat, lon = np.radians(geodetic[:, 0]), np.radians(geodetic[:, 1])
        return earth.geodetic_to_enu(
            lat, lon, geodetic[:, 2], float(lat0), float(lon0), float(truth[0, 2])
        )

    attitude = Rotation.from_quat(np.asarray(reference.attitude.values[at]))
    antenna = enu(truth) + attitude.apply(SURVEY_CAR.gnss_antenna_flu_m)
    error = enu(fix_geodetic) - antenna
    return t - inputs.t0_s, np.hypot(error[:, 0], error[:, 1])


def _fmt(value: float | None, digits: int = 3) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


def bench_speed() -> None:
    inputs = INPUTS["test_pattern"]
    report = _run(("test_pattern", {}, [])).report
    print(
        f"1. speed, 240 s test pattern at 134 Hz ({report['imu_samples']} IMU samples): read "
        f"{report['read_time_s']:.2f} s + fusion {report['fusion_time_s']:.2f} s = "
        f"{report['wall_time_s']:.2f} s -> {report['realtime_factor']:.0f}x real time "
        f"(fusion alone {inputs.duration_s / report['fusion_time_s']:.0f}x)"
    )


def bench_acceptance(pool: ProcessPoolExecutor) -> None:
    outages = _outages(20.0)
    jobs: list[Job] = [
        ("test_pattern", {}, outages),
        ("test_pattern", {"use_attitude": False}, outages),
    ]
    print(
        "\n2. acceptance: imu400cc, test pattern, RTK 1 Hz,"
        " 20 s outages at 50/85/145 s of the drive"
    )
    for (_, parameters, _), summary in zip(jobs, pool.map(_run, jobs), strict=True):
        report = summary.report
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
        known = summary.heading_known_s
        print(
            f"    roll/pitch/yaw rms {_fmt(att['roll_rms'])}/{_fmt(att['pitch_rms'])}/"
            f"{_fmt(att['yaw_rms'])} deg, yaw max {_fmt(att['yaw_max'])} deg; heading known"
            f" (yaw σ < {HEADING_KNOWN_SIGMA_DEG:.0f}°) at {_fmt(known, 1)} s"
            f" ({_fmt(None if known is None else known - DRIVE_START_S, 1)} s after the drive"
            f" starts), yaw rms from then on {_fmt(summary.yaw_rms_known_deg)} deg"
        )
        for part, title in (("in_outage", "in outages"), ("out_of_outage", "outside")):
            stats = nees[part]
            fraction = stats["position_within_3sigma_fraction"]
            print(
                f"    position NEES {title}: mean {_fmt(stats['position_mean'], 2)} (dof 3),"
                f" {_fmt(None if fraction is None else 100 * fraction, 1)} % within 3σ"
                f" ({stats['samples']} stamps)"
            )


def bench_outage_lengths(pool: ProcessPoolExecutor) -> None:
    jobs: list[Job] = []
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
    for key, summary in zip(keys, pool.map(_run, jobs), strict=True):
        ends[key] += [o["horizontal_error_end_m"] for o in summary.report["outages"]]
        nees[key].append(summary.report["nees"]["in_outage"]["position_mean"])
    print("\n3. horizontal error [m] at the end of outages at 50/85/145 s of the drive")
    print(f"  {'length':>6}  {'variant':<13}  {'ends':<24}  NEES in outages")
    for key, values in ends.items():
        cells = "/".join(_fmt(v, 2) for v in values)
        means = ", ".join(_fmt(v, 2) for v in nees[key])
        print(f"  {key[0]:>5.0f}s  {key[1]:<13}  {cells:<24}  {means}")


def bench_noise_free(pool: ProcessPoolExecutor) -> None:
    cases = [
        (gnss, filter_label, parameters)
        for gnss in ("rtk", "exact")
        for filter_label, parameters in (("default", {}), ("perfect IMU", PERFECT_IMU))
    ]
    jobs: list[Job] = [
        (f"{gnss}{seed}", parameters, [])
        for gnss, _, parameters in cases
        for seed in NOISE_FREE_SEEDS
    ]
    summaries = iter(pool.map(_run, jobs))
    print(
        f"\n4. noise-free IMU (ideal), 600 s test pattern, no outage: horizontal error [cm] at"
        f" the end and over the last {LAST_MINUTE_S:.0f} s; 'perfect IMU' = imu_noise densities"
        f" x {PERFECT_IMU_FRACTION:g}; fixes = the bag's RTK fixes against the true antenna"
    )
    print(
        f"  {'GNSS':<5}  {'filter':<11}  seed  {'final':>6}  {'rms':>6}  {'p95':>6}  {'max':>6}"
        "  fixes rms run / last min"
    )
    for gnss, filter_label, _ in cases:
        rms = []
        for seed in NOISE_FREE_SEEDS:
            last = next(summaries).last_minute_m
            t, fix_error = _fix_errors(INPUTS[f"{gnss}{seed}"])
            fix_last = fix_error[t >= t[-1] - LAST_MINUTE_S]
            rms.append(last["rms"])
            cells = "  ".join(f"{100 * last[k]:6.2f}" for k in ("final", "rms", "p95", "max"))
            print(
                f"  {gnss:<5}  {filter_label:<11}  {seed:>4}  {cells}"
                f"  {100 * _rms(fix_error):6.2f} / {100 * _rms(fix_last):.2f}"
            )
        print(
            f"  {gnss:<5}  {filter_label:<11}   all  rms over the seeds' last minutes"
            f" {100 * math.sqrt(np.mean(np.square(rms))):.2f} cm (worst seed"
            f" {100 * max(rms):.2f})"
        )


def main() -> None:
    configs = {"test_pattern": SimulationConfig(duration_s=240.0, seed=1)}
    for seed in NOISE_FREE_SEEDS:
        for gnss, scale in (("rtk", 1.0), ("exact", 0.0)):
            configs[f"{gnss}{seed}"] = SimulationConfig(  # noise-free: no vibration either
                imu="ideal", duration_s=600.0, seed=seed, gnss_noise_scale=scale, vibration="none"
            )
    context = multiprocessing.get_context("fork")
    with tempfile.TemporaryDirectory() as tmp:
        paths = [Path(tmp) / name for name in configs]
        with ProcessPoolExecutor(mp_context=context) as pool:
            jobs = zip(paths, configs.values(), strict=True)
            INPUTS.update(zip(configs, pool.map(_simulate, jobs), strict=True))
        # Read again alone: its read time is part of the speed.
        INPUTS["test_pattern"] = load_bag(paths[0])
    bench_speed()
    with ProcessPoolExecutor(mp_context=context) as pool:
        bench_acceptance(pool)
        bench_outage_lengths(pool)
        bench_noise_free(pool)


if __name__ == "__main__":
    main()
