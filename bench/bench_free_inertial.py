"""The Aalborg report's evaluation of the IMU400CC on the simulated unit; prints ours beside the
report's numbers, asserts nothing (docs/accuracy.md quotes the output).

1. Random-error growth (report §2.1.2, Fig. 2-20; Aalborg notes §3.4): the constructed straight
   run (20 → 60 km/h in 10 s, then cruising) integrated by the strapdown alone from the true
   initial state, with only the IMU400CC's random errors (white noise, band-limited as the
   device; the Gauss-Markov bias instability, drawn stationary at the start; quantisation): no
   turn-on bias, scale factor or g-dependence. Mean horizontal and Down deviation over RUNS runs
   at 5...180 s; the report used 1000 pieces of 180 s of its 50 h static record. Then the white
   noise alone, at the profile's density and at WHITE_SCALE_FIT times it.
2. Free-inertial replay (report §9.1.3-§9.1.5, calibrations 03-05): SEEDS simulated test-pattern
   drives (60 s standstill, 180 s of urban driving) of the imu400cc profile with Leica RTK and
   ADU5, ``gnss_ins replay --free-inertial 60`` with the shipped calibration
   (config/imu400cc_calibration.yaml), σ_pos (9.3) and σ_afv (9.4) of the horizontal distance
   (2D) and the Down deviation (1D) at 5...180 s after the drive began, over the runs as the
   report took them over its six drives.

Usage: bench_free_inertial.py [RUNS] [SEEDS] (default 40 and 6).
"""

from __future__ import annotations

import json
import math
import sys
import tempfile
from contextlib import redirect_stderr, redirect_stdout
from dataclasses import replace
from io import StringIO
from pathlib import Path

import numpy as np

from ins_fusion.core.nav import earth
from ins_fusion.core.nav.rotation import flu_to_frd
from ins_fusion.core.nav.strapdown import SampleIntegrator, propagate
from ins_fusion.replay.free_inertial import ELAPSED_S, sigma_afv, sigma_pos
from ins_fusion.sim.imu_model import IMU400CC, ImuErrorModel, TriadErrors
from ins_fusion.sim.scenarios import SURVEY_CAR, aalborg_straight
from ins_fusion.sim.vehicle import VehicleTruth
from ins_fusion.tools import cli

REPO = Path(__file__).resolve().parents[1]
RATE_HZ = IMU400CC.rate_hz
#: Fig. 2-20 (Aalborg notes §3.4): mean deviation from random errors alone, straight run.
REPORT_TIMES_S = (5.0, 10.0, 20.0, 30.0, 45.0, 60.0, 120.0, 180.0)
REPORT_RANDOM_NE_M = (0.02, 0.14, 0.87, 2.5, 7.0, 14.5, 77.9, 184.8)
REPORT_RANDOM_DOWN_M = (0.002, 0.010, 0.037, 0.064, 0.105, 0.149, 0.417, 1.119)
#: Aalborg notes §8.3 (report Bilag 5 Fig. 5-2 to 5-4): σ_pos2D, σ_afv2D, σ_pos1D, σ_afv1D at
#: ELAPSED_S for calibrations 03 (biases), 04 (+ gyro scale) and 05 (+ accelerometer scale).
REPORT_CALIBRATIONS = {
    "03": (
        (0.46, 0.45, 1.43, 2.59, 7.07, 13.15, 21.64, 42.84, 212.43, 1043.03),
        (0.31, 0.22, 0.92, 1.75, 4.48, 6.89, 14.43, 25.64, 103.50, 314.05),
        (0.15, 0.33, 0.59, 0.84, 1.34, 1.94, 2.98, 4.29, 17.15, 34.64),
        (0.02, 0.03, 0.10, 0.19, 0.47, 0.64, 0.73, 0.94, 3.12, 7.51),
    ),
    "04": (
        (0.54, 0.68, 1.92, 3.54, 8.18, 11.45, 15.91, 28.52, 231.32, 1060.00),
        (0.38, 0.36, 1.20, 2.27, 4.65, 5.11, 8.72, 13.42, 85.40, 304.89),
        (0.15, 0.33, 0.60, 0.85, 1.41, 2.03, 2.97, 4.12, 16.25, 31.32),
        (0.02, 0.03, 0.10, 0.17, 0.42, 0.64, 0.75, 0.94, 3.13, 7.82),
    ),
    "05": (
        (0.49, 0.48, 1.89, 3.07, 7.66, 13.30, 19.50, 33.57, 250.99, 1123.84),
        (0.31, 0.20, 1.40, 2.26, 4.49, 5.08, 10.74, 18.83, 87.86, 336.87),
        (0.16, 0.36, 0.65, 0.93, 1.54, 2.21, 3.19, 4.43, 18.11, 35.53),
        (0.02, 0.03, 0.09, 0.17, 0.46, 0.77, 0.93, 1.24, 5.61, 13.77),
    ),
}
#: The white noise scale at which the report's Fig. 2-20 NE is matched: an ARW of 0.65 °/√h
#: (mean distance 1.25 g N sqrt(t⁵/20) through 14.5 m at 60 s) against the profile's 2.82-3.30.
WHITE_SCALE_FIT = 0.22
#: 60 s standstill + 180 s drive, and a second so that the last withheld fix brackets 180 s.
DRIVE_START_S, BAG_S = 60.0, 241.0


