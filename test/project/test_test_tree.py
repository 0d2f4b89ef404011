"""The test tree's own rules: its folders mirror the source (test/core/filter/ tests
ins_fusion/core/filter/, test/gnss_driver/ the gnss_driver package, test/ros/<folder>/ the real
nodes of one), every module with real-node tests lives under test/ros/ (the node session
collects that folder), and no test sleeps except through support.pacing.pause (time let pass
on purpose) or the polls of support.waiting. What tests share is in the support package: no
test module imports another."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest
from support.paths import REPO, TESTS

PACKAGES = ("gnss_ins_common", "imu400cc_driver", "gnss_driver", "ntrip_client", "ins_fusion")
#: Folders of test/ that are not a source folder's tests.
OWN = {"support", "fixtures", "data", "project", "ros", "__pycache__"}
#: The only modules that call time.sleep.
SLEEPERS = {TESTS / "support" / "pacing.py", TESTS / "support" / "waiting.py"}


def _source_folder(relative: Path) -> Path | None:
    """The source folder a test folder (relative to test/ or test/ros/) stands for: a package,
    or a folder of ins_fusion (core's folders under core/)."""
    base = REPO if relative.parts[0] in PACKAGES else REPO / "ins_fusion"
    candidate = base / relative
    return candidate if (candidate / "__init__.py").is_file() else None


def _test_folders() -> list[Path]:
    folders = []
    for path in sorted(TESTS.rglob("test_*.py")):
        relative = path.parent.relative_to(TESTS)
        if relative.parts and relative.parts[0] == "ros":
            relative = Path(*relative.parts[1:])
        if relative.parts and relative.parts[0] not in OWN:
            folders.append(relative)
    return sorted(set(folders))


@pytest.mark.parametrize("folder", _test_folders(), ids=str)
def test_each_test_folder_stands_for_a_source_folder(folder):
    assert _source_folder(folder) is not None, f"test/{folder} mirrors no source folder"


def _calls_sleep(tree: ast.AST) -> bool:
    return any(
        isinstance(node, ast.Call)
        and (
            (isinstance(node.func, ast.Attribute) and node.func.attr == "sleep")
            or (isinstance(node.func, ast.Name) and node.func.id == "sleep")
        )
        for node in ast.walk(tree)
    )


def _modules() -> list[Path]:
    return sorted(p for p in TESTS.rglob("*.py") if "__pycache__" not in p.parts)


def test_no_test_sleeps_but_through_pause_or_a_poll():
    sleeping = [
        str(path.relative_to(TESTS))
        for path in _modules()
        if path not in SLEEPERS and _calls_sleep(ast.parse(path.read_text()))
    ]
    assert sleeping == [], "time.sleep outside support.pacing and support.waiting"


def test_real_node_tests_live_under_test_ros():
    outside = [
        str(path.relative_to(TESTS))
        for path in _modules()
        if "mark.ros" in path.read_text()
        and path.relative_to(TESTS).parts[0] != "ros"
        and path.name != "test_test_tree.py"
    ]
    assert outside == []


#: An import of a test module (test_*), at any indentation.
TEST_IMPORT = re.compile(r"^\s*(from|import) test_\w+", re.M)


def test_no_test_module_imports_another():
    importing = [
        str(path.relative_to(TESTS)) for path in _modules() if TEST_IMPORT.search(path.read_text())
    ]
    assert importing == [], "shared code belongs in test/support"


def test_the_checks_see_a_sleep_and_a_stray_folder():
    assert TEST_IMPORT.search("import os\nfrom test_bag_io import T0\n")
    assert not TEST_IMPORT.search("from support.bag_messages import T0\n")
    assert _calls_sleep(ast.parse("import time\ntime.sleep(1)\n"))
    assert not _calls_sleep(ast.parse('SCRIPT = "import time; time.sleep(1)"\n'))
    assert _source_folder(Path("core/filter")) is not None
    assert _source_folder(Path("gnss_driver")) is not None
    assert _source_folder(Path("replay")) is not None
    assert _source_folder(Path("filter")) is None
