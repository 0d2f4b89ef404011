"""core.measurements.heading on its own: the heading from the GNSS course and its variance,
``set_heading`` turning the attitude and velocity about the vertical while the antenna stays
where it was, and ``heading_from_course`` restarting from the fix and the velocity."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from ins_fusion.core.filter.eskf import ATT, ErrorStateFilter, StateLayout
from ins_fusion.core.filter.records import GnssFixMeasurement, GnssVelocityMeasurement
from ins_fusion.core.filter.state import FilterState, Geometry
from ins_fusion.core.measurements.gnss_noise import GnssNoise
from ins_fusion.core.measurements.heading import course, heading_from_course, set_heading
from ins_fusion.core.nav import earth
from ins_fusion.core.nav.rotation import euler_rad, quat_from_euler
from ins_fusion.core.nav.strapdown import NavState
from ins_fusion.core.settings.config import FusionConfig

LAYOUT = StateLayout(False, False, False, False, False)
LAT, LON, HEIGHT = math.radians(57.0), math.radians(10.0), 40.0
#: Antenna 1 m ahead of and 1.5 m above the IMU (base_link FLU) [m].
CONFIG = FusionConfig.from_parameters(
    {
        "imu_mounting_rpy_deg": [0.0, 0.0, 0.0],
        "imu_lever_arm": [0.0, 0.0, 0.0],
        "gnss_lever_arm": [1.0, 0.0, 1.5],
    }
)


def _state(yaw: float, vel_ned=(0.0, 0.0, 0.0)) -> tuple[FilterState, ErrorStateFilter]:
    nav = NavState(LAT, LON, HEIGHT, np.array(vel_ned), quat_from_euler(0.0, 0.0, yaw))
    s = FilterState(0.0, nav, (0.0, 0.0, 0.0), False)
    kf = ErrorStateFilter(LAYOUT, CONFIG.imu_noise)
    kf.P = np.eye(LAYOUT.size) * 1e-2
    return s, kf


def _north_east(s: FilterState) -> tuple[float, float]:
    """The IMU's position relative to (LAT, LON) [m], north and east."""
    r_m, r_n = earth.radii_from_sin(math.sin(LAT))
    nav = s.nav
    return (nav.lat_rad - LAT) * (r_m + HEIGHT), (nav.lon_rad - LON) * (r_n + HEIGHT) * math.cos(
        LAT
    )


@settings(max_examples=50, deadline=None)
@given(
    heading=st.floats(-math.pi + 1e-6, math.pi - 1e-6),
    speed=st.floats(1.0, 40.0),
    sigma=st.floats(0.01, 1.0),
)
def test_the_course_is_the_direction_of_travel(heading: float, speed: float, sigma: float) -> None:
    """Heading from north towards east; its variance σ²/v² (per horizontal axis σ²) plus a
    floor of (0.5°)² for side slip."""
    vel = GnssVelocityMeasurement(
        0.0,
        np.array([speed * math.sin(heading), speed * math.cos(heading), 0.0]),
        np.eye(3) * sigma**2,
    )
    yaw, variance = course(vel)
    assert abs(math.remainder(yaw - heading, math.tau)) < 1e-9
    assert math.isclose(variance, sigma**2 / speed**2 + math.radians(0.5) ** 2, rel_tol=1e-9)


def test_set_heading_turns_attitude_and_velocity_about_the_antenna() -> None:
    """Facing north at 10 m/s, turned to east: the velocity turns with the body, the yaw is
    decoupled with the given variance, and the antenna (1 m ahead) stays put: the IMU moves
    from 1 m south of it to 1 m west of it, i.e. by (+1 m north, -1 m east)."""
    s, kf = _state(0.0, (10.0, 0.0, 0.0))
    geometry = Geometry(CONFIG, LAYOUT)
    set_heading(s, kf, geometry, math.pi / 2, 0.01)
    assert s.heading_known
    assert abs(euler_rad(s.mat_nb)[2] - math.pi / 2) < 1e-12
    np.testing.assert_allclose(s.nav.vel_ned_m_s, [0.0, 10.0, 0.0], atol=1e-12)
    north, east = _north_east(s)
    assert abs(north - 1.0) < 1e-6 and abs(east + 1.0) < 1e-6
    assert s.nav.height_m == HEIGHT
    assert kf.P[ATT + 2, ATT + 2] == 0.01
    np.testing.assert_array_equal(kf.P[ATT + 2, : ATT + 2], 0.0)


def test_heading_from_course_restarts_from_the_fix_and_the_velocity() -> None:
    """Moving south-east at √2·5 m/s: the yaw is 135°, the velocity the GNSS's (NED), the IMU
    1 m behind and 1.5 m below the fix's antenna."""
    s, kf = _state(0.3, (1.0, 2.0, 0.0))
    vel = GnssVelocityMeasurement(0.0, np.array([5.0, -5.0, 0.0]), np.eye(3) * 0.01)
    fix = GnssFixMeasurement(0.0, math.degrees(LAT), math.degrees(LON), HEIGHT, np.eye(3) * 0.04)
    geometry = Geometry(CONFIG, LAYOUT)
    assert heading_from_course(s, kf, geometry, GnssNoise(CONFIG, LAYOUT), fix, vel)
    assert s.heading_known
    assert abs(euler_rad(s.mat_nb)[2] - math.radians(135.0)) < 1e-12
    np.testing.assert_allclose(s.nav.vel_ned_m_s, [-5.0, 5.0, 0.0], atol=1e-12)
    north, east = _north_east(s)
    back = 1.0 / math.sqrt(2.0)  # 1 m behind a vehicle heading south-east: north-west
    assert abs(north - back) < 1e-6 and abs(east + back) < 1e-6
    assert abs(s.nav.height_m - (HEIGHT - 1.5)) < 1e-9


def test_no_course_heading_without_a_fix_near_the_velocity() -> None:
    s, kf = _state(0.3)
    vel = GnssVelocityMeasurement(10.0, np.array([5.0, 0.0, 0.0]), np.eye(3) * 0.01)
    old = GnssFixMeasurement(8.0, 57.0, 10.0, HEIGHT, np.eye(3) * 0.04)
    geometry, noise = Geometry(CONFIG, LAYOUT), GnssNoise(CONFIG, LAYOUT)
    assert not heading_from_course(s, kf, geometry, noise, None, vel)
    assert not heading_from_course(s, kf, geometry, noise, old, vel)
    assert not s.heading_known
