"""Where each module of the fusion core is tested: an explicit map, checked both ways. Every
module of ins_fusion/core has an entry, and every test module named for it imports it (or, for
the module only the engine reaches, drives the engine). A new core module without tests
fails here until it has them or its entry says why not."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
CORE = REPO / "ins_fusion" / "core"

#: core module (relative to ins_fusion/core) -> the test modules that test it directly.
TESTS: dict[str, tuple[str, ...]] = {
    "compiled.py": ("test_compiled.py",),
    "layout.py": ("test_core_layouts.py",),
    "nav/calibration.py": ("test_calibration_frame.py", "test_core_intake.py"),
    "nav/earth.py": ("test_earth.py",),
    "nav/levelling.py": ("test_fusion_config.py",),
    "nav/rotation.py": ("test_fusion_config.py", "test_fusion_eskf.py"),
    "nav/strapdown.py": ("test_compiled.py", "test_core_propagation.py"),
    "nav/units.py": ("test_fusion_config.py",),
    "settings/config.py": ("test_fusion_config.py",),
    "settings/params.py": ("test_fusion_config.py",),
    "smoother/history.py": ("test_smoother.py",),
    "smoother/rts.py": ("test_smoother.py",),
    "filter/adaptation.py": ("test_fusion_adaptation.py",),
    "filter/eskf.py": ("test_fusion_eskf.py",),
    "filter/propagation.py": ("test_core_propagation.py",),
    "filter/records.py": ("test_fusion_2d_fixes.py",),
    "filter/state.py": ("test_core_layouts.py", "test_core_heading.py"),
    "filter/status.py": ("test_fusion_timeline.py",),
    "filter/timeline.py": ("test_fusion_timeline.py",),
    "filter/update_algebra.py": ("test_fusion_eskf.py", "test_core_gate.py"),
    "measurements/attitude.py": ("test_fusion_eskf.py", "test_sample_runs.py"),
    "measurements/common.py": ("test_fusion_eskf.py",),
    "measurements/gate.py": ("test_core_gate.py",),
    "measurements/gnss_noise.py": ("test_fusion_gnss_noise.py",),
    "measurements/gnss_position.py": ("test_fusion_eskf.py", "test_fusion_2d_fixes.py"),
    "measurements/gnss_velocity.py": ("test_fusion_eskf.py", "test_sample_runs.py"),
    "measurements/heading.py": ("test_core_heading.py",),
    "measurements/nhc.py": ("test_fusion_eskf.py", "test_compiled.py"),
    "measurements/stationary.py": ("test_fusion_eskf.py", "test_sample_runs.py"),
    "measurements/stop_detector.py": ("test_fusion_config.py", "test_compiled.py"),
    "measurements/vehicle_speed.py": ("test_fusion_vehicle_speed.py",),
    "output/output_clock.py": ("test_replay_run.py",),
    "output/output_numbers.py": ("test_output_numbers.py",),
    "output/solution.py": ("test_output_numbers.py", "test_fusion_engine.py"),
    "output/solution_rows.py": ("test_sample_runs.py", "test_smoother_engine.py"),
    "engine/engine.py": ("test_fusion_engine.py", "test_fusion_drives.py"),
    "engine/intake.py": ("test_core_intake.py",),
    "engine/sample_runs.py": ("test_sample_runs.py",),
    "engine/smoothed_solution.py": ("test_smoother_engine.py",),
    "engine/startup.py": ("test_core_startup.py",),
    "engine/warm_up.py": ("test_compiled.py",),
}
#: Modules only the engine reaches (InsEngine's base class): tested through the engine's
#: tests, which must drive it.
THROUGH_THE_ENGINE: dict[str, tuple[str, ...]] = {
    "engine/loop.py": ("test_fusion_engine.py", "test_fusion_drives.py"),
}


def _core_modules() -> set[str]:
    return {
        path.relative_to(CORE).as_posix()
        for path in CORE.rglob("*.py")
        if path.name != "__init__.py" and "__pycache__" not in path.parts
    }


def _imports(test: str, module: str) -> bool:
    """Whether test/``test`` imports ins_fusion.core.``module`` (as a module or from it)."""
    dotted = "ins_fusion.core." + module.removesuffix(".py").replace("/", ".")
    package, name = dotted.rsplit(".", 1)
    text = (REPO / "test" / test).read_text()
    direct = re.search(rf"\b(from|import) {re.escape(dotted)}\b", text)
    listed = re.search(rf"from {re.escape(package)} import \(?[^)]*?\b{name}\b", text, re.S)
    return bool(direct or listed)


def test_every_core_module_has_an_entry_and_no_entry_is_stale():
    mapped = set(TESTS) | set(THROUGH_THE_ENGINE)
    assert _core_modules() - mapped == set(), "core modules without tests in the map"
    assert mapped - _core_modules() == set(), "entries for modules that do not exist"


@pytest.mark.parametrize(("module", "tests"), sorted(TESTS.items()))
def test_each_named_test_module_imports_its_core_module(module, tests):
    for test in tests:
        assert (REPO / "test" / test).is_file(), test
        assert _imports(test, module), f"{test} does not import {module}"


@pytest.mark.parametrize(("module", "tests"), sorted(THROUGH_THE_ENGINE.items()))
def test_modules_reached_through_the_engine_have_tests_that_drive_it(module, tests):
    for test in tests:
        text = (REPO / "test" / test).read_text()
        assert "InsEngine(" in text or "run_fusion(" in text, f"{test} does not drive the engine"
