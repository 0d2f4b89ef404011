"""Vehicle trajectories with exact kinematics on WGS-84, and the truth they imply.

A trajectory is three smooth channels of time: speed along the path, yaw rate and path pitch
(grade). Each channel is constant between knots and changes between knots along a septic
smooth step (continuous value and first three derivatives), so the vehicle's acceleration and
angular rate are continuous, as for a real car. The body roll follows the lateral acceleration
(suspension roll). The base_link attitude is (roll, path pitch, heading); base_link x points
along the velocity, so the non-holonomic constraint holds exactly at base_link. The knots come
from a route scripted as segments (sim.route).

Position is the integral of the NED velocity on the WGS-84 ellipsoid (Aalborg notes §5.3,
C-1.15 to C-1.17), solved once with an 8th-order integrator at tight tolerance (error < 1e-6 m).
Everything else is analytic. The truth of any point fixed to the body (IMU, GNSS antenna) is
derived from rigid-body kinematics in ECEF, so lever arms and the slightly different local
vertical at the point are exact; the specific force includes normal gravity, Coriolis and the
transport rate, the angular rate includes earth rotation and transport rate.

Frames: NED / FRD internally, REP-103 ENU / FLU at the interfaces. Mountings (sensor frames in
base_link) are given REP-103 style: lever arm in base_link FLU, roll/pitch/yaw of the sensor frame.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from gnss_ins_common.types import FloatArray
from ins_fusion.core.nav import earth
from ins_fusion.core.nav.rotation import (
    MAT_FLU_FRD,
    frd_to_flu,
    ned_to_enu,
    quat_enu_flu_from_nb,
)
from ins_fusion.core.nav.strapdown import NavState

# --------------------------------------------------------------------------------------------
# Smooth channels

#: Position quadrature: cell length [s] and 6-point Gauss-Legendre nodes/weights on [0, 1].
_CELL_S = 0.25
_GL_X, _GL_W = np.polynomial.legendre.leggauss(6)
_GL_NODES, _GL_WEIGHTS = 0.5 * (_GL_X + 1.0), 0.5 * _GL_W


def _smooth_step(s: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Septic smooth step S(s) = 35s⁴ - 84s⁵ + 70s⁶ - 20s⁷ on [0, 1]: (S, S', S'', ∫₀ˢ S).

    The first three derivatives vanish at both ends, so a channel and its first three time
    derivatives are continuous across knots.
    """
    s2 = s * s
    s4 = s2 * s2
    su = s * (1.0 - s)
    return (
        s4 * (35.0 - 84.0 * s + 70.0 * s2 - 20.0 * s2 * s),
        140.0 * su**3,
        420.0 * su**2 * (1.0 - 2.0 * s),
        s4 * s * (7.0 - 14.0 * s + 10.0 * s2 - 2.5 * s2 * s),
    )


