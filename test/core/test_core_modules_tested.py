"""Every module of the fusion core has tests, found from the test tree: some test module under
test/core/ (which mirrors ins_fusion/core/: a module's tests live in the folder of the same name
where they can) imports it. The few modules that only the engine reaches are listed, and the
engine's tests must drive the engine. A new core module without tests fails here until a test
under test/core/ imports it."""

from __future__ import annotations

import re

import pytest
from support.paths import REPO, TESTS

CORE = REPO / "ins_fusion" / "core"
CORE_TESTS = TESTS / "core"

#: Modules only the engine reaches (InsEngine's base class): tested through test/core/engine/,
#: whose modules drive the engine.
THROUGH_THE_ENGINE = {"engine/loop.py"}


def _core_modules() -> list[str]:
    return sorted(
        path.relative_to(CORE).as_posix()
        for path in CORE.rglob("*.py")
        if path.name != "__init__.py" and "__pycache__" not in path.parts
    )


def _imports(text: str, module: str) -> bool:
    """Whether ``text`` imports ins_fusion.core.``module`` (as a module or from its package)."""
    dotted = "ins_fusion.core." + module.removesuffix(".py").replace("/", ".")
    package, name = dotted.rsplit(".", 1)
    direct = re.search(rf"\b(from|import) {re.escape(dotted)}\b", text)
    listed = re.search(rf"from {re.escape(package)} import \(?[^)]*?\b{name}\b", text, re.S)
    return bool(direct or listed)


_TEXTS = {path: path.read_text() for path in sorted(CORE_TESTS.rglob("test_*.py"))}


@pytest.mark.parametrize("module", sorted(set(_core_modules()) - THROUGH_THE_ENGINE))
def test_a_test_under_test_core_imports_each_core_module(module):
    importers = [path.name for path, text in _TEXTS.items() if _imports(text, module)]
    assert importers, f"no test module under test/core/ imports ins_fusion/core/{module}"


def test_the_modules_reached_through_the_engine_exist_and_the_engine_tests_drive_it():
    assert set(_core_modules()) >= THROUGH_THE_ENGINE, "entries for modules that do not exist"
    engine_tests = [text for path, text in _TEXTS.items() if path.parent.name == "engine"]
    assert any("InsEngine(" in text or "run_fusion(" in text for text in engine_tests)


def test_the_check_sees_a_missing_import():
    assert _imports("from ins_fusion.core.nav import (\n    earth,\n)\n", "nav/earth.py")
    assert _imports("from ins_fusion.core.nav.earth import radii\n", "nav/earth.py")
    assert not _imports("from ins_fusion.core.nav import rotation\n", "nav/earth.py")
