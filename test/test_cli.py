"""The gnss_ins tool: every registered sub-command imports and explains itself."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from ins_fusion.tools.cli import SUBCOMMANDS

GNSS_INS = Path(sys.executable).parent / "gnss_ins"


def test_top_level_help_lists_every_sub_command():
    result = subprocess.run([GNSS_INS, "--help"], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0
    for name in SUBCOMMANDS:
        assert name in result.stdout


@pytest.mark.parametrize("name", sorted(SUBCOMMANDS))
def test_sub_command_help(name):
    result = subprocess.run([GNSS_INS, name, "--help"], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    assert f"usage: gnss_ins {name}" in result.stdout


def test_unknown_sub_command_is_refused():
    result = subprocess.run([GNSS_INS, "fly"], capture_output=True, text=True, timeout=60)
    assert result.returncode == 2
    assert "invalid choice" in result.stderr


@pytest.mark.ros
def test_imu_demo_runs_the_node_on_an_emulated_device():
    """Its rclpy half (ins_fusion/tools/ros_imu_demo.py) in a process of its own."""
    result = subprocess.run(
        [GNSS_INS, "imu-demo", "--duration", "3", "--every", "1000"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 0, result.stderr
    assert "imu/data_raw  t=" in result.stdout and "Imu messages over" in result.stdout
    assert "mean specific force (FLU)" in result.stdout
