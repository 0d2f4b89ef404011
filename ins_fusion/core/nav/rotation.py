"""Rotations and frame conventions: quaternions, Euler angles, NED/ENU and FRD/FLU.

Quaternions are Hamilton, unit, scalar last (x, y, z, w) as in scipy and ROS. ``quat_ab`` rotates
vectors from frame b into frame a: v_a = R(quat_ab) v_b, and q_ac = q_ab ⊗ q_bc. Euler angles are
roll, pitch, yaw of the intrinsic z-y'-x'' sequence (yaw first), i.e. the standard NED/FRD angles
of Aalborg notes §5.5 (7.10)-(7.12) (shared/reference/imu400cc-aalborg-notes.md).

The scalar helpers (``quat_multiply``, ``quat_from_rotvec``, ``quat_rotate``, ...) work on plain
float tuples and are ``compilable``: the compiled strapdown and solution (core.compiled) call
them. Batch conversions use scipy.spatial.transform.Rotation.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from gnss_ins_common.types import FloatArray, Quat, Vec3
from ins_fusion.core.compiled import compilable

#: NED -> ENU (and ENU -> NED): swap the first two axes and negate the third (REP-103).
MAT_ENU_NED: FloatArray = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
#: FRD -> FLU (and FLU -> FRD): negate y and z (REP-103 body axes).
MAT_FLU_FRD: FloatArray = np.diag([1.0, -1.0, -1.0])
_ROT_FLU_FRD = Rotation.from_matrix(MAT_FLU_FRD)  # 180° about x
_ROT_ENU_NED = Rotation.from_matrix(MAT_ENU_NED)  # 180° about (N+E)/sqrt(2)
#: ENU <-> NED quaternion (180° about (N+E)/√2) and FRD <-> FLU (180° about x), scalar last.
_Q_ENU_NED: Quat = (math.sqrt(0.5), math.sqrt(0.5), 0.0, 0.0)
_Q_FRD_FLU: Quat = (1.0, 0.0, 0.0, 0.0)


@compilable
def quat_multiply(q: Quat, p: Quat) -> Quat:
    """Hamilton product q ⊗ p of scalar-last quaternions."""
    qx, qy, qz, qw = q
    px, py, pz, pw = p
    return (
        qw * px + qx * pw + qy * pz - qz * py,
        qw * py - qx * pz + qy * pw + qz * px,
        qw * pz + qx * py - qy * px + qz * pw,
        qw * pw - qx * px - qy * py - qz * pz,
    )


@compilable
def quat_from_rotvec(rx: float, ry: float, rz: float) -> Quat:
    """Quaternion of the rotation vector (rx, ry, rz) [rad] (series form for small angles)."""
    angle_sq = rx * rx + ry * ry + rz * rz
    if angle_sq < 1e-8:
        # sin(a/2)/a and cos(a/2) to O(a^4): error < 1e-20 at a = 1e-4.
        k = 0.5 - angle_sq / 48.0
        w = 1.0 - angle_sq / 8.0 + angle_sq * angle_sq / 384.0
    else:
        angle = math.sqrt(angle_sq)
        k = math.sin(0.5 * angle) / angle
        w = math.cos(0.5 * angle)
    return (k * rx, k * ry, k * rz, w)


@compilable
def mat_from_quat(x: float, y: float, z: float, w: float) -> FloatArray:
    """Rotation matrix of the unit quaternion (x, y, z, w): v_a = M v_b for quat_ab (scipy's
    ``Rotation.from_quat(q).as_matrix()`` in a tenth of the time, for per-output use)."""
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


@compilable
def quat_normalize(q: Quat) -> Quat:
    """Unit quaternion with a non-negative scalar part."""
    x, y, z, w = q
    inv = 1.0 / math.sqrt(x * x + y * y + z * z + w * w)
    if w < 0.0:
        inv = -inv
    return (x * inv, y * inv, z * inv, w * inv)


@compilable
def quat_rotate(q: Quat, v: Vec3) -> Vec3:
    """R(q) v for a unit quaternion q: v + 2w(u×v) + 2u×(u×v) with u the vector part."""
    x, y, z, w = q
    vx, vy, vz = v
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    return (
        vx + w * tx + y * tz - z * ty,
        vy + w * ty + z * tx - x * tz,
        vz + w * tz + x * ty - y * tx,
    )


def quat_from_euler(roll_rad: float, pitch_rad: float, yaw_rad: float) -> FloatArray:
    """Body (FRD) -> NED quaternion from roll, pitch, yaw [rad] (z-y'-x'' intrinsic)."""
    return np.asarray(
        Rotation.from_euler("ZYX", [yaw_rad, pitch_rad, roll_rad]).as_quat(), dtype=np.float64
    )


def euler_from_quat(quat_nb: FloatArray) -> FloatArray:
    """(roll, pitch, yaw) [rad] of a body (FRD) -> NED quaternion; shape (3,) or (n, 3)."""
    yaw_pitch_roll = Rotation.from_quat(quat_nb).as_euler("ZYX")
    return np.asarray(yaw_pitch_roll[..., ::-1], dtype=np.float64)


def ned_to_enu(vec: FloatArray) -> FloatArray:
    """NED vector(s) -> ENU (the same swap maps ENU -> NED); shape (3,) or (n, 3)."""
    v = np.asarray(vec, dtype=np.float64)
    return np.stack((v[..., 1], v[..., 0], -v[..., 2]), axis=-1)


enu_to_ned = ned_to_enu


def frd_to_flu(vec: FloatArray) -> FloatArray:
    """FRD body vector(s) -> FLU (the same sign flip maps FLU -> FRD); shape (3,) or (n, 3)."""
    v = np.asarray(vec, dtype=np.float64)
    return np.stack((v[..., 0], -v[..., 1], -v[..., 2]), axis=-1)


flu_to_frd = frd_to_flu


def quat_enu_flu_from_nb(quat_nb: FloatArray) -> FloatArray:
    """Body (FRD) -> NED quaternion(s) -> body (FLU) -> ENU quaternion(s) (REP-103 orientation)."""
    rot = _ROT_ENU_NED * Rotation.from_quat(quat_nb) * _ROT_FLU_FRD
    return np.asarray(rot.as_quat(canonical=True), dtype=np.float64)


def quat_nb_from_enu_flu(quat_enu_flu: FloatArray) -> FloatArray:
    """Body (FLU) -> ENU quaternion(s) -> body (FRD) -> NED quaternion(s)."""
    rot = _ROT_ENU_NED * Rotation.from_quat(quat_enu_flu) * _ROT_FLU_FRD
    return np.asarray(rot.as_quat(canonical=True), dtype=np.float64)


@compilable
def skew(v: FloatArray | Vec3) -> FloatArray:
    """[v×]: the matrix with [v×] a = v × a."""
    x, y, z = float(v[0]), float(v[1]), float(v[2])
    return np.array(((0.0, -z, y), (z, 0.0, -x), (-y, x, 0.0)))


@compilable
def euler_rad(mat_nb: FloatArray) -> FloatArray:
    """(roll, pitch, yaw) [rad] of an FRD -> NED rotation matrix (Aalborg notes (7.16)-(7.18))."""
    return np.array(
        (
            math.atan2(mat_nb[2, 1], mat_nb[2, 2]),
            -math.asin(max(-1.0, min(1.0, mat_nb[2, 0]))),
            math.atan2(mat_nb[1, 0], mat_nb[0, 0]),
        )
    )


@compilable
def wrap_angle(angle_rad: FloatArray) -> FloatArray:
    """Angles wrapped to [-π, π)."""
    return np.asarray((angle_rad + math.pi) % (2.0 * math.pi) - math.pi, dtype=np.float64)


def as_quat(values: FloatArray) -> Quat:
    """A quaternion array (x, y, z, w) as a float tuple (the hot-path form)."""
    x, y, z, w = values.tolist()
    return (x, y, z, w)


@compilable
def quat_enu_flu(quat_nb: Quat) -> Quat:
    """REP-103 orientation (FLU in ENU) of a body (FRD) -> NED quaternion, w >= 0; also the
    inverse map, as both frame changes are half turns (``quat_nb_from_enu_flu``)."""
    return quat_normalize(quat_multiply(quat_multiply(_Q_ENU_NED, quat_nb), _Q_FRD_FLU))


def flu_to_frd_array(v_flu: Sequence[float]) -> FloatArray:
    """A FLU vector (any sequence) as an FRD array (y and z negated)."""
    return np.array([v_flu[0], -v_flu[1], -v_flu[2]], dtype=np.float64)


def mat_from_rpy_flu(rpy_rad: Sequence[float]) -> FloatArray:
    """FRD -> FRD rotation of a sensor whose FLU frame has REP-103 roll, pitch, yaw in base_link."""
    q = quat_from_euler(rpy_rad[0], rpy_rad[1], rpy_rad[2])
    mat = mat_from_quat(*q.tolist())
    return np.asarray(MAT_FLU_FRD @ mat @ MAT_FLU_FRD, dtype=np.float64)


@compilable
def enu_skew(x: float, y: float, z: float) -> tuple[Vec3, Vec3, Vec3]:
    """MAT_ENU_NED @ [v×] for a NED vector v = (x, y, z): the rows of [v×] for E, N and -D."""
    return ((z, 0.0, -x), (0.0, -z, y), (y, -x, 0.0))
