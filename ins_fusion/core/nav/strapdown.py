"""Strapdown mechanization on WGS-84: NED velocity, geodetic position, body->NED quaternion.

The body frame b of the mechanization is the IMU's own frame in FRD (x forward, y right, z down);
REP-145 data (imu_link, FLU) is converted with rotation.flu_to_frd. The update follows the
two-sample increment algorithm of Shin (2001) as implemented in KF-GINS (velocity, then position,
then attitude, with a predictor-corrector midpoint for the earth/transport rates and gravity):

- navigation equation dv/dt = C_nb f - (2ω_ie + ω_en) × v + g (Aalborg notes §5.3, C-1.14),
- position rates (C-1.15)-(C-1.17), normal gravity and rates from core.nav.earth,
- rotation compensation dθ×dv/2 + dθ×(dθ×dv)/6 and two-sample sculling and coning corrections
  generalised to unequal intervals, so any (jittered) dt is handled.

``mechanize`` is compiled (core.compiled) and works on a flat array; ``propagate`` is its form
for NavState. Errors of the algorithm are third order in dt for smooth motion.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from gnss_ins_common.types import FloatArray, Vec3
from ins_fusion.core.compiled import compilable, jit
from ins_fusion.core.layout import offsets
from ins_fusion.core.nav import earth
from ins_fusion.core.nav.rotation import (
    euler_from_quat,
    mat_from_quat,
    ned_to_enu,
    quat_enu_flu_from_nb,
    quat_from_rotvec,
    quat_multiply,
    quat_nb_from_enu_flu,
    quat_normalize,
    quat_rotate,
)


@dataclass(frozen=True, slots=True)
class NavState:
    """Navigation state of the IMU.

    lat_rad, lon_rad, height_m: WGS-84 geodetic position (ellipsoidal height).
    vel_ned_m_s: velocity relative to the earth in NED, shape (3,).
    quat_nb: body (FRD) -> NED unit quaternion, scalar last (x, y, z, w), shape (4,).
    """

    lat_rad: float
    lon_rad: float
    height_m: float
    vel_ned_m_s: FloatArray
    quat_nb: FloatArray

    @property
    def mat_nb(self) -> FloatArray:
        """Body (FRD) -> NED rotation matrix."""
        return mat_from_quat(*self.quat_nb.tolist())

    @property
    def euler_rad(self) -> FloatArray:
        """(roll, pitch, yaw) of the FRD body in NED [rad]."""
        return euler_from_quat(self.quat_nb)

    @property
    def vel_enu_m_s(self) -> FloatArray:
        """Velocity relative to the earth in ENU (REP-103) [m/s]."""
        return ned_to_enu(self.vel_ned_m_s)

    @property
    def quat_enu_flu(self) -> FloatArray:
        """Body (FLU) -> ENU quaternion, scalar last: the REP-103 orientation."""
        return quat_enu_flu_from_nb(self.quat_nb)

    @classmethod
    def from_enu_flu(
        cls,
        lat_rad: float,
        lon_rad: float,
        height_m: float,
        vel_enu_m_s: Sequence[float] | FloatArray,
        quat_enu_flu: Sequence[float] | FloatArray,
    ) -> NavState:
        """State from a REP-103 velocity (ENU) and orientation (FLU body in ENU)."""
        return cls(
            lat_rad,
            lon_rad,
            height_m,
            ned_to_enu(np.asarray(vel_enu_m_s, dtype=np.float64)),
            quat_nb_from_enu_flu(np.asarray(quat_enu_flu, dtype=np.float64)),
        )


#: An IMU increment, the output integrated over one interval in the FRD body frame, is an array
#: (``increment``): the compiled code takes arrays.
INCREMENT_LAYOUT = (
    ("dt", 1),  # the interval [s]
    ("angle", 3),  # angle increment dθ = ∫ω_ib dt [rad]
    ("vel", 3),  # velocity increment dv = ∫f dt [m/s]
)
INC_DT, INC_ANGLE, INC_VEL, INCREMENT_SIZE = offsets(INCREMENT_LAYOUT)


def increment(dt_s: float, dtheta_rad: Sequence[float], dvel_m_s: Sequence[float]) -> FloatArray:
    """The increment array of an interval of dt_s [s]: angle ∫ω_ib dt [rad] and velocity
    ∫f dt [m/s] increments, FRD body."""
    return np.array((dt_s, *dtheta_rad, *dvel_m_s), dtype=np.float64)


class SampleIntegrator:
    """Turns instantaneous IMU samples (rate and specific force, FRD) into increments.

    The increment over [t_{k-1}, t_k] integrates the quadratic through the last three samples
    (weights -1/12, 8/12, 5/12 for equal spacing; exact for any spacing), and the trapezoid for
    the first interval after a reset. The trapezoid alone leaves an error of dt²/12·dω/dt per
    interval that the rotating body frame does not let cancel: about 1e-7 rad of tilt per
    rolling turn at 134 Hz, i.e. decimetres after ten minutes of free inertial navigation.
    """

    def __init__(self) -> None:
        #: Rows 0-2: the last samples (t, ω, f), the newest last; [3, 0]: how many are held.
        self.buffer = np.zeros((4, INCREMENT_SIZE))

    def reset(self) -> None:
        """Forget the history (after a data gap or a time jump)."""
        self.buffer[3, 0] = 0.0

    def push(
        self,
        t_s: float,
        rate_rad_s: Sequence[float] | FloatArray,
        specific_force_m_s2: Sequence[float] | FloatArray,
    ) -> FloatArray | None:
        """Add a sample; returns the increment since the previous sample (None for the first)."""
        inc = np.empty(INCREMENT_SIZE)
        sample = tuple(float(v) for v in (*rate_rad_s[:3], *specific_force_m_s2[:3]))
        has_interval = integrate_sample(self.buffer, float(t_s), sample, inc)
        return inc if has_interval else None


@jit
def integrate_sample(
    buffer: FloatArray, t_s: float, sample: tuple[float, ...], inc: FloatArray
) -> bool:
    """SampleIntegrator.push on its ``buffer``: file the sample (ω (3), f (3)) stamped ``t_s``,
    write the increment since the previous one into ``inc``; False (``inc`` untouched) for the
    first sample."""
    count = int(buffer[3, 0])
    if count == 3:
        buffer[0, :] = buffer[1, :]
        buffer[1, :] = buffer[2, :]
        count = 2
    row = buffer[count]
    row[0] = t_s
    for k in range(6):
        row[1 + k] = sample[k]
    count += 1
    buffer[3, 0] = count
    if count == 1:
        return False
    t1 = buffer[count - 2, 0]
    h2 = t_s - t1
    if count == 2:
        c0, c1, c2 = 0.0, 0.5 * h2, 0.5 * h2
        k0 = k1 = 0
    else:
        h1 = t1 - buffer[0, 0]
        c0 = -(h2**3) / (6.0 * h1 * (h1 + h2))
        c1 = h2 * h2 / (6.0 * h1) + 0.5 * h2
        c2 = (h2 * h2 / 3.0 + 0.5 * h1 * h2) / (h1 + h2)
        k0, k1 = 0, 1
    inc[0] = h2
    for j in range(1, INCREMENT_SIZE):
        inc[j] = c0 * buffer[k0, j] + c1 * buffer[k1, j] + c2 * buffer[count - 1, j]
    return True


@compilable
def _velocity_change(
    dvel_n: Vec3,
    vel: Vec3,
    sin_lat: float,
    cos_lat: float,
    radii: tuple[float, float],
    height: float,
    dt: float,
) -> Vec3:
    """Velocity change over dt: the NED-resolved specific-force increment dvel_n corrected for the
    rotation of the NED frame over half the interval, plus gravity and Coriolis over dt, with the
    rates and gravity evaluated at (latitude, height, vel)."""
    w_ie_n, w_ie_d = earth.EARTH_RATE_RAD_S * cos_lat, -earth.EARTH_RATE_RAD_S * sin_lat
    w_en_n, w_en_e, w_en_d = earth.transport_rate_from(
        sin_lat, cos_lat, radii[0], radii[1], height, vel[0], vel[1]
    )
    g = earth.normal_gravity_from_sin_cos(sin_lat, cos_lat, height)
    # frame rotation ζ/2 × dvel_n with ζ = (ω_ie + ω_en) dt; Coriolis (2ω_ie + ω_en) × v.
    zx, zy, zz = 0.5 * dt * (w_ie_n + w_en_n), 0.5 * dt * w_en_e, 0.5 * dt * (w_ie_d + w_en_d)
    cx, cy, cz = 2.0 * w_ie_n + w_en_n, w_en_e, 2.0 * w_ie_d + w_en_d
    fx, fy, fz = dvel_n
    vx, vy, vz = vel
    return (
        fx - (zy * fz - zz * fy) - (cy * vz - cz * vy) * dt,
        fy - (zz * fx - zx * fz) - (cz * vx - cx * vz) * dt,
        fz - (zx * fy - zy * fx) + (g - (cx * vy - cy * vx)) * dt,
    )


#: Layout of the navigation array ``mechanize`` advances (NavState's numbers; FilterState.x
#: holds it at core.filter.state.X_NAV).
NAV_LAYOUT = (
    ("lat", 1),  # WGS-84 geodetic latitude [rad]
    ("lon", 1),  # longitude [rad]
    ("height", 1),  # ellipsoidal height [m]
    ("vel", 3),  # velocity relative to the earth, NED [m/s]
    ("quat", 4),  # body (FRD) -> NED unit quaternion, scalar last (x, y, z, w)
)
NAV_LAT, NAV_LON, NAV_HEIGHT, NAV_VEL, NAV_QUAT, NAV_SIZE = offsets(NAV_LAYOUT)


def propagate(state: NavState, inc: FloatArray, prev: FloatArray | None = None) -> NavState:
    """Advance the state over one IMU increment (``increment``, FRD body).

    ``prev`` is the increment of the preceding interval, used for the two-sample coning and
    sculling corrections; pass None for the first sample or after a data gap.
    """
    nav = np.empty(NAV_SIZE)
    nav[NAV_LAT], nav[NAV_LON], nav[NAV_HEIGHT] = state.lat_rad, state.lon_rad, state.height_m
    nav[NAV_VEL : NAV_VEL + 3] = state.vel_ned_m_s
    nav[NAV_QUAT : NAV_QUAT + 4] = state.quat_nb
    mechanize(nav, inc, inc if prev is None else prev, prev is not None)
    return NavState(
        float(nav[NAV_LAT]),
        float(nav[NAV_LON]),
        float(nav[NAV_HEIGHT]),
        nav[NAV_VEL : NAV_VEL + 3],
        nav[NAV_QUAT : NAV_QUAT + 4],
    )


@jit
def mechanize(nav: FloatArray, inc: FloatArray, prev: FloatArray, use_prev: bool) -> None:
    """Advance the navigation array ``nav`` (NAV_SIZE layout) in place over the increment
    ``inc``; ``prev`` (read when ``use_prev``) is that of the preceding interval, for the
    two-sample coning and sculling corrections.

    sin φ and cos φ are computed once: the midpoint values are their first-order expansions in
    the latitude step (≤ 2e-8 rad at 40 m/s, so the expansion errs by < 1e-16), and the radii of
    the start serve the whole interval (they change by < 1e-10 relative over a sample).
    """
    dt = inc[INC_DT]
    lat, lon, height = nav[NAV_LAT], nav[NAV_LON], nav[NAV_HEIGHT]
    vn, ve, vd = nav[NAV_VEL], nav[NAV_VEL + 1], nav[NAV_VEL + 2]
    qx, qy, qz, qw = nav[NAV_QUAT], nav[NAV_QUAT + 1], nav[NAV_QUAT + 2], nav[NAV_QUAT + 3]

    # Specific-force increment in b(k-1): rotation compensation to third order plus sculling;
    # rotation vector with coning. Linear rate and specific force over both intervals (equal dt
    # gives the usual 1/12 coefficient). Cross products written out.
    tx, ty, tz = inc[INC_ANGLE], inc[INC_ANGLE + 1], inc[INC_ANGLE + 2]
    ux, uy, uz = inc[INC_VEL], inc[INC_VEL + 1], inc[INC_VEL + 2]
    r1x, r1y, r1z = ty * uz - tz * uy, tz * ux - tx * uz, tx * uy - ty * ux  # dθ × dv
    r2x, r2y, r2z = ty * r1z - tz * r1y, tz * r1x - tx * r1z, tx * r1y - ty * r1x  # dθ × (dθ × dv)
    dvb_x = ux + 0.5 * r1x + r2x / 6.0
    dvb_y = uy + 0.5 * r1y + r2y / 6.0
    dvb_z = uz + 0.5 * r1z + r2z / 6.0
    rx, ry, rz = tx, ty, tz
    if use_prev:
        k = dt * dt / (6.0 * prev[INC_DT] * (dt + prev[INC_DT]))
        px, py, pz = prev[INC_ANGLE], prev[INC_ANGLE + 1], prev[INC_ANGLE + 2]
        wx, wy, wz = prev[INC_VEL], prev[INC_VEL + 1], prev[INC_VEL + 2]
        # sculling dθ_prev × dv + dv_prev × dθ; coning dθ_prev × dθ
        dvb_x += k * (py * uz - pz * uy + wy * tz - wz * ty)
        dvb_y += k * (pz * ux - px * uz + wz * tx - wx * tz)
        dvb_z += k * (px * uy - py * ux + wx * ty - wy * tx)
        rx += k * (py * tz - pz * ty)
        ry += k * (pz * tx - px * tz)
        rz += k * (px * ty - py * tx)
    quat = (qx, qy, qz, qw)
    dvel_n = quat_rotate(quat, (dvb_x, dvb_y, dvb_z))

    # Velocity: predictor at the start of the interval, corrector at the extrapolated midpoint.
    sin_lat, cos_lat = math.sin(lat), math.cos(lat)
    radii = earth.radii_from_sin(sin_lat)
    r_meridian, r_prime_vertical = radii
    change = _velocity_change(dvel_n, (vn, ve, vd), sin_lat, cos_lat, radii, height, dt)
    vel_mid = (vn + 0.5 * change[0], ve + 0.5 * change[1], vd + 0.5 * change[2])
    d_lat = 0.5 * dt * vel_mid[0] / (r_meridian + height)
    change = _velocity_change(
        dvel_n,
        vel_mid,
        sin_lat + cos_lat * d_lat,
        cos_lat - sin_lat * d_lat,
        radii,
        height - 0.5 * dt * vel_mid[2],
        dt,
    )
    vn_new, ve_new, vd_new = vn + change[0], ve + change[1], vd + change[2]

    # Position: trapezoidal velocity, latitude and height at the midpoint.
    vn_bar, ve_bar, vd_bar = 0.5 * (vn + vn_new), 0.5 * (ve + ve_new), 0.5 * (vd + vd_new)
    height_mid = height - 0.5 * dt * vd_bar
    d_lat = 0.5 * dt * vn_bar / (r_meridian + height_mid)
    sin_mid, cos_mid = sin_lat + cos_lat * d_lat, cos_lat - sin_lat * d_lat
    nav[NAV_LAT] = lat + 2.0 * d_lat
    nav[NAV_LON] = lon + dt * ve_bar / ((r_prime_vertical + height_mid) * cos_mid)
    nav[NAV_HEIGHT] = height - dt * vd_bar
    nav[NAV_VEL], nav[NAV_VEL + 1], nav[NAV_VEL + 2] = vn_new, ve_new, vd_new

    # Attitude: body rotation (with coning) and NED-frame rotation over dt at the midpoint.
    w_en = earth.transport_rate_from(
        sin_mid, cos_mid, r_meridian, r_prime_vertical, height_mid, vn_bar, ve_bar
    )
    w_n = earth.EARTH_RATE_RAD_S * cos_mid + w_en[0]
    w_d = -earth.EARTH_RATE_RAD_S * sin_mid + w_en[2]
    q_bb = quat_from_rotvec(rx, ry, rz)
    q_nn = quat_from_rotvec(-w_n * dt, -w_en[1] * dt, -w_d * dt)
    quat_new = quat_normalize(quat_multiply(q_nn, quat_multiply(quat, q_bb)))
    nav[NAV_QUAT], nav[NAV_QUAT + 1], nav[NAV_QUAT + 2], nav[NAV_QUAT + 3] = quat_new
