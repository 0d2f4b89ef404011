"""A unit levelled far from its configured mounting is reported (issue 14 item 3): the
IMU400CC's accelerometer sign is not settled by the report, so an upside-down unit must not be
levelled at roll 180° without a word (engine warning, node log and diagnostics, replay report)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from support.drives import Drive, config, feed, simulate

from ins_fusion.core.engine.engine import InsEngine
from ins_fusion.replay.report import format_table

#: imu_link turned 180° about its x axis: FLU (x, y, z) reads (x, -y, -z).
UPSIDE_DOWN = np.array([1.0, -1.0, -1.0])


@pytest.fixture(scope="module")
def standstill() -> Drive:
    return simulate(duration_s=40.0)  # the test pattern starts with a standstill


def _warnings(drive: Drive, **overrides: object) -> tuple[str, ...]:
    engine = InsEngine(config(**overrides))
    feed(engine, drive)
    return engine.status().warnings


def test_an_upright_unit_levels_without_a_warning(standstill: Drive) -> None:
    assert _warnings(standstill) == ()


def test_an_upside_down_unit_is_reported_with_the_way_to_check_it(standstill: Drive) -> None:
    flipped = dataclasses.replace(
        standstill,
        imu_rate=standstill.imu_rate * UPSIDE_DOWN,
        imu_force=standstill.imu_force * UPSIDE_DOWN,
    )
    (warning,) = _warnings(flipped)
    assert "tilted 180 deg" in warning and "roll 180" in warning
    assert "gnss_ins calibrate axes" in warning
    # Told the mounting, the same record levels quietly.
    assert _warnings(flipped, imu_mounting_rpy_deg=[180.0, 0.0, 0.0]) == ()
    table = format_table(_report_stub(warning))
    assert f"WARNING: {warning}" in table


def _report_stub(warning: str) -> dict[str, object]:
    return {
        "bag": "b",
        "imu_samples": 1,
        "duration_s": 1.0,
        "wall_time_s": 1.0,
        "realtime_factor": 1.0,
        "aligned_at_s": 0.0,
        "final_state": "navigating",
        "resets": 0,
        "warnings": [warning],
        "reference": None,
        "withheld_fixes": [],
        "measurements": {},
    }
