"""The repository builds as a ROS 2 ament_python package with colcon (as on a real ROS machine)."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

from support.paths import REPO

EXECUTABLES = ("imu400cc_node", "gnss_node", "ntrip_node", "ins_fusion_node", "gnss_ins")


def test_colcon_build_installs_executables_config_and_launch(tmp_path):
    colcon = Path(sys.executable).parent / "colcon"
    assert colcon.exists(), "colcon-common-extensions is installed by the test extras"
    src = tmp_path / "src" / "gnss_ins"
    shutil.copytree(
        REPO,
        src,
        ignore=shutil.ignore_patterns(
            ".venv", ".git", "build", "install", "log", "*.egg-info", "__pycache__", ".*cache"
        ),
    )
    result = subprocess.run(
        [colcon, "build", "--base-paths", "src"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    prefix = tmp_path / "install" / "gnss_ins"
    for exe in EXECUTABLES:
        script = prefix / "lib" / "gnss_ins" / exe
        assert script.is_file(), f"{exe} not installed"
        assert script.stat().st_mode & 0o111, f"{exe} not executable"
    share = prefix / "share" / "gnss_ins"
    assert (share / "package.xml").is_file()
    assert (prefix / "share" / "ament_index" / "resource_index" / "packages" / "gnss_ins").is_file()
    for config in (REPO / "config").glob("*.yaml"):
        assert (share / "config" / config.name).is_file(), config.name
    assert (share / "launch" / "vehicle.launch.py").is_file()
    site = next((prefix / "lib").glob("python3*/site-packages"))
    for package in (
        "imu400cc_driver",
        "gnss_driver",
        "ntrip_client",
        "ins_fusion",
        "gnss_ins_common",
    ):
        assert (site / package / "__init__.py").is_file(), package
