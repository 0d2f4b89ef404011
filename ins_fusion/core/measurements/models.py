"""Measurements of the fusion engine and their models z = h(x) + v, linearised in the error state.

Every model returns (z, H, R) with the innovation z = measured - predicted, so that
z ≈ H δx + v for the error state of core.filter.eskf (x_true = x_nominal + δx, C_true = (I + [ψ×])
C). The prediction is the nominal state at the measurement's own stamp (``Prediction``). Frames:
NED/FRD inside; the ROS-facing records (core.filter.records) use ENU/FLU (REP-103) like the messages
they come from. Lever arms are base_link FRD vectors from the IMU (the mechanised point) to
the point measured.
"""

from __future__ import annotations

import math

import numpy as np

from gnss_ins_common.types import FloatArray
from ins_fusion.core.compiled import compilable, jit, kernel_array
from ins_fusion.core.filter.eskf import ATT, BG, POS, VEL
from ins_fusion.core.filter.records import (
    GnssFixMeasurement,
    GnssVelocityMeasurement,
    Prediction,
)
from ins_fusion.core.nav import earth
from ins_fusion.core.nav.levelling import earth_rate_body_rad_s
from ins_fusion.core.nav.rotation import euler_rad, skew, wrap_angle

#: A variance at or above this marks a component as not measured: GNSS vertical velocity [m²/s²]
#: (the contract of gnss/vel) and attitude angles [rad²].
UNKNOWN_VELOCITY_VARIANCE = 1.0e4
UNKNOWN_ANGLE_VARIANCE = 1.0
#: ENU <-> NED: the axis each NED axis is read from and its sign (rotation.MAT_ENU_NED).
_AXIS = (1, 0, 2)
_SIGN = (1.0, 1.0, -1.0)
#: FLU <-> FRD sign flips of the (roll, pitch, yaw) errors of a REP-103 orientation covariance.
_RPY_SIGN = (1.0, -1.0, -1.0)


Model = tuple[FloatArray, FloatArray, FloatArray]

#: Attitude measurements observe the IMU time offset only above this Euler rate [rad/s].
TIME_OFFSET_MIN_TURN_RATE = math.radians(2.0)


@compilable
def mounting_skew(mounting_rad: tuple[float, float]) -> FloatArray:
    """[μ×] of a residual mounting μ = (0, pitch, yaw) about base_link FRD y, z [rad]: the
    vehicle frame v is the engine's body frame b turned by it, C_bv = I + [μ×]."""
    return skew((0.0, mounting_rad[0], mounting_rad[1]))


@compilable
def ned_cov(cov_enu: FloatArray) -> FloatArray:
    """ENU covariance -> NED (and back: the axis swap is its own inverse), element by element
    (a product with MAT_ENU_NED would spread a non-finite vertical variance into the
    horizontal block)."""
    out = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            out[i, j] = _SIGN[i] * _SIGN[j] * cov_enu[_AXIS[i], _AXIS[j]]
    return out


def gnss_position(
    pred: Prediction,
    meas: GnssFixMeasurement,
    lever_b: FloatArray,
    white_cov_ned: FloatArray,
    gnss_error_ned: tuple[float, float, float],
) -> Model:
    """Antenna position p + C_nb l plus the estimated time-correlated receiver error ε_g (when
    it is a state). H: δp -> I, ψ -> -[(C_nb l)×], δε_g -> I; R: the white part of the
    receiver's covariance. North and east rows only for a 2-D fix. Compiled
    (``_position_model``)."""
    return _position_model(
        pred.lat_rad,
        pred.lon_rad,
        pred.height_m,
        pred.mat_nb,
        math.radians(meas.lat_deg),
        math.radians(meas.lon_deg),
        meas.height_m,
        lever_b,
        white_cov_ned,
        gnss_error_ned,
        pred.layout.size,
        pred.layout.columns[2],
        meas.height_known,
    )


