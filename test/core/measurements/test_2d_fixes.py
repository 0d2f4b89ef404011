"""2-D fixes (height unknown: gnss_ins_common.navsat.HEIGHT_UNKNOWN_VARIANCE_M2) in the engine.

On a simulated drive whose receiver drops to 2-D fixes for a minute and writes a wrong
altitude into them (a receiver in 2-D mode holds some height of its own), the fusion takes
their horizontal position and keeps its height from the IMU and the last 3-D fixes; the same
fixes taken as 3-D pull the height off (so the test can fail). And the compiled GNSS position
update (core.measurements.gnss_position) with a replay's compiled runs gives, with 2-D fixes,
the same rows to the bit as the engine run the general way.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from support.drives import Drive, RunResult, run, simulate
from support.sample_runs import figure_eight, sample_by_sample

from gnss_ins_common.navsat import HEIGHT_UNKNOWN_VARIANCE_M2
from gnss_ins_common.params import validate_all
from ins_fusion.core.filter.records import GnssFixMeasurement
from ins_fusion.core.measurements.gnss_position import PositionUpdate
from ins_fusion.core.settings.params import PARAMETERS
from ins_fusion.replay.inputs import ReplayInputs
from ins_fusion.replay.run import run_fusion

#: The receiver's 2-D minute [s] of the simulated drive, and the altitude it writes meanwhile.
TWO_D = (150.0, 210.0)
WRONG_HEIGHT_M = 40.0


def _wrong_height(fix: GnssFixMeasurement, two_d: bool) -> GnssFixMeasurement:
    """The fix with its altitude ``WRONG_HEIGHT_M`` off, marked 2-D when ``two_d``."""
    cov = fix.cov_enu_m2.copy()
    if two_d:
        cov[2, 2] = HEIGHT_UNKNOWN_VARIANCE_M2
    return dataclasses.replace(fix, height_m=fix.height_m + WRONG_HEIGHT_M, cov_enu_m2=cov)


def _drive_with_wrong_heights(drive: Drive, two_d: bool) -> Drive:
    events = [
        (t, _wrong_height(m, two_d))
        if isinstance(m, GnssFixMeasurement) and TWO_D[0] <= m.t_s < TWO_D[1]
        else (t, m)
        for t, m in drive.events
    ]
    return dataclasses.replace(drive, events=events)


@pytest.fixture(scope="module")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> ReplayInputs:
    return figure_eight(tmp_path_factory)


@pytest.fixture(scope="module")
def drive() -> Drive:
    return simulate(240.0, seed=3)


def _window(result: RunResult) -> np.ndarray:
    return (result.t >= TWO_D[0]) & (result.t < TWO_D[1] + 5.0)


def test_2d_fixes_keep_the_height_of_the_imu_and_the_last_3d_fixes(drive):
    result = run(_drive_with_wrong_heights(drive, two_d=True))
    window = _window(result)
    assert window.sum() > 500 and result.status.resets == 0
    height_error = np.abs(result.err_enu[window, 2])
    horizontal = result.horizontal[window]
    print(
        f"2-D minute: height error max {height_error.max():.2f} m, horizontal max"
        f" {horizontal.max():.3f} m"
    )
    assert height_error.max() < 2.0  # the wrong altitude is 40 m off
    # The horizontal part is used: without it a minute of the imu400cc alone drifts metres
    # (test_fusion_drives: up to 3 m after 20 s outages).
    assert horizontal.max() < 0.3
    # The vertical σ grows while the height is not measured, and shrinks after.
    sigma_up = np.sqrt(result.cov_enu[:, 2, 2])
    assert sigma_up[result.at(TWO_D[1] - 1.0)] > 3 * sigma_up[result.at(TWO_D[0] - 1.0)]
    assert sigma_up[result.at(TWO_D[1] + 10.0)] < sigma_up[result.at(TWO_D[1] - 1.0)]


def test_the_same_fixes_taken_as_3d_pull_the_height_off(drive):
    result = run(_drive_with_wrong_heights(drive, two_d=False))
    assert np.abs(result.err_enu[_window(result), 2]).max() > 10.0


def _two_d_inputs(replay: ReplayInputs) -> ReplayInputs:
    """The replay inputs with every other fix of the second half 2-D and its altitude off."""
    fixes = [k for k, (_, role, _) in enumerate(replay.measurements) if role == "fix"]
    later = set(fixes[len(fixes) // 2 :: 2])
    measurements = [
        (i, role, _wrong_height(m, two_d=True) if k in later else m)
        for k, (i, role, m) in enumerate(replay.measurements)
    ]
    return dataclasses.replace(replay, measurements=measurements)


def test_2d_fixes_take_the_same_update_compiled_and_the_general_way(
    inputs: ReplayInputs,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    two_d = _two_d_inputs(inputs)
    parameters = validate_all(PARAMETERS, {})
    expected_rows, expected_status = sample_by_sample(two_d, parameters, smooth=True)
    fused = {"2d": 0}
    apply = PositionUpdate.fused

    def counted(self, s, kf, record, live):  # type: ignore[no-untyped-def]
        done = apply(self, s, kf, record, live)
        fused["2d"] += done and not record[1].height_known
        return done

    monkeypatch.setattr(PositionUpdate, "fused", counted)
    run_ = run_fusion(two_d, parameters)
    assert fused["2d"] > 10
    np.testing.assert_array_equal(run_.track.rows, expected_rows)
    assert repr(run_.status) == repr(expected_status)
