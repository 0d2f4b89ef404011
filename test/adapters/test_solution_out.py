"""adapters.solution_out: the fused solution as Odometry numbers (frames and covariances)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from ins_fusion.adapters.solution_out import odometry_arrays, publishable
from ins_fusion.core.engine.engine import InsSolution


def _solution(yaw_deg: float, vel_enu, cov_vel) -> InsSolution:
    quat = Rotation.from_euler("z", yaw_deg, degrees=True).as_quat()  # FLU in ENU, x y z w
    return InsSolution(
        t_s=10.0,
        lat_deg=57.0,
        lon_deg=10.0,
        height_m=50.0,
        pos_enu_m=np.array([1.0, 2.0, 3.0]),
        vel_enu_m_s=np.asarray(vel_enu, dtype=float),
        quat_enu_flu_xyzw=quat,
        rate_flu_rad_s=np.array([0.0, 0.0, 0.1]),
        cov_pos_enu_m2=np.diag([0.01, 0.04, 0.09]),
        cov_vel_enu=np.asarray(cov_vel, dtype=float),
        cov_att_enu_rad2=np.diag([1e-6, 2e-6, 3e-6]),
        gyro_bias_flu_rad_s=np.zeros(3),
        accel_bias_flu_m_s2=np.zeros(3),
        state="navigating",
    )


def test_velocity_is_published_in_base_link_and_pose_in_map():
    # Heading north (yaw 90 deg from east in ENU) at 10 m/s: forward speed 10 in FLU.
    arrays = odometry_arrays(_solution(90.0, [0.0, 10.0, 0.0], np.diag([0.01, 0.04, 1.0])), 2e-5)
    assert arrays.linear_velocity_flu_m_s == pytest.approx([10.0, 0.0, 0.0], abs=1e-12)
    assert arrays.position_enu_m == pytest.approx([1.0, 2.0, 3.0])
    pose = arrays.pose_covariance.reshape(6, 6)
    assert np.diag(pose) == pytest.approx([0.01, 0.04, 0.09, 1e-6, 2e-6, 3e-6])
    twist = arrays.twist_covariance.reshape(6, 6)
    # North variance (0.04) becomes the forward variance, east (0.01) the lateral one.
    assert np.diag(twist)[:3] == pytest.approx([0.04, 0.01, 1.0])
    assert np.diag(twist)[3:] == pytest.approx([2e-5] * 3)


@given(st.floats(-180, 180), st.lists(st.floats(-30, 30), min_size=3, max_size=3))
def test_body_velocity_keeps_speed_and_covariance_stays_symmetric(yaw, vel):
    cov = np.array([[0.02, 0.005, 0.0], [0.005, 0.03, 0.0], [0.0, 0.0, 0.5]])
    arrays = odometry_arrays(_solution(yaw, vel, cov), 1e-5)
    assert np.linalg.norm(arrays.linear_velocity_flu_m_s) == pytest.approx(
        np.linalg.norm(vel), abs=1e-9
    )
    twist = arrays.twist_covariance.reshape(6, 6)
    assert np.allclose(twist, twist.T)
    assert np.trace(twist[:3, :3]) == pytest.approx(np.trace(cov))


@pytest.mark.parametrize(
    "change",
    [
        {"lat_deg": math.nan},
        {"height_m": math.inf},
        {"pos_enu_m": np.array([0.0, math.nan, 0.0])},
        {"quat_enu_flu_xyzw": np.array([0.0, 0.0, math.nan, 1.0])},
        {"cov_pos_enu_m2": np.diag([0.01, -0.04, 0.09])},
        {"cov_vel_enu": np.array([[1.0, 2.0, 0.0], [2.0, 1.0, 0.0], [0.0, 0.0, 1.0]])},
        {"cov_att_enu_rad2": np.diag([1e-6, math.nan, 3e-6])},
    ],
    ids=["nan_lat", "inf_height", "nan_enu", "nan_quat", "negative_var", "indefinite", "nan_cov"],
)
def test_invalid_solutions_are_not_publishable(change):
    good = _solution(30.0, [1.0, 2.0, 0.0], np.eye(3) * 0.01)
    assert publishable(good)
    assert publishable(dataclasses.replace(good, cov_vel_enu=np.zeros((3, 3))))  # PSD
    assert not publishable(dataclasses.replace(good, **change))
