"""core.engine.startup.Startup on its own: a levelled standstill gives the first state (roll and
pitch from gravity, the gyro bias seed, the position from the fix at the IMU), nothing before the
levelling is long enough or without a recent fix, and the variance ceiling of the filter."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ins_fusion.core.engine.measurement_kinds import MEASUREMENT_NAMES
from ins_fusion.core.engine.startup import Startup
from ins_fusion.core.filter.eskf import ATT, BA, BG, ErrorStateFilter, StateLayout
from ins_fusion.core.filter.records import GnssFixMeasurement
from ins_fusion.core.filter.state import UNKNOWN_YAW_VARIANCE, FilterState, Geometry, LatestInputs
from ins_fusion.core.filter.status import new_counters
from ins_fusion.core.measurements.gnss_noise import GnssNoise
from ins_fusion.core.nav import earth
from ins_fusion.core.nav.rotation import euler_rad
from ins_fusion.core.settings.config import FusionConfig

LAT_DEG, LON_DEG, HEIGHT_M = 57.0, 10.0, 40.0
ROLL, PITCH = math.radians(2.0), math.radians(-3.0)
BIAS = (1e-4, -2e-4, 3e-4)  # gyro bias, imu FRD [rad/s]
PARAMETERS = {
    "imu_mounting_rpy_deg": [0.0, 0.0, 0.0],
    "imu_lever_arm": [0.0, 0.0, 0.0],
    "gnss_lever_arm": [0.0, 0.0, 0.0],
    "alignment.duration": 2.0,
}


def _startup(layout: StateLayout) -> tuple[Startup, LatestInputs]:
    config = FusionConfig.from_parameters(PARAMETERS)
    latest = LatestInputs()
    startup = Startup(
        config,
        None,
        Geometry(config, layout),
        GnssNoise(config, layout),
        layout,
        new_counters(MEASUREMENT_NAMES),
        latest,
    )
    return startup, latest


def _level(startup: Startup, seconds: float) -> None:
    """A standstill tilted by ROLL and PITCH: the specific force of gravity in FRD,
    g (sin θ, -sin φ cos θ, -cos φ cos θ), and the gyro bias plus the earth rate's vertical part
    (the heading is unknown: the rest is part of the seed's variance)."""
    g = earth.normal_gravity_m_s2(math.radians(LAT_DEG), HEIGHT_M)
    force = (
        g * math.sin(PITCH),
        -g * math.sin(ROLL) * math.cos(PITCH),
        -g * math.cos(ROLL) * math.cos(PITCH),
    )
    down = -earth.EARTH_RATE_RAD_S * math.sin(math.radians(LAT_DEG))  # Ω_D in NED
    # The earth rate's down component seen in the tilted body: C_bn e_D, the third row of C_nb.
    c_nb_down = (
        -math.sin(PITCH),
        math.sin(ROLL) * math.cos(PITCH),
        math.cos(ROLL) * math.cos(PITCH),
    )
    rate = tuple(b + down * c for b, c in zip(BIAS, c_nb_down, strict=True))
    for k in range(round(seconds * 100) + 1):
        startup.levelling.push(k * 0.01, rate, force)


def _fix(t: float) -> GnssFixMeasurement:
    return GnssFixMeasurement(t, LAT_DEG, LON_DEG, HEIGHT_M, np.diag([0.04, 0.04, 0.09]))


def _started(layout: StateLayout) -> tuple[FilterState, ErrorStateFilter]:
    """The first state and filter after 2 s of levelling with a fix at its end."""
    startup, latest = _startup(layout)
    _level(startup, 2.0)
    latest.fix = _fix(2.0)
    started = startup.try_start(2.0, True)
    assert started is not None
    return started


def test_a_levelled_standstill_gives_the_first_state() -> None:
    s, kf = _started(StateLayout(False, False, True, False, False))
    roll, pitch, _ = euler_rad(s.mat_nb)
    assert abs(roll - ROLL) < 1e-9 and abs(pitch - PITCH) < 1e-9
    assert not s.heading_known
    assert kf.P[ATT + 2, ATT + 2] == UNKNOWN_YAW_VARIANCE
    np.testing.assert_allclose(s.gyro_bias, BIAS, atol=1e-12)
    nav = s.nav  # no lever arm: the IMU at the fix
    assert math.isclose(math.degrees(nav.lat_rad), LAT_DEG, rel_tol=0.0, abs_tol=1e-12)
    assert math.isclose(math.degrees(nav.lon_rad), LON_DEG, rel_tol=0.0, abs_tol=1e-12)
    assert nav.height_m == HEIGHT_M
    np.testing.assert_array_equal(nav.vel_ned_m_s, 0.0)
    assert s.t_s == 2.0


def test_no_start_before_the_levelling_is_long_enough_or_without_a_recent_fix() -> None:
    layout = StateLayout(False, False, False, False, False)
    startup, latest = _startup(layout)
    _level(startup, 1.0)
    latest.fix = _fix(1.0)
    assert startup.try_start(1.0, True) is None  # 1 s of 2
    _level(startup, 2.0)
    latest.fix = _fix(0.0)
    assert startup.try_start(2.0, True) is None  # the fix is 2 s old (> 1.5 s)
    latest.fix = _fix(1.9)
    assert startup.try_start(2.0, True) is not None


@pytest.mark.parametrize("optional", [False, True])
def test_the_variance_ceiling_bounds_what_a_fading_may_grow(optional: bool) -> None:
    """No ceiling on position, velocity and the correlated GNSS error; the attitude at least an
    unknown angle's variance; the accelerometer bias at its datasheet prior (turn-on² +
    instability²); the gyro bias at least its prior."""
    layout = StateLayout(*[optional] * 5)
    ceiling = _started(layout)[1].variance_ceiling
    assert np.all(np.isinf(ceiling[:ATT]))
    assert np.all(ceiling[ATT : ATT + 3] >= UNKNOWN_YAW_VARIANCE)
    noise = FusionConfig.from_parameters(PARAMETERS).imu_noise
    accel_prior = noise.accel_turn_on_bias**2 + np.square(noise.accel_bias_instability)
    np.testing.assert_allclose(ceiling[BA : BA + 3], accel_prior, rtol=1e-12)
    gyro_prior = noise.gyro_turn_on_bias**2 + np.square(noise.gyro_bias_instability)
    assert np.all(ceiling[BG : BG + 3] >= gyro_prior * (1.0 - 1e-12))
    if layout.gp is not None:
        assert np.all(np.isinf(ceiling[layout.gp : layout.gp + 3]))
    if layout.mt is not None:
        config = FusionConfig.from_parameters(PARAMETERS)
        np.testing.assert_allclose(ceiling[layout.mt : layout.mt + 2], config.mounting_sigma_rad**2)


def test_what_the_alignment_waits_for_is_said() -> None:
    startup, latest = _startup(StateLayout(False, False, False, False, False))
    assert startup.waiting_for(10.0, True, False) == "no GNSS fix yet"
    latest.fix = _fix(0.0)
    assert startup.waiting_for(10.0, True, False).startswith("last GNSS fix 10.0 s old")
    _level(startup, 1.0)
    latest.fix = _fix(1.0)
    assert startup.waiting_for(1.0, True, False) == "levelling at rest, 1 of 2 s"
    moving = startup.waiting_for(1.0, False, False)
    assert moving.startswith("moving before 2 s at rest") and "course above 3 m/s" in moving
    assert startup.waiting_for(1.0, False, True).startswith("heading unknown")
