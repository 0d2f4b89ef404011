"""core.filter.propagation on its own: the white noise of a covariance step, the covariance
step of a level IMU at rest (symmetric, positive semi-definite, the random walks of the
datasheet), and the prediction of the nominal state to a stamp."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from ins_fusion.core.filter.adaptation import B_MEAN, B_SIZE, B_VERSION
from ins_fusion.core.filter.eskf import ATT, VEL, ErrorStateFilter, StateLayout
from ins_fusion.core.filter.propagation import (
    ImuDensities,
    Propagator,
    densities_in_force,
    monitored_white_noise,
    predicted_state,
    white_noise,
)
from ins_fusion.core.filter.state import (
    X_ACCEL_N,
    X_COV_DT,
    X_RATE_B,
    X_RATE_I,
    X_T,
    FilterState,
    Geometry,
)
from ins_fusion.core.nav import earth
from ins_fusion.core.nav.rotation import euler_rad, quat_from_euler
from ins_fusion.core.nav.strapdown import NavState, increment
from ins_fusion.core.settings.config import FusionConfig

LAT, LON, HEIGHT = math.radians(57.0), math.radians(10.0), 40.0
G = earth.normal_gravity_m_s2(LAT, HEIGHT)
CONFIG = FusionConfig.from_parameters({"imu_mounting_rpy_deg": [0.0, 0.0, 0.0]})
LAYOUT = StateLayout(False, False, False, False, False)


def _state(vel_ned=(0.0, 0.0, 0.0), yaw: float = 0.0) -> FilterState:
    nav = NavState(LAT, LON, HEIGHT, np.array(vel_ned), quat_from_euler(0.0, 0.0, yaw))
    return FilterState(0.0, nav, (0.0, 0.0, 0.0), True)


def _propagator() -> tuple[Propagator, ImuDensities]:
    noise = CONFIG.imu_noise
    densities = ImuDensities(noise.gyro_psd, noise.accel_psd)
    return Propagator(CONFIG, Geometry(CONFIG, LAYOUT), densities), densities


def test_the_densities_in_force_are_the_floor_raised_to_the_measured() -> None:
    floor = (np.array([1.0, 2.0, 3.0]), np.array([4.0, 5.0, 6.0]))
    gyro, accel = densities_in_force(floor, np.array([0.5, 2.5, 3.0]), np.array([7.0, 1.0, 6.5]))
    np.testing.assert_array_equal(gyro, [1.0, 2.5, 3.0])
    np.testing.assert_array_equal(accel, [7.0, 5.0, 6.5])


def test_the_white_noise_is_the_densities_times_the_process_noise_scale() -> None:
    floor = (np.array([1.0, 2.0, 3.0]), np.array([4.0, 5.0, 6.0]))
    gyro, accel = white_noise(floor, 2.0)
    np.testing.assert_array_equal(gyro, [2.0, 4.0, 6.0])
    np.testing.assert_array_equal(accel, [8.0, 10.0, 12.0])
    block = np.zeros(B_SIZE)  # no estimate yet: the floor
    for got, want in zip(monitored_white_noise(block, floor, 2.0), (gyro, accel), strict=True):
        np.testing.assert_array_equal(got, want)
    block[B_VERSION] = 1.0
    block[B_MEAN : B_MEAN + 6] = (0.0, 10.0, 0.0, 0.0, 0.0, 20.0)
    gyro, accel = monitored_white_noise(block, floor, 0.5)
    np.testing.assert_array_equal(gyro, [0.5, 5.0, 1.5])
    np.testing.assert_array_equal(accel, [2.0, 2.5, 10.0])


def test_the_propagator_uses_the_densities_of_the_state_or_the_floor() -> None:
    propagator, densities = _propagator()
    s = _state()
    s.q_scale = 3.0
    gyro, accel = propagator.white_noise(s)
    np.testing.assert_array_equal(gyro, densities.floor[0] * 3.0)
    measured = (np.full(3, 1e-6), np.full(3, 1e-3))
    s.imu_psd = measured
    gyro, accel = propagator.white_noise(s)
    np.testing.assert_array_equal(accel, measured[1] * 3.0)


def _rest(propagator: Propagator, s: FilterState, kf: ErrorStateFilter, n: int) -> None:
    """``n`` increments of 10 ms of a level IMU at rest (earth rate left out)."""
    for k in range(1, n + 1):
        inc = increment(0.01, (0.0, 0.0, 0.0), (0.0, 0.0, -G * 0.01))
        propagator.step(s, kf, inc, None, 0.01 * k, None)


def test_a_covariance_step_at_rest_adds_the_random_walks_of_the_datasheet() -> None:
    """From P = 0, one covariance interval Δt at rest, level, IMU axes = NED axes: the vertical
    velocity variance grows by VRW²·Δt and the attitude variance by ARW²·Δt per axis; the
    horizontal velocity also by the tilt's random walk seen through gravity, g²·ARW²·Δt³/3
    exactly, Δt³/2 with the trapezoidal discretisation (eskf's docstring), and the height by
    the vertical velocity's, VRW²·Δt³/3 (trapezoid: /2). The bias instabilities add < 1 %."""
    propagator, densities = _propagator()
    s = _state()
    kf = ErrorStateFilter(LAYOUT, CONFIG.imu_noise)
    _rest(propagator, s, kf, 5)
    dt = float(s.x[X_COV_DT])
    assert abs(dt - 0.05) < 1e-12
    propagator.propagate_covariance(s, kf)
    variance = np.diagonal(kf.P)
    gyro_psd, accel_psd = densities.floor
    np.testing.assert_allclose(variance[ATT : ATT + 3], gyro_psd * dt, rtol=1e-3)
    np.testing.assert_allclose(variance[VEL + 2], accel_psd[2] * dt, rtol=1e-3)
    tilt = G**2 * gyro_psd[[1, 0]] * dt**3  # north from the east tilt, east from the north
    horizontal = variance[VEL : VEL + 2] - accel_psd[:2] * dt
    assert np.all(horizontal > tilt / 3.0) and np.all(horizontal < tilt / 2.0 * 1.01)
    down = variance[2]  # no tilt in the vertical
    assert accel_psd[2] * dt**3 / 3.0 < down < accel_psd[2] * dt**3 / 2.0 * 1.01


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), steps=st.integers(1, 40))
def test_the_covariance_stays_symmetric_and_positive_semi_definite(seed: int, steps: int) -> None:
    rng = np.random.default_rng(seed)
    propagator, _ = _propagator()
    s = _state(vel_ned=tuple(rng.normal(0.0, 10.0, 3)), yaw=float(rng.uniform(-3.0, 3.0)))
    kf = ErrorStateFilter(LAYOUT, CONFIG.imu_noise)
    A = rng.normal(size=(LAYOUT.size, LAYOUT.size)) * 0.1
    kf.P = A @ A.T
    before = np.linalg.eigvalsh(kf.P).min()
    _rest(propagator, s, kf, steps * 10)
    propagator.propagate_covariance(s, kf)
    P = kf.P
    np.testing.assert_allclose(P, P.T, rtol=0.0, atol=1e-13 * np.abs(P).max())  # to rounding
    eig = np.linalg.eigvalsh(P)
    assert eig.min() >= min(before, 0.0) - 1e-12 * eig.max()


