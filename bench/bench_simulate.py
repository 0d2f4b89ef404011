"""Simulation speed of ins_fusion/sim and strapdown speed; prints numbers, asserts nothing.

1. IMU: ten minutes of the seed test pattern (60 s standstill + 3 × 180 s urban drive) at the
   IMU400CC's 134 Hz, truth of imu_link on the survey car plus the imu400cc error model, in
   blocks of 10 s as a bag writer would: simulated seconds per wall second.
2. GNSS: the Leica RTK (1 Hz) and ADU5 (5 Hz) error models over the same drive, with the truth
   evaluated per epoch (scalar gnss_truth) and from one batch per 10 s block (TruthCache, the bag
   writer's path).
3. Strapdown: SampleIntegrator + propagate per IMU sample (the filter's per-sample work):
   steps per second and the real-time factor at 134 Hz.
4. Bag writing (``gnss_ins simulate``): the same drive with the band-limited imu400cc at 134 Hz,
   the Leica RTK and the ADU5 through their NMEA and gnss_node's reading, and the truth at 50 Hz,
   to an MCAP and a sqlite3 bag: simulated seconds per wall second, messages per second, and the
   share of the message generation alone.
"""

from __future__ import annotations

import tempfile
import time
from contextlib import redirect_stdout
from io import StringIO
from pathlib import Path

import numpy as np

from ins_fusion.core.nav.rotation import flu_to_frd
from ins_fusion.core.nav.strapdown import SampleIntegrator, propagate
from ins_fusion.sim.drive import Simulation, SimulationConfig
from ins_fusion.sim.gnss_model import PROFILES as GNSS_PROFILES
from ins_fusion.sim.gnss_model import GnssErrorModel
from ins_fusion.sim.imu_model import IMU400CC, ImuErrorModel
from ins_fusion.sim.scenarios import SURVEY_CAR, seed_test_pattern
from ins_fusion.sim.simulated_bag import write_bag
from ins_fusion.sim.vehicle import TruthCache, VehicleTruth

DURATION_S = 600.0
BLOCK_S = 10.0


def bench_imu(truth: VehicleTruth) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
    model = ImuErrorModel(IMU400CC, seed=1)
    t_all = np.arange(0.0, DURATION_S, 1.0 / IMU400CC.rate_hz)
    rates, forces = [], []
    start = time.perf_counter()
    for block_start in np.arange(0.0, DURATION_S, BLOCK_S):
        t = t_all[(t_all >= block_start) & (t_all < block_start + BLOCK_S)]
        imu = truth.imu(t)
        rate, force = model.apply(t, imu.rate_flu_rad_s, imu.specific_force_flu_m_s2)
        rates.append(rate)
        forces.append(force)
    wall = time.perf_counter() - start
    return wall, t_all, np.concatenate(rates), np.concatenate(forces)


def main() -> None:
    start = time.perf_counter()
    trajectory = seed_test_pattern(DURATION_S)
    truth = VehicleTruth(trajectory, SURVEY_CAR)
    print(f"trajectory build ({DURATION_S:.0f} s drive): {time.perf_counter() - start:.3f} s")

    wall, t, rate, force = bench_imu(truth)
    print(
        f"IMU imu400cc at {IMU400CC.rate_hz:.0f} Hz: {len(t)} samples in {wall:.2f} s wall "
        f"-> {DURATION_S / wall:.0f} simulated s per wall s ({len(t) / wall:.0f} samples/s)"
    )

    for name in ("leica_rtk", "adu5"):
        profile = GNSS_PROFILES[name]
        model = GnssErrorModel(truth.gnss_truth, profile, seed=1)
        start = time.perf_counter()
        count = sum(1 for _ in model.fixes(0.0, DURATION_S))
        wall = time.perf_counter() - start
        cache = TruthCache(truth.gnss_truths, truth.gnss_truth)
        batched = GnssErrorModel(cache, profile, seed=1)
        start = time.perf_counter()
        for block_start in np.arange(0.0, DURATION_S, BLOCK_S):
            sum(1 for _ in batched.fixes(block_start, block_start + BLOCK_S))
        wall_batched = time.perf_counter() - start
        print(
            f"GNSS {name} at {profile.rate_hz:.0f} Hz: {count} fixes in {wall:.2f} s wall "
            f"-> {DURATION_S / wall:.0f} simulated s per wall s; truth batched per block: "
            f"{wall_batched:.2f} s -> {DURATION_S / wall_batched:.0f} simulated s per wall s"
        )

    rate_frd, force_frd = flu_to_frd(rate), flu_to_frd(force)
    state = truth.imu(t[:1]).nav_state(0)
    integrator = SampleIntegrator()
    integrator.push(float(t[0]), rate_frd[0], force_frd[0])
    prev = None
    start = time.perf_counter()
    for k in range(1, len(t)):
        inc = integrator.push(float(t[k]), rate_frd[k], force_frd[k])
        assert inc is not None
        state = propagate(state, inc, prev)
        prev = inc
    wall = time.perf_counter() - start
    steps = len(t) - 1
    print(
        f"strapdown (SampleIntegrator.push + propagate): {steps / wall:.0f} steps/s, "
        f"{wall / steps * 1e6:.1f} us/step -> {steps / wall / IMU400CC.rate_hz:.0f}x real time "
        "at 134 Hz"
    )

    config = SimulationConfig(duration_s=DURATION_S, seed=1)
    start = time.perf_counter()
    count = sum(1 for _ in Simulation(config).stream())
    generate = time.perf_counter() - start
    for storage in ("mcap", "sqlite3"):
        with tempfile.TemporaryDirectory() as tmp, redirect_stdout(StringIO()):
            start = time.perf_counter()
            write_bag(config, Path(tmp) / "drive", storage)
            wall = time.perf_counter() - start
        print(
            f"bag ({storage}) imu400cc 134 Hz band-limited + leica_rtk + adu5 + truth 50 Hz: "
            f"{count} messages in {wall:.2f} s wall -> {DURATION_S / wall:.0f} simulated s per "
            f"wall s ({count / wall:.0f} messages/s; generating them alone {generate:.2f} s)"
        )


if __name__ == "__main__":
    main()
