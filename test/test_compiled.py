"""The compiled engine (numba, core.compiled) against its pure-Python source: the same drive
replayed in two processes, one with NUMBA_DISABLE_JIT=1, must give the same track to 1e-9."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gnss_ins_common.params import validate_all
from ins_fusion.core import (
    eskf,
    intake,
    measurements,
    propagation,
    solution,
    state,
    stop_detector,
    strapdown,
)
from ins_fusion.core.compiled import jit
from ins_fusion.core.params import PARAMETERS
from ins_fusion.core.warm_up import warm_up
from ins_fusion.replay.inputs import load_bag
from ins_fusion.replay.outages import Outage
from ins_fusion.replay.run import run_fusion
from ins_fusion.replay.topics import TopicMap
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


#: The kernels the engine calls from Python, each to be compiled for one set of argument types
#: (strapdown.mechanize is compiled into propagation.advance, the calibration into
#: intake.take_sample).
_KERNELS = (
    strapdown.integrate_sample,
    intake.take_sample,
    intake.record_sample,
    stop_detector.ring_push,
    stop_detector.window_statistics,
    measurements._nhc_model,
    propagation.advance,
    propagation.covariance_interval,
    propagation.predicted_state,
    eskf._propagate,
    eskf._joseph_update,
    solution._fill_row,
    state.inject_nominal,
)
_REAL = Path(__file__).parent / "fixtures" / "comma2k19" / "comma2k19_ex1_seg40"


def test_warm_up_types_every_kernel_the_drives_use(drive: Path) -> None:
    """After core.warm_up, drives (simulated with every optional state, the real segment) add
    no compilation: a live sample never waits for the compiler."""
    if os.environ.get("NUMBA_DISABLE_JIT") == "1":
        pytest.skip("pure-Python run requested")
    warm_up()
    assert all(hasattr(kernel, "py_func") for kernel in _KERNELS)  # compiled, not Python
    signatures = {kernel: list(kernel.signatures) for kernel in _KERNELS}
    assert all(len(s) == 1 for s in signatures.values()), signatures
    all_states = {
        "self_calibration.mounting": True,
        "self_calibration.time_offset": True,
        "imu_noise.gyro_scale_sigma": 0.001,
        "imu_noise.accel_scale_sigma": 0.001,
        "gnss_noise.correlation_time": 0.0,
    }
    for bag, values in ((drive, all_states), (drive, {}), (_REAL, {})):
        run = run_fusion(
            load_bag(bag, TopicMap()), validate_all(PARAMETERS, values), (Outage(40.0, 15.0),)
        )
        assert len(run.track.rows) > 1000
    assert {kernel: list(kernel.signatures) for kernel in _KERNELS} == signatures


def test_kernel_without_a_writable_cache_still_compiles() -> None:
    """A function numba cannot cache (no file: no cache locator, as for a read-only install
    and home) is compiled without the cache, with a warning naming NUMBA_CACHE_DIR."""
    namespace: dict[str, object] = {}
    exec("def add_one(x):\n    return x + 1.0", namespace)  # defined without a source file
    with pytest.warns(RuntimeWarning, match="NUMBA_CACHE_DIR"):
        kernel = jit(namespace["add_one"])
    assert kernel(1.0) == 2.0
