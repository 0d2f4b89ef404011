"""The engine's nominal state and what acts on it directly: the per-sample state
(``FilterState``), the fixed sensor geometry (``Geometry``), the latest raw inputs the start-up
reads (``LatestInputs``), and the closed-loop feedback of an error estimate (``inject``).

Frames: the engine's body frame is base_link FRD (the IMU point with vehicle axes), the
navigation frame NED; error states as in core.filter.eskf.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gnss_ins_common.types import FloatArray, Quat, Vec3
from ins_fusion.core.compiled import compilable, jit
from ins_fusion.core.filter.adaptation import WhiteNoiseMonitor
from ins_fusion.core.filter.eskf import (
    ATT,
    BA,
    BG,
    NONFINITE_NAVIGATION,
    POS,
    USABLE,
    VEL,
    Columns,
    ErrorStateFilter,
    StateLayout,
)
from ins_fusion.core.filter.records import (
    AttitudeMeasurement,
    GnssFixMeasurement,
    GnssVelocityMeasurement,
)
from ins_fusion.core.filter.update_algebra import covariance_problem
from ins_fusion.core.layout import offsets
from ins_fusion.core.nav import earth
from ins_fusion.core.nav.rotation import (
    as_quat,
    flu_to_frd_array,
    mat_from_quat,
    mat_from_rpy_flu,
    quat_enu_flu,
    quat_from_euler,
    quat_from_rotvec,
    quat_multiply,
    quat_normalize,
    skew,
)
from ins_fusion.core.nav.strapdown import (
    INCREMENT_SIZE,
    NAV_HEIGHT,
    NAV_LAT,
    NAV_LON,
    NAV_QUAT,
    NAV_SIZE,
    NAV_VEL,
    NavState,
)
from ins_fusion.core.settings.config import FusionConfig

#: Yaw variance standing for 'heading unknown' [rad²].
UNKNOWN_YAW_VARIANCE = (math.pi / 2.0) ** 2


#: Layout of FilterState.x: the per-sample numbers the compiled time update advances
#: (core.filter.propagation.advance), from "nav" to "t"; then the filter's bookkeeping that a
#: rollback restores with them (FilterState's fields of the same names), from "gnss_error".
X_LAYOUT = (
    ("nav", NAV_SIZE),  # navigation (core.nav.strapdown.NAV_LAYOUT; X_LAT ... X_QUAT below)
    ("bg", 3),  # gyro bias, imu FRD [rad/s]
    ("ba", 3),  # accelerometer bias, imu FRD [m/s²]
    ("sg", 3),  # gyro scale factor error, imu FRD [fraction]
    ("sa", 3),  # accelerometer scale factor error, imu FRD [fraction]
    ("prev", INCREMENT_SIZE),  # the previous corrected increment (body FRD; strapdown.increment)
    ("has_prev", 1),  # 1.0 when there is a previous increment
    ("rate_b", 3),  # corrected angular rate, body FRD [rad/s]
    ("rate_i", 3),  # corrected angular rate, imu FRD [rad/s]
    ("accel_n", 3),  # acceleration, NED [m/s²]
    ("accel_lp", 3),  # low-passed acceleration, NED [m/s²]
    ("rate_lp", 3),  # low-passed angular rate, body FRD [rad/s]
    ("cov_dt", 1),  # covariance interval: its duration [s]
    ("cov_dth", 3),  # its angle increment, imu FRD [rad]
    ("cov_dv", 3),  # its velocity increment, imu FRD [m/s]
    ("cov_vel0", 3),  # the velocity at its start, NED [m/s]
    ("t", 1),  # stamp [s]
    ("gnss_error", 3),  # correlated GNSS error estimate, NED [m]
    ("gnss_variance", 3),  # its stationary variance, NED [m²]
    ("gnss_reported", 3),  # the reported variance at its last restart, NED [m²]
    ("mounting", 2),  # residual mounting: pitch, yaw [rad]
    ("time_offset", 1),  # residual IMU time offset [s]
    ("nis_mean", 1),  # running NIS mean (core.filter.adaptation)
    ("q_scale", 1),  # process-noise scale (core.filter.adaptation)
    ("last_position_t", 1),  # stamp of the last GNSS position used [s]
    ("heading_known", 1),  # 1.0 while the heading is known
    ("speed_scale", 1),  # the vehicle speed's scale error (measured / true - 1)
    ("sr", 3),  # gyro scale asymmetry: error per unit of |rate|, imu FRD [fraction]
)
(
    X_NAV,
    X_BG,
    X_BA,
    X_SG,
    X_SA,
    X_PREV,
    X_HAS_PREV,
    X_RATE_B,
    X_RATE_I,
    X_ACCEL_N,
    X_ACCEL_LP,
    X_RATE_LP,
    X_COV_DT,
    X_COV_DTH,
    X_COV_DV,
    X_COV_VEL0,
    X_T,
    X_GNSS_ERROR,
    X_GNSS_VARIANCE,
    X_GNSS_REPORTED,
    X_MOUNTING,
    X_TIME_OFFSET,
    X_NIS_MEAN,
    X_Q_SCALE,
    X_LAST_POSITION_T,
    X_HEADING_KNOWN,
    X_SPEED_SCALE,
    X_SR,
    X_SIZE,
) = offsets(X_LAYOUT)
#: The navigation's fields in FilterState.x: latitude, longitude [rad], height [m], NED velocity
#: (3) [m/s], body (FRD) -> NED quaternion (4, scalar last).
X_LAT, X_LON, X_HEIGHT = X_NAV + NAV_LAT, X_NAV + NAV_LON, X_NAV + NAV_HEIGHT
X_VEL, X_QUAT = X_NAV + NAV_VEL, X_NAV + NAV_QUAT


class _Vec3Field:
    """A Vec3 attribute kept in FilterState.x from index ``start``."""

    def __init__(self, start: int) -> None:
        self.start = start

    def __get__(self, s: FilterState, owner: type | None = None) -> Vec3:
        x, k = s.x, self.start
        return (float(x[k]), float(x[k + 1]), float(x[k + 2]))

    def __set__(self, s: FilterState, value: Vec3 | FloatArray) -> None:
        k = self.start
        s.x[k : k + 3] = value


class _ScalarField:
    """A float attribute kept in FilterState.x at ``index``."""

    def __init__(self, index: int) -> None:
        self.index = index

    def __get__(self, s: FilterState, owner: type | None = None) -> float:
        return float(s.x[self.index])

    def __set__(self, s: FilterState, value: float) -> None:
        s.x[self.index] = value


class FilterState:
    """Nominal state and filter bookkeeping at one IMU stamp. Copies are history checkpoints:
    ``x`` (X_* layout, which holds the numbers among the fields) is copied, every other field
    is immutable or never modified in place, so a shallow copy of those suffices.
    """

    __slots__ = ("_mat_nb", "_nav", "gated_runs", "gnss_white", "imu_psd", "x")

    _nav: NavState | None
    _mat_nb: FloatArray | None
    gyro_bias = _Vec3Field(X_BG)
    accel_bias = _Vec3Field(X_BA)
    gyro_scale = _Vec3Field(X_SG)
    accel_scale = _Vec3Field(X_SA)
    accel_lp = _Vec3Field(X_ACCEL_LP)
    rate_lp = _Vec3Field(X_RATE_LP)
    t_s = _ScalarField(X_T)
    gnss_error = _Vec3Field(X_GNSS_ERROR)
    gnss_variance = _Vec3Field(X_GNSS_VARIANCE)
    gnss_reported = _Vec3Field(X_GNSS_REPORTED)
    time_offset = _ScalarField(X_TIME_OFFSET)
    nis_mean = _ScalarField(X_NIS_MEAN)
    q_scale = _ScalarField(X_Q_SCALE)
    last_position_t_s = _ScalarField(X_LAST_POSITION_T)
    speed_scale = _ScalarField(X_SPEED_SCALE)

    def __init__(self, t_s: float, nav: NavState, gyro_bias: Vec3, heading_known: bool) -> None:
        zero: Vec3 = (0.0, 0.0, 0.0)
        self.x = np.zeros(X_SIZE)
        self.t_s = t_s
        self.set_nav(nav)
        self.gyro_bias = gyro_bias
        self.heading_known = heading_known
        self.last_position_t_s = t_s
        self.gnss_error = self.gnss_variance = self.gnss_reported = zero
        self.gnss_white = WhiteNoiseMonitor()
        self.imu_psd: tuple[FloatArray, FloatArray] | None = None
        self.nis_mean = self.q_scale = 1.0
        self.mounting = (0.0, 0.0)
        self.time_offset = 0.0
        self.x[X_COV_VEL0 : X_COV_VEL0 + 3] = nav.vel_ned_m_s
        self.gated_runs: dict[str, int] = {}  # replaced, never changed in place (copy shares it)

    def copy(self) -> FilterState:
        other = FilterState.__new__(FilterState)
        other.x = self.x.copy()
        other._nav = self._nav
        other._mat_nb = self._mat_nb
        other.gnss_white = self.gnss_white
        other.imu_psd = self.imu_psd
        other.gated_runs = self.gated_runs
        return other

    @staticmethod
    def checkpoint_of(
        x: FloatArray,
        imu_psd: tuple[FloatArray, FloatArray] | None,
        gnss_white: WhiteNoiseMonitor,
        gated_runs: dict[str, int],
    ) -> FilterState:
        """A state of array ``x`` (taken, not copied) and those members: what ``copy`` gives
        of a state advanced to those numbers with densities ``imu_psd``
        (core.engine.sample_runs)."""
        other = FilterState.__new__(FilterState)
        other.x = x
        other._nav = None
        other._mat_nb = None
        other.gnss_white = gnss_white
        other.imu_psd = imu_psd
        other.gated_runs = gated_runs
        return other

    @property
    def mounting(self) -> tuple[float, float]:
        """The residual mounting (pitch, yaw [rad]; core.filter.state.Geometry.arms)."""
        x = self.x
        return (float(x[X_MOUNTING]), float(x[X_MOUNTING + 1]))

    @mounting.setter
    def mounting(self, value: tuple[float, float]) -> None:
        self.x[X_MOUNTING], self.x[X_MOUNTING + 1] = value

    @property
    def heading_known(self) -> bool:
        """Whether the heading is known (else the yaw error is kept out of the filter)."""
        return bool(self.x[X_HEADING_KNOWN] != 0.0)

    @heading_known.setter
    def heading_known(self, known: bool) -> None:
        self.x[X_HEADING_KNOWN] = 1.0 if known else 0.0

    @property
    def nav(self) -> NavState:
        """The navigation state (built from ``x`` once per change)."""
        nav = self._nav
        if nav is None:
            x = self.x
            nav = self._nav = NavState(
                float(x[X_LAT]),
                float(x[X_LON]),
                float(x[X_HEIGHT]),
                x[X_VEL : X_VEL + 3].copy(),
                x[X_QUAT : X_QUAT + 4].copy(),
            )
        return nav

    @property
    def mat_nb(self) -> FloatArray:
        """Body (base_link FRD) -> NED rotation of ``nav`` (computed once per state)."""
        if self._mat_nb is None:
            self._mat_nb = self.nav.mat_nb
        return self._mat_nb

    def set_nav(self, nav: NavState) -> None:
        x = self.x
        x[X_LAT], x[X_LON], x[X_HEIGHT] = nav.lat_rad, nav.lon_rad, nav.height_m
        x[X_VEL : X_VEL + 3] = nav.vel_ned_m_s
        x[X_QUAT : X_QUAT + 4] = nav.quat_nb
        self._nav = nav
        self._mat_nb = None

    def changed(self) -> None:
        """``x`` was advanced in place (core.filter.propagation): drop what was derived from it."""
        self._nav = None
        self._mat_nb = None

    def move(self, offset_ned_m: FloatArray) -> None:
        """Shift the nominal position by a NED offset [m]."""
        nav = self.nav
        lat, lon, height = earth.displace(
            nav.lat_rad,
            nav.lon_rad,
            nav.height_m,
            float(offset_ned_m[0]),
            float(offset_ned_m[1]),
            float(offset_ned_m[2]),
        )
        self.set_nav(NavState(lat, lon, height, nav.vel_ned_m_s, nav.quat_nb))


@dataclass
class LatestInputs:
    """The newest usable GNSS inputs as they arrived (the start-up and the course heading read
    them directly); ``gnss_speed``: (stamp [s], horizontal speed [m/s]) of the newest velocity."""

    fix: GnssFixMeasurement | None = None
    velocity: GnssVelocityMeasurement | None = None
    attitude: AttitudeMeasurement | None = None
    gnss_speed: tuple[float, float] | None = None


class Geometry:
    """The configured sensor geometry in the engine's body frame (base_link FRD): the IMU
    mounting rotation imu FRD -> body (``mat_bi``, also row-major ``r_bi`` for the kernels),
    the lever arms from the IMU to the antenna, to the base_link origin and to the speed's
    measuring point [m], and the attitude receiver's mounting."""

    def __init__(self, config: FusionConfig, layout: StateLayout) -> None:
        self.estimates_mounting = layout.mt is not None
        self.mat_bi = mat_from_rpy_flu(config.imu_mounting_rpy_rad)
        self.r_bi = self.mat_bi.ravel().copy()
        imu_arm_b = flu_to_frd_array(config.imu_lever_arm_flu_m)
        self.antenna_arm_b = flu_to_frd_array(config.gnss_lever_arm_flu_m) - imu_arm_b
        self.base_arm_b = -imu_arm_b
        self.speed_arm_b = flu_to_frd_array(config.speed_lever_arm_flu_m) - imu_arm_b
        self.arm_bi = skew(self.base_arm_b) @ self.mat_bi
        # Orientation of base_link from that of the attitude receiver's frame a: q_ea ⊗ q_ab.
        q_ba = quat_from_euler(*config.attitude_mounting_rpy_rad)
        self.q_a_base: Quat = (-q_ba[0], -q_ba[1], -q_ba[2], q_ba[3])
        # The last mounting's arms and angles (the mounting changes only at updates).
        self._mounting_cache: tuple[tuple[float, float], FloatArray] | None = None
        self._arms_cache: tuple[tuple[float, float], tuple[FloatArray, FloatArray]] | None = None

    def arms(self, s: FilterState) -> tuple[FloatArray, FloatArray]:
        """(antenna, base_link origin) lever arms from the IMU [m] in the engine's body frame
        at the residual mounting of ``s`` (``mounted_arm``)."""
        mounting = s.mounting
        cached = self._arms_cache
        if cached is None or cached[0] != mounting:
            x, estimated = s.x, self.estimates_mounting
            arms = (
                mounted_arm(self.antenna_arm_b, x, estimated),
                mounted_arm(self.base_arm_b, x, estimated),
            )
            cached = self._arms_cache = (mounting, arms)
        return cached[1]

    def speed_arm(self, s: FilterState) -> FloatArray:
        """The lever arm from the IMU to the speed's measuring point [m] (body FRD), turned
        by the residual mounting as ``arms`` (``mounted_arm``)."""
        return mounted_arm(self.speed_arm_b, s.x, self.estimates_mounting)

    def measured_mat_nb(self, att: AttitudeMeasurement) -> FloatArray:
        """Base_link FRD -> NED rotation from an attitude measurement and its mounting."""
        return base_mat_nb(as_quat(att.quat_enu_flu_xyzw), self.q_a_base)

    def mounting_rpy(self, mounting: tuple[float, float]) -> FloatArray:
        """REP-103 roll, pitch, yaw [rad] of imu_link in the base_link of a residual mounting
        (pitch, yaw about base_link FRD y, z [rad]; ``mounting_rpy_from``)."""
        cached = self._mounting_cache
        if cached is not None and cached[0] == mounting:
            return cached[1]
        rpy = np.array(mounting_rpy_from(self.r_bi, mounting[0], mounting[1]))
        self._mounting_cache = (mounting, rpy)
        return rpy