@jit
def _position_model(
    lat_rad: float,
    lon_rad: float,
    height_m: float,
    mat_nb: FloatArray,
    fix_lat_rad: float,
    fix_lon_rad: float,
    fix_height_m: float,
    lever_b: FloatArray,
    white_cov_ned: FloatArray,
    gnss_error_ned: tuple[float, float, float],
    size: int,
    gp: int,
    vertical: bool,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``gnss_position``'s model from the predicted IMU position (lat, lon [rad], h [m]) and
    attitude, the fix's position and the layout's size and GNSS error column (-1: none);
    without ``vertical`` (a 2-D fix) the north and east rows only."""
    arm_n = mat_nb @ lever_b
    r_m, r_n = earth.radii_from_sin(math.sin(lat_rad))
    offset = (
        (fix_lat_rad - lat_rad) * (r_m + height_m),
        (fix_lon_rad - lon_rad) * (r_n + height_m) * math.cos(lat_rad),
        height_m - fix_height_m,
    )
    H = np.zeros((3, size))
    z = np.empty(3)
    for k in range(3):
        H[k, POS + k] = 1.0
        if gp >= 0:
            H[k, gp + k] = 1.0
        z[k] = offset[k] - arm_n[k] - gnss_error_ned[k]
    H[:, ATT : ATT + 3] = -skew(arm_n)
    rows = 3 if vertical else 2
    return z[:rows].copy(), H[:rows].copy(), white_cov_ned[:rows, :rows].copy()


def gnss_velocity(
    pred: Prediction, meas: GnssVelocityMeasurement, lever_b: FloatArray, mat_bi: FloatArray
) -> Model | None:
    """Antenna velocity v + C_nb (ω_b × l) (the ω_in × C l term, < 2e-4 m/s, is left out);
    horizontal rows only when the vertical is unknown (its velocity or variance not finite, or
    the variance at least UNKNOWN_VELOCITY_VARIANCE). None when the horizontal is unusable.
    Compiled (``_velocity_model``)."""
    rows, z, H, R = _velocity_model(
        pred.mat_nb,
        pred.vel_ned_m_s,
        pred.rate_b,
        pred.rate_i,
        lever_b,
        mat_bi,
        kernel_array(meas.vel_enu_m_s),
        kernel_array(meas.cov_enu_m2_s2),
        pred.layout.size,
        pred.layout.columns[0],
    )
    return None if rows == 0 else (z, H, R)


@jit
def _velocity_model(
    mat_nb: FloatArray,
    vel: FloatArray,
    rate_b: FloatArray,
    rate_i: FloatArray,
    lever_b: FloatArray,
    mat_bi: FloatArray,
    vel_enu: FloatArray,
    cov_enu: FloatArray,
    size: int,
    sg: int,
) -> tuple[int, FloatArray, FloatArray, FloatArray]:
    """``gnss_velocity``'s model (rows, z, H, R; 0 rows: unusable) from the prediction's
    arrays, the measured ENU velocity and covariance, the layout's size and the gyro scale
    column (-1: not estimated)."""
    measured = np.array((vel_enu[1], vel_enu[0], -vel_enu[2]))
    cov = ned_cov(cov_enu)
    if not np.isfinite(measured[:2]).all() or not np.isfinite(cov[:2, :2]).all():
        return 0, measured[:0], np.zeros((0, size)), cov[:0, :0].copy()
    vertical = math.isfinite(measured[2]) and cov[2, 2] < UNKNOWN_VELOCITY_VARIANCE
    rows = 3 if vertical else 2
    rot_n = mat_nb @ (skew(rate_b) @ lever_b)
    H = np.zeros((3, size))
    for k in range(3):
        H[k, VEL + k] = 1.0
    H[:, ATT : ATT + 3] = -skew(rot_n)
    gyro_error_columns(H, -(mat_nb @ skew(lever_b)), mat_bi, rate_i, sg)
    z = measured - vel - rot_n
    return rows, z[:rows].copy(), H[:rows].copy(), cov[:rows, :rows].copy()


@compilable
def gyro_error_columns(
    H: FloatArray, d_rate: FloatArray, mat_bi: FloatArray, rate_i: FloatArray, sg: int
) -> None:
    """H's columns of the gyro bias and scale errors (``sg``: the scale's first column, -1
    when not estimated) for a measurement that depends on the body rate through ``d_rate``
    (rows x 3, d(measured)/dω_b, base FRD): dω_b/dδb_g = -R_bi, dω_b/dδs_g = -R_bi diag(ω_i)."""
    H[:, BG : BG + 3] = d_rate @ -mat_bi
    if sg >= 0:
        H[:, sg : sg + 3] = d_rate @ (-mat_bi * rate_i)


@compilable
def euler_jacobian(mat_nb: FloatArray) -> FloatArray:
    """d(roll, pitch, yaw)/dψ for C_true = (I + [ψ×]) C (rows roll, pitch, yaw)."""
    c = mat_nb
    d_roll = c[2, 1] ** 2 + c[2, 2] ** 2
    d_yaw = c[0, 0] ** 2 + c[1, 0] ** 2
    cos_pitch = math.sqrt(d_yaw)
    return np.array(
        (
            (
                (c[2, 2] * c[1, 1] - c[2, 1] * c[1, 2]) / d_roll,
                (c[2, 1] * c[0, 2] - c[2, 2] * c[0, 1]) / d_roll,
                0.0,
            ),
            (-c[1, 0] / cos_pitch, c[0, 0] / cos_pitch, 0.0),
            (-c[0, 0] * c[2, 0] / d_yaw, -c[1, 0] * c[2, 0] / d_yaw, 1.0),
        )
    )


def attitude(
    pred: Prediction,
    mat_nb_measured: FloatArray,
    cov_rpy_flu: FloatArray,
    time_offset_s: float = 0.0,
    mounting_rad: tuple[float, float] = (0.0, 0.0),
) -> Model | None:
    """Euler angles (roll, pitch, yaw) of base_link; angles marked unknown are dropped.

    The REP-103 covariance (errors about the FLU axes) becomes the covariance of the NED Euler
    angles by the sign flips of pitch and yaw (element by element: a non-finite variance of one
    angle leaves the others usable). None when no angle is measured. With a residual IMU time
    offset state, the measurement is compared with the attitude ``time_offset_s`` later on the
    IMU's timeline: the Euler angles move by their rate J C_nb ω_b (the earth and transport
    rates, < 1e-4 rad/s, left out) times it, and H gets that rate on δt_d when above
    ``TIME_OFFSET_MIN_TURN_RATE`` (a slower one is mostly gyro noise). The measured frame is
    the vehicle's: C_nb (I + [μ×]) with the residual mounting μ = (0, pitch, yaw), which is
    ψ = C_nb μ, so H gets J C_nb on (μ_y, μ_z). Compiled (``attitude_model``).
    """
    layout = pred.layout
    rows, z, H, R = attitude_model(
        kernel_array(pred.mat_nb),
        kernel_array(mat_nb_measured),
        kernel_array(cov_rpy_flu),
        mounting_rad,
        (kernel_array(pred.rate_b), time_offset_s),
        layout.size,
        layout.columns[3],
        layout.columns[4],
    )
    return None if rows == 0 else (z, H, R)


@jit
def attitude_model(
    mat_nb: FloatArray,
    mat_nb_measured: FloatArray,
    cov_rpy_flu: FloatArray,
    mounting_rad: tuple[float, float],
    late: tuple[FloatArray, float],
    size: int,
    mt: int,
    td: int,
) -> tuple[int, FloatArray, FloatArray, FloatArray]:
    """``attitude``'s model (rows, z, H, R; 0 rows: no angle measured) from the predicted and
    the measured body -> NED rotation, the REP-103 covariance [rad²], the residual mounting
    (pitch, yaw) [rad], ``late`` = (the corrected body rate [rad/s], base FRD, the IMU time
    offset estimate [s]), the layout's size and its mounting and time-offset columns (-1: not
    estimated)."""
    cov = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            cov[i, j] = _RPY_SIGN[i] * _RPY_SIGN[j] * cov_rpy_flu[i, j]
    keep = np.empty(3, dtype=np.int64)
    rows = 0
    for k in range(3):
        if math.isfinite(cov[k, k]) and cov[k, k] < UNKNOWN_ANGLE_VARIANCE:
            keep[rows] = k
            rows += 1
    if rows == 0:
        return 0, np.zeros(0), np.zeros((0, size)), np.zeros((0, 0))
    mat_nv = mat_nb
    if mounting_rad[0] != 0.0 or mounting_rad[1] != 0.0:
        mat_nv = mat_nb @ (np.eye(3) + mounting_skew(mounting_rad))
    z = wrap_angle(euler_rad(mat_nb_measured) - euler_rad(mat_nv))
    H = np.zeros((3, size))
    jacobian = euler_jacobian(mat_nv)
    H[:, ATT : ATT + 3] = jacobian
    if mt >= 0:
        H[:, mt : mt + 2] = (jacobian @ mat_nb)[:, 1:3]
    if td >= 0:
        rate_b, time_offset_s = late
        euler_rate = jacobian @ (mat_nb @ rate_b)
        z = z - euler_rate * time_offset_s
        if math.sqrt(euler_rate @ euler_rate) >= TIME_OFFSET_MIN_TURN_RATE:
            H[:, td] = euler_rate
    keep = keep[:rows]
    R = np.empty((rows, rows))
    for a in range(rows):
        for b in range(rows):
            R[a, b] = cov[keep[a], keep[b]]
    return rows, z[keep], H[keep], R


def zupt(pred: Prediction, sigma_m_s: float) -> Model:
    """Zero velocity of the IMU point: H: δv -> I. Compiled (``zupt_model``)."""
    return zupt_model(kernel_array(pred.vel_ned_m_s), sigma_m_s, pred.layout.size)


@jit
def zupt_model(
    vel: FloatArray, sigma_m_s: float, size: int
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``zupt``'s model from the predicted NED velocity [m/s], σ [m/s] and the state size."""
    H = np.zeros((3, size))
    for k in range(3):
        H[k, VEL + k] = 1.0
    return -vel, H, np.eye(3) * sigma_m_s**2


