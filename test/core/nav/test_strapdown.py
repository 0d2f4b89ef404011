"""Strapdown mechanization, quaternion helpers and REP-103 conversions (no simulator)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from ins_fusion.core.nav import earth
from ins_fusion.core.nav.rotation import (
    frd_to_flu,
    ned_to_enu,
    quat_enu_flu_from_nb,
    quat_from_euler,
    quat_from_rotvec,
    quat_multiply,
    quat_nb_from_enu_flu,
    quat_rotate,
)
from ins_fusion.core.nav.strapdown import NavState, SampleIntegrator, increment, propagate

LAT, LON, HEIGHT = math.radians(57.0), math.radians(9.987), 40.0
unit = st.floats(-1.0, 1.0)
angle = st.floats(-3.0, 3.0)


def _quat(x: float, y: float, z: float, w: float) -> tuple[float, float, float, float]:
    q = np.array([x, y, z, w]) + np.array([0.0, 0.0, 0.0, 1e-3])
    q /= np.linalg.norm(q)
    return (float(q[0]), float(q[1]), float(q[2]), float(q[3]))


@given(st.tuples(unit, unit, unit, unit), st.tuples(unit, unit, unit, unit))
def test_quat_multiply_matches_scipy(q, p):
    q, p = _quat(*q), _quat(*p)
    expected = (Rotation.from_quat(q) * Rotation.from_quat(p)).as_quat()
    product = np.array(quat_multiply(q, p))
    assert min(np.abs(product - expected).max(), np.abs(product + expected).max()) < 1e-12


@given(st.tuples(angle, angle, angle))
def test_quat_from_rotvec_matches_scipy_including_tiny_angles(rotvec):
    for scale in (1.0, 1e-3, 1e-9):
        v = np.array(rotvec) * scale
        expected = Rotation.from_rotvec(v).as_quat()
        assert quat_from_rotvec(*v) == pytest.approx(expected, abs=1e-15)


@given(st.tuples(unit, unit, unit, unit), st.tuples(angle, angle, angle))
def test_quat_rotate_matches_scipy(q, v):
    q = _quat(*q)
    assert quat_rotate(q, v) == pytest.approx(Rotation.from_quat(q).apply(v), abs=1e-12)


def test_rep103_orientation_of_headings():
    # Facing east in NED (yaw +90°) is the identity orientation in ENU/FLU.
    east = quat_enu_flu_from_nb(quat_from_euler(0.0, 0.0, math.pi / 2))
    assert abs(east[3]) == pytest.approx(1.0)
    # Facing north is +90° about ENU up; nose up is a negative pitch about the FLU y (left) axis.
    north = Rotation.from_quat(quat_enu_flu_from_nb(quat_from_euler(0.0, 0.0, 0.0)))
    assert north.as_euler("ZYX") == pytest.approx([math.pi / 2, 0.0, 0.0])
    nose_up = Rotation.from_quat(quat_enu_flu_from_nb(quat_from_euler(0.0, 0.1, math.pi / 2)))
    assert nose_up.as_euler("ZYX") == pytest.approx([0.0, -0.1, 0.0])
    assert nose_up.apply([1.0, 0.0, 0.0])[2] > 0.0  # the nose points up


@given(st.tuples(angle, st.floats(-1.5, 1.5), angle))
def test_enu_flu_conversions_round_trip(rpy):
    q_nb = quat_from_euler(*rpy)
    back = quat_nb_from_enu_flu(quat_enu_flu_from_nb(q_nb))
    assert (Rotation.from_quat(back) * Rotation.from_quat(q_nb).inv()).magnitude() < 1e-12
    v = np.array(rpy)
    assert ned_to_enu(ned_to_enu(v)) == pytest.approx(v)
    assert frd_to_flu(frd_to_flu(v)) == pytest.approx(v)


def test_nav_state_enu_views():
    state = NavState(LAT, LON, HEIGHT, np.array([1.0, 2.0, 3.0]), quat_from_euler(0.1, 0.2, 0.3))
    assert state.vel_enu_m_s == pytest.approx([2.0, 1.0, -3.0])
    assert state.euler_rad == pytest.approx([0.1, 0.2, 0.3])
    assert state.mat_nb == pytest.approx(Rotation.from_quat(state.quat_nb).as_matrix())
    again = NavState.from_enu_flu(LAT, LON, HEIGHT, state.vel_enu_m_s, state.quat_enu_flu)
    assert again.vel_ned_m_s == pytest.approx(state.vel_ned_m_s)
    assert again.euler_rad == pytest.approx(state.euler_rad)


def test_sample_integrator_is_exact_for_quadratic_signals_with_jitter():
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.uniform(0.005, 0.01, 50))
    coeff = rng.normal(size=(3, 3))

    def signal(x: float) -> np.ndarray:
        return coeff[0] + coeff[1] * x + coeff[2] * x * x

    def integral(a: float, b: float) -> np.ndarray:
        return coeff[0] * (b - a) + coeff[1] * (b * b - a * a) / 2 + coeff[2] * (b**3 - a**3) / 3

    integrator = SampleIntegrator()
    assert integrator.push(t[0], signal(t[0]), 2 * signal(t[0])) is None
    for k in range(1, len(t)):
        inc = integrator.push(t[k], signal(t[k]), 2 * signal(t[k]))
        assert inc is not None
        assert inc[0] == pytest.approx(t[k] - t[k - 1])
        if k >= 2:  # the first interval is a trapezoid
            assert inc[1:4] == pytest.approx(integral(t[k - 1], t[k]), abs=1e-14)
            assert inc[4:7] == pytest.approx(2 * integral(t[k - 1], t[k]), abs=1e-14)
    integrator.reset()
    assert integrator.push(1.0, signal(1.0), signal(1.0)) is None


def _vec(v: np.ndarray) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))


def _static_imu_frd(state: NavState) -> tuple[np.ndarray, np.ndarray]:
    """Exact rate and specific force of an IMU at rest in the given attitude (FRD)."""
    mat_bn = state.mat_nb.T
    g = earth.normal_gravity_m_s2(state.lat_rad, state.height_m)
    w_ie = np.array(earth.earth_rate_ned_rad_s(state.lat_rad))
    return mat_bn @ w_ie, mat_bn @ np.array([0.0, 0.0, -g])


def test_resting_imu_stays_put_for_ten_minutes():
    start = NavState(LAT, LON, HEIGHT, np.zeros(3), quat_from_euler(0.05, -0.03, 2.0))
    rate, force = _static_imu_frd(start)
    dt = 1.0 / 134.0
    inc = increment(dt, _vec(rate * dt), _vec(force * dt))
    state, prev = start, None
    for _ in range(134 * 600):
        state = propagate(state, inc, prev)
        prev = inc
    r_m, r_n = earth.radii_m(LAT)
    assert (state.lat_rad - LAT) * r_m == pytest.approx(0.0, abs=1e-4)
    assert (state.lon_rad - LON) * r_n * math.cos(LAT) == pytest.approx(0.0, abs=1e-4)
    assert state.height_m == pytest.approx(HEIGHT, abs=1e-4)
    assert np.abs(state.vel_ned_m_s).max() < 1e-6
    err = Rotation.from_quat(state.quat_nb) * Rotation.from_quat(start.quat_nb).inv()
    assert err.magnitude() < 1e-9


def test_constant_rate_yaw_integrates_exactly():
    # Oslo notes "Implications" R7: a constant-rate rotation of 1 rad over 10 s within 1e-6 rad.
    start = NavState(LAT, LON, HEIGHT, np.zeros(3), quat_from_euler(0.0, 0.0, 0.0))
    g = earth.normal_gravity_m_s2(LAT, HEIGHT)
    w_ie = np.array(earth.earth_rate_ned_rad_s(LAT))
    yaw_rate, dt = 0.1, 0.01
    state, prev = start, None
    for k in range(1000):
        # Earth rate seen by the turning body, at the middle of the interval.
        mat_bn = Rotation.from_euler("z", yaw_rate * (k + 0.5) * dt).as_matrix().T
        rate = mat_bn @ w_ie + np.array([0.0, 0.0, yaw_rate])
        inc = increment(dt, _vec(rate * dt), (0.0, 0.0, -g * dt))
        state = propagate(state, inc, prev)
        prev = inc
    assert state.euler_rad[2] == pytest.approx(1.0, abs=1e-6)
    assert state.euler_rad[:2] == pytest.approx([0.0, 0.0], abs=1e-6)
    assert np.abs(state.vel_ned_m_s).max() < 1e-6