@compilable
def base_mat_nb(quat_enu_flu_a: Quat, q_a_base: Quat) -> FloatArray:
    """Base_link FRD -> NED rotation from the REP-103 orientation (x, y, z, w) of an attitude
    receiver's frame a and the rotation of base_link in a (Geometry.q_a_base): q_ea ⊗ q_ab,
    FLU in ENU -> FRD in NED (the map is its own inverse)."""
    x, y, z, w = quat_enu_flu(quat_multiply(quat_enu_flu_a, q_a_base))
    return mat_from_quat(x, y, z, w)


@compilable
def mounted_arm(arm_b: FloatArray, x: FloatArray, estimates_mounting: bool) -> FloatArray:
    """A configured lever arm [m] (body FRD, vehicle axes) at the nominal state ``x`` (X_*
    layout): turned by the residual mounting μ = (0, pitch, yaw) [rad] when it is estimated,
    (I + [μ×]) l; ``arm_b`` itself while μ is zero or not estimated (Geometry.arms, and inside
    core.engine.sample_runs' compiled runs)."""
    pitch, yaw = x[X_MOUNTING], x[X_MOUNTING + 1]
    if not estimates_mounting or (pitch == 0.0 and yaw == 0.0):
        return arm_b
    a0, a1, a2 = arm_b[0], arm_b[1], arm_b[2]
    return np.array((a0 + (pitch * a2 - yaw * a1), a1 + yaw * a0, a2 - pitch * a0))