def test_the_prediction_at_the_state_stamp_is_the_state() -> None:
    s = _state(vel_ned=(3.0, -4.0, 0.5), yaw=0.7)
    s.x[X_ACCEL_N : X_ACCEL_N + 3] = (1.0, 2.0, 3.0)  # no time to act
    s.x[X_RATE_B : X_RATE_B + 3] = (0.1, 0.2, 0.3)
    s.x[X_RATE_I : X_RATE_I + 3] = (0.3, 0.2, 0.1)
    lat, lon, height, vel, mat_nb, rate_b, rate_i = predicted_state(s.x, float(s.x[X_T]))
    assert (lat, lon, height) == (LAT, LON, HEIGHT)
    np.testing.assert_array_equal(vel, [3.0, -4.0, 0.5])
    np.testing.assert_array_equal(rate_b, [0.1, 0.2, 0.3])
    np.testing.assert_array_equal(rate_i, [0.3, 0.2, 0.1])
    np.testing.assert_allclose(euler_rad(mat_nb), [0.0, 0.0, 0.7], atol=1e-12)


def test_the_prediction_carries_position_velocity_and_heading_over_a_short_interval() -> None:
    """10 ms ahead at 20 m/s north accelerating 2 m/s² north and turning 0.5 rad/s: the
    velocity gains a·dt, the position moves by v·dt + a·dt²/2 along the meridian, the yaw by
    ω·dt."""
    v, a, omega, dt = 20.0, 2.0, 0.5, 0.01
    s = _state(vel_ned=(v, 0.0, 0.0))
    s.x[X_ACCEL_N : X_ACCEL_N + 3] = (a, 0.0, 0.0)
    s.x[X_RATE_B : X_RATE_B + 3] = (0.0, 0.0, omega)
    lat, lon, height, vel, mat_nb, _, _ = predicted_state(s.x, float(s.x[X_T]) + dt)
    np.testing.assert_allclose(vel, [v + a * dt, 0.0, 0.0], atol=1e-12)
    r_m, _ = earth.radii_from_sin(math.sin(LAT))
    north = (lat - LAT) * (r_m + HEIGHT)
    assert abs(north - (v * dt + 0.5 * a * dt**2)) < 1e-9
    assert lon == LON and height == HEIGHT
    # The turn is carried to second order: the yaw errs by about (ω·dt)³/6 = 2e-8 rad.
    assert abs(euler_rad(mat_nb)[2] - omega * dt) < 2 * (omega * dt) ** 3 / 6
