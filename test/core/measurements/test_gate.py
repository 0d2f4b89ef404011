"""core.measurements.gate.Corrections on its own: the gated update in closed form (a direct
velocity measurement on an uncorrelated covariance), the counters, the runs of gated updates, the
gate recovery of a sensor and none for a pseudo-measurement, ``reject`` and ``count_used``."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from ins_fusion.core.engine.measurement_kinds import MEASUREMENT_NAMES
from ins_fusion.core.filter.eskf import VEL, ErrorStateFilter, StateLayout
from ins_fusion.core.filter.state import FilterState
from ins_fusion.core.filter.status import new_counters
from ins_fusion.core.filter.update_algebra import chi2_threshold
from ins_fusion.core.measurements.attitude import ATTITUDE
from ins_fusion.core.measurements.gate import Corrections
from ins_fusion.core.measurements.gnss_velocity import COURSE_HEADING, VELOCITY
from ins_fusion.core.measurements.stationary import ZUPT
from ins_fusion.core.nav.strapdown import NavState
from ins_fusion.core.settings.config import FusionConfig

LAYOUT = StateLayout(False, False, False, False, False)
P_VEL, R_VEL = 0.04, 0.01  # prior velocity variance and measurement variance [m²/s²]
RECOVER = 3


def _setup(recover: int = RECOVER) -> tuple[Corrections, FilterState, ErrorStateFilter]:
    config = FusionConfig.from_parameters({"gate_recovery_count": recover})
    counters = new_counters(MEASUREMENT_NAMES)
    corrections = Corrections(config, counters)
    nav = NavState(1.0, 0.2, 40.0, np.array([5.0, 0.0, 0.0]), np.array([0.0, 0.0, 0.0, 1.0]))
    s = FilterState(0.0, nav, (0.0, 0.0, 0.0), True)
    kf = ErrorStateFilter(LAYOUT, config.imu_noise)
    kf.P = np.eye(LAYOUT.size) * 1e-4
    kf.P[VEL : VEL + 3, VEL : VEL + 3] = np.eye(3) * P_VEL
    return corrections, s, kf


def _velocity_model(z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The NED velocity measured directly: z = measured - predicted, H on δv, R = R_VEL·I."""
    H = np.zeros((3, LAYOUT.size))
    H[:, VEL : VEL + 3] = np.eye(3)
    return np.asarray(z, dtype=float), H, np.eye(3) * R_VEL


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(-0.3, 0.3), min_size=3, max_size=3))
def test_an_accepted_update_is_the_scalar_kalman_gain_per_axis(z: list[float]) -> None:
    """P_vv = p I, R = r I: NIS = |z|²/(p + r), δv = p/(p + r) z injected into the velocity,
    the velocity variance p r/(p + r); counted used, NIS kept."""
    corrections, s, kf = _setup()
    innovation = np.array(z)
    nis = float(innovation @ innovation) / (P_VEL + R_VEL)
    if nis > chi2_threshold(0.999, 3):
        return  # beyond the gate: the next test
    before = s.x[3:6].copy()
    dx = corrections.update(s, kf, VELOCITY, _velocity_model(innovation), True)
    assert dx is not None
    gain = P_VEL / (P_VEL + R_VEL)
    np.testing.assert_allclose(s.x[3:6] - before, gain * innovation, atol=1e-12)
    np.testing.assert_allclose(np.diagonal(kf.P)[VEL : VEL + 3], P_VEL * R_VEL / (P_VEL + R_VEL))
    assert math.isclose(corrections.nis["gnss_velocity"], nis, rel_tol=1e-9, abs_tol=1e-15)
    assert corrections._counters["gnss_velocity"]["used"] == 1


def test_a_gated_update_changes_nothing_and_is_counted() -> None:
    corrections, s, kf = _setup()
    x, P = s.x.copy(), kf.P
    z = np.array([2.0, 0.0, 0.0])  # NIS 80 against a gate of 16.3
    assert corrections.update(s, kf, VELOCITY, _velocity_model(z), True) is None
    np.testing.assert_array_equal(s.x[:10], x[:10])
    assert kf.P is P
    counters = corrections._counters["gnss_velocity"]
    assert (counters["used"], counters["rejected"], counters["gated"]) == (0, 1, 1)
    assert s.gated_runs == {"gnss_velocity": 1}
    assert corrections.nis["gnss_velocity"] == 4.0 / (P_VEL + R_VEL)