@compilable
def mounting_rpy_from(r_bi: FloatArray, pitch: float, yaw: float) -> Vec3:
    """REP-103 roll, pitch, yaw [rad] (z-y'-x'') of imu_link in the vehicle frame of a residual
    mounting μ = (0, pitch, yaw) about base_link FRD y, z [rad], for the configured rotation
    ``r_bi`` (imu FRD -> base_link FRD, row-major): imu -> vehicle (FRD) = (I - [μ×]) R_bi,
    taken into FLU on both sides (the signs below), then Aalborg notes (7.16)-(7.18)."""
    turn = np.array(((1.0, yaw, -pitch), (-yaw, 1.0, 0.0), (pitch, 0.0, 1.0)))  # I - [μ×]
    m = turn @ r_bi.reshape((3, 3))
    return (
        math.atan2(m[2, 1], m[2, 2]),
        -math.asin(max(-1.0, min(1.0, -m[2, 0]))),
        math.atan2(-m[1, 0], m[0, 0]),
    )


def inject(s: FilterState, kf: ErrorStateFilter, dx: FloatArray) -> None:
    """Closed-loop feedback of an error estimate ``dx`` (layout ``kf.layout``) into the nominal
    state."""
    if kf.smoother_hooks is not None:  # smoother hook: the correction of this step
        kf.smoother_hooks.on_correction(dx)
    inject_nominal(s.x, dx, kf.layout.columns)
    s.changed()
    if not s.heading_known:
        decouple_yaw(kf)


