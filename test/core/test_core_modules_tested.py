"""Where each module of the fusion core is tested: an explicit map, checked both ways. Every
module of ins_fusion/core has an entry, and every test module named for it imports it (or, for
the two modules only the engine reaches, drives the engine). A new core module without tests
fails here until it has them or its entry says why not."""

from __future__ import annotations

import re

import pytest
from support.paths import REPO

CORE = REPO / "ins_fusion" / "core"

#: core module (relative to ins_fusion/core) -> the test modules that test it directly.
TESTS: dict[str, tuple[str, ...]] = {
    "compiled.py": ("core/test_compiled.py",),
    "layout.py": ("core/test_layout.py",),
    "nav/calibration.py": ("core/nav/test_calibration_frame.py", "core/engine/test_intake.py"),
    "nav/earth.py": ("core/nav/test_earth.py",),
    "nav/levelling.py": ("core/settings/test_config.py",),
    "nav/rotation.py": ("core/settings/test_config.py", "core/filter/test_eskf.py"),
    "nav/strapdown.py": ("core/test_compiled.py", "core/filter/test_propagation.py"),
    "nav/units.py": ("core/settings/test_config.py",),
    "settings/config.py": ("core/settings/test_config.py",),
    "settings/params.py": ("core/settings/test_config.py",),
    "smoother/history.py": ("core/smoother/test_smoother.py",),
    "smoother/rts.py": ("core/smoother/test_smoother.py",),
    "filter/adaptation.py": ("core/filter/test_adaptation.py",),
    "filter/eskf.py": ("core/filter/test_eskf.py",),
    "filter/propagation.py": ("core/filter/test_propagation.py",),
    "filter/records.py": ("core/measurements/test_2d_fixes.py",),
    "filter/state.py": ("core/test_layout.py", "core/measurements/test_heading.py"),
    "filter/status.py": ("core/filter/test_timeline.py",),
    "filter/timeline.py": ("core/filter/test_timeline.py",),
    "filter/update_algebra.py": ("core/filter/test_eskf.py", "core/measurements/test_gate.py"),
    "measurements/attitude.py": ("core/filter/test_eskf.py", "core/engine/test_sample_runs.py"),
    "measurements/common.py": ("core/filter/test_eskf.py",),
    "measurements/gate.py": ("core/measurements/test_gate.py",),
    "measurements/gnss_noise.py": ("core/measurements/test_gnss_noise.py",),
    "measurements/gnss_position.py": ("core/filter/test_eskf.py", "core/measurements/test_2d_fixes.py"),
    "measurements/gnss_velocity.py": ("core/filter/test_eskf.py", "core/engine/test_sample_runs.py"),
    "measurements/heading.py": ("core/measurements/test_heading.py",),
    "measurements/nhc.py": ("core/filter/test_eskf.py", "core/test_compiled.py"),
    "measurements/stationary.py": ("core/filter/test_eskf.py", "core/engine/test_sample_runs.py"),
    "measurements/stop_detector.py": ("core/settings/test_config.py", "core/test_compiled.py"),
    "measurements/vehicle_speed.py": ("core/measurements/test_vehicle_speed.py",),
    "output/output_clock.py": ("replay/test_replay_run.py",),
    "output/output_numbers.py": ("core/output/test_output_numbers.py",),
    "output/solution.py": ("core/output/test_output_numbers.py", "core/engine/test_engine.py"),
    "output/solution_rows.py": ("core/engine/test_sample_runs.py", "core/engine/test_smoothed_solution.py"),
    "engine/engine.py": ("core/engine/test_engine.py",),
    "engine/intake.py": ("core/engine/test_intake.py",),
    "engine/sample_runs.py": ("core/engine/test_sample_runs.py",),
    "engine/smoothed_solution.py": ("core/engine/test_smoothed_solution.py",),
    "engine/startup.py": ("core/engine/test_startup.py",),
    "engine/warm_up.py": ("core/test_compiled.py",),
}
#: Modules only the engine reaches (InsEngine's base class, the choice of the compiled
#: updates): tested through the engine's tests, which must drive it.
THROUGH_THE_ENGINE: dict[str, tuple[str, ...]] = {
    "engine/loop.py": ("core/engine/test_engine.py",),
    "measurements/fused.py": ("core/engine/test_sample_runs.py",),
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
