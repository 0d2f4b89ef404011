"""The engine's output: the fused base_link state with its covariance (``InsSolution``), built
from the nominal state and the error covariance, and the self-calibration figures.

The covariances come from one Jacobian over the position, velocity, attitude and gyro bias
error states (the first 12, which the lever arm couples), rows in ENU.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gnss_ins_common.types import FloatArray
from ins_fusion.core import earth
from ins_fusion.core.config import FusionConfig
from ins_fusion.core.eskf import ATT, BG, POS, VEL, ErrorStateFilter, StateLayout
from ins_fusion.core.rotation import (
    MAT_ENU_NED,
    as_quat,
    enu_skew,
    quat_enu_flu,
    quat_from_rotvec,
    quat_multiply,
)
from ins_fusion.core.state import FilterState, Geometry


@dataclass(frozen=True)
class InsSolution:
    """Fused state of base_link at the latest IMU stamp t_s [s].

    lat_deg, lon_deg, height_m: WGS-84 position of the base_link origin (ellipsoidal height);
    pos_enu_m: the same in the ENU tangent plane at ``datum``; vel_enu_m_s: base_link velocity;
    quat_enu_flu_xyzw: base_link (FLU) in ENU; rate_flu_rad_s: bias-corrected ω_ib in base_link
    FLU; covariances [m², m²/s², rad²] in ENU (attitude: errors about the ENU axes);
    gyro_bias_flu_rad_s, accel_bias_flu_m_s2: estimated sensor biases in imu_link FLU (after the
    calibration file's correction); state: 'aligning' | 'navigating' | 'degraded';
    imu_mounting_rpy_rad: REP-103 roll, pitch, yaw of imu_link in base_link with the estimated
    residual mounting (None when it is not estimated: the configured one). base_link is the
    vehicle frame of that mounting: position, velocity, orientation and rate include it.
    """

    t_s: float
    lat_deg: float
    lon_deg: float
    height_m: float
    pos_enu_m: FloatArray
    vel_enu_m_s: FloatArray
    quat_enu_flu_xyzw: FloatArray
    rate_flu_rad_s: FloatArray
    cov_pos_enu_m2: FloatArray
    cov_vel_enu: FloatArray
    cov_att_enu_rad2: FloatArray
    gyro_bias_flu_rad_s: FloatArray
    accel_bias_flu_m_s2: FloatArray
    state: str
    imu_mounting_rpy_rad: FloatArray | None = None


class SolutionBuilder:
    """Builds ``InsSolution`` at the output rate (see the module docstring)."""

    def __init__(self, geometry: Geometry, layout: StateLayout) -> None:
        self._geometry = geometry
        self._mt = layout.mt
        # ENU position, velocity and attitude of base_link over the first 12 error states; the
        # blocks that depend on the state are filled in per call.
        self._j_solution = np.zeros((9, BG + 3))
        for row, col in ((0, POS), (3, VEL), (6, ATT)):
            self._j_solution[row : row + 3, col : col + 3] = MAT_ENU_NED
        self._j_mounting = np.zeros((9, BG + 5))
        mt = layout.mt
        self._solution_states = np.r_[0 : BG + 3, [] if mt is None else [mt, mt + 1]].astype(int)
        self._plane: earth.TangentPlane | None = None
        #: Jacobian of the last ``build`` (rows ENU position, velocity, attitude of base_link,
        #: columns the error states of core.smoothed_solution.solution_states); reused per call.
        self.jacobian: FloatArray = self._j_solution

    def build(
        self,
        s: FilterState,
        kf: ErrorStateFilter,
        datum_deg: tuple[float, float, float],
        rate_i: tuple[float, float, float],
        state_name: str,
    ) -> InsSolution:
        """The solution of state ``s`` with covariance ``kf.P``; ``rate_i``: the latest raw
        sample's rate (imu FRD [rad/s]); ``datum_deg``: the ENU plane's origin (lat, lon [deg],
        height [m])."""
        geometry = self._geometry
        C = s.mat_nb
        (c00, c01, c02), (c10, c11, c12), (c20, c21, c22) = C.tolist()
        # base_link of the estimated mounting: the lever arm turned by it, and below the
        # orientation and rate turned into it (C_bv = I + [μ×]).
        ax, ay, az = geometry.arms(s)[1].tolist()
        # Lever arm in NED, and its velocity ω × r (body) rotated into NED; 3-vectors in plain
        # floats (numpy per 3-vector costs more than the arithmetic at the output rate).
        n0 = c00 * ax + c01 * ay + c02 * az
        n1 = c10 * ax + c11 * ay + c12 * az
        n2 = c20 * ax + c21 * ay + c22 * az
        wx, wy, wz = geometry.corrected_rate_b(s, rate_i)
        ux, uy, uz = wy * az - wz * ay, wz * ax - wx * az, wx * ay - wy * ax
        r0 = c00 * ux + c01 * uy + c02 * uz
        r1 = c10 * ux + c11 * uy + c12 * uz
        r2 = c20 * ux + c21 * uy + c22 * uz
        nav = s.nav
        lat, lon, height = earth.displace(nav.lat_rad, nav.lon_rad, nav.height_m, n0, n1, n2)
        J = self._j_solution
        J[0:3, ATT : ATT + 3] = enu_skew(-n0, -n1, -n2)
        J[3:6, ATT : ATT + 3] = enu_skew(-r0, -r1, -r2)
        J[3:6, BG : BG + 3] = MAT_ENU_NED @ C @ geometry.arm_bi
        if self._mt is None:
            cov = J @ kf.P[: BG + 3, : BG + 3] @ J.T
            self.jacobian = J
        else:  # the vehicle's attitude error is ψ + C_nb μ: the mounting states join
            J_mt = self._j_mounting
            J_mt[:, : BG + 3] = J
            J_mt[6:9, BG + 3 :] = (MAT_ENU_NED @ C)[:, 1:3]
            cov = J_mt @ kf.P[np.ix_(self._solution_states, self._solution_states)] @ J_mt.T
            self.jacobian = J_mt
        vn, ve, vd = nav.vel_ned_m_s.tolist()
        lat0, lon0, h0 = datum_deg
        datum_rad = (math.radians(lat0), math.radians(lon0), h0)
        if self._plane is None or self._plane.datum != datum_rad:
            self._plane = earth.TangentPlane(*datum_rad)
        bg, ba = s.gyro_bias, s.accel_bias
        quat_nb = as_quat(nav.quat_nb)
        mounting = None
        if self._mt is not None:
            mu_y, mu_z = s.mounting
            quat_nb = quat_multiply(quat_nb, quat_from_rotvec(0.0, mu_y, mu_z))
            wx, wy, wz = wx - (mu_y * wz - mu_z * wy), wy - mu_z * wx, wz + mu_y * wx
            mounting = geometry.mounting_rpy(s.mounting)
        return InsSolution(
            t_s=s.t_s,
            lat_deg=math.degrees(lat),
            lon_deg=math.degrees(lon),
            height_m=height,
            pos_enu_m=self._plane.enu(lat, lon, height),
            vel_enu_m_s=np.array((ve + r1, vn + r0, -(vd + r2))),
            quat_enu_flu_xyzw=np.array(quat_enu_flu(quat_nb)),
            rate_flu_rad_s=np.array((wx, -wy, -wz)),
            cov_pos_enu_m2=cov[0:3, 0:3],
            cov_vel_enu=cov[3:6, 3:6],
            cov_att_enu_rad2=cov[6:9, 6:9],
            gyro_bias_flu_rad_s=np.array((bg[0], -bg[1], -bg[2])),
            accel_bias_flu_m_s2=np.array((ba[0], -ba[1], -ba[2])),
            state=state_name,
            imu_mounting_rpy_rad=mounting,
        )


def self_calibration(
    config: FusionConfig, geometry: Geometry, s: FilterState | None, kf: ErrorStateFilter | None
) -> dict[str, float]:
    """The self-calibration (NaN where not estimated or before the filter starts):
    ``time_offset_s`` = imu_time_offset + the estimated residual, with the residual and its
    σ [s]; the residual mounting pitch and yaw about base_link FRD y, z and their σ [deg];
    ``imu_mounting_{roll,pitch,yaw}_deg``: the imu_mounting_rpy_deg that holds them (REP-103,
    for the configuration)."""
    values = dict.fromkeys(
        (
            "time_offset_s",
            "time_offset_residual_s",
            "time_offset_sigma_s",
            "mounting_pitch_residual_deg",
            "mounting_yaw_residual_deg",
            "mounting_pitch_sigma_deg",
            "mounting_yaw_sigma_deg",
            "imu_mounting_roll_deg",
            "imu_mounting_pitch_deg",
            "imu_mounting_yaw_deg",
        ),
        math.nan,
    )
    if s is None or kf is None:
        return values
    layout = kf.layout
    if layout.td is not None:
        values["time_offset_residual_s"] = s.time_offset
        values["time_offset_s"] = config.imu_time_offset_s + s.time_offset
        values["time_offset_sigma_s"] = math.sqrt(max(kf.P[layout.td, layout.td], 0.0))
    if layout.mt is not None:
        mt = layout.mt
        pitch, yaw = s.mounting
        values["mounting_pitch_residual_deg"] = math.degrees(pitch)
        values["mounting_yaw_residual_deg"] = math.degrees(yaw)
        values["mounting_pitch_sigma_deg"] = math.degrees(math.sqrt(max(kf.P[mt, mt], 0.0)))
        values["mounting_yaw_sigma_deg"] = math.degrees(math.sqrt(max(kf.P[mt + 1, mt + 1], 0.0)))
        roll_p_yaw = geometry.mounting_rpy(s.mounting)
        for name, value in zip(("roll", "pitch", "yaw"), roll_p_yaw, strict=True):
            values[f"imu_mounting_{name}_deg"] = math.degrees(float(value))
    return values
