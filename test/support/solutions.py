"""Fused solutions built by hand for the replay's metrics."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from ins_fusion.core.engine.engine import InsSolution


def quaternion(roll=0.0, pitch=0.0, yaw=0.0):
    return Rotation.from_euler("ZYX", [yaw, pitch, roll], degrees=True).as_quat()


def solution(t, pos_enu, quat=None, cov_pos=None, state="navigating", cov_att=None):
    return InsSolution(
        t_s=t,
        lat_deg=0.0,
        lon_deg=0.0,
        height_m=0.0,
        pos_enu_m=np.asarray(pos_enu, dtype=float),
        vel_enu_m_s=np.zeros(3),
        quat_enu_flu_xyzw=quaternion() if quat is None else quat,
        rate_flu_rad_s=np.zeros(3),
        cov_pos_enu_m2=np.eye(3) * 0.01 if cov_pos is None else cov_pos,
        cov_vel_enu=np.eye(3) * 1e-4,
        cov_att_enu_rad2=np.eye(3) * 1e-6 if cov_att is None else cov_att,
        gyro_bias_flu_rad_s=np.zeros(3),
        accel_bias_flu_m_s2=np.zeros(3),
        state=state,
    )
