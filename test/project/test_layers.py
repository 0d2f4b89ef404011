"""The layering of the packages (CONTRIBUTING.md "Layers"), read from the sources with ``ast``.

Each folder is one layer and imports only run downward: a module imports its own folder or a
lower layer, never a higher one nor a sibling folder of its own layer. Only ``node.py`` and
``ros_*.py`` modules import rclpy. Every import counts, also those inside functions.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest
from support.paths import REPO

PACKAGES = ("gnss_ins_common", "imu400cc_driver", "gnss_driver", "ntrip_client", "ins_fusion")
#: Folder (dotted prefix) -> layer, lowest 0; the longest prefix of a module names its folder.
LAYERS: dict[str, int] = {
    "gnss_ins_common": 0,
    "imu400cc_driver": 1,
    "gnss_driver": 1,
    # The NTRIP client: its core uses the drivers' NMEA helpers; its node.py is the ROS layer.
    "ntrip_client": 2,
    # The fusion core, itself layered (ARCHITECTURE.md): compiled.py at its root, the models,
    # the filter, the measurements and the output, the engine on top.
    "ins_fusion.core": 2,
    "ins_fusion.core.nav": 3,
    "ins_fusion.core.settings": 4,
    "ins_fusion.core.smoother": 5,
    "ins_fusion.core.filter": 6,
    "ins_fusion.core.measurements": 7,
    "ins_fusion.core.output": 7,
    "ins_fusion.core.engine": 8,
    "ins_fusion.adapters": 9,
    "ins_fusion.bags": 10,
    "ins_fusion.runtime": 10,
    "ins_fusion.sim": 11,
    "ins_fusion.redecode": 11,
    "ins_fusion.replay": 12,
    "ins_fusion.noise_id": 12,
    "ins_fusion.calibration_id": 12,
    "ins_fusion.qfree": 12,
    "ins_fusion.fleet": 13,
    "ins_fusion": 13,  # the package root: node.py and ros_*.py, the ROS layer
    "ins_fusion.tools": 14,
}
ROS_MODULE = re.compile(r"(^|\.)(node|ros_[^.]*)$")


def folder(module: str) -> str | None:
    """The LAYERS key of a module of ours (None: not ours)."""
    keys = [k for k in LAYERS if module == k or module.startswith(f"{k}.")]
    return max(keys, key=len) if keys else None


def _is_module(name: str) -> bool:
    path = REPO.joinpath(*name.split("."))
    return path.with_suffix(".py").is_file() or (path / "__init__.py").is_file()


def imports(module: str, source: str, package: bool = False) -> list[tuple[int, str]]:
    """(line, imported module) of every import statement of ``source``, the module (or, with
    ``package``, the package ``__init__``) ``module``: relative imports resolved, ``from P import
    M`` as P.M when that is a module of ours."""
    found: list[tuple[int, str]] = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = module.split(".")
                parent = parts[: len(parts) - node.level + (1 if package else 0)]
                base = ".".join([*parent, base] if base else parent)
            for alias in node.names:
                name = f"{base}.{alias.name}"
                found.append((node.lineno, name if _is_module(name) else base))
    return found


def violations(module: str, source: str, package: bool = False) -> list[str]:
    """What ``module`` (its ``source``) imports against the layering."""
    own = folder(module)
    assert own is not None, module
    problems = []
    for line, name in imports(module, source, package):
        if name.split(".")[0] == "rclpy" and not ROS_MODULE.search(module):
            problems.append(f"{module}:{line}: imports {name} (only node.py / ros_*.py may)")
        target = folder(name)
        if target in (None, own) or module.startswith(f"{name}."):  # ours, or a parent package
            continue
        if LAYERS[target] >= LAYERS[own]:
            problems.append(
                f"{module}:{line}: imports {name} ({target}, layer {LAYERS[target]}) from"
                f" {own} (layer {LAYERS[own]})"
            )
    return problems


def _modules() -> list[tuple[str, Path]]:
    found = []
    for package in PACKAGES:
        for path in sorted((REPO / package).rglob("*.py")):
            parts = path.relative_to(REPO).with_suffix("").parts
            name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
            found.append((name, path))
    return found


def test_every_module_has_a_layer():
    assert [name for name, _ in _modules() if folder(name) is None] == []
    folders = {p.parent.relative_to(REPO).as_posix().replace("/", ".") for _, p in _modules()}
    assert sorted(f for f in folders if f not in LAYERS) == []


def test_imports_only_run_downward_and_rclpy_only_in_ros_modules():
    problems = [
        problem
        for name, path in _modules()
        for problem in violations(name, path.read_text(), path.name == "__init__.py")
    ]
    assert problems == []


@pytest.mark.parametrize(
    ("module", "source", "problem"),
    [
        ("ins_fusion.core.engine.engine", "from ins_fusion.tools.cli import main", "layer 14"),
        (
            "ins_fusion.core.filter.state",
            "from ins_fusion.core.measurements.nhc import nhc",
            "ins_fusion.core.measurements",
        ),
        (
            "ins_fusion.core.output.solution",
            "from ins_fusion.core.measurements import nhc",
            "layer 7",
        ),
        ("ins_fusion.core.nav.earth", "from ins_fusion.core.engine import engine", "layer 8"),
        ("ins_fusion.replay.run", "import ins_fusion.tools.progress", "layer 14"),
        ("ins_fusion.bags.imu", "def f():\n    from ins_fusion.sim import drive", "ins_fusion.sim"),
        ("ins_fusion.sim.drive", "from ins_fusion.replay.topics import TopicMap", "replay"),
        ("ins_fusion.noise_id.record", "from ins_fusion.replay import run", "ins_fusion.replay"),
        ("gnss_driver.solution", "from ins_fusion.adapters import messages_in", "adapters"),
        ("gnss_driver.driver", "from imu400cc_driver.framer import Framer", "imu400cc_driver"),
        ("ins_fusion.adapters.cdr_fields", "from ins_fusion import node", "ins_fusion.node"),
        ("ins_fusion.tools.record", "import rclpy", "only node.py / ros_*.py"),
        ("ins_fusion.adapters.solution_out", "from rclpy.node import Node", "only node.py"),
    ],
)
def test_an_upward_import_or_a_stray_rclpy_is_found(module, source, problem):
    found = violations(module, source)
    assert len(found) == 1 and problem in found[0]


@pytest.mark.parametrize(
    ("module", "source"),
    [
        ("ins_fusion.tools.ros_record", "import rclpy\nfrom ins_fusion.bags import bag_io"),
        (
            "ins_fusion.node",
            "from rclpy.node import Node\nfrom ins_fusion.adapters import tf_frames",
        ),
        ("ins_fusion.sim.drive", "from ins_fusion.bags.topics import IMU_DATA"),
        (
            "ins_fusion.core.settings.config",
            "from ins_fusion.core.settings.params import PARAMETERS",
        ),
        ("ins_fusion.replay.inputs", "from . import topics\nfrom ..adapters import cdr_fields"),
    ],
)
def test_downward_imports_and_ros_modules_pass(module, source):
    assert violations(module, source) == []
