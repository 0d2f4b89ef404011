"""The compiled engine (numba, core.compiled) against its pure-Python source: the same drive
replayed in this process (compiled) and in a process with NUMBA_DISABLE_JIT=1 (every parameter
set in one run) must give the same track to 1e-9."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from support.compiled_tracks import OUTAGES, PARAMETER_SETS, track
from support.paths import FIXTURES, TESTS
from support.sim_bags import FIGURE_EIGHT_90_S, shared_bag

from gnss_ins_common.params import validate_all
from ins_fusion.core.compiled import jit
from ins_fusion.core.engine import intake, sample_runs
from ins_fusion.core.engine.warm_up import warm_up
from ins_fusion.core.filter import adaptation, propagation, state, update_algebra
from ins_fusion.core.measurements import (
    attitude,
    gnss_noise,
    gnss_position,
    gnss_velocity,
    nhc,
    stationary,
    stop_detector,
    vehicle_speed,
)
from ins_fusion.core.nav import strapdown
from ins_fusion.core.output import output_numbers, solution
from ins_fusion.core.settings.params import PARAMETERS
from ins_fusion.replay.inputs import load_bag
from ins_fusion.replay.run import run_fusion
from ins_fusion.replay.topics import TopicMap

#: Saves the track of every parameter set (argv: the test tree's root, bag, output folder).
_RUN = """
import sys
from pathlib import Path
import numpy as np
sys.path.insert(0, sys.argv[1])
from support.compiled_tracks import PARAMETER_SETS, track
for name in PARAMETER_SETS:
    np.save(Path(sys.argv[3]) / f"{name}.npy", track(Path(sys.argv[2]), name))
"""


@pytest.fixture(scope="module")
def drive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return shared_bag(tmp_path_factory, "figure_eight_90_s", FIGURE_EIGHT_90_S)


@pytest.fixture(scope="module")
def pure_tracks(drive: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[str, np.ndarray]:
    """The track of every parameter set from the pure-Python source (one process)."""
    out = tmp_path_factory.mktemp("pure")
    env = {**os.environ, "NUMBA_DISABLE_JIT": "1"}
    subprocess.run(
        [sys.executable, "-c", _RUN, str(TESTS), str(drive), str(out)], check=True, env=env
    )
    return {name: np.load(out / f"{name}.npy") for name in PARAMETER_SETS}


#: The whole session runs uncompiled: nothing to compare with.
_PURE_SESSION = os.environ.get("NUMBA_DISABLE_JIT") == "1"


@pytest.mark.parametrize("parameter_set", sorted(PARAMETER_SETS))
def test_compiled_track_equals_pure_python(
    drive: Path, pure_tracks: dict[str, np.ndarray], parameter_set: str
) -> None:
    if _PURE_SESSION:
        pytest.skip("pure-Python run requested")
    assert all(hasattr(kernel, "py_func") for kernel in _KERNELS)  # compiled, not Python
    compiled = track(drive, parameter_set)
    pure = pure_tracks[parameter_set]
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
    nhc.nhc_model,
    propagation.advance,
    propagation.covariance_step,
    propagation.predicted_state,
    update_algebra.joseph_update,
    solution._fill_row,
    state.inject_nominal,
    gnss_noise._position_noise,
    gnss_noise.shrink_correlated,
    gnss_position.position_model,
    gnss_velocity.velocity_model,
    update_algebra.projected_variance,
    update_algebra.covariance_problem,
    adaptation.white_push_fix,
    output_numbers.output_numbers,
    sample_runs.take_run,
    sample_runs.advance_run,
    nhc.nhc_apply,
    gnss_velocity.velocity_apply,
    gnss_position.position_apply,
    attitude.attitude_apply,
    attitude.attitude_model,
    stationary.zupt_apply,
    stationary.zaru_apply,
    stationary.zupt_model,
    stationary.zaru_model,
    vehicle_speed.speed_model,
)
_REAL = FIXTURES / "comma2k19" / "comma2k19_ex1_seg40"
_REAL_SPEED = _REAL.with_name("comma2k19_ex1_seg40_speed")


def _callee_specialised(signatures: list[tuple[object, ...]]) -> bool:
    """Two signatures that differ only where one has a literal (numba's Literal type)."""
    if len(signatures) != 2:
        return False
    first, second = (tuple(str(t) for t in s) for s in signatures)
    return len(first) == len(second) and all(
        a == b or "Literal" in a or "Literal" in b for a, b in zip(first, second, strict=True)
    )


def test_warm_up_types_every_kernel_the_drives_use(drive: Path) -> None:
    """After core.engine.warm_up, drives (simulated with every optional state, the real segment) add
    no compilation: a live sample never waits for the compiler."""
    if _PURE_SESSION:
        pytest.skip("pure-Python run requested")
    warm_up()
    assert all(hasattr(kernel, "py_func") for kernel in _KERNELS)  # compiled, not Python
    signatures = {kernel: list(kernel.signatures) for kernel in _KERNELS}
    # One set of argument types each; compiled afresh (an empty cache), a kernel that another
    # kernel calls also gets the caller's specialisation (a literal flag or column: advance,
    # attitude_model, zaru_model), which a process loading the cache does not list.
    assert all(len(s) == 1 or _callee_specialised(s) for s in signatures.values()), signatures
    all_states = {**PARAMETER_SETS["all_states"], "gnss_noise.correlation_time": 0.0}
    for bag, values in ((drive, all_states), (drive, {}), (_REAL, {}), (_REAL_SPEED, {})):
        run = run_fusion(load_bag(bag, TopicMap()), validate_all(PARAMETERS, values), OUTAGES)
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


def test_the_kernel_cache_is_dropped_when_the_sources_change(tmp_path):
    """numba would keep a caller's cached code after its callee's source changed: the caches of
    the package and its sub-packages go when any of their sources does (and only then)."""
    from ins_fusion.core.compiled import drop_stale_kernels

    (tmp_path / "kernel.py").write_text("def f(): return 1\n")
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "callee.py").write_text("def g(): return 1\n")
    kernels = []
    for folder, module in ((tmp_path, "kernel"), (tmp_path / "sub", "callee")):
        cache = folder / "__pycache__"
        cache.mkdir()
        kernels += [cache / f"{module}.f-1.py311.nbi", cache / f"{module}.f-1.py311.1.nbc"]
    other = tmp_path / "__pycache__" / "kernel.cpython-311.pyc"
    for path in [*kernels, other]:
        path.write_bytes(b"x")
    assert drop_stale_kernels(tmp_path)  # no digest yet: of unknown sources
    assert not any(k.exists() for k in kernels) and other.exists()
    for source in ("kernel.py", "sub/callee.py"):
        for path in kernels:
            path.write_bytes(b"x")
        assert not drop_stale_kernels(tmp_path)  # same sources: kept
        assert all(k.exists() for k in kernels)
        (tmp_path / source).write_text("def f(): return 2\n")
        assert drop_stale_kernels(tmp_path)
        assert not any(k.exists() for k in kernels)