def _random_only(triad: TriadErrors, white_scale: float, instability: bool) -> TriadErrors:
    """The triad's random errors alone (white noise times white_scale, bias instability if
    ``instability``, random walk, counts)."""
    return TriadErrors(
        noise_density=(
            white_scale * triad.noise_density[0],
            white_scale * triad.noise_density[1],
            white_scale * triad.noise_density[2],
        ),
        bias_instability=triad.bias_instability if instability else (0.0, 0.0, 0.0),
        bias_correlation_time_s=triad.bias_correlation_time_s,
        random_walk=triad.random_walk,
        resolution=triad.resolution,
        bandwidth_hz=triad.bandwidth_hz,
    )


def random_error_growth(
    runs: int, white_scale: float = 1.0, instability: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """Mean horizontal and mean |Down| deviation [m] at REPORT_TIMES_S over ``runs`` runs."""
    profile = replace(
        IMU400CC,
        gyro=_random_only(IMU400CC.gyro, white_scale, instability),
        accel=_random_only(IMU400CC.accel, white_scale, instability),
        gyro_g_sensitivity=((0.0, 0.0, 0.0),) * 3,
    )
    truth = VehicleTruth(aalborg_straight(180.0), SURVEY_CAR)
    t = np.arange(round(180.0 * RATE_HZ) + 1) / RATE_HZ
    imu = truth.imu(t)
    checks = [round(s * RATE_HZ) for s in REPORT_TIMES_S]
    horizontal, down = np.zeros((runs, len(checks))), np.zeros((runs, len(checks)))
    for run in range(runs):
        rate, force = ImuErrorModel(profile, seed=run, band_limited=True).apply(
            t, imu.rate_flu_rad_s, imu.specific_force_flu_m_s2
        )
        rate, force = flu_to_frd(rate), flu_to_frd(force)
        state, integrator, prev = imu.nav_state(0), SampleIntegrator(), None
        integrator.push(t[0], rate[0], force[0])
        column = 0
        for k in range(1, len(t)):
            inc = integrator.push(t[k], rate[k], force[k])
            assert inc is not None
            state, prev = propagate(state, inc, prev), inc
            if k == checks[column]:
                r_m, r_n = earth.radii_m(state.lat_rad)
                north = (state.lat_rad - imu.lat_rad[k]) * (r_m + state.height_m)
                east = (
                    (state.lon_rad - imu.lon_rad[k])
                    * (r_n + state.height_m)
                    * math.cos(state.lat_rad)
                )
                horizontal[run, column] = math.hypot(north, east)
                down[run, column] = abs(imu.height_m[k] - state.height_m)
                column += 1
                if column == len(checks):
                    break
    return horizontal.mean(axis=0), down.mean(axis=0)


def _quiet(argv: list[str]) -> int:
    with redirect_stdout(StringIO()), redirect_stderr(StringIO()):
        return cli.main(argv)


def free_inertial_runs(seeds: int, work: Path) -> tuple[np.ndarray, np.ndarray]:
    """Horizontal distance and Down deviation (seeds, len(ELAPSED_S)) [m] of the replays."""
    horizontal, down = [], []
    calibration = REPO / "config" / "imu400cc_calibration.yaml"
    for seed in range(1, seeds + 1):
        bag, report = work / f"drive{seed}", work / f"drive{seed}.json"
        simulate = ["simulate", "--scenario", "test_pattern", "--imu", "imu400cc", "--adu5"]
        if _quiet([*simulate, "--duration", str(BAG_S), "--seed", str(seed), "-o", str(bag)]):
            raise RuntimeError(f"simulate seed {seed} failed")
        replay = ["replay", str(bag), "--free-inertial", str(DRIVE_START_S), "--report"]
        if _quiet([*replay, str(report), "--set", f"calibration_file={calibration}"]):
            raise RuntimeError(f"replay seed {seed} failed")
        section = json.loads(report.read_text())["free_inertial"]
        horizontal.append([math.nan if v is None else v for v in section["horizontal_m"]])
        down.append([math.nan if v is None else v for v in section["down_m"]])
        print(
            f"  seed {seed}: horizontal at 30/60/180 s {horizontal[-1][4]:.2f} / "
            f"{horizontal[-1][7]:.2f} / {horizontal[-1][9]:.1f} m",
            flush=True,
        )
    return np.array(horizontal), np.array(down)


def _row(label: str, values: object) -> str:
    return f"| {label} | " + " | ".join(f"{v:.3g}" for v in np.asarray(values)) + " |"


def main() -> None:
    runs = int(sys.argv[1]) if len(sys.argv) > 1 else 40
    seeds = int(sys.argv[2]) if len(sys.argv) > 2 else 6
    print(f"1. Random errors only, constructed straight run, {runs} runs (report: 1000)")
    horizontal, down = random_error_growth(runs)
    print("| s | " + " | ".join(f"{s:g}" for s in REPORT_TIMES_S) + " |")
    print("|---" * (len(REPORT_TIMES_S) + 1) + "|")
    print(_row("ours, mean NE [m]", horizontal))
    print(_row("report Fig. 2-20, NE [m]", REPORT_RANDOM_NE_M))
    print(_row("ours, mean Down [m]", down))
    print(_row("report Fig. 2-20, Down [m]", REPORT_RANDOM_DOWN_M))
    for scale in (1.0, WHITE_SCALE_FIT):
        horizontal, down = random_error_growth(runs, scale, instability=False)
        print(_row(f"ours, white noise × {scale:g} only, NE [m]", horizontal))
        print(_row(f"ours, white noise × {scale:g} only, Down [m]", down))
    print(
        f"\n2. Free-inertial replay of {seeds} simulated test-pattern drives, shipped calibration"
    )
    with tempfile.TemporaryDirectory() as work:
        d2, d1 = free_inertial_runs(seeds, Path(work))
    print("| s | " + " | ".join(f"{s:g}" for s in ELAPSED_S) + " |")
    print("|---" * (len(ELAPSED_S) + 1) + "|")
    ours = (sigma_pos(d2), sigma_afv(d2), sigma_pos(d1), sigma_afv(d1))
    names = ("σ_pos2D", "σ_afv2D", "σ_pos1D", "σ_afv1D")
    for k, name in enumerate(names):
        print(_row(f"ours {name}", ours[k]))
        for calibration, table in REPORT_CALIBRATIONS.items():
            print(_row(f"report {calibration} {name}", table[k]))


if __name__ == "__main__":
    main()
