"""`gnss_ins allan` on 40 min static records of the simulated IMU400CC (134 Hz, band-limited):
what the provisional noise file holds (ins_fusion.noise_id.provisional); prints numbers, asserts
nothing.

Per axis over the seeds: recovered / true white noise (ARW/VRW), the node's provisional bias σ
over the true Gauss-Markov σ (min, median, max), how often it comes from the floor B, and the
record length the tool asks for (median). docs/allan.md §6 quotes the output.
"""

from __future__ import annotations

import numpy as np

from ins_fusion.noise_id.analysis import identify
from ins_fusion.noise_id.provisional import provisional_biases
from ins_fusion.noise_id.record import sample_clock
from ins_fusion.noise_id.synthetic import static_record
from ins_fusion.sim.imu_model import PROFILES

LENGTH_S = 2400.0
SEEDS = range(1, 13)


def main() -> None:
    profile = PROFILES["imu400cc"]
    triads = (profile.gyro, profile.gyro, profile.gyro, profile.accel, profile.accel, profile.accel)
    white, sigma, floor, needed = [], [], [], []
    for seed in SEEDS:
        record = static_record(profile, LENGTH_S, seed=seed, band_limited=True)
        report = identify(record, sample_clock(record.t_s), f"seed {seed}")
        covers = provisional_biases(report)
        white.append(
            [
                a.terms.white.value / t.noise_density[i % 3]
                for i, (a, t) in enumerate(zip(report.axes, triads, strict=True))
            ]
        )
        row_sigma, row_floor, row_needed = [], [], []
        for i, (axis, triad) in enumerate(zip(report.axes, triads, strict=True)):
            cover = covers.of(axis)
            value = axis.terms.bias.sigma.value if cover is None and axis.terms.bias else np.nan
            row_sigma.append((cover.sigma if cover else value) / triad.bias_instability[i % 3])
            row_floor.append(bool(cover and cover.sigma_from_floor))
            row_needed.append(cover.needed_s if cover else 0.0)
        sigma.append(row_sigma)
        floor.append(row_floor)
        needed.append(row_needed)
        print(f"seed {seed}: T {covers.time_constant_s:.0f} s, provisional axes {len(covers.axes)}")
    names = [a.name for a in report.axes]
    w, s, f, n = (np.array(x) for x in (white, sigma, floor, needed))
    print(f"\n{LENGTH_S / 60:.0f} min at {profile.rate_hz:g} Hz, {len(SEEDS)} seeds")
    print(
        "| axis | white found/true: min, max | bias sigma node/true: min, median, max "
        "| from floor B | record asked (median) |"
    )
    print("|---|---|---|---|---|")
    for k, name in enumerate(names):
        print(
            f"| {name} | {w[:, k].min():.3f}, {w[:, k].max():.3f} | {s[:, k].min():.2f}, "
            f"{np.median(s[:, k]):.2f}, {s[:, k].max():.2f} | {f[:, k].sum()}/{len(SEEDS)} | "
            f"{np.median(n[:, k]) / 3600:.0f} h |"
        )


if __name__ == "__main__":
    main()