def test_a_sensor_gated_recover_times_running_is_admitted_by_fading_the_covariance() -> None:
    """After RECOVER - 1 gated velocities the next gated one fades P by the least factor λ that
    makes its NIS typical: |z|²/(λ p + r) = 3 rows -> λ = (|z|²/3 - r)/p; then it is used and
    the run of gated updates ends."""
    corrections, s, kf = _setup()
    z = np.array([2.0, 0.0, 0.0])
    for _ in range(RECOVER - 1):
        corrections.update(s, kf, VELOCITY, _velocity_model(z), True)
    assert s.gated_runs["gnss_velocity"] == RECOVER - 1
    dx = corrections.update(s, kf, VELOCITY, _velocity_model(z), True)
    assert dx is not None
    factor = (4.0 / 3.0 - R_VEL) / P_VEL
    assert math.isclose(corrections.fading, factor, rel_tol=1e-8)
    counters = corrections._counters["gnss_velocity"]
    assert (counters["used"], counters["gated"], counters["recoveries"]) == (1, RECOVER - 1, 1)
    assert s.gated_runs["gnss_velocity"] == 0
    # The update after the fading: gain λp/(λp + r) on the innovation.
    gain = factor * P_VEL / (factor * P_VEL + R_VEL)
    np.testing.assert_allclose(dx[VEL : VEL + 3], gain * z, rtol=1e-6)


def test_a_pseudo_measurement_is_never_recovered() -> None:
    """A constraint a vehicle can break (a skid): its rejections stay rejections."""
    corrections, s, kf = _setup()
    z = np.array([2.0, 0.0, 0.0])
    for _ in range(3 * RECOVER):
        assert corrections.update(s, kf, ZUPT, _velocity_model(z), True) is None
    assert s.gated_runs["zupt"] == 3 * RECOVER
    assert corrections._counters["zupt"]["recoveries"] == 0
    assert corrections.fading == 1.0


def test_no_recovery_when_the_count_is_zero() -> None:
    corrections, s, kf = _setup(recover=0)
    z = np.array([2.0, 0.0, 0.0])
    for _ in range(10):
        assert corrections.update(s, kf, VELOCITY, _velocity_model(z), True) is None
    assert corrections._counters["gnss_velocity"]["recoveries"] == 0


def test_a_replayed_update_is_not_counted_but_keeps_the_run_of_gated_updates() -> None:
    corrections, s, kf = _setup()
    z = np.array([2.0, 0.0, 0.0])
    corrections.update(s, kf, VELOCITY, _velocity_model(z), False)
    assert corrections._counters["gnss_velocity"]["rejected"] == 0
    assert s.gated_runs["gnss_velocity"] == 1


def test_reject_counts_only_live_measurements() -> None:
    corrections, _, _ = _setup()
    corrections.reject(ATTITUDE, False)
    assert corrections._counters["attitude"]["rejected"] == 0
    corrections.reject(ATTITUDE, True)
    assert corrections._counters["attitude"] == {
        **dict.fromkeys(corrections._counters["attitude"], 0),
        "rejected": 1,
    }


def test_count_used_counts_only_live_measurements() -> None:
    """A measurement used outside an update (a heading set from it) is counted used, live."""
    corrections, _, _ = _setup()
    corrections.count_used(COURSE_HEADING, False)
    assert corrections._counters["course_heading"]["used"] == 0
    corrections.count_used(COURSE_HEADING, True)
    assert corrections._counters["course_heading"] == {
        **dict.fromkeys(corrections._counters["course_heading"], 0),
        "used": 1,
    }


def test_only_gnss_updates_adapt_the_process_noise() -> None:
    """The GNSS NIS feeds the running NIS mean (core.filter.adaptation); a ZUPT's does not."""
    corrections, s, kf = _setup()
    z = np.array([0.1, 0.0, 0.0])
    corrections.update(s, kf, ZUPT, _velocity_model(z), True)
    assert s.nis_mean == 1.0
    corrections.update(s, kf, VELOCITY, _velocity_model(z), True)
    assert s.nis_mean != 1.0
