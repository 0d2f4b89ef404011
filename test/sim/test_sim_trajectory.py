"""Trajectory kinematics: smooth channels, segments, exact truth of mounted frames."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from ins_fusion.core.nav import earth
from ins_fusion.core.nav.rotation import euler_from_quat
from ins_fusion.sim.route import Route
from ins_fusion.sim.scenarios import AALBORG_START, SURVEY_CAR, figure_eight, seed_test_pattern
from ins_fusion.sim.trajectory import Mounting, SmoothChannel
from ins_fusion.sim.vehicle import VehicleSetup, VehicleTruth


def test_smooth_channel_derivatives_and_integral():
    channel = SmoothChannel(np.array([0.0, 2.0, 5.0, 6.0]), np.array([1.0, 4.0, 4.0, -2.0]))
    t = np.linspace(-1.0, 8.0, 901)
    value, d1, d2, integral = channel.evaluate(t)
    h = 1e-5
    plus, minus = channel.evaluate(t + h), channel.evaluate(t - h)
    assert d1 == pytest.approx((plus[0] - minus[0]) / (2 * h), abs=1e-6)
    assert d2 == pytest.approx((plus[1] - minus[1]) / (2 * h), abs=1e-5)
    assert (plus[3] - minus[3]) / (2 * h) == pytest.approx(value, abs=1e-6)
    assert channel.evaluate(np.array([0.0]))[3][0] == 0.0
    # ∫ = 0.5·(1+4)·2 + 4·3 + 0.5·(4-2)·1 - 2·2 = 14 at t = 8; -1 at t = -1 (held before).
    assert integral[[0, -1]] == pytest.approx([-1.0, 14.0], abs=1e-12)
    # Knot values are reached and held.
    assert channel.evaluate(np.array([2.0, 3.5, 7.0]))[0] == pytest.approx([4.0, 4.0, -2.0])


def test_turn_and_climb_segments_are_exact():
    route = Route(AALBORG_START, speed_m_s=10.0).turn(90.0, radius_m=25.0).climb(5.0, 20.0)
    trajectory = route.cruise(5.0).build(roll_per_lateral_accel_deg_per_m_s2=0.0)
    t = np.array([0.0, trajectory.duration_s])
    rpy = euler_from_quat(trajectory.frame_truth(t).quat_nb)
    assert rpy[1, 2] - rpy[0, 2] == pytest.approx(-math.pi / 2, abs=1e-12)  # left = -NED yaw
    heights = trajectory.frame_truth(np.linspace(0.0, trajectory.duration_s, 2001)).height_m
    climbed = heights[-1] - heights[0]
    # 20 s at 10 m/s: (20 - 3) s at sin 5° on average for the smooth ramps -> about 14.8 m.
    assert climbed == pytest.approx(10.0 * 17.0 * math.sin(math.radians(5.0)), rel=0.01)


def test_turn_needs_exactly_one_of_radius_and_rate():
    with pytest.raises(ValueError, match="exactly one"):
        Route(AALBORG_START, 5.0).turn(90.0)
    with pytest.raises(ValueError, match="moving"):
        Route(AALBORG_START).turn(90.0, radius_m=10.0)


def test_static_imu_reads_gravity_and_earth_rate():
    # Level and at rest: REP-145 reads +g up and the earth rate (north and up components). (A
    # horizontal lever arm would tilt the local vertical by lever/R, 5e-8 rad per 0.3 m.)
    setup = VehicleSetup(imu=Mounting((0.0, 0.0, 1.0)))
    truth = VehicleTruth(Route(AALBORG_START).stand(10.0).build(), setup)
    rate, force = truth.imu_truth(5.0)
    imu = truth.imu(np.array([5.0]))
    lat = float(imu.lat_rad[0])
    g = earth.normal_gravity_m_s2(lat, float(imu.height_m[0]))
    assert imu.height_m[0] == pytest.approx(41.0, abs=1e-6)
    assert np.linalg.norm(force) == pytest.approx(g, abs=1e-12)
    assert force == pytest.approx([0.0, 0.0, g], abs=1e-9)
    omega = earth.EARTH_RATE_RAD_S
    # Heading north: FLU x = north, y = west, z = up.
    assert rate == pytest.approx([omega * math.cos(lat), 0.0, omega * math.sin(lat)], abs=1e-15)


def test_constant_rate_turn_gives_centripetal_acceleration():
    speed, radius = 12.0, 40.0
    route = Route(AALBORG_START, speed_m_s=speed).turn(180.0, radius_m=radius, ramp_s=1.0)
    truth = VehicleTruth(route.build(roll_per_lateral_accel_deg_per_m_s2=0.0))
    t_mid = truth.duration_s / 2
    rate, force = truth.imu_truth(t_mid)
    omega = speed / radius + earth.EARTH_RATE_RAD_S * math.sin(AALBORG_START.lat_rad)
    # Left turn: positive about FLU z (up); the transport rate adds v tan(lat)/R < 5e-6 rad/s.
    assert rate[2] == pytest.approx(omega, abs=5e-6)
    # Centripetal v²/r to the left (FLU +y), plus Coriolis/transport (< 1e-3 m/s²).
    assert force[1] == pytest.approx(speed**2 / radius, abs=2e-3)
    assert force[0] == pytest.approx(0.0, abs=2e-3)


def test_base_link_moves_along_its_x_axis():
    base = seed_test_pattern().frame_truth(np.linspace(0.0, 240.0, 2401))
    vel_b = np.einsum("nji,nj->ni", _mats(base.quat_nb), base.vel_ned_m_s)
    assert np.abs(vel_b[:, 1:]).max() < 1e-9
    assert vel_b[:, 0].min() > -1e-9


def _mats(quat_nb: np.ndarray) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    return Rotation.from_quat(quat_nb).as_matrix()


def test_position_matches_an_independent_ode_solution():
    trajectory = figure_eight(duration_s=100.0)
    start = trajectory.start

    def rates(t: float, y: np.ndarray) -> list[float]:
        vel = trajectory.frame_truth(np.array([t])).vel_ned_m_s[0]
        r_m, r_n = earth.radii_m(float(y[0]))
        return [vel[0] / (r_m + y[2]), vel[1] / ((r_n + y[2]) * math.cos(y[0])), -vel[2]]

    solution = solve_ivp(
        rates,
        (0.0, 100.0),
        [start.lat_rad, start.lon_rad, start.height_m],
        method="DOP853",
        rtol=1e-12,
        atol=[1e-14, 1e-14, 1e-8],
        max_step=0.5,  # small enough not to step over the knots
        t_eval=[100.0],
    )
    end = trajectory.frame_truth(np.array([100.0]))
    r_m, r_n = earth.radii_m(start.lat_rad)
    assert (end.lat_rad[0] - solution.y[0, -1]) * r_m == pytest.approx(0.0, abs=1e-5)
    assert (end.lon_rad[0] - solution.y[1, -1]) * r_n == pytest.approx(0.0, abs=1e-5)
    assert end.height_m[0] == pytest.approx(solution.y[2, -1], abs=1e-6)


def test_mounted_frame_kinematics_match_finite_differences():
    """Velocity of a lever-armed point = d/dt of its ECEF position; its specific force = d/dt of
    its ECEF velocity + 2Ω×v - g. Checks the analytic rigid-body terms (ω̇, transport rate)."""
    mounting = Mounting((1.5, -0.7, 1.9), (0.1, -0.05, 0.3))
    trajectory = seed_test_pattern()
    t = np.array([75.0, 90.3, 121.7, 157.2, 201.4])  # turns, roundabout, climb, braking
    h = 1e-3

    def ecef(times: np.ndarray) -> np.ndarray:
        truth = trajectory.frame_truth(times, mounting)
        return earth.geodetic_to_ecef(truth.lat_rad, truth.lon_rad, truth.height_m)

    def vel_ecef(times: np.ndarray) -> np.ndarray:
        truth = trajectory.frame_truth(times, mounting)
        return np.einsum(
            "nij,nj->ni", earth.mat_en(truth.lat_rad, truth.lon_rad), truth.vel_ned_m_s
        )

    truth = trajectory.frame_truth(t, mounting)
    numeric_vel = (ecef(t + h) - ecef(t - h)) / (2 * h)
    assert vel_ecef(t) == pytest.approx(numeric_vel, abs=1e-6)

    acc = (vel_ecef(t + h) - vel_ecef(t - h)) / (2 * h)
    mat_en = earth.mat_en(truth.lat_rad, truth.lon_rad)
    g = earth.normal_gravity_m_s2(truth.lat_rad, truth.height_m)
    omega = np.array([0.0, 0.0, earth.EARTH_RATE_RAD_S])
    force_e = acc + 2 * np.cross(omega, vel_ecef(t)) - mat_en[:, :, 2] * g[:, None]
    mat_es = mat_en @ _mats(truth.quat_nb)
    expected = np.einsum("nji,nj->ni", mat_es, force_e)
    assert truth.specific_force_frd_m_s2 == pytest.approx(expected, abs=2e-6)


def test_imu_rate_includes_mounting_rotation():
    # An IMU yawed 90° left in base_link sees the vehicle's forward acceleration on its -y axis.
    route = Route(AALBORG_START).stand(1.0).accelerate(10.0, 10.0)
    base = VehicleTruth(route.build())
    yawed = VehicleTruth(route.build(), VehicleSetup(imu=Mounting(rpy_rad=(0.0, 0.0, math.pi / 2))))
    _, force_base = base.imu_truth(6.0)
    _, force_yawed = yawed.imu_truth(6.0)
    assert force_base[0] > 1.0
    assert force_yawed == pytest.approx([force_base[1], -force_base[0], force_base[2]], abs=1e-12)


def test_gnss_truth_is_at_the_antenna():
    truth = VehicleTruth(seed_test_pattern(), SURVEY_CAR)
    base = truth.base_link(np.array([30.0]))
    antenna = truth.gnss_truth(30.0)
    assert antenna.height_m - base.height_m[0] == pytest.approx(1.75, abs=1e-6)
    assert antenna.vel_enu_m_s == pytest.approx([0.0, 0.0, 0.0], abs=1e-12)
    assert antenna.quat_enu_flu == pytest.approx(base.quat_enu_flu[0], abs=1e-6)
    with pytest.raises(ValueError, match="outside"):
        truth.gnss_truth(241.0)


@pytest.mark.parametrize("duration_s", [90.0, 150.0, 240.0, 500.0])
def test_a_short_or_odd_test_pattern_still_drives_after_its_standstill(duration_s):
    trajectory = seed_test_pattern(duration_s)
    t = np.array([30.0, 59.0, 60.0 + 0.75 * (min(duration_s, 240.0) - 60.0)])
    speed = np.linalg.norm(trajectory.frame_truth(t, Mounting()).vel_ned_m_s, axis=1)
    assert speed[:2] == pytest.approx([0.0, 0.0], abs=1e-9)
    assert speed[2] > 2.0