def zaru(
    pred: Prediction,
    rates_i: tuple[FloatArray, FloatArray],
    mat_bi: FloatArray,
    variance: FloatArray,
    heading_known: bool,
) -> Model:
    """Zero angular rate: the mean calibrated rate (imu FRD) over an interval at rest minus the
    earth rate and the bias estimate (``rates_i``: those two rates [rad/s]) measures the bias
    error (the scale error times the earth rate, < 1e-7 rad/s, is left out); the earth rate's
    horizontal part only with the heading known. H: δb_g -> I. Compiled (``zaru_model``)."""
    mean_rate_i, gyro_bias_i = rates_i
    return zaru_model(
        kernel_array(pred.mat_nb),
        pred.lat_rad,
        heading_known,
        (kernel_array(mean_rate_i), kernel_array(gyro_bias_i)),
        mat_bi,
        kernel_array(variance),
        pred.layout.size,
    )


@jit
def zaru_model(
    mat_nb: FloatArray,
    lat_rad: float,
    heading_known: bool,
    rates_i: tuple[FloatArray, FloatArray],
    mat_bi: FloatArray,
    variance: FloatArray,
    size: int,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``zaru``'s model from the predicted body -> NED rotation and latitude [rad], the mean
    rate and the bias estimate (imu FRD) [rad/s], the rotation imu -> body, the variances
    [rad²/s²] and the state size."""
    mean_rate_i, gyro_bias_i = rates_i
    earth_rate_i = mat_bi.T @ earth_rate_body_rad_s(mat_nb, lat_rad, heading_known)
    H = np.zeros((3, size))
    for k in range(3):
        H[k, BG + k] = 1.0
    return mean_rate_i - earth_rate_i - gyro_bias_i, H, np.diag(variance)


def nhc(
    pred: Prediction,
    arm_b: FloatArray,
    mat_bi: FloatArray,
    sigma_m_s: float,
    mounting_rad: tuple[float, float] = (0.0, 0.0),
) -> Model:
    """No lateral or vertical velocity of the point ``arm_b`` (base_link origin) in the
    vehicle frame: v_b = C_nbᵀ v + ω_b × r in base_link, turned into the vehicle frame by the
    residual mounting μ = (pitch, yaw) about base_link FRD y and z, C_vb = I - [μ×]:
    lateral v_b,y - μ_z v_b,x, vertical v_b,z + μ_y v_b,x. H: δv -> C_nbᵀ, ψ -> C_nbᵀ [v×],
    gyro errors -> -[r×] dω_b (``gyro_error_columns``), δμ_y -> +v_b,x
    (vertical), δμ_z -> -v_b,x (lateral) (the mounting's second-order terms in H left out).
    Compiled (``nhc_model``)."""
    layout = pred.layout
    return nhc_model(
        pred.mat_nb,
        pred.vel_ned_m_s,
        pred.rate_b,
        pred.rate_i,
        arm_b,
        mat_bi,
        sigma_m_s,
        mounting_rad,
        layout.size,
        layout.columns[0],
        layout.columns[3],
    )


@jit
def nhc_model(
    mat_nb: FloatArray,
    vel: FloatArray,
    rate_b: FloatArray,
    rate_i: FloatArray,
    arm_b: FloatArray,
    mat_bi: FloatArray,
    sigma_m_s: float,
    mounting_rad: tuple[float, float],
    size: int,
    sg: int,
    mt: int,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``nhc``'s model from the prediction's arrays and the layout's size and columns (-1:
    state not estimated)."""
    c_bn = np.ascontiguousarray(mat_nb.T)
    v_b = c_bn @ vel + skew(rate_b) @ arm_b
    H = np.zeros((3, size))
    H[:, VEL : VEL + 3] = c_bn
    H[:, ATT : ATT + 3] = c_bn @ skew(vel)
    gyro_error_columns(H, -skew(arm_b), mat_bi, rate_i, sg)
    pitch, yaw = mounting_rad
    forward = v_b[0]
    predicted = np.array((v_b[1] - yaw * forward, v_b[2] + pitch * forward))
    if mt >= 0:
        H[1, mt + 1] = -forward
        H[2, mt] = forward
    return -predicted, H[1:].copy(), np.eye(2) * sigma_m_s**2
