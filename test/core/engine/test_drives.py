"""Acceptance of the fusion engine on simulated drives (issue 5), in-process, no bags.

The harness (``simulate``, ``feed``, ``run`` in test/support/drives.py) is shared with the other
engine tests and bench/bench_fusion_engine.py, which prints the precise numbers written to
docs/accuracy.md; the tests assert generous bounds.

Streams: the simulator's IMU (imu_link on the survey car, imu400cc or ideal profile, 134 Hz),
the Leica RTK receiver (1 Hz, 0.053 s latency, no vertical velocity, RTK float for 30 s after an
outage) with scripted outages, and optionally the ADU5 attitude (5 Hz), fed to the engine in
arrival order as the node receives them. The fused base_link solution is compared with the
simulated base_link truth.
"""

from __future__ import annotations

import numpy as np
import pytest
from support.drives import (
    AALBORG_OUTAGES,
    CALIBRATION,
    DRIVE_START_S,
    RunResult,
    run,
    simulate,
)

from ins_fusion.core.nav.calibration import ImuCalibration

# ------------------------------------------------------------------------------- tests


@pytest.fixture(scope="module")
def calibration() -> ImuCalibration:
    return ImuCalibration.from_yaml(CALIBRATION)


@pytest.fixture(scope="module")
def aalborg_outages(calibration) -> RunResult:
    """imu400cc, test pattern, RTK with the three Aalborg outages, no attitude receiver."""
    return run(simulate(outages=AALBORG_OUTAGES, seed=1), calibration=calibration)


@pytest.mark.slow
def test_noise_free_imu_with_rtk_stays_within_5_cm_for_ten_minutes():
    result = run(simulate(600.0, imu_profile="ideal", seed=2), evaluate_hz=1.0)
    assert result.t[0] < 75.0 and result.t[-1] >= 599.0
    assert result.status.resets == 0
    final = np.linalg.norm(result.err_enu[-1])
    print(f"ideal IMU, 10 min: final error {final * 100:.2f} cm")
    assert final < 0.05
    assert np.linalg.norm(result.err_enu[result.t > 120.0], axis=1).max() < 0.15


def test_aalborg_outages_end_within_3_m(aalborg_outages):
    errors = aalborg_outages.outage_end_errors(AALBORG_OUTAGES)
    print("horizontal error at the end of the outages [m]:", np.round(errors, 2))
    assert max(errors) <= 3.0  # the Aalborg design: 10, 15, 60 m
    status = aalborg_outages.status
    assert status.resets == 0
    for name in ("gnss_position", "gnss_velocity", "zupt", "zaru", "nhc", "course_heading"):
        assert status.measurements[name]["used"] > 0, name
    assert status.rollbacks > 0 and status.measurements["gnss_position"]["too_old"] == 0


def test_position_covariance_is_consistent_in_and_out_of_outages(aalborg_outages):
    result = aalborg_outages
    for inside in (True, False):
        mask = result.mask(AALBORG_OUTAGES, inside)
        nees = result.nees(mask).mean()
        within = result.within_3_sigma(mask)
        print(f"{'in' if inside else 'out of'} outages: NEES {nees:.2f}, within 3σ {within}")
        assert 0.5 * 3 <= nees <= 2.0 * 3
        assert within.min() >= 0.95


def test_states_follow_the_gnss_outages(aalborg_outages):
    states = dict(zip(aalborg_outages.t.round(1), aalborg_outages.states, strict=True))
    for start, _ in AALBORG_OUTAGES:
        assert states[round(start - 1.0, 1)] == "navigating"
        assert states[round(start + 10.0, 1)] == "degraded"
    assert states[round(aalborg_outages.t[-1], 1)] == "navigating"


def test_yaw_with_and_without_the_attitude_receiver(calibration):
    with_adu5 = run(simulate(seed=3, with_attitude=True), calibration=calibration)
    without = run(simulate(seed=3), calibration=calibration)
    driving = [r.t > DRIVE_START_S for r in (with_adu5, without)]
    rms = [
        float(np.sqrt(np.mean(r.yaw_err_deg[m] ** 2)))
        for r, m in zip((with_adu5, without), driving, strict=True)
    ]
    print(f"yaw RMS while driving: {rms[0]:.3f} deg with ADU5, {rms[1]:.3f} deg without")
    assert rms[0] < 0.2
    assert rms[1] < 1.0
    assert with_adu5.status.measurements["attitude"]["used"] > 500
    assert with_adu5.status.measurements["course_heading"]["used"] == 0
