"""Heading initialisation: from the GNSS course (NTNU notes §8) or an attitude receiver, turning
the nominal attitude about the vertical while the antenna position is kept. Angles [rad], NED."""

from __future__ import annotations

import math

import numpy as np

from gnss_ins_common.types import FloatArray
from ins_fusion.core.filter.eskf import VEL, ErrorStateFilter
from ins_fusion.core.filter.records import GnssFixMeasurement, GnssVelocityMeasurement
from ins_fusion.core.filter.state import FilterState, Geometry, decouple_yaw, restart_block
from ins_fusion.core.measurements.common import ned_cov
from ins_fusion.core.measurements.gnss_noise import GnssNoise
from ins_fusion.core.nav.rotation import (
    MAT_ENU_NED,
    as_quat,
    euler_rad,
    quat_from_rotvec,
    quat_multiply,
    quat_normalize,
    wrap_angle,
)
from ins_fusion.core.nav.strapdown import NavState

#: Largest distance in time between a fix and the alignment (or course heading) using it [s].
ALIGN_FIX_MAX_AGE_S = 1.5
#: Course-heading variance floor for side slip and antenna motion [rad²] (0.5°).
_COURSE_EXTRA_VARIANCE = math.radians(0.5) ** 2


def course(vel: GnssVelocityMeasurement) -> tuple[float, float]:
    """Heading [rad] and its variance [rad²] from the GNSS course (NTNU notes §8)."""
    east, north = float(vel.vel_enu_m_s[0]), float(vel.vel_enu_m_s[1])
    speed_sq = east * east + north * north
    sigma_sq = 0.5 * float(vel.cov_enu_m2_s2[0, 0] + vel.cov_enu_m2_s2[1, 1])
    return math.atan2(east, north), sigma_sq / speed_sq + _COURSE_EXTRA_VARIANCE


def velocity_variance(vel: GnssVelocityMeasurement) -> FloatArray:
    """Per NED axis variance of a GNSS velocity [m²/s²], unknown components capped at 1."""
    return np.minimum(np.nan_to_num(np.diagonal(ned_cov(vel.cov_enu_m2_s2)), nan=1.0), 1.0)


def set_heading(
    s: FilterState, kf: ErrorStateFilter, geometry: Geometry, yaw: float, yaw_variance: float
) -> None:
    """Turn the attitude about the vertical to ``yaw`` keeping the antenna position; the
    heading is known from now on."""
    if kf.smoother_hooks is not None:  # smoother hook: the heading is set, not estimated
        kf.smoother_hooks.on_break(kf.P)
    turn = float(wrap_angle(np.array(yaw - euler_rad(s.mat_nb)[2])))
    nav = s.nav
    antenna_n = s.mat_nb @ geometry.antenna_arm_b
    q_turn = quat_from_rotvec(0.0, 0.0, turn)
    quat = quat_normalize(quat_multiply(q_turn, as_quat(nav.quat_nb)))
    cos_t, sin_t = math.cos(turn), math.sin(turn)
    vn, ve, vd = nav.vel_ned_m_s.tolist()
    s.set_nav(
        NavState(
            nav.lat_rad,
            nav.lon_rad,
            nav.height_m,
            np.array([cos_t * vn - sin_t * ve, sin_t * vn + cos_t * ve, vd]),
            np.array(quat),
        )
    )
    s.move(antenna_n - s.mat_nb @ geometry.antenna_arm_b)
    decouple_yaw(kf, yaw_variance)
    s.heading_known = True
    s.last_position_t_s = s.t_s


def heading_from_course(
    s: FilterState,
    kf: ErrorStateFilter,
    geometry: Geometry,
    gnss_noise: GnssNoise,
    fix: GnssFixMeasurement | None,
    vel: GnssVelocityMeasurement,
) -> bool:
    """Heading unknown and fast enough: heading from the course; position and velocity
    restart from the latest fix and this velocity (the INS ran with the wrong heading).
    False (nothing done) without a fix near the velocity's epoch."""
    if fix is None or abs(fix.t_s - vel.t_s) > ALIGN_FIX_MAX_AGE_S:
        return False
    yaw, yaw_var = course(vel)
    set_heading(s, kf, geometry, yaw, yaw_var)
    vel_ned = np.nan_to_num(MAT_ENU_NED @ vel.vel_enu_m_s)
    nav = s.nav
    fix_nav = NavState(
        math.radians(fix.lat_deg), math.radians(fix.lon_deg), fix.height_m, vel_ned, nav.quat_nb
    )
    s.set_nav(fix_nav)
    s.move(-(s.mat_nb @ geometry.antenna_arm_b) + vel_ned * (s.t_s - fix.t_s))
    P = kf.P.copy()
    restart_block(P, VEL, np.diag(velocity_variance(vel)))
    kf.P = P
    gnss_noise.restart_position(s, kf, fix)
    s.last_position_t_s = s.t_s
    return True


def fast_enough(vel: GnssVelocityMeasurement, min_speed_m_s: float) -> bool:
    """GNSS horizontal speed at or above ``min_speed_m_s`` (course usable, clearly moving)."""
    speed = float(np.hypot(vel.vel_enu_m_s[0], vel.vel_enu_m_s[1]))
    return speed >= min_speed_m_s
