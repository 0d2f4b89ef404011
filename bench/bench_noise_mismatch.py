"""Ordinary noise models and vibration (issue 10 acceptance, simulated part): the engine given
datasheet noise parameters on drives whose noise differs from them; prints tables and verdicts.

Harness: test/support/mismatch_drives.py (streams from the ins_fusion.sim API, figure-eight drive of
200 s) and test/support/noise_mismatch.py (errors of base_link from 30 s on at 10 Hz). Baseline:
test/support/reference_ekf.py, a
position-only 15-state EKF told the exact simulated noise and started at the true state.

1. IMU {stim300 (tactical, 500 Hz), imu400cc (MEMS, 134 Hz)} x GNSS {Leica RTK 1 Hz, white
   5 m at 5 Hz} x vibration {none, car}, datasheet parameters: position NEES (3 dof), share of
   stamps with E, N and U inside 3σ, share of the fixes gated, horizontal RMS against the
   baseline's, and the noise the engine adapted to.
2. The baseline (a column of 1 and 3).
3. imu400cc with the car vibration scaled to 10x its datasheet density (equivalent density,
   RMS over the drive), RTK with a 20 s outage while turning: horizontal error at the end of
   the outage with (a) datasheet and (b) exact parameters (datasheet ⊕ vibration), and the
   share of stamps with roll, pitch, yaw inside 3σ of the filter's attitude covariance.
4. Diagnostic (no acceptance item): case 1's stim300 / RTK / no vibration without the profile's
   per-power-up scale-factor and misalignment draws.

Acceptance (issue 10): NEES mean in [1.5, 6], >= 95 % inside 3σ, < 5 % of fixes gated, RMS <=
baseline, drift ratio (a)/(b) <= 1.5. A failed item is printed as FAIL; nothing is tuned here.

Usage: python bench/bench_noise_mismatch.py [--seeds 1 2 3] [--case 1 3 4] [--per-seed]
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ins_fusion.core.nav.units import to_deg_sqrt_h, to_m_s_sqrt_h
from ins_fusion.sim.imu_model import PROFILES as IMU_PROFILES
from ins_fusion.sim.vibration import CAR

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "test"))  # the harness is a test helper

from support.mismatch_drives import (  # noqa: E402
    DURATION_S,
    SCENARIO,
    Streams,
    build_streams,
    drive_truth,
    scaled_vibration,
)
from support.noise_mismatch import (  # noqa: E402
    EVALUATE_FROM_S,
    Track,
    datasheet_parameters,
    exact_parameters,
    run_engine,
    run_reference,
)

IMUS = (("stim300", "tactical"), ("imu400cc", "MEMS"))
GNSS = (("rtk", "RTK"), ("white5", "white 5 m"))
VIBRATIONS = ("none", "car")
NEES_RANGE = (1.5, 6.0)
WITHIN_MIN = 0.95
GATED_MAX = 0.05
DRIFT_RATIO_MAX = 1.5
#: Case 3: 20 s outage while the figure-eight turns; vibration / datasheet density.
OUTAGE = (120.0, 20.0)
VIBRATION_RATIO = 10.0
#: The simulated white part of the GNSS position error per E/N/U axis [m] (RTK fixed: the
#: receiver model's white σ; its correlated part, as large again, is not white).
EXACT_GNSS_WHITE = {"rtk": "0.014/0.014/0.021", "white5": "5/5/5"}
#: RMS also over the last stretch (after the engine's convergence) [s].
LATE_FROM_S = 100.0


def verdict(ok: bool) -> str:
    return "ok" if ok else "FAIL"


def axes(values: np.ndarray, fmt: str = "{:.3g}") -> str:
    return "/".join(fmt.format(v) for v in values)


@dataclass
class Outcome:
    """One engine run and the baseline on the same streams."""

    seed: int
    streams: Streams
    engine: Track
    reference: Track

    def adapted(self, kind: str) -> np.ndarray:
        names = {
            "gyro": [f"gyro_arw_{a}_deg_sqrt_h" for a in "xyz"],
            "accel": [f"accel_vrw_{a}_m_s_sqrt_h" for a in "xyz"],
            "gnss": [f"gnss_white_sigma_{a}_m" for a in "enu"],
        }[kind]
        assert self.engine.status is not None
        return np.array([self.engine.status.adapted[n] for n in names])


def recoveries(track: Track) -> str:
    """Number of GNSS position gate recoveries and when (first 10 Hz stamp after each)."""
    if not track.recovery_t:
        return "0"
    return f"{len(track.recovery_t)} ({', '.join(f'{t:.1f}' for t in track.recovery_t)} s)"


def pooled_rms(tracks: list[Track], start_s: float) -> float:
    squares = [t.horizontal()[t.window(start_s)] ** 2 for t in tracks]
    return float(np.sqrt(np.mean(np.concatenate(squares))))


def pooled_nees(tracks: list[Track]) -> float:
    return float(np.mean([t.nees(t.window()) for t in tracks]))


def pooled_within(tracks: list[Track]) -> float:
    return float(np.mean([t.within_3_sigma(t.window()) for t in tracks]))


def case_1(seeds: list[int], per_seed: bool) -> list[str]:
    print(f"\n## Case 1: datasheet parameters, seeds {seeds}, {SCENARIO} {DURATION_S:.0f} s")
    failures: list[str] = []
    rows: list[str] = []
    adapted_rows: list[str] = []
    seed_rows: list[str] = []
    for imu, imu_label in IMUS:
        for gnss, gnss_label in GNSS:
            for vib in VIBRATIONS:
                outcomes = []
                for seed in seeds:
                    streams = build_streams(imu, gnss, vib, seed)
                    engine = run_engine(streams, datasheet_parameters(streams.profile))
                    outcomes.append(Outcome(seed, streams, engine, run_reference(streams)))
                engines = [o.engine for o in outcomes]
                refs = [o.reference for o in outcomes]
                nees, within = pooled_nees(engines), pooled_within(engines)
                gated = sum(
                    e.status.measurements["gnss_position"]["gated"]
                    for e in engines
                    if e.status is not None
                ) / sum(e.fixes for e in engines)
                rms, rms_ref = (
                    pooled_rms(engines, EVALUATE_FROM_S),
                    pooled_rms(refs, EVALUATE_FROM_S),
                )
                late, late_ref = pooled_rms(engines, LATE_FROM_S), pooled_rms(refs, LATE_FROM_S)
                checks = {
                    "NEES": NEES_RANGE[0] <= nees <= NEES_RANGE[1],
                    "3σ": within >= WITHIN_MIN,
                    "gated": gated < GATED_MAX,
                    "RMS": rms <= rms_ref,
                }
                label = f"{imu_label} ({imu}) | {gnss_label} | {vib}"
                failures += [
                    f"case 1 {label}: {name}"
                    + {
                        "NEES": f" {nees:.2f} outside [{NEES_RANGE[0]}, {NEES_RANGE[1]}]",
                        "3σ": f" {within * 100:.1f} % < 95 %",
                        "gated": f" {gated * 100:.1f} % >= 5 %",
                        "RMS": f" {rms:.3f} m > baseline {rms_ref:.3f} m ({rms / rms_ref:.2f}x)",
                    }[name]
                    for name, ok in checks.items()
                    if not ok
                ]
                rows.append(
                    f"| {label} | {nees:.2f} {verdict(checks['NEES'])} | "
                    f"{within * 100:.1f} % {verdict(checks['3σ'])} | "
                    f"{gated * 100:.1f} % {verdict(checks['gated'])} | "
                    f"{rms:.3f} / {rms_ref:.3f} {verdict(checks['RMS'])} | "
                    f"{late:.3f} / {late_ref:.3f} |"
                )
                profile = IMU_PROFILES[imu]
                density = outcomes[0].streams.vibration_density
                exact_g = np.hypot(np.array(profile.gyro.noise_density), density[0])
                exact_a = np.hypot(np.array(profile.accel.noise_density), density[1])
                mean = {
                    k: np.mean([o.adapted(k) for o in outcomes], axis=0)
                    for k in ("gyro", "accel", "gnss")
                }
                adapted_rows.append(
                    f"| {label} | {axes(mean['gyro'])} | "
                    f"{axes(np.array([to_deg_sqrt_h(x) for x in profile.gyro.noise_density]))} | "
                    f"{axes(np.array([to_deg_sqrt_h(x) for x in exact_g]))} | "
                    f"{axes(mean['accel'])} | "
                    f"{axes(np.array([to_m_s_sqrt_h(x) for x in profile.accel.noise_density]))} | "
                    f"{axes(np.array([to_m_s_sqrt_h(x) for x in exact_a]))} | "
                    f"{axes(mean['gnss'])} | {EXACT_GNSS_WHITE[gnss]} |"
                )
                for o in outcomes:
                    e, r = o.engine, o.reference
                    w = e.window()
                    assert e.status is not None
                    seed_rows.append(
                        f"| {label} | {o.seed} | {e.nees(w):.2f} | "
                        f"{e.within_3_sigma(w) * 100:.1f} % | "
                        f"{e.gated_fraction() * 100:.1f} % | {e.horizontal_rms(w):.3f} / "
                        f"{r.horizontal_rms(r.window()):.3f} | {r.nees(r.window()):.2f} | "
                        f"{recoveries(e)} | "
                        f"{e.status.adapted['fading_factor_last']:.3g} | {e.cpu_s:.1f} s |"
                    )
                print(f"  done: {label}", flush=True)
    print(
        "\nConsistency and accuracy (engine, datasheet parameters; RMS engine / baseline [m]; "
        f"from {EVALUATE_FROM_S:.0f} s, late = from {LATE_FROM_S:.0f} s):\n"
    )
    print(
        "| IMU | GNSS | vibration | NEES (3 dof) | E, N, U in 3σ | fixes gated | "
        "horiz. RMS / baseline | late RMS / baseline |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for row in rows:
        print(row)
    print(
        "\nAdapted noise at the end of the drive (mean over seeds; x/y/z or E/N/U): the "
        "engine's, the datasheet value it was given, and the exact value (datasheet ⊕ "
        "vibration equivalent density):\n"
    )
    print(
        "| IMU | GNSS | vibration | gyro ARW used [°/√h] | datasheet | exact | "
        "accel VRW used [m/s/√h] | datasheet | exact | GNSS white σ [m] | exact |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for row in adapted_rows:
        print(row)
    if per_seed:
        print("\nPer seed (baseline NEES: the reference filter's own position NEES):\n")
        print(
            "| IMU | GNSS | vibration | seed | NEES | in 3σ | gated | RMS / baseline [m] | "
            "baseline NEES | gate recoveries (at) | last fading | engine CPU |"
        )
        print("|---|---|---|---|---|---|---|---|---|---|---|---|")
        for row in seed_rows:
            print(row)
    return failures


def case_3(seeds: list[int]) -> list[str]:
    start, length = OUTAGE
    end = start + length
    print(
        f"\n## Case 3: imu400cc, car vibration scaled to {VIBRATION_RATIO:g}x the datasheet "
        f"density, RTK, outage {start:.0f}-{end:.0f} s, seeds {seeds}"
    )
    profile = IMU_PROFILES["imu400cc"]
    vib = scaled_vibration(CAR, profile, VIBRATION_RATIO, drive_truth(), DURATION_S)
    print(
        f"vibration σ at {vib.reference_speed_m_s:g} m/s: gyro "
        f"{axes(np.array(vib.gyro_sigma_rad_s), '{:.4f}')} rad/s, accel "
        f"{axes(np.array(vib.accel_sigma_m_s2), '{:.4f}')} m/s²"
    )
    failures: list[str] = []
    rows: list[str] = []
    drifts: dict[str, list[float]] = {"a": [], "b": [], "ref": []}
    attitude: dict[str, list[np.ndarray]] = {"a": [], "b": []}
    for seed in seeds:
        streams = build_streams("imu400cc", "rtk", vib, seed, outages=(OUTAGE,))
        exact = exact_parameters(streams.profile, streams.vibration_density)
        runs = {
            "a": run_engine(streams, datasheet_parameters(streams.profile)),
            "b": run_engine(streams, exact),
        }
        ref = run_reference(streams)
        if seed == seeds[0]:
            g, a = streams.vibration_density
            print(
                "equivalent density (RMS over the drive): gyro "
                f"{axes(np.array([to_deg_sqrt_h(x) for x in g]))} °/√h, accel "
                f"{axes(np.array([to_m_s_sqrt_h(x) for x in a]))} m/s/√h; exact parameters: "
                f"gyro ARW {axes(np.array(exact['imu_noise.gyro_arw']))} °/√h, accel VRW "
                f"{axes(np.array(exact['imu_noise.accel_vrw']))} m/s/√h"
            )
        for key, track in runs.items():
            drifts[key].append(track.horizontal_at(end))
            attitude[key].append(track.attitude_within_3_sigma(track.window()))
        drifts["ref"].append(ref.horizontal_at(end))
        ratio = drifts["a"][-1] / drifts["b"][-1]
        ra, rb = runs["a"], runs["b"]
        assert ra.status is not None
        rows.append(
            f"| {seed} | {drifts['a'][-1]:.2f} | {drifts['b'][-1]:.2f} | {ratio:.2f} "
            f"{verdict(ratio <= DRIFT_RATIO_MAX)} | {drifts['ref'][-1]:.2f} | "
            f"{axes(attitude['a'][-1] * 100, '{:.1f}')} | "
            f"{axes(attitude['b'][-1] * 100, '{:.1f}')} | "
            f"{ra.nees(ra.window()):.2f} / {rb.nees(rb.window()):.2f} | "
            f"{ra.gated_fraction() * 100:.1f} % / {rb.gated_fraction() * 100:.1f} % | "
            f"{axes(np.array([ra.status.adapted[f'gyro_arw_{x}_deg_sqrt_h'] for x in 'xyz']))} / "
            f"{axes(np.array([ra.status.adapted[f'accel_vrw_{x}_m_s_sqrt_h'] for x in 'xyz']))} |"
        )
        if ratio > DRIFT_RATIO_MAX:
            failures.append(f"case 3 seed {seed}: drift ratio {ratio:.2f} > {DRIFT_RATIO_MAX}")
    mean_ratio = float(np.mean(drifts["a"]) / np.mean(drifts["b"]))
    att = {k: np.mean(v, axis=0) for k, v in attitude.items()}
    print(
        "\nHorizontal error at the end of the outage [m]; roll/pitch/yaw inside 3σ of the "
        f"filter's attitude covariance (stamps from {EVALUATE_FROM_S:.0f} s); NEES and gated "
        "(a) / (b); adapted gyro ARW [°/√h] / accel VRW [m/s/√h] of (a):\n"
    )
    print(
        "| seed | (a) datasheet | (b) exact | ratio a/b | baseline | (a) r/p/y in 3σ [%] | "
        "(b) r/p/y in 3σ [%] | NEES a / b | gated a / b | adapted (a) |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for row in rows:
        print(row)
    print(
        f"| **mean** | **{np.mean(drifts['a']):.2f}** | **{np.mean(drifts['b']):.2f}** | "
        f"**{mean_ratio:.2f} {verdict(mean_ratio <= DRIFT_RATIO_MAX)}** | "
        f"**{np.mean(drifts['ref']):.2f}** | {axes(att['a'] * 100, '{:.1f}')} | "
        f"{axes(att['b'] * 100, '{:.1f}')} | | | |"
    )
    if mean_ratio > DRIFT_RATIO_MAX:
        failures.append(f"case 3 mean drift ratio {mean_ratio:.2f} > {DRIFT_RATIO_MAX}")
    for key, label in (("a", "datasheet"), ("b", "exact")):
        low = att[key] < WITHIN_MIN
        if low.any():
            failures.append(
                f"case 3 ({key}) {label}: roll/pitch/yaw in 3σ {axes(att[key] * 100, '{:.1f}')} % "
                "(below 95 %: informational, not an issue-10 acceptance item)"
            )
    return failures


def case_4(seeds: list[int]) -> None:
    """Diagnostic (no acceptance item): case 1's stim300 / RTK / no vibration row with the
    profile's per-power-up scale-factor and misalignment draws removed (neither filter models
    them: 500 / 300 ppm and 1 mrad against a 0.58 °/h gyro bias instability)."""
    print(
        "\n## Diagnostic 4: stim300, RTK, no vibration, without the profile's scale-factor and "
        f"misalignment draws, seeds {seeds}\n"
    )
    base = IMU_PROFILES["stim300"]
    profile = replace(
        base,
        gyro=replace(base.gyro, scale_sigma=(0.0, 0.0, 0.0), misalignment_sigma_rad=0.0),
        accel=replace(base.accel, scale_sigma=(0.0, 0.0, 0.0), misalignment_sigma_rad=0.0),
    )
    print("| seed | NEES | E, N, U in 3σ | gated | horiz. RMS / baseline [m] | baseline NEES |")
    print("|---|---|---|---|---|---|")
    for seed in seeds:
        streams = build_streams(profile, "rtk", "none", seed)
        e = run_engine(streams, datasheet_parameters(profile))
        r = run_reference(streams)
        w, wr = e.window(), r.window()
        print(
            f"| {seed} | {e.nees(w):.2f} | {e.within_3_sigma(w) * 100:.1f} % | "
            f"{e.gated_fraction() * 100:.1f} % | {e.horizontal_rms(w):.3f} / "
            f"{r.horizontal_rms(wr):.3f} | {r.nees(wr):.2f} |"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    parser.add_argument("--case", type=int, nargs="+", default=[1, 3, 4], choices=[1, 3, 4])
    parser.add_argument("--per-seed", action="store_true", help="print the per-seed table")
    args = parser.parse_args()
    start = time.monotonic()
    failures: list[str] = []
    if 1 in args.case:
        failures += case_1(args.seeds, args.per_seed)
    if 3 in args.case:
        failures += case_3(args.seeds)
    if 4 in args.case:
        case_4(args.seeds)
    print("\n## Verdicts")
    if failures:
        for failure in failures:
            print(f"FAIL {failure}")
    else:
        print("all acceptance items met")
    print(f"\nwall time {time.monotonic() - start:.0f} s")


if __name__ == "__main__":
    main()
