"""The compiled engine (numba, core.compiled) against its pure-Python source: the same drive
replayed in two processes, one with NUMBA_DISABLE_JIT=1, must give the same track to 1e-9."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ins_fusion.core import propagation, solution, strapdown
from ins_fusion.sim.drive import SimulationConfig
from ins_fusion.tools.simulate import write_bag

#: Runs the replay's engine over a bag and saves the track's rows (argv: bag, output, set).
_RUN = """
import sys
import numpy as np
from gnss_ins_common.params import validate_all
from ins_fusion.core.params import PARAMETERS
from ins_fusion.replay.inputs import load_bag
from ins_fusion.replay.outages import Outage
from ins_fusion.replay.run import run_fusion
from ins_fusion.replay.topics import TopicMap

sets = {
    "defaults": {},
    "all_states": {
        "self_calibration.mounting": True,
        "self_calibration.time_offset": True,
        "imu_noise.gyro_scale_sigma": 0.001,
        "imu_noise.accel_scale_sigma": 0.001,
    },
}
params = validate_all(PARAMETERS, sets[sys.argv[3]])
run = run_fusion(load_bag(sys.argv[1], TopicMap()), params, (Outage(40.0, 15.0),))
np.save(sys.argv[2], run.track.rows)
"""


@pytest.fixture(scope="module")
def drive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("compiled") / "drive"
    write_bag(SimulationConfig(scenario="figure_eight", duration_s=90.0, seed=6), path)
    return path


def _track(bag: Path, out: Path, parameter_set: str, pure_python: bool) -> np.ndarray:
    env = dict(os.environ)
    env.pop("NUMBA_DISABLE_JIT", None)
    if pure_python:
        env["NUMBA_DISABLE_JIT"] = "1"
    subprocess.run(
        [sys.executable, "-c", _RUN, str(bag), str(out), parameter_set], check=True, env=env
    )
    return np.load(out)


@pytest.mark.parametrize("parameter_set", ["defaults", "all_states"])
def test_compiled_track_equals_pure_python(drive: Path, tmp_path: Path, parameter_set: str) -> None:
    compiled = _track(drive, tmp_path / "compiled.npy", parameter_set, pure_python=False)
    pure = _track(drive, tmp_path / "pure.npy", parameter_set, pure_python=True)
    assert compiled.shape == pure.shape and len(compiled) > 2000
    assert np.isfinite(compiled[:, :50]).all()
    np.testing.assert_allclose(compiled, pure, rtol=1e-12, atol=1e-9)


def test_hot_path_is_compiled() -> None:
    """Without NUMBA_DISABLE_JIT the per-sample functions are numba dispatchers."""
    if os.environ.get("NUMBA_DISABLE_JIT") == "1":
        pytest.skip("pure-Python run requested")
    for function in (strapdown.mechanize, propagation.advance, solution._fill_row):
        assert hasattr(function, "py_func"), function