@jit
def inject_nominal(x: FloatArray, dx: FloatArray, columns: Columns) -> None:
    """The part of ``inject`` kept in ``x`` (X_* layout): attitude (the error rotation applied
    on the NED side), position (a NED offset), velocity, the biases and the optional blocks
    whose ``columns`` (StateLayout.columns: sg, sa, sr, gp, mt, td, ks) are not -1: scale factors,
    correlated GNSS error, residual mounting, time offset and speed scale."""
    q_err = quat_from_rotvec(dx[ATT], dx[ATT + 1], dx[ATT + 2])
    q = quat_normalize(
        quat_multiply(q_err, (x[X_QUAT], x[X_QUAT + 1], x[X_QUAT + 2], x[X_QUAT + 3]))
    )
    lat, lon, height = earth.displace(
        x[X_LAT], x[X_LON], x[X_HEIGHT], dx[POS], dx[POS + 1], dx[POS + 2]
    )
    x[X_LAT], x[X_LON], x[X_HEIGHT] = lat, lon, height
    x[X_QUAT], x[X_QUAT + 1], x[X_QUAT + 2], x[X_QUAT + 3] = q
    for k in range(3):
        x[X_VEL + k] += dx[VEL + k]
        x[X_BG + k] += dx[BG + k]
        x[X_BA + k] += dx[BA + k]
        if columns.sg >= 0:
            x[X_SG + k] += dx[columns.sg + k]
        if columns.sa >= 0:
            x[X_SA + k] += dx[columns.sa + k]
        if columns.sr >= 0:
            x[X_SR + k] += dx[columns.sr + k]
        if columns.gp >= 0:
            x[X_GNSS_ERROR + k] += dx[columns.gp + k]
    if columns.mt >= 0:
        x[X_MOUNTING] += dx[columns.mt]
        x[X_MOUNTING + 1] += dx[columns.mt + 1]
    if columns.td >= 0:
        x[X_TIME_OFFSET] += dx[columns.td]
    if columns.ks >= 0:
        x[X_SPEED_SCALE] += dx[columns.ks]


