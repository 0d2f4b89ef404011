"""Simulated bags that several test modules read: written once per test run, also when the
modules run in different pytest-xdist workers."""

from __future__ import annotations

import fcntl
import os
from contextlib import redirect_stdout
from io import StringIO
from pathlib import Path

import pytest

from ins_fusion.sim.drive import SimulationConfig
from ins_fusion.sim.simulated_bag import write_bag

#: 90 s of the figure-eight scenario (10 s standstill, accelerating to 10 m/s, one lap of two
#: 40 m circles, braking), imu400cc IMU, Leica RTK at 1 Hz, ADU5 at 5 Hz, truth at 50 Hz.
FIGURE_EIGHT_90_S = SimulationConfig(scenario="figure_eight", duration_s=90.0, seed=3)
#: 75 s of the test pattern (60 s standstill, then urban driving), the same receivers: the
#: filter starts during the standstill and applies ZUPT and ZARU for most of it.
TEST_PATTERN_75_S = SimulationConfig(scenario="test_pattern", duration_s=75.0, seed=4)


def shared_bag(factory: pytest.TempPathFactory, name: str, config: SimulationConfig) -> Path:
    """The bag of ``config`` in this run's temporary directory (the workers' common parent under
    xdist), written by whichever module asks first; the others wait for it. Read only."""
    root = factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        root = root.parent
    path = root / name
    with (root / f"{name}.lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not (path / "metadata.yaml").exists():
            with redirect_stdout(StringIO()):  # write_bag prints a summary of the bag
                write_bag(config, path)
    return path