@dataclass(frozen=True)
class SmoothChannel:
    """A scalar function of time through knots (t_i, y_i): constant before the first and after
    the last knot, a septic smooth step from y_i to y_{i+1} between knots."""

    knot_t_s: FloatArray
    knot_value: FloatArray
    _knot_integral: FloatArray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        dt = np.diff(self.knot_t_s)
        if np.any(dt <= 0.0):
            raise ValueError("knot times must increase strictly")
        # ∫ over a full step = dt * (y_i + y_{i+1}) / 2 since ∫₀¹ S = 1/2.
        pieces = dt * 0.5 * (self.knot_value[:-1] + self.knot_value[1:])
        object.__setattr__(self, "_knot_integral", np.concatenate(([0.0], np.cumsum(pieces))))

    def evaluate(self, t_s: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """(y, dy/dt, d²y/dt², ∫ y dt from the first knot) at times t_s (any shape)."""
        knots, values = self.knot_t_s, self.knot_value
        idx = np.clip(np.searchsorted(knots, t_s, side="right") - 1, 0, len(knots) - 2)
        t0 = knots[idx]
        span = knots[idx + 1] - t0
        delta = values[idx + 1] - values[idx]
        tau = np.clip(t_s - t0, 0.0, None)
        s = np.clip(tau / span, 0.0, 1.0)
        step, d_step, dd_step, int_step = _smooth_step(s)
        beyond = tau - s * span  # time past the last knot (0 elsewhere)
        before = np.minimum(t_s - knots[0], 0.0)  # time before the first knot (<= 0)
        value = values[idx] + delta * step
        integral = (
            self._knot_integral[idx]
            + values[idx] * s * span
            + delta * span * int_step
            + value * beyond
            + values[0] * before
        )
        return value, delta * d_step / span, delta * dd_step / span**2, integral


# --------------------------------------------------------------------------------------------
# The start of a route


@dataclass(frozen=True)
class GeodeticStart:
    """Start of a route: WGS-84 position and heading of base_link (clockwise from north)."""

    lat_rad: float
    lon_rad: float
    height_m: float
    heading_rad: float = 0.0


# --------------------------------------------------------------------------------------------
# Truth


@dataclass(frozen=True)
class Mounting:
    """Pose of a sensor frame in base_link (REP-103): lever arm [m] in base_link FLU and the
    roll/pitch/yaw [rad] of the sensor's FLU frame in base_link FLU."""

    lever_arm_flu_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy_rad: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def mat_base_sensor_frd(self) -> FloatArray:
        """Rotation sensor (FRD) -> base_link (FRD)."""
        roll, pitch, yaw = self.rpy_rad
        mat_flu = Rotation.from_euler("ZYX", [yaw, pitch, roll]).as_matrix()
        return np.asarray(MAT_FLU_FRD @ mat_flu @ MAT_FLU_FRD, dtype=np.float64)


@dataclass(frozen=True)
class FrameTruth:
    """Truth of a frame fixed to the vehicle at times t_s (arrays over time, first axis).

    lat_rad, lon_rad, height_m: WGS-84 position of the frame origin; vel_ned_m_s: its velocity
    relative to the earth in its local NED; quat_nb: frame (FRD) -> local NED, scalar last;
    rate_frd_rad_s: angular rate ω_ib; specific_force_frd_m_s2: specific force at the origin.
    """

    t_s: FloatArray
    lat_rad: FloatArray
    lon_rad: FloatArray
    height_m: FloatArray
    vel_ned_m_s: FloatArray
    quat_nb: FloatArray
    rate_frd_rad_s: FloatArray
    specific_force_frd_m_s2: FloatArray

    @property
    def vel_enu_m_s(self) -> FloatArray:
        """Velocity in ENU [m/s]."""
        return ned_to_enu(self.vel_ned_m_s)

    @property
    def quat_enu_flu(self) -> FloatArray:
        """Frame (FLU) -> ENU quaternion, scalar last (REP-103 orientation)."""
        return quat_enu_flu_from_nb(self.quat_nb)

    @property
    def rate_flu_rad_s(self) -> FloatArray:
        """Angular rate ω_ib in the frame's FLU axes (what a REP-145 IMU reads) [rad/s]."""
        return frd_to_flu(self.rate_frd_rad_s)

    @property
    def specific_force_flu_m_s2(self) -> FloatArray:
        """Specific force in the frame's FLU axes (a level resting IMU reads +g on z) [m/s²]."""
        return frd_to_flu(self.specific_force_frd_m_s2)

    def nav_state(self, index: int) -> NavState:
        """Strapdown state of this frame at one sample."""
        return NavState(
            float(self.lat_rad[index]),
            float(self.lon_rad[index]),
            float(self.height_m[index]),
            self.vel_ned_m_s[index].copy(),
            self.quat_nb[index].copy(),
        )


class Trajectory:
    """Exact kinematics of base_link along a route; build with Route.build() (sim.route)."""

    def __init__(
        self,
        start: GeodeticStart,
        duration_s: float,
        speed: SmoothChannel,
        yaw_rate: SmoothChannel,
        pitch: SmoothChannel,
        roll_gain_rad_per_m_s2: float,
    ) -> None:
        self.start = start
        self.duration_s = duration_s
        self._speed = speed
        self._yaw_rate = yaw_rate
        self._pitch = pitch
        self._roll_gain = roll_gain_rad_per_m_s2
        self._integrate_position()

    def _angles(self, t: FloatArray) -> dict[str, FloatArray]:
        """Speed, Euler angles of base_link (FRD in NED) and their first two derivatives."""
        v, dv, ddv, _ = self._speed.evaluate(t)
        r, dr, ddr, yaw_int = self._yaw_rate.evaluate(t)
        pitch, dpitch, ddpitch, _ = self._pitch.evaluate(t)
        k = -self._roll_gain  # lateral accel (FRD y) = v r; the body rolls out of the turn
        return {
            "v": v,
            "dv": dv,
            "yaw": self.start.heading_rad + yaw_int,
            "dyaw": r,
            "ddyaw": dr,
            "pitch": pitch,
            "dpitch": dpitch,
            "ddpitch": ddpitch,
            "roll": k * v * r,
            "droll": k * (dv * r + v * dr),
            "ddroll": k * (ddv * r + 2.0 * dv * dr + v * ddr),
        }

    @staticmethod
    def _velocity_ned(a: dict[str, FloatArray]) -> tuple[FloatArray, FloatArray]:
        """NED velocity along the path and its time derivative."""
        cy, sy = np.cos(a["yaw"]), np.sin(a["yaw"])
        cp, sp = np.cos(a["pitch"]), np.sin(a["pitch"])
        direction = np.stack((cp * cy, cp * sy, -sp), axis=-1)
        d_yaw = np.stack((-cp * sy, cp * cy, 0.0 * cp), axis=-1)
        d_pitch = np.stack((-sp * cy, -sp * sy, -cp), axis=-1)
        v = a["v"][..., None]
        vel = v * direction
        acc = (
            a["dv"][..., None] * direction
            + v * a["dyaw"][..., None] * d_yaw
            + v * a["dpitch"][..., None] * d_pitch
        )
        return vel, acc

    def _position_rates(
        self, t: FloatArray, lat: FloatArray, height: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """(dlat/dt, dlon/dt, dh/dt) at times t for a given latitude and height (C-1.15-17)."""
        vel, _ = self._velocity_ned(self._angles(t))
        r_meridian, r_prime_vertical = earth.radii_m(lat)
        return (
            vel[..., 0] / (r_meridian + height),
            vel[..., 1] / ((r_prime_vertical + height) * np.cos(lat)),
            -vel[..., 2],
        )

    def _grid_position(self, t: FloatArray, which: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Latitude and height at times t, linearly interpolated from the grid solution."""
        return np.interp(t, self._grid_t, which[0]), np.interp(t, self._grid_t, which[2])

    def _integrate_position(self) -> None:
        """Position on a grid aligned with every knot, by Gauss-Legendre quadrature of the
        velocity in each cell (no knot inside a cell, where the velocity is analytic) and Picard
        iteration for the weak dependence of the rates on latitude and height through the radii
        (each iteration gains about six orders of magnitude)."""
        knots = np.unique(
            np.concatenate(
                [ch.knot_t_s for ch in (self._speed, self._yaw_rate, self._pitch)]
                + [np.array([0.0, self.duration_s])]
            )
        )
        knots = knots[(knots >= 0.0) & (knots <= self.duration_s)]
        pieces = [
            np.linspace(t0, t1, max(1, math.ceil((t1 - t0) / _CELL_S)) + 1)[:-1]
            for t0, t1 in itertools.pairwise(knots)
        ]
        self._grid_t = np.concatenate([*pieces, knots[-1:]])
        start = np.array([self.start.lat_rad, self.start.lon_rad, self.start.height_m])
        self._grid_pos = np.repeat(start[:, None], len(self._grid_t), axis=1)
        cell_t0 = self._grid_t[:-1]
        cell_len = np.diff(self._grid_t)
        node_t = cell_t0[:, None] + cell_len[:, None] * _GL_NODES
        for _ in range(3):
            lat, height = self._grid_position(node_t, self._grid_pos)
            rates = self._position_rates(node_t, lat, height)
            cell_integrals = np.stack([(r * _GL_WEIGHTS).sum(axis=1) * cell_len for r in rates])
            self._grid_pos = start[:, None] + np.concatenate(
                (np.zeros((3, 1)), np.cumsum(cell_integrals, axis=1)), axis=1
            )

    def _position(self, t: FloatArray) -> FloatArray:
        """(lat, lon, height) at times t, shape (3, n): grid value plus quadrature in the cell."""
        idx = np.clip(np.searchsorted(self._grid_t, t, side="right") - 1, 0, len(self._grid_t) - 2)
        t0 = self._grid_t[idx]
        span = (t - t0)[:, None]
        node_t = t0[:, None] + span * _GL_NODES
        lat, height = self._grid_position(node_t, self._grid_pos)
        rates = self._position_rates(node_t, lat, height)
        quadrature = np.stack([(r * _GL_WEIGHTS).sum(axis=1) * span[:, 0] for r in rates])
        return np.asarray(self._grid_pos[:, idx] + quadrature, dtype=np.float64)

    def _check_times(self, t_s: FloatArray) -> FloatArray:
        t = np.atleast_1d(np.asarray(t_s, dtype=np.float64))
        if t.size and (t.min() < 0.0 or t.max() > self.duration_s + 1e-9):
            raise ValueError(f"time outside the trajectory [0, {self.duration_s}] s")
        return t

    def path_speed(self, t_s: FloatArray) -> tuple[FloatArray, FloatArray]:
        """base_link speed along its path [m/s] and its rate of change [m/s²] at times t_s."""
        speed, accel, _, _ = self._speed.evaluate(self._check_times(t_s))
        return speed, accel

    def frame_truth(self, t_s: FloatArray, mounting: Mounting = Mounting()) -> FrameTruth:
        """Truth of a frame mounted on base_link (default: base_link itself) at times t_s."""
        t = self._check_times(t_s)
        a = self._angles(t)
        vel_n, acc_n = self._velocity_ned(a)
        lat, lon, height = self._position(t)

        # Earth and transport rates at base_link and their time derivatives.
        r_m, r_n = earth.radii_m(lat)
        dr_m, dr_n = earth.radii_derivative_m_per_rad(lat)
        cos_lat, tan_lat = np.cos(lat), np.tan(lat)
        dlat = vel_n[:, 0] / (r_m + height)
        dheight = -vel_n[:, 2]
        w_ie = np.stack(earth.earth_rate_ned_rad_s(lat), axis=-1)
        rate_e = vel_n[:, 1] / (r_n + height)
        drate_e = (
            acc_n[:, 1] / (r_n + height)
            - vel_n[:, 1] * (dr_n * dlat + dheight) / (r_n + height) ** 2
        )
        rate_n = -vel_n[:, 0] / (r_m + height)
        drate_n = (
            -acc_n[:, 0] / (r_m + height)
            + vel_n[:, 0] * (dr_m * dlat + dheight) / (r_m + height) ** 2
        )
        w_en = np.stack((rate_e, rate_n, -rate_e * tan_lat), axis=-1)
        dw_en = np.stack(
            (drate_e, drate_n, -drate_e * tan_lat - rate_e * dlat / cos_lat**2), axis=-1
        )

        # Attitude of base_link (FRD) and its angular rate relative to NED, with derivative.
        yaw, pitch, roll = a["yaw"], a["pitch"], a["roll"]
        dyaw, dpitch, droll = a["dyaw"], a["dpitch"], a["droll"]
        ddyaw, ddpitch, ddroll = a["ddyaw"], a["ddpitch"], a["ddroll"]
        rot_nb = Rotation.from_euler("ZYX", np.stack((yaw, pitch, roll), axis=-1))
        mat_nb = rot_nb.as_matrix()
        cr, sr, cp, sp = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch)
        w_nb = np.stack(
            (
                droll - dyaw * sp,
                dpitch * cr + dyaw * sr * cp,
                -dpitch * sr + dyaw * cr * cp,
            ),
            axis=-1,
        )
        dw_nb = np.stack(
            (
                ddroll - ddyaw * sp - dyaw * dpitch * cp,
                ddpitch * cr
                - dpitch * droll * sr
                + ddyaw * sr * cp
                + dyaw * droll * cr * cp
                - dyaw * dpitch * sr * sp,
                -ddpitch * sr
                - dpitch * droll * cr
                + ddyaw * cr * cp
                - dyaw * droll * sr * cp
                - dyaw * dpitch * cr * sp,
            ),
            axis=-1,
        )
        w_en_b = np.einsum("nji,nj->ni", mat_nb, w_en)
        w_in_b = w_en_b + np.einsum("nji,nj->ni", mat_nb, w_ie)
        w_eb = w_nb + w_en_b
        dw_eb = dw_nb + np.einsum("nji,nj->ni", mat_nb, dw_en) - np.cross(w_nb, w_en_b)
        w_ib = w_nb + w_in_b

        # Rigid-body kinematics of the mounted frame's origin P in ECEF.
        mat_en = earth.mat_en(lat, lon)
        mat_eb = mat_en @ mat_nb
        lever_b = MAT_FLU_FRD @ np.asarray(mounting.lever_arm_flu_m, dtype=np.float64)
        pos_e = earth.geodetic_to_ecef(lat, lon, height) + mat_eb @ lever_b
        vel_e = np.einsum("nij,nj->ni", mat_en, vel_n) + np.einsum(
            "nij,nj->ni", mat_eb, np.cross(w_eb, lever_b)
        )
        acc_e = np.einsum("nij,nj->ni", mat_en, acc_n + np.cross(w_en, vel_n)) + np.einsum(
            "nij,nj->ni", mat_eb, np.cross(dw_eb, lever_b) + np.cross(w_eb, np.cross(w_eb, lever_b))
        )
        lat_p, lon_p, height_p = earth.ecef_to_geodetic(pos_e)
        mat_en_p = earth.mat_en(lat_p, lon_p)
        earth_rate_e = np.array([0.0, 0.0, earth.EARTH_RATE_RAD_S])
        gravity_e = mat_en_p[:, :, 2] * earth.normal_gravity_m_s2(lat_p, height_p)[:, None]
        force_e = acc_e + 2.0 * np.cross(earth_rate_e, vel_e) - gravity_e

        mat_bs = mounting.mat_base_sensor_frd()
        mat_es = mat_eb @ mat_bs
        mat_ns = np.einsum("nji,njk->nik", mat_en_p, mat_es)
        return FrameTruth(
            t_s=t,
            lat_rad=lat_p,
            lon_rad=lon_p,
            height_m=height_p,
            vel_ned_m_s=np.einsum("nji,nj->ni", mat_en_p, vel_e),
            quat_nb=np.asarray(Rotation.from_matrix(mat_ns).as_quat(canonical=True)),
            rate_frd_rad_s=w_ib @ mat_bs,
            specific_force_frd_m_s2=np.einsum("nji,nj->ni", mat_es, force_e),
        )