@compilable
def filter_problem(P: FloatArray, x: FloatArray) -> int:
    """Whether the covariance ``P`` and the nominal state ``x`` (X_* layout) are usable
    (core.filter.eskf.USABLE) or why not: eskf's codes, or the state whose variance is the most
    negative."""
    worst: int = covariance_problem(P)
    if worst == USABLE and not np.isfinite(x[X_NAV : X_NAV + NAV_SIZE]).all():
        return NONFINITE_NAVIGATION
    return worst


@compilable
def nav_speeds(x: FloatArray) -> tuple[float, float]:
    """Horizontal and 3-D speed of the nominal state ``x`` (X_* layout) [m/s]."""
    horizontal = math.hypot(x[X_VEL], x[X_VEL + 1])
    return horizontal, math.hypot(horizontal, x[X_VEL + 2])


def decouple_yaw(kf: ErrorStateFilter, yaw_variance: float = UNKNOWN_YAW_VARIANCE) -> None:
    """Make the yaw error uncorrelated with variance ``yaw_variance`` [rad²] (default: heading
    unknown)."""
    P = kf.P.copy()
    P[ATT + 2, :] = 0.0
    P[:, ATT + 2] = 0.0
    P[ATT + 2, ATT + 2] = yaw_variance
    kf.P = P


def restart_block(P: FloatArray, start: int, block: FloatArray) -> None:
    """Set a 3x3 diagonal block of P and clear its correlations (in place on a copy)."""
    P[start : start + 3, :] = 0.0
    P[:, start : start + 3] = 0.0
    P[start : start + 3, start : start + 3] = block
