"""The engine run sample by sample (the general path) on a simulated drive, clean or damaged,
for comparing the compiled runs with it (tests and bench/engine_fingerprint.py)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ins_fusion.core.engine.engine import InsEngine
from ins_fusion.core.engine.smoothed_solution import attach_history
from ins_fusion.core.output.output_clock import output_ticks
from ins_fusion.core.settings.config import FusionConfig
from ins_fusion.replay.inputs import ImuSeries, ReplayInputs, load_bag
from ins_fusion.replay.topics import TopicMap
from support.compiled_tracks import PARAMETER_SETS
from support.sim_bags import FIGURE_EIGHT_90_S, shared_bag

#: The kernel tests' parameter sets, the second also with an IMU time offset taken off its
#: stamps, and one without pseudo-measurements.
SETS: dict[str, dict[str, object]] = {
    "defaults": PARAMETER_SETS["defaults"],
    "all_states": {**PARAMETER_SETS["all_states"], "imu_time_offset": 0.004},
    # no pseudo-measurement epoch, a short covariance interval: re-propagations reach it
    "no_pseudo": {
        "use_nhc": False,
        "use_zupt": False,
        "use_zaru": False,
        "covariance_interval": 0.02,
    },
}


def figure_eight(tmp_path_factory: pytest.TempPathFactory) -> ReplayInputs:
    """The 90 s figure-eight drive's inputs (its bag built once per session)."""
    return load_bag(
        shared_bag(tmp_path_factory, "figure_eight_90_s", FIGURE_EIGHT_90_S), TopicMap()
    )


def damaged(inputs: ReplayInputs) -> ReplayInputs:
    """Corrupt samples, a 0.3 s gap, a duplicate, one stamp out of order, and at 70 s the clock
    back by 2 s for the rest (a restarted stream: the engine resets)."""
    t, rate, force = (
        a.copy() for a in (inputs.imu.t_s, inputs.imu.rate_flu_rad_s, inputs.imu.force_flu_m_s2)
    )
    n = len(t)
    rate[n // 5, 1] = np.nan
    force[n // 4, 2] = 1e6  # beyond the range
    t[n // 3 + 7] = t[n // 3 + 6]  # duplicate stamp
    t[n // 2 + 3] = t[n // 2 + 1] - 0.001  # one sample in the past
    back = int(0.78 * n)
    t[back:] -= 2.0
    keep = np.ones(n, dtype=bool)
    keep[int(0.6 * n) : int(0.6 * n) + 40] = False  # 0.3 s gap at 134 Hz
    kept_before = np.cumsum(keep)  # [k]: samples kept among the first k + 1
    measurements = [
        (int(kept_before[k - 1]) if k else 0, role, m) for k, role, m in inputs.measurements
    ]
    imu = ImuSeries(t[keep], rate[keep], force[keep])
    return dataclasses.replace(inputs, imu=imu, measurements=measurements)


def sample_by_sample(inputs: ReplayInputs, parameters: dict[str, object], smooth: bool):
    """The replay's loop before the compiled runs: add_imu per sample, a row at each tick, the
    re-propagations entry by entry."""
    config = FusionConfig.from_parameters(parameters)
    engine = InsEngine(config)

    # Re-propagation entry by entry, as before the runs: no entry is taken in a run.
    engine._runs.repropagate = lambda _s, _kf, k: k
    if smooth:
        attach_history(engine)
    feed = {
        "fix": engine.add_gnss_fix,
        "vel": engine.add_gnss_velocity,
        "attitude": engine.add_attitude,
    }
    ticks = output_ticks(inputs.imu.t_s, inputs.t0_s, config.output_rate_hz)
    rows, j, kept = [], 0, inputs.measurements
    for k, (t, rate, force) in enumerate(inputs.imu.samples()):
        while j < len(kept) and kept[j][0] <= k:
            feed[kept[j][1]](kept[j][2])
            j += 1
        engine.add_imu(t, rate, force)
        if ticks[k] and (row := engine.solution_row()) is not None:
            rows.append(row)
    for _, role, measurement in kept[j:]:
        feed[role](measurement)
    return np.array(rows), engine.status()
