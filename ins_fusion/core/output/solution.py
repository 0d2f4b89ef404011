"""The engine's output: the fused base_link state with its covariance (``InsSolution``), built
from the nominal state and the error covariance, and the self-calibration figures.

The covariances come from one Jacobian over the position, velocity, attitude and gyro bias
error states (the first 12, which the lever arm couples) and the mounting's when estimated, rows
in ENU.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from gnss_ins_common.types import FloatArray, IntArray, Vec3
from ins_fusion.core.compiled import compilable, jit, kernel_array, plain
from ins_fusion.core.filter.eskf import ATT, BG, ErrorStateFilter, StateLayout
from ins_fusion.core.filter.eskf import POS as POS_STATE
from ins_fusion.core.filter.eskf import VEL as VEL_STATE
from ins_fusion.core.filter.propagation import corrected_gyro
from ins_fusion.core.filter.state import (
    X_BA,
    X_BG,
    X_HEADING_KNOWN,
    X_HEIGHT,
    X_LAST_POSITION_T,
    X_LAT,
    X_LON,
    X_QUAT,
    X_SG,
    X_SR,
    X_T,
    X_VEL,
    FilterState,
    Geometry,
    mounting_rpy_from,
)
from ins_fusion.core.layout import fields, offsets
from ins_fusion.core.nav import earth
from ins_fusion.core.nav.earth import ecef_from_geodetic
from ins_fusion.core.nav.rotation import (
    MAT_ENU_NED,
    enu_skew,
    mat_from_quat,
    quat_enu_flu,
    quat_from_rotvec,
    quat_multiply,
)
from ins_fusion.core.settings.config import FusionConfig


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
    cov_att_imu_enu_rad2: the attitude covariance of imu_link (errors about the ENU axes): the
    mechanised frame's own, without the estimated mounting's uncertainty that base_link's holds
    (the vehicle's attitude error is the IMU's plus the mounting's; a straight drive knows the
    vehicle's heading from its course far better than the IMU's); None: cov_att_enu_rad2.
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
    cov_att_imu_enu_rad2: FloatArray | None = None


#: Rows of the solution's Jacobian (``SolutionBuilder.jacobian``; core.smoother's smoothed change
#: and covariance have them too, core.layout): the errors of base_link's ENU position, velocity
#: and attitude and of imu_link's attitude (about the ENU axes).
ERROR_LAYOUT = (("pos", 3), ("vel", 3), ("att", 3), ("att_imu", 3))
E_POS, E_VEL, E_ATT, E_ATT_IMU, E_SIZE = offsets(ERROR_LAYOUT)

#: ``InsSolution`` as one row of float64 numbers (core.output.solution_rows holds many): t_s;
#: lat_deg, lon_deg, height_m; pos_enu_m (3); vel_enu_m_s (3); quat_enu_flu_xyzw (4); rate_flu_rad_s
#: (3); cov_pos_enu_m2, cov_vel_enu, cov_att_enu_rad2 (9 each, row-major); gyro_bias_flu_rad_s (3);
#: accel_bias_flu_m_s2 (3); imu_mounting_rpy_rad (3, NaN = None); the state as its index in
#: ``STATES``; cov_att_imu_enu_rad2 (9, that of base_link when None). Units and frames as
#: InsSolution.
STATES = ("aligning", "navigating", "degraded")


@compilable
def state_code(x: FloatArray, degraded_after_s: float) -> int:
    """The index in STATES of the engine's state of FilterState.x ``x``: aligning while the
    heading is unknown, degraded when no GNSS position was used for ``degraded_after_s`` [s],
    else navigating."""
    if x[X_HEADING_KNOWN] == 0.0:
        return 0
    if x[X_T] - x[X_LAST_POSITION_T] > degraded_after_s:
        return 2
    return 1


#: Layout of a solution row: ``InsSolution``'s fields (core.layout), units and frames as there.
ROW_LAYOUT = (
    ("t", 1),
    ("lat", 1),
    ("lon", 1),
    ("height", 1),
    ("pos", 3),
    ("vel", 3),
    ("quat", 4),
    ("rate", 3),
    ("cov_pos", 9),
    ("cov_vel", 9),
    ("cov_att", 9),
    ("gyro", 3),
    ("accel", 3),
    ("mounting", 3),
    ("state", 1),
    ("cov_att_imu", 9),
)
_ROW = fields(ROW_LAYOUT)
#: The row's one-number fields as indices, the others as slices.
T, LAT, LON, HEIGHT, STATE = (_ROW[name][0] for name in ("t", "lat", "lon", "height", "state"))
POS, VEL, QUAT, RATE, COV_POS, COV_VEL, COV_ATT, GYRO, ACCEL, MOUNTING, COV_ATT_IMU = (
    slice(_ROW[name][0], _ROW[name][0] + _ROW[name][1])
    for name in (
        "pos",
        "vel",
        "quat",
        "rate",
        "cov_pos",
        "cov_vel",
        "cov_att",
        "gyro",
        "accel",
        "mounting",
        "cov_att_imu",
    )
)
WIDTH = offsets(ROW_LAYOUT)[-1]
#: (offset, width) of the row's navigation fields, latitude to rate (the numbers that must be
#: finite for an output, core.output.output_numbers).
NAVIGATION_FIELDS = tuple(
    _ROW[name] for name in ("lat", "lon", "height", "pos", "vel", "quat", "rate")
)


def unpack(row: FloatArray) -> InsSolution:
    """The solution of one row (its arrays are copies)."""
    mounting = row[MOUNTING]
    return InsSolution(
        t_s=float(row[T]),
        lat_deg=float(row[LAT]),
        lon_deg=float(row[LON]),
        height_m=float(row[HEIGHT]),
        pos_enu_m=row[POS].copy(),
        vel_enu_m_s=row[VEL].copy(),
        quat_enu_flu_xyzw=row[QUAT].copy(),
        rate_flu_rad_s=row[RATE].copy(),
        cov_pos_enu_m2=row[COV_POS].reshape(3, 3).copy(),
        cov_vel_enu=row[COV_VEL].reshape(3, 3).copy(),
        cov_att_enu_rad2=row[COV_ATT].reshape(3, 3).copy(),
        gyro_bias_flu_rad_s=row[GYRO].copy(),
        accel_bias_flu_m_s2=row[ACCEL].copy(),
        state=STATES[int(row[STATE])],
        imu_mounting_rpy_rad=None if np.isnan(mounting).any() else mounting.copy(),
        cov_att_imu_enu_rad2=row[COV_ATT_IMU].reshape(3, 3).copy(),
    )


class RowModel(NamedTuple):
    """What a solution row is made from besides the nominal state and the rate
    (``SolutionBuilder.model``)."""

    J: FloatArray  #: the row's Jacobian (written; SolutionBuilder.jacobian)
    P: FloatArray  #: the error covariance
    states: IntArray  #: the error states of the solution (J's columns)
    arm_b: FloatArray  #: base_link's lever arm from the IMU, turned by the mounting [m]
    arm_bi: FloatArray  #: [l×] R_bi of the configured arm (the velocity rows' gyro-bias terms)
    mat_enu_ecef: FloatArray  #: the ENU plane's rotation from ECEF
    mounting: tuple[float, float]  #: the residual mounting (pitch, yaw) [rad] (0: not estimated)
    origin: Vec3  #: the ENU plane's ECEF origin [m]


#: ``RowModel``'s fields in order, as ``_fill_row`` takes them (plain: core.compiled.plain).
RowFields = tuple[
    FloatArray, FloatArray, IntArray, FloatArray, FloatArray, FloatArray, tuple[float, float], Vec3
]


class SolutionBuilder:
    """Builds ``InsSolution`` rows at the output rate (see the module docstring)."""

    def __init__(self, geometry: Geometry, layout: StateLayout) -> None:
        self._geometry = geometry
        self._mt = layout.mt
        # ENU position, velocity and attitude of base_link and the attitude of imu_link over the
        # first 12 error states (and the two mounting states when they are estimated); the
        # blocks that depend on the state are filled in per call.
        mt = layout.mt
        self._solution_states = np.r_[0 : BG + 3, [] if mt is None else [mt, mt + 1]].astype(int)
        self._jacobian = np.zeros((E_SIZE, len(self._solution_states)))
        for row, col in ((E_POS, POS_STATE), (E_VEL, VEL_STATE), (E_ATT, ATT), (E_ATT_IMU, ATT)):
            self._jacobian[row : row + 3, col : col + 3] = MAT_ENU_NED
        self._plane: earth.TangentPlane | None = None
        self._datum_deg = (math.nan, math.nan, math.nan)  # that of _plane
        #: Jacobian of the last ``row`` (rows ENU position, velocity, attitude of base_link and
        #: attitude of imu_link, columns the error states of
        #: core.engine.smoothed_solution.solution_states); reused per call.
        self.jacobian: FloatArray = self._jacobian

    def row(
        self,
        s: FilterState,
        kf: ErrorStateFilter,
        datum_deg: tuple[float, float, float],
        rate_i: FloatArray,
        state_name: str,
    ) -> FloatArray:
        """The solution row (``WIDTH``) of state ``s`` with covariance ``kf.P``; ``rate_i``: the
        latest raw sample's rate (imu FRD [rad/s]); ``datum_deg``: the ENU plane's origin (lat,
        lon [deg], height [m])."""
        out = np.empty(WIDTH)
        _fill_row(out, s.x, plain(self.model(s, kf, datum_deg)), self._geometry.r_bi, rate_i)
        out[STATE] = STATES.index(state_name)
        return out

    def model(
        self, s: FilterState, kf: ErrorStateFilter, datum_deg: tuple[float, float, float]
    ) -> RowModel:
        """What ``_fill_row`` takes besides the state and the rate, for ``s`` and ``kf.P``."""
        geometry = self._geometry
        if self._plane is None or self._datum_deg != datum_deg:
            lat0, lon0, h0 = datum_deg
            self._plane = earth.TangentPlane(math.radians(lat0), math.radians(lon0), h0)
            self._datum_deg = datum_deg
        return RowModel(
            self._jacobian,
            kernel_array(kf.P),
            self._solution_states,
            geometry.arms(s)[1],
            geometry.arm_bi,
            self._plane.mat_enu_ecef,
            s.mounting if self._mt is not None else (0.0, 0.0),
            self._plane.origin,
        )


@jit
def _fill_row(
    out: FloatArray, x: FloatArray, model: RowFields, r_bi: FloatArray, rate_i: FloatArray
) -> None:
    """The numbers of a solution row but its state (``SolutionBuilder.row``) from the nominal
    state ``x``, ``model`` and the latest raw rate ``rate_i`` (imu FRD [rad/s]; ``r_bi`` imu ->
    body), and its Jacobian ``model.J`` (first 12 columns; the mounting's two when ``J`` has
    them: then the row's mounting, else NaN; imu_link's attitude rows are ψ's alone,
    constant)."""
    J, P, states, arm_b, arm_bi, mat_enu_ecef, mounting, origin = model
    C = mat_from_quat(x[X_QUAT], x[X_QUAT + 1], x[X_QUAT + 2], x[X_QUAT + 3])
    # base_link of the estimated mounting: the lever arm turned by it (arm_b), and below the
    # orientation and rate turned into it (C_bv = I + [μ×]). The lever arm in NED, and its
    # velocity ω × r (body) rotated into NED.
    ax, ay, az = arm_b[0], arm_b[1], arm_b[2]
    n0 = C[0, 0] * ax + C[0, 1] * ay + C[0, 2] * az
    n1 = C[1, 0] * ax + C[1, 1] * ay + C[1, 2] * az
    n2 = C[2, 0] * ax + C[2, 1] * ay + C[2, 2] * az
    c0 = corrected_gyro(rate_i[0], x[X_BG], x[X_SG], x[X_SR])
    c1 = corrected_gyro(rate_i[1], x[X_BG + 1], x[X_SG + 1], x[X_SR + 1])
    c2 = corrected_gyro(rate_i[2], x[X_BG + 2], x[X_SG + 2], x[X_SR + 2])
    wx = r_bi[0] * c0 + r_bi[1] * c1 + r_bi[2] * c2
    wy = r_bi[3] * c0 + r_bi[4] * c1 + r_bi[5] * c2
    wz = r_bi[6] * c0 + r_bi[7] * c1 + r_bi[8] * c2
    ux, uy, uz = wy * az - wz * ay, wz * ax - wx * az, wx * ay - wy * ax
    r0 = C[0, 0] * ux + C[0, 1] * uy + C[0, 2] * uz
    r1 = C[1, 0] * ux + C[1, 1] * uy + C[1, 2] * uz
    r2 = C[2, 0] * ux + C[2, 1] * uy + C[2, 2] * uz
    lat, lon, height = earth.displace(x[X_LAT], x[X_LON], x[X_HEIGHT], n0, n1, n2)
    c_en = np.empty((3, 3))  # MAT_ENU_NED @ C
    c_en[0, :], c_en[1, :], c_en[2, :] = C[1, :], C[0, :], -C[2, :]
    for first, rows in ((E_POS, enu_skew(-n0, -n1, -n2)), (E_VEL, enu_skew(-r0, -r1, -r2))):
        for i in range(3):
            for j in range(3):
                J[first + i, ATT + j] = rows[i][j]
    J[E_VEL : E_VEL + 3, BG : BG + 3] = c_en @ arm_bi
    mu_y, mu_z = mounting
    if J.shape[1] > BG + 3:  # the vehicle's attitude error is ψ + C_nb μ: the mounting states
        J[E_ATT : E_ATT + 3, BG + 3 :] = c_en[:, 1:3]
    n = len(states)
    P_sub = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            P_sub[i, j] = P[states[i], states[j]]
    cov = J @ P_sub @ J.T
    cov = 0.5 * (cov + cov.T)  # symmetric to the bit, as the outputs' check requires
    vn, ve, vd = x[X_VEL], x[X_VEL + 1], x[X_VEL + 2]
    quat_nb = (x[X_QUAT], x[X_QUAT + 1], x[X_QUAT + 2], x[X_QUAT + 3])
    out[MOUNTING] = np.nan
    if J.shape[1] > BG + 3:
        out[MOUNTING] = np.array(mounting_rpy_from(r_bi, mu_y, mu_z))
        quat_nb = quat_multiply(quat_nb, quat_from_rotvec(0.0, mu_y, mu_z))
        wx, wy, wz = wx - (mu_y * wz - mu_z * wy), wy - mu_z * wx, wz + mu_y * wx
    e_x, e_y, e_z = ecef_from_geodetic(lat, lon, height)
    d = np.array((e_x - origin[0], e_y - origin[1], e_z - origin[2]))
    out[T] = x[X_T]
    out[LAT], out[LON], out[HEIGHT] = math.degrees(lat), math.degrees(lon), height
    out[POS] = mat_enu_ecef @ d
    out[VEL] = np.array((ve + r1, vn + r0, -(vd + r2)))
    out[QUAT] = np.array(quat_enu_flu(quat_nb))
    out[RATE] = np.array((wx, -wy, -wz))
    out[COV_POS] = cov[E_POS : E_POS + 3, E_POS : E_POS + 3].copy().ravel()
    out[COV_VEL] = cov[E_VEL : E_VEL + 3, E_VEL : E_VEL + 3].copy().ravel()
    out[COV_ATT] = cov[E_ATT : E_ATT + 3, E_ATT : E_ATT + 3].copy().ravel()
    out[COV_ATT_IMU] = cov[E_ATT_IMU : E_ATT_IMU + 3, E_ATT_IMU : E_ATT_IMU + 3].copy().ravel()
    out[GYRO] = np.array((x[X_BG], -x[X_BG + 1], -x[X_BG + 2]))
    out[ACCEL] = np.array((x[X_BA], -x[X_BA + 1], -x[X_BA + 2]))


def self_calibration(
    config: FusionConfig, geometry: Geometry, s: FilterState | None, kf: ErrorStateFilter | None
) -> dict[str, float]:
    """The self-calibration (NaN where not estimated or before the filter starts):
    ``time_offset_s`` = imu_time_offset + the estimated residual, with the residual and its
    σ [s]; the residual mounting pitch and yaw about base_link FRD y, z and their σ [deg];
    ``imu_mounting_{roll,pitch,yaw}_deg``: the imu_mounting_rpy_deg that holds them (REP-103,
    for the configuration); with ``use_speed`` the vehicle speed's scale error (measured /
    true - 1) and its σ [%]."""
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
    if config.use_speed:  # only then: an engine without a speed reports as before there was one
        values["speed_scale_error_pct"] = values["speed_scale_sigma_pct"] = math.nan
    if s is None or kf is None:
        return values
    layout = kf.layout
    if layout.td is not None:
        values["time_offset_residual_s"] = s.time_offset
        values["time_offset_s"] = config.imu_time_offset_s + s.time_offset
        values["time_offset_sigma_s"] = math.sqrt(max(kf.P[layout.td, layout.td], 0.0))
    if layout.ks is not None:
        values["speed_scale_error_pct"] = 100.0 * s.speed_scale
        values["speed_scale_sigma_pct"] = 100.0 * math.sqrt(max(kf.P[layout.ks, layout.ks], 0.0))
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
