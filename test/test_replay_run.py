"""One engine run of the replay (ins_fusion.replay.run): the solution is recorded once per
output tick, also when the IMU samples fall exactly on the ticks."""

from __future__ import annotations

import numpy as np

from ins_fusion.adapters.messages_in import ImuSample
from ins_fusion.core.measurements import GnssFixMeasurement
from ins_fusion.replay.inputs import ImuSeries, ReplayInputs
from ins_fusion.replay.run import run_fusion
from ins_fusion.replay.topics import TopicMap

T0_S = 1717236000.0  # stamps in seconds since 1970, as in a bag: k / rate is not exact there


def test_one_solution_per_output_tick_at_200_hz():
    """200 Hz samples, 50 Hz output: every tick falls on a sample; a stamp a rounding error
    before its tick must not record the next sample too (it did: half the ticks twice)."""
    imu = ImuSeries.from_samples(
        [ImuSample(T0_S + k / 200.0, (0.0, 0.0, 0.0), (0.0, 0.0, 9.81)) for k in range(2800)]
    )
    fixes = [
        (k, "fix", GnssFixMeasurement(T0_S + k / 200.0, 57.0, 10.0, 50.0, np.eye(3) * 1e-4))
        for k in range(0, 2800, 40)
    ]
    run = run_fusion(ReplayInputs("bag", TopicMap(), imu, fixes, None, 0.0), {})
    t = run.track.t_s
    assert len(t) > 100  # recorded from the end of the 10 s levelling on
    assert np.allclose(np.diff(t), 0.02, atol=1e-6)
    ticks = (t - T0_S) * 50.0
    assert np.allclose(ticks, np.round(ticks), atol=1e-4)  # each at its tick's own sample
