"""The parameter sets whose tracks the compiled kernels must reproduce, and the track of a bag
under one of them (shared by the kernel tests and the comparisons of the fast paths)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from gnss_ins_common.params import validate_all
from ins_fusion.core.settings.params import PARAMETERS
from ins_fusion.replay.inputs import load_bag
from ins_fusion.replay.outages import Outage
from ins_fusion.replay.run import run_fusion
from ins_fusion.replay.topics import TopicMap

PARAMETER_SETS: dict[str, dict[str, object]] = {
    "defaults": {},
    "all_states": {
        "self_calibration.mounting": True,
        "self_calibration.time_offset": True,
        "imu_noise.gyro_scale_sigma": 0.001,
        "imu_noise.accel_scale_sigma": 0.001,
    },
}


OUTAGES = (Outage(40.0, 15.0),)


def track(bag: Path, parameter_set: str) -> np.ndarray:
    params = validate_all(PARAMETERS, PARAMETER_SETS[parameter_set])
    return run_fusion(load_bag(bag, TopicMap()), params, OUTAGES).track.rows
