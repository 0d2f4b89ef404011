"""GNSS-aided INS engine: the pure fusion core behind ins_fusion_node and ``gnss_ins replay``.

Feed it IMU samples and GNSS/attitude measurements in arrival order; ask for ``solution()`` and
``status()``. It knows nothing of ROS, files or clocks: every time is a message stamp [s].

Pipeline per IMU sample (imu_link FLU, SI, REP-145): calibration (core.calibration, Aalborg notes
(9.1)/(9.2)) -> FRD -> increments (strapdown.SampleIntegrator, interval from the stamps) ->
filter bias/scale correction -> mounting rotation imu_link -> base_link -> strapdown mechanization
of the IMU point with base_link axes -> covariance propagation (core.eskf) -> pseudo-measurements
(ZUPT, ZARU, NHC) at ``pseudo_measurement_rate``.

Measurements at their own stamps: every IMU sample leaves a history entry (its increment and a
checkpoint of the state after it) for ``history_s`` seconds. A measurement stamped t_m is applied
at the last entry at or before t_m, with the prediction carried from that entry to t_m by the
entry's velocity, acceleration and body rate (less than one IMU interval: the neglected terms are
below 0.1 mm and 1e-5 rad at car dynamics). If later entries exist, the engine rolls back to that
entry's checkpoint, applies the entry's measurements in stamp order and re-propagates the later
samples with their own measurements, once, before the next IMU sample or output (a fix and its
velocity share one re-propagation). Re-propagation (rather than carrying the correction forward
with a transition matrix) is exact for any delay; it costs one ``_step`` per replayed sample,
i.e. the latency times 134 samples per epoch: 7 for the Leica's 0.053 s, about 7 % of the
samples (measured in bench/bench_fusion_engine.py). Measurements newer than the latest IMU
sample wait for it.
Duplicates (same kind and stamp) are ignored and counted; measurements older than the history
are rejected and counted as ``too_old``; a backwards IMU stamp resets the engine.

Adaptation and self-calibration (core.adaptation, docs/fusion.md): the IMU white noise is
measured from the samples and raises the process noise above the user's densities; the GNSS
white share is measured from consecutive innovations; the GNSS normalised innovations scale the
process noise while they stay too large; a gate recovery fades the whole covariance. Optional
error states estimate the residual IMU-to-vehicle mounting (pitch, yaw; with the NHC) and the
IMU time offset (``imu_time_offset`` is taken off every IMU stamp).

Alignment and states: 'aligning' while levelling on a standstill (no solution yet) and while the
heading is unknown; 'navigating'; 'degraded' when no GNSS position was used for
``degraded_after_s``. Levelling (core.alignment) averages ``alignment.duration`` seconds of a
detected standstill for roll, pitch and the gyro-bias seed; the heading comes from the attitude
receiver, or from the GNSS course once faster than ``alignment.course_speed`` (NTNU notes §8). A
vehicle that is already moving aligns from attitude or course with roll = pitch = 0 ± the
``alignment.moving_tilt_sigma``. While the heading is unknown the yaw error is kept out of the
filter (its covariance row and column zeroed): GNSS updates are applied only near standstill,
where the yaw does not enter them except through the lever arm, whose antenna position the
heading initialisation then keeps.
"""

from __future__ import annotations

import bisect
import heapq
import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np

from ins_fusion.core import earth
from ins_fusion.core.adaptation import (
    ImuNoiseMonitor,
    WhiteNoiseMonitor,
    adapt_process_noise,
    fading_factor,
)
from ins_fusion.core.alignment import (
    Levelling,
    earth_rate_body_rad_s,
    level,
    unknown_earth_rate_rad_s,
)
from ins_fusion.core.calibration import ImuCalibration
from ins_fusion.core.config import FusionConfig
from ins_fusion.core.eskf import (
    ATT,
    BA,
    BG,
    POS,
    VEL,
    ErrorStateFilter,
    StateLayout,
    chi2_threshold,
    skew,
)
from ins_fusion.core.measurements import (
    UNKNOWN_ANGLE_VARIANCE,
    AttitudeMeasurement,
    GnssFixMeasurement,
    GnssVelocityMeasurement,
    Model,
    Prediction,
    attitude,
    euler_rad,
    gnss_position,
    gnss_velocity,
    mounting_skew,
    ned_cov,
    nhc,
    wrap_angle,
    zaru,
    zupt,
)
from ins_fusion.core.rotation import (
    MAT_ENU_NED,
    MAT_FLU_FRD,
    FloatArray,
    Quat,
    Vec3,
    mat_from_quat,
    quat_from_euler,
    quat_from_rotvec,
    quat_multiply,
    quat_normalize,
)
from ins_fusion.core.smoother import SmootherHooks
from ins_fusion.core.stop_detector import GNSS_SPEED_MAX_AGE_S, StopDetector
from ins_fusion.core.strapdown import ImuIncrement, NavState, SampleIntegrator, propagate
from ins_fusion.core.units import STANDARD_GRAVITY_M_S2

__all__ = [
    "MEASUREMENT_NAMES",
    "AttitudeMeasurement",
    "EngineStatus",
    "FusionConfig",
    "GnssFixMeasurement",
    "GnssVelocityMeasurement",
    "ImuCalibration",
    "InsEngine",
    "InsSolution",
]

#: Measurement kinds, as counted in ``EngineStatus.measurements``.
MEASUREMENT_NAMES = (
    "gnss_position",
    "gnss_velocity",
    "attitude",
    "zupt",
    "zaru",
    "nhc",
    "course_heading",
)
#: Counters kept per measurement kind ('rejected' includes 'gated' and 'too_old').
COUNTERS = ("used", "rejected", "gated", "too_old", "duplicates", "recoveries")

#: The measurements whose normalised innovations scale the IMU process noise (adaptation.py).
_ADAPTING_KINDS = frozenset({"gnss_position", "gnss_velocity"})
#: The error states a gate recovery widens, per sensor measurement (InsEngine._update); the
#: pseudo-measurements (ZUPT, ZARU, NHC) are constraints a real vehicle can break (a skid),
#: so their rejections stay rejections.
_RECOVERY_BLOCKS = {"gnss_position": POS, "gnss_velocity": VEL, "attitude": ATT}

#: An IMU interval longer than this many nominal intervals is a gap (bridged, counted).
_GAP_FACTOR = 2.5
#: Yaw variance standing for 'heading unknown' [rad²].
_UNKNOWN_YAW_VARIANCE = (math.pi / 2.0) ** 2
#: While the heading is unknown, GNSS updates are applied only below this speed [m/s].
_ALIGN_MAX_SPEED_M_S = 1.0
#: Largest distance in time between a fix and the alignment that uses it [s].
_ALIGN_FIX_MAX_AGE_S = 1.5
#: A vehicle levelled on a standstill tilted more than this [deg] (roads: < 12°) means the IMU is
#: mounted otherwise than imu_mounting_rpy_deg says, or its axis map or accelerometer sign is
#: wrong (an upside-down unit levels at roll 180°): EngineStatus.warnings says so.
_LEVEL_TILT_WARNING_DEG = 30.0
#: A change of the receiver's reported variance by more than this factor restarts the
#: correlated GNSS error states (another fix type).
_GNSS_NOISE_JUMP = 1.5
#: The time offset is observed only above these rates of the measured quantity: speed [m/s]
#: for positions, acceleration [m/s²] for velocities (core.measurements for attitude).
_TIME_OFFSET_MIN_SPEED_M_S = 1.0
_TIME_OFFSET_MIN_ACCEL_M_S2 = 0.3
#: Time constant of the smoothed acceleration and rate of the time-offset model [s].
_ACCEL_SMOOTHING_S = 0.1
#: Largest factor by which a fix's covariance grows when its epochs scatter more than reported.
_MAX_GNSS_INFLATION = 100.0
#: IMU samples stamped before the last one, in a row, that make a new stream (a reset); fewer
#: are skipped one by one.
_BACK_RUN_RESET = 10
#: Most measurements waiting for a later IMU sample.
_MAX_PENDING = 256
#: Course-heading variance floor for side slip and antenna motion [rad²] (0.5°).
_COURSE_EXTRA_VARIANCE = math.radians(0.5) ** 2
#: ENU <-> NED quaternion (180° about (N+E)/√2) and FRD <-> FLU (180° about x), scalar last.
_Q_ENU_NED: Quat = (math.sqrt(0.5), math.sqrt(0.5), 0.0, 0.0)
_Q_FRD_FLU: Quat = (1.0, 0.0, 0.0, 0.0)


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


@dataclass(frozen=True)
class EngineStatus:
    """Diagnostics: state, per-measurement counters ({name: {counter: n}}, COUNTERS), resets
    with the reason of the last one, IMU samples/gaps/duplicate stamps/samples skipped for a
    stamp in the past (out of order) or a value beyond the unit's range (implausible, also
    counted as gaps), the last normalised
    innovation squared per measurement, rollbacks and re-propagated samples for late
    measurements, the stop detector's decision, and the noise the filter adapted to
    (``adapted``, flat names with units; InsEngine.adapted_noise) and the self-calibration
    (``calibration``; InsEngine.self_calibration); ``warnings``: set-up problems the data show
    (e.g. a unit levelled far from its configured mounting), each once, for the log."""

    state: str
    measurements: dict[str, dict[str, int]]
    resets: int
    last_reset_reason: str
    imu_samples: int
    imu_gaps: int
    imu_duplicates: int
    imu_out_of_order: int
    imu_implausible: int
    nis: dict[str, float]
    rollbacks: int
    replayed_samples: int
    stationary: bool
    adapted: dict[str, float]
    calibration: dict[str, float]
    warnings: tuple[str, ...] = ()


class _State:
    """Nominal state and filter bookkeeping at one IMU stamp. Copies are history checkpoints:
    every field is immutable or never modified in place, so a shallow copy suffices.

    cov_dt, cov_dth, cov_dv, cov_vel0: IMU interval not yet in the covariance (duration [s],
    corrected angle and velocity increments in imu FRD, NED velocity at its start).
    """

    __slots__ = (
        "_mat_nb",
        "accel_bias",
        "accel_lp",
        "accel_n",
        "accel_scale",
        "cov_dt",
        "cov_dth",
        "cov_dv",
        "cov_vel0",
        "gated_runs",
        "gnss_error",
        "gnss_reported",
        "gnss_variance",
        "gnss_white",
        "gyro_bias",
        "gyro_scale",
        "heading_known",
        "imu_psd",
        "last_position_t_s",
        "mounting",
        "nav",
        "nis_mean",
        "prev_inc",
        "q_scale",
        "rate_b",
        "rate_i",
        "rate_lp",
        "t_s",
        "time_offset",
    )

    def __init__(self, t_s: float, nav: NavState, gyro_bias: Vec3, heading_known: bool) -> None:
        zero: Vec3 = (0.0, 0.0, 0.0)
        self.t_s = t_s
        self.nav = nav
        self._mat_nb: FloatArray | None = None
        self.gyro_bias = gyro_bias
        self.accel_bias = self.gyro_scale = self.accel_scale = zero
        self.prev_inc: ImuIncrement | None = None
        self.rate_b = self.rate_i = self.accel_n = zero
        self.heading_known = heading_known
        self.last_position_t_s = t_s
        self.gnss_error = self.gnss_variance = self.gnss_reported = zero
        self.gnss_white = WhiteNoiseMonitor()
        self.imu_psd: tuple[FloatArray, FloatArray] | None = None
        self.accel_lp = self.rate_lp = zero
        self.nis_mean = self.q_scale = 1.0
        self.mounting = (0.0, 0.0)
        self.time_offset = 0.0
        self.cov_dt = 0.0
        self.cov_dth = self.cov_dv = zero
        self.cov_vel0 = nav.vel_ned_m_s
        self.gated_runs: dict[str, int] = {}  # replaced, never changed in place (copy shares it)

    def copy(self) -> _State:
        other = _State.__new__(_State)
        other._mat_nb = self._mat_nb
        other.accel_bias = self.accel_bias
        other.accel_n = self.accel_n
        other.accel_scale = self.accel_scale
        other.cov_dt = self.cov_dt
        other.cov_dth = self.cov_dth
        other.cov_dv = self.cov_dv
        other.cov_vel0 = self.cov_vel0
        other.gnss_error = self.gnss_error
        other.gnss_variance = self.gnss_variance
        other.gnss_reported = self.gnss_reported
        other.gnss_white = self.gnss_white
        other.imu_psd = self.imu_psd
        other.accel_lp = self.accel_lp
        other.nis_mean = self.nis_mean
        other.q_scale = self.q_scale
        other.rate_lp = self.rate_lp
        other.mounting = self.mounting
        other.time_offset = self.time_offset
        other.gated_runs = self.gated_runs
        other.gyro_bias = self.gyro_bias
        other.gyro_scale = self.gyro_scale
        other.heading_known = self.heading_known
        other.last_position_t_s = self.last_position_t_s
        other.nav = self.nav
        other.prev_inc = self.prev_inc
        other.rate_b = self.rate_b
        other.rate_i = self.rate_i
        other.t_s = self.t_s
        return other

    @property
    def mat_nb(self) -> FloatArray:
        """Body (base_link FRD) -> NED rotation of ``nav`` (computed once per state)."""
        if self._mat_nb is None:
            self._mat_nb = self.nav.mat_nb
        return self._mat_nb

    def set_nav(self, nav: NavState) -> None:
        self.nav = nav
        self._mat_nb = None


_M = TypeVar("_M", AttitudeMeasurement, GnssVelocityMeasurement)

#: A measurement in the history: (stamp, rank of its kind in MEASUREMENT_NAMES, arrival
#: sequence, kind, payload). Records sort by stamp, then kind: measurements with the same stamp
#: are applied in one order whatever order they arrived in.
_Record = tuple[float, int, int, str, Any]
_RANK = {name: rank for rank, name in enumerate(MEASUREMENT_NAMES)}


@dataclass(frozen=True, slots=True)
class _Gap:
    """Uncertainty of the increment that bridges missing IMU samples: variances of the angle
    [rad²] and velocity [m²/s²] increments per imu FRD axis (see InsEngine._bridge)."""

    angle_var_rad2: tuple[float, ...]
    velocity_var_m2_s2: tuple[float, ...]


class _Entry:
    """One IMU sample in the history: its raw increment (imu FRD, calibrated), the gap it
    bridges (None: none; after one the coning/sculling history restarts), the IMU white-noise
    densities in force at it (InsEngine._imu_psd), the checkpoint after it and its
    measurements."""

    __slots__ = ("checkpoint", "gap", "inc", "measurements", "noise", "t_s")

    def __init__(
        self,
        t_s: float,
        inc: ImuIncrement,
        gap: _Gap | None,
        noise: tuple[FloatArray, FloatArray] | None,
        checkpoint: tuple[_State, FloatArray],
    ) -> None:
        self.t_s = t_s
        self.inc = inc
        self.gap = gap
        self.noise = noise
        self.checkpoint = checkpoint
        self.measurements: list[_Record] = []


def _frd(v_flu: Sequence[float]) -> FloatArray:
    return np.array([v_flu[0], -v_flu[1], -v_flu[2]], dtype=np.float64)


def _mat_from_rpy_flu(rpy_rad: Sequence[float]) -> FloatArray:
    """FRD -> FRD rotation of a sensor whose FLU frame has REP-103 roll, pitch, yaw in base_link."""
    q = quat_from_euler(rpy_rad[0], rpy_rad[1], rpy_rad[2])
    mat = mat_from_quat(*q.tolist())
    return np.asarray(MAT_FLU_FRD @ mat @ MAT_FLU_FRD, dtype=np.float64)


def _enu_skew(x: float, y: float, z: float) -> tuple[Vec3, Vec3, Vec3]:
    """MAT_ENU_NED @ [v×] for a NED vector v = (x, y, z): the rows of [v×] for E, N and -D."""
    return ((z, 0.0, -x), (0.0, -z, y), (y, -x, 0.0))


def _quat(values: FloatArray) -> Quat:
    x, y, z, w = values.tolist()
    return (x, y, z, w)


def _quat_enu_flu(quat_nb: Quat) -> Quat:
    """REP-103 orientation (FLU in ENU) of a body (FRD) -> NED quaternion, w >= 0; also the
    inverse map, as both frame changes are half turns (rotation.quat_nb_from_enu_flu)."""
    return quat_normalize(quat_multiply(quat_multiply(_Q_ENU_NED, quat_nb), _Q_FRD_FLU))


class InsEngine:
    """Loosely coupled, closed-loop error-state GNSS/INS (see the module docstring)."""

    _filter: ErrorStateFilter | None
    _state: _State | None
    _history: list[_Entry]
    _history_t: list[float]
    _pending: list[_Record]
    _replay_from: int | None
    _fresh: set[int]
    _seen: dict[str, set[float]]
    _last_t_s: float | None
    _last_sample: tuple[Vec3, Vec3]
    _last_fix: GnssFixMeasurement | None
    _last_velocity: GnssVelocityMeasurement | None
    _last_attitude: AttitudeMeasurement | None
    _gnss_speed: tuple[float, float] | None
    _nominal_dt_s: float
    _next_pseudo_t_s: float
    _zaru_sum: list[float]
    _zaru_count: int
    _zaru_start_s: float

    def __init__(self, config: FusionConfig, calibration: ImuCalibration | None = None) -> None:
        """``calibration`` overrides ``config.calibration_file`` (empty file name = none)."""
        self.config = config
        if calibration is None and config.calibration_file:
            calibration = ImuCalibration.from_yaml(config.calibration_file)
        self.calibration = calibration
        noise = config.imu_noise
        self.layout = StateLayout(
            noise.gyro_scale_sigma > 0.0,
            noise.accel_scale_sigma > 0.0,
            config.gnss_correlation_time_s > 0.0,
            config.estimate_mounting,
            config.estimate_time_offset,
        )
        self._mat_bi = _mat_from_rpy_flu(config.imu_mounting_rpy_rad)
        self._r_bi = tuple(float(v) for v in self._mat_bi.ravel())
        imu_arm_b = _frd(config.imu_lever_arm_flu_m)
        self._antenna_arm_b = _frd(config.gnss_lever_arm_flu_m) - imu_arm_b
        self._base_arm_b = -imu_arm_b
        self._arm_bi = skew(self._base_arm_b) @ self._mat_bi
        # solution(): ENU position, velocity and attitude of base_link over the first 12 error
        # states; the blocks that depend on the state are filled in per call.
        self._j_solution = np.zeros((9, BG + 3))
        for row, col in ((0, POS), (3, VEL), (6, ATT)):
            self._j_solution[row : row + 3, col : col + 3] = MAT_ENU_NED
        self._j_mounting = np.zeros((9, BG + 5))
        mt = self.layout.mt
        self._solution_states = np.r_[0 : BG + 3, [] if mt is None else [mt, mt + 1]].astype(int)
        # Orientation of base_link from that of the attitude receiver's frame a: q_ea ⊗ q_ab.
        q_ba = quat_from_euler(*config.attitude_mounting_rpy_rad)
        self._q_a_base: Quat = (-q_ba[0], -q_ba[1], -q_ba[2], q_ba[3])
        self._gates = {dof: chi2_threshold(config.gate_probability, dof) for dof in (1, 2, 3)}
        self._pseudo_period_s = 1.0 / config.pseudo_measurement_rate_hz
        self._gyro_psd = np.square(noise.gyro_arw)
        self._gnss_white_var_ned = np.square(MAT_ENU_NED @ config.gnss_white_sigma_enu_m)
        self.datum: tuple[float, float, float] | None = config.datum_deg
        self._plane: earth.TangentPlane | None = None
        self._counters = {name: dict.fromkeys(COUNTERS, 0) for name in MEASUREMENT_NAMES}
        self._nis = dict.fromkeys(MEASUREMENT_NAMES, math.nan)
        self._resets = 0
        self._last_reset_reason = ""
        self._warnings: tuple[str, ...] = ()
        self._imu_samples = 0
        self._imu_gaps = 0
        self._imu_duplicates = 0
        self._imu_out_of_order = 0
        self._imu_implausible = 0
        self._imu_back_run = 0
        range_margin = 1.1  # calibration and scale errors may carry a reading past the range
        self._max_rate = math.radians(config.imu_range_rate_deg_s) * range_margin
        self._max_force = config.imu_range_accel_g * STANDARD_GRAVITY_M_S2 * range_margin
        self._rollbacks = 0
        self._replayed_samples = 0
        self._sequence = itertools.count()
        self._handlers: dict[str, Callable[[Prediction, Any, bool], None]] = {
            "gnss_position": self._gnss_position,
            "gnss_velocity": self._gnss_velocity,
            "attitude": self._attitude,
            "zupt": self._zupt,
            "zaru": self._zaru,
            "nhc": self._nhc,
        }
        self._detector = StopDetector(config.stop_detector, self._mat_bi)
        self._imu_noise = ImuNoiseMonitor()
        self._accel_psd_floor = np.square(noise.accel_vrw)
        self._measured_psd: tuple[FloatArray, FloatArray] | None = None
        self._mounting_cache: tuple[tuple[float, float], FloatArray] | None = None
        self._effective_psd = (self._gyro_psd, self._accel_psd_floor)
        self._fading = 1.0
        self._levelling = Levelling()
        self._integrator = SampleIntegrator()
        #: RTS smoother hooks (core.smoother; set by core.smoothed_solution.attach_recorder).
        self.recorder: SmootherHooks | None = None
        #: Jacobian of the last solution() (rows ENU position, velocity, attitude of base_link,
        #: columns the error states core.smoothed_solution.solution_states); reused per call.
        self.solution_jacobian: FloatArray = self._j_solution
        self._clear()

    # ----------------------------------------------------------------------------- inputs

    def add_imu(
        self,
        t_s: float,
        rate_flu_rad_s: Sequence[float] | FloatArray,
        force_flu_m_s2: Sequence[float] | FloatArray,
    ) -> None:
        """One IMU sample as published by imu400cc_node: imu_link FLU, rad/s and m/s², stamp
        (``imu_time_offset`` is taken off it: the engine runs on the GNSS time base)."""
        t = float(t_s) - self.config.imu_time_offset_s
        rate: Vec3 = (float(rate_flu_rad_s[0]), float(rate_flu_rad_s[1]), float(rate_flu_rad_s[2]))
        force: Vec3 = (float(force_flu_m_s2[0]), float(force_flu_m_s2[1]), float(force_flu_m_s2[2]))
        # One test for all seven: a NaN or an infinity in any makes the sum non-finite.
        if not math.isfinite(t + rate[0] + rate[1] + rate[2] + force[0] + force[1] + force[2]):
            self._imu_gaps += 1  # a corrupt sample is a one-sample gap
            return
        if (
            max(abs(rate[0]), abs(rate[1]), abs(rate[2])) > self._max_rate
            or max(abs(force[0]), abs(force[1]), abs(force[2])) > self._max_force
        ):
            self._imu_gaps += 1  # beyond what the unit can measure: corrupt, a one-sample gap
            self._imu_implausible += 1
            return
        last = self._last_t_s
        if last is not None and t <= last:
            if t == last:
                self._imu_duplicates += 1
                return
            # One sample in the past is a fault of that sample (skipped); a run of them is the
            # clock that went back (a restarted recording, a reset device): start again.
            self._imu_back_run += 1
            if self._imu_back_run < _BACK_RUN_RESET:
                self._imu_out_of_order += 1
                return
            self._reset(
                f"IMU stamp went back by {last - t:.3f} s for {_BACK_RUN_RESET} samples in a row"
            )
            last = None
        self._imu_back_run = 0
        self._imu_samples += 1
        if self.calibration is not None:
            rate, force = self.calibration.correct(rate, force)
        rate_i: Vec3 = (rate[0], -rate[1], -rate[2])
        force_i: Vec3 = (force[0], -force[1], -force[2])

        if last is None:
            self._start_stream(t, rate_i, force_i)
            return
        dt = t - last
        gap: _Gap | None = None
        if dt > _GAP_FACTOR * self._nominal_dt_s:
            self._imu_gaps += 1
            if dt > self.config.imu_gap_reset_s:
                self._reset(f"IMU gap of {dt:.3f} s")
                self._start_stream(t, rate_i, force_i)
                return
            inc, gap = self._bridge(dt, rate_i, force_i)
        else:
            pushed = self._integrator.push(t, rate_i, force_i)
            assert pushed is not None
            inc = pushed
            nominal = self._nominal_dt_s
            self._nominal_dt_s = dt if nominal == math.inf else nominal + 0.01 * (dt - nominal)
        self._last_t_s = t
        self._last_sample = (rate_i, force_i)
        self._detector.push(t, rate_i, force_i)
        if gap is not None:
            self._imu_noise.reset()
        self._imu_noise.push(t, rate_i, force_i)
        zs = self._zaru_sum
        zs[0] += rate_i[0]
        zs[1] += rate_i[1]
        zs[2] += rate_i[2]
        self._zaru_count += 1

        if self._filter is None:
            if self._detector.stationary:
                self._levelling.push(t, rate_i, force_i)
            if t >= self._next_pseudo_t_s:
                self._align_epoch(t)
            return
        self._catch_up()
        pending = self._pending
        while pending and pending[0][0] < t:
            self._insert(heapq.heappop(pending))
        self._catch_up()
        noise = self._imu_psd()
        self._step(inc, gap, t, noise)
        entry = _Entry(t, inc, gap, noise, self._checkpoint())
        self._history.append(entry)
        self._history_t.append(t)
        if t >= self._next_pseudo_t_s:
            self._pseudo_epoch(t, entry)
            if self._filter is None:
                return  # reset by a health check
        if self._history_t[0] < t - self.config.history_s - 1.0:
            keep = bisect.bisect_left(self._history_t, t - self.config.history_s)
            del self._history[:keep]
            del self._history_t[:keep]

    def add_gnss_fix(self, fix: GnssFixMeasurement) -> None:
        """Antenna position (gnss/fix) at its epoch ``fix.t_s``."""
        if fix.valid and all(map(math.isfinite, (fix.lat_deg, fix.lon_deg, fix.height_m))):
            self._last_fix = fix
            if self.datum is None:
                self.datum = (fix.lat_deg, fix.lon_deg, fix.height_m)
        self._add("gnss_position", fix.t_s, fix)

    def add_gnss_velocity(self, vel: GnssVelocityMeasurement) -> None:
        """Antenna velocity (gnss/vel) at its epoch."""
        horizontal = float(np.hypot(vel.vel_enu_m_s[0], vel.vel_enu_m_s[1]))
        if math.isfinite(horizontal):
            self._last_velocity = vel
            self._gnss_speed = (vel.t_s, horizontal)
        if self.config.use_gnss_velocity or self.config.use_course_heading:
            self._add("gnss_velocity", vel.t_s, vel)

    def add_attitude(self, att: AttitudeMeasurement) -> None:
        """Orientation from the attitude receiver (gnss/attitude) at its epoch."""
        if self.config.use_attitude:
            self._last_attitude = att
            self._add("attitude", att.t_s, att)

    # ---------------------------------------------------------------------------- outputs

    def solution(self) -> InsSolution | None:
        """The fused base_link state at the latest IMU sample; None before the filter starts.

        The covariances come from one Jacobian over the position, velocity, attitude and gyro
        bias states (the first 12, which the lever arm couples), rows in ENU: this runs at the
        output rate.
        """
        self._catch_up()
        s, kf = self._state, self._filter
        if s is None or kf is None or self.datum is None:
            return None
        C = s.mat_nb
        (c00, c01, c02), (c10, c11, c12), (c20, c21, c22) = C.tolist()
        # base_link of the estimated mounting: the lever arm turned by it, and below the
        # orientation and rate turned into it (C_bv = I + [μ×]).
        ax, ay, az = self._arms(s)[1].tolist()
        # Lever arm in NED, and its velocity ω × r (body) rotated into NED; 3-vectors in plain
        # floats (numpy per 3-vector costs more than the arithmetic at the output rate).
        n0 = c00 * ax + c01 * ay + c02 * az
        n1 = c10 * ax + c11 * ay + c12 * az
        n2 = c20 * ax + c21 * ay + c22 * az
        wx, wy, wz = self._corrected_rate_b(s)
        ux, uy, uz = wy * az - wz * ay, wz * ax - wx * az, wx * ay - wy * ax
        r0 = c00 * ux + c01 * uy + c02 * uz
        r1 = c10 * ux + c11 * uy + c12 * uz
        r2 = c20 * ux + c21 * uy + c22 * uz
        nav = s.nav
        r_m, r_n = earth.radii_m(nav.lat_rad)
        lat = nav.lat_rad + n0 / (r_m + nav.height_m)
        lon = nav.lon_rad + n1 / ((r_n + nav.height_m) * math.cos(nav.lat_rad))
        height = nav.height_m - n2
        J = self._j_solution
        J[0:3, ATT : ATT + 3] = _enu_skew(-n0, -n1, -n2)
        J[3:6, ATT : ATT + 3] = _enu_skew(-r0, -r1, -r2)
        J[3:6, BG : BG + 3] = MAT_ENU_NED @ C @ self._arm_bi
        mt = self.layout.mt
        if mt is None:
            cov = J @ kf.P[: BG + 3, : BG + 3] @ J.T
            self.solution_jacobian = J  # smoother hook
        else:  # the vehicle's attitude error is ψ + C_nb μ: the mounting states join
            J_mt = self._j_mounting
            J_mt[:, : BG + 3] = J
            J_mt[6:9, BG + 3 :] = (MAT_ENU_NED @ C)[:, 1:3]
            cov = J_mt @ kf.P[np.ix_(self._solution_states, self._solution_states)] @ J_mt.T
            self.solution_jacobian = J_mt  # smoother hook
        vn, ve, vd = nav.vel_ned_m_s.tolist()
        lat0, lon0, h0 = self.datum
        datum_rad = (math.radians(lat0), math.radians(lon0), h0)
        if self._plane is None or self._plane.datum != datum_rad:
            self._plane = earth.TangentPlane(*datum_rad)
        bg, ba = s.gyro_bias, s.accel_bias
        quat_nb = _quat(nav.quat_nb)
        mounting = None
        if self.layout.mt is not None:
            mu_y, mu_z = s.mounting
            quat_nb = quat_multiply(quat_nb, quat_from_rotvec(0.0, mu_y, mu_z))
            wx, wy, wz = wx - (mu_y * wz - mu_z * wy), wy - mu_z * wx, wz + mu_y * wx
            mounting = self._mounting_rpy(s.mounting)
        return InsSolution(
            t_s=s.t_s,
            lat_deg=math.degrees(lat),
            lon_deg=math.degrees(lon),
            height_m=height,
            pos_enu_m=self._plane.enu(lat, lon, height),
            vel_enu_m_s=np.array((ve + r1, vn + r0, -(vd + r2))),
            quat_enu_flu_xyzw=np.array(_quat_enu_flu(quat_nb)),
            rate_flu_rad_s=np.array((wx, -wy, -wz)),
            cov_pos_enu_m2=cov[0:3, 0:3],
            cov_vel_enu=cov[3:6, 3:6],
            cov_att_enu_rad2=cov[6:9, 6:9],
            gyro_bias_flu_rad_s=np.array((bg[0], -bg[1], -bg[2])),
            accel_bias_flu_m_s2=np.array((ba[0], -ba[1], -ba[2])),
            state=self._state_name(),
            imu_mounting_rpy_rad=mounting,
        )

    def _mounting_rpy(self, mounting: tuple[float, float]) -> FloatArray:
        """REP-103 roll, pitch, yaw [rad] of imu_link in the base_link of a residual mounting
        (pitch, yaw about base_link FRD y, z [rad]): imu -> vehicle (FRD) = (I - [μ×]) R_bi."""
        cached = self._mounting_cache
        if cached is not None and cached[0] == mounting:
            return cached[1]
        mat_vi = (np.eye(3) - mounting_skew(mounting)) @ self._mat_bi
        rpy = euler_rad(MAT_FLU_FRD @ mat_vi @ MAT_FLU_FRD)  # z-y'-x'' of the FLU rotation
        self._mounting_cache = (mounting, rpy)
        return rpy

    def status(self) -> EngineStatus:
        """Counters and diagnostics (see EngineStatus)."""
        self._catch_up()
        return EngineStatus(
            state=self._state_name(),
            measurements={name: dict(c) for name, c in self._counters.items()},
            resets=self._resets,
            last_reset_reason=self._last_reset_reason,
            imu_samples=self._imu_samples,
            imu_gaps=self._imu_gaps,
            imu_duplicates=self._imu_duplicates,
            imu_out_of_order=self._imu_out_of_order,
            imu_implausible=self._imu_implausible,
            nis=dict(self._nis),
            rollbacks=self._rollbacks,
            replayed_samples=self._replayed_samples,
            stationary=self._detector.stationary,
            adapted=self.adapted_noise(),
            calibration=self.self_calibration(),
            warnings=self._warnings,
        )

    def self_calibration(self) -> dict[str, float]:
        """The self-calibration (NaN where not estimated or before the filter starts):
        ``time_offset_s`` = imu_time_offset + the estimated residual, with the residual and its
        σ [s]; the residual mounting pitch and yaw about base_link FRD y, z and their σ [deg];
        ``imu_mounting_{roll,pitch,yaw}_deg``: the imu_mounting_rpy_deg that holds them (REP-103,
        for the configuration)."""
        s, kf, layout = self._state, self._filter, self.layout
        nan = math.nan
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
            nan,
        )
        if s is None or kf is None:
            return values
        if layout.td is not None:
            values["time_offset_residual_s"] = s.time_offset
            values["time_offset_s"] = self.config.imu_time_offset_s + s.time_offset
            values["time_offset_sigma_s"] = math.sqrt(max(kf.P[layout.td, layout.td], 0.0))
        if layout.mt is not None:
            mt = layout.mt
            pitch, yaw = s.mounting
            values["mounting_pitch_residual_deg"] = math.degrees(pitch)
            values["mounting_yaw_residual_deg"] = math.degrees(yaw)
            values["mounting_pitch_sigma_deg"] = math.degrees(math.sqrt(max(kf.P[mt, mt], 0.0)))
            values["mounting_yaw_sigma_deg"] = math.degrees(
                math.sqrt(max(kf.P[mt + 1, mt + 1], 0.0))
            )
            roll_p_yaw = self._mounting_rpy(s.mounting)
            for name, value in zip(("roll", "pitch", "yaw"), roll_p_yaw, strict=True):
                values[f"imu_mounting_{name}_deg"] = math.degrees(float(value))
        return values

    def adapted_noise(self) -> dict[str, float]:
        """The noise model in use after adaptation (core.adaptation), in user units: gyro ARW
        [deg/√h] and accelerometer VRW [m/s/√h] per imu_link axis (the user's value or the
        measured one, whichever is larger), the measured white GNSS position σ per ENU axis
        [m] (NaN until measured) and the last fading factor of a gate recovery (1 = none)."""
        gyro_psd, accel_psd = self._imu_psd() or (self._gyro_psd, self._accel_psd_floor)
        s = self._state
        share = None if s is None else s.gnss_white.share
        white = None if s is None or share is None else share * np.array(s.gnss_reported)
        white_enu = np.full(3, math.nan) if white is None else white[[1, 0, 2]]  # N E D -> E N U
        values: dict[str, float] = {}
        for k, axis in enumerate("xyz"):
            values[f"gyro_arw_{axis}_deg_sqrt_h"] = math.degrees(math.sqrt(gyro_psd[k])) * 60.0
        for k, axis in enumerate("xyz"):
            values[f"accel_vrw_{axis}_m_s_sqrt_h"] = math.sqrt(accel_psd[k]) * 60.0
        for k, axis in enumerate("enu"):
            values[f"gnss_white_sigma_{axis}_m"] = math.sqrt(float(white_enu[k]))
        values["fading_factor_last"] = self._fading
        values["process_noise_scale"] = math.nan if s is None else s.q_scale
        values["gnss_nis_mean"] = math.nan if s is None else s.nis_mean
        return values

    @property
    def covariance(self) -> FloatArray | None:
        """Error-state covariance (layout ``self.layout``; NED/FRD, see core.eskf) or None."""
        self._catch_up()
        return None if self._filter is None else self._filter.P

    # --------------------------------------------------------------- stream and history

    def _clear(self) -> None:
        """Forget everything but the counters and the datum (start, reset)."""
        if self.recorder is not None:  # smoother hook: the filter starts again
            self.recorder.on_reset(None if self._filter is None else self._filter.P)
        self._filter = None
        self._state = None
        self._history = []
        self._history_t = []
        self._pending = []
        self._replay_from = None
        self._fresh = set()
        self._seen = {name: set() for name in MEASUREMENT_NAMES}
        self._last_t_s = None
        self._last_sample = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
        self._nominal_dt_s = math.inf
        self._next_pseudo_t_s = math.inf
        self._zaru_sum = [0.0, 0.0, 0.0]
        self._zaru_count = 0
        self._zaru_start_s = 0.0
        self._last_fix = None
        self._last_velocity = None
        self._last_attitude = None
        self._gnss_speed = None
        self._detector.reset()
        self._imu_noise.reset()
        self._levelling.reset()
        self._integrator.reset()

    def _reset(self, reason: str) -> None:
        self._resets += 1
        self._last_reset_reason = reason
        self._clear()

    def _start_stream(self, t: float, rate_i: Vec3, force_i: Vec3) -> None:
        """First sample after start or reset: no interval yet."""
        self._integrator.reset()
        self._integrator.push(t, rate_i, force_i)
        self._last_t_s = t
        self._last_sample = (rate_i, force_i)
        self._nominal_dt_s = math.inf
        self._detector.push(t, rate_i, force_i)
        self._start_pseudo_interval(t)

    def _bridge(self, dt: float, rate_i: Vec3, force_i: Vec3) -> tuple[ImuIncrement, _Gap]:
        """Trapezoidal increment over a gap and its uncertainty; the integrator restarts at this
        sample. The trapezoid is exact for a rate and force that change linearly; for a change
        at an unknown instant inside the gap (a turn starting) it errs by Δ·dt·(1/2 - τ/dt), of
        RMS Δ·dt/√12, with Δ the change from the last sample to this one."""
        rate0, force0 = self._last_sample
        h = 0.5 * dt
        inc = ImuIncrement(
            dt,
            (h * (rate0[0] + rate_i[0]), h * (rate0[1] + rate_i[1]), h * (rate0[2] + rate_i[2])),
            (
                h * (force0[0] + force_i[0]),
                h * (force0[1] + force_i[1]),
                h * (force0[2] + force_i[2]),
            ),
        )
        k = dt * dt / 12.0
        gap = _Gap(
            tuple(k * (a - b) ** 2 for a, b in zip(rate_i, rate0, strict=True)),
            tuple(k * (a - b) ** 2 for a, b in zip(force_i, force0, strict=True)),
        )
        assert self._last_t_s is not None
        self._integrator.reset()
        self._integrator.push(self._last_t_s + dt, rate_i, force_i)
        return inc, gap

    def _start_pseudo_interval(self, t: float) -> None:
        self._next_pseudo_t_s = (
            math.floor(t / self._pseudo_period_s) + 1.0
        ) * self._pseudo_period_s
        self._zaru_sum = [0.0, 0.0, 0.0]
        self._zaru_count = 0
        self._zaru_start_s = t

    def _checkpoint(self) -> tuple[_State, FloatArray]:
        assert self._state is not None and self._filter is not None
        if self.recorder is not None:  # smoother hook: what a rollback to here keeps
            self.recorder.on_checkpoint(self._state.t_s)
        return self._state.copy(), self._filter.P

    def _restore(self, checkpoint: tuple[_State, FloatArray]) -> None:
        assert self._filter is not None
        if self.recorder is not None:  # smoother hook: drop what the rollback undoes
            self.recorder.on_rollback(checkpoint[0].t_s)
        self._state = checkpoint[0].copy()
        self._filter.P = checkpoint[1]
        self._filter.gnss_variance = self._state.gnss_variance

    def _add(self, kind: str, t_m: float, payload: Any) -> None:
        """Route a measurement: duplicate, too old, pending, or applied at its stamp."""
        counters = self._counters[kind]
        seen = self._seen[kind]
        if t_m in seen:
            counters["duplicates"] += 1
            return
        if self._filter is None or not math.isfinite(t_m):
            return  # the alignment reads the latest measurements directly
        if t_m < self._history_t[0]:
            counters["too_old"] += 1
            counters["rejected"] += 1
            return
        seen.add(t_m)
        if len(seen) > 4 * _MAX_PENDING:
            oldest = self._history_t[0]
            self._seen[kind] = {t for t in seen if t >= oldest}
        record: _Record = (t_m, _RANK[kind], next(self._sequence), kind, payload)
        if t_m > self._history_t[-1]:
            if len(self._pending) >= _MAX_PENDING:
                dropped = heapq.heappop(self._pending)
                self._counters[dropped[3]]["rejected"] += 1
            heapq.heappush(self._pending, record)
            return
        self._insert(record)

    def _insert(self, record: _Record) -> None:
        """File a measurement at the last history entry at or before its stamp: applied now
        when it is the newest, else re-propagation from that entry is due (``_catch_up``)."""
        k = bisect.bisect_right(self._history_t, record[0]) - 1
        entry = self._history[k]
        newest = not entry.measurements or entry.measurements[-1] < record
        if self._replay_from is None and k == len(self._history) - 1 and newest:
            entry.measurements.append(record)
            self._apply(record, live=True)
            return
        bisect.insort(entry.measurements, record)
        self._fresh.add(record[2])
        self._replay_from = k if self._replay_from is None else min(self._replay_from, k)

    def _catch_up(self) -> None:
        """Roll back to the earliest entry with a late measurement and re-propagate; deferred
        until the next IMU sample or output, so measurements arriving together (a fix and its
        velocity) share one re-propagation."""
        k = self._replay_from
        if k is None:
            return
        self._replay_from = None
        self._rollbacks += 1
        entry = self._history[k]
        self._restore(entry.checkpoint)
        self._apply_entry(entry)
        for later in self._history[k + 1 :]:
            self._step(later.inc, later.gap, later.t_s, later.noise)
            later.checkpoint = self._checkpoint()
            self._apply_entry(later)
        self._replayed_samples += len(self._history) - k - 1

    def _apply_entry(self, entry: _Entry) -> None:
        """Apply an entry's measurements in stamp order; new ones are counted."""
        for record in entry.measurements:
            live = record[2] in self._fresh
            self._fresh.discard(record[2])
            self._apply(record, live)

    def _apply(self, record: _Record, live: bool) -> None:
        """Propagate P to the current sample, apply the measurement, restart the interval."""
        t_m, _, _, kind, payload = record
        self._propagate_covariance()
        self._handlers[kind](self._predict(t_m), payload, live)
        assert self._state is not None
        self._state.cov_vel0 = self._state.nav.vel_ned_m_s

    # ---------------------------------------------------------------------- propagation

    def _step(
        self,
        inc: ImuIncrement,
        gap: _Gap | None,
        t: float,
        noise: tuple[FloatArray, FloatArray] | None,
    ) -> None:
        """Correct an increment with the filter's sensor errors and mechanize (``gap``: it
        bridges missing samples; ``noise``: the IMU white-noise densities from now on, None =
        the user's); the covariance follows every ``covariance_interval`` seconds."""
        s = self._state
        assert s is not None
        s.imu_psd = noise
        dt = inc.dt_s
        bg, ba, sg, sa = s.gyro_bias, s.accel_bias, s.gyro_scale, s.accel_scale
        th, dv = inc.dtheta_rad, inc.dvel_m_s
        ti0 = (th[0] - bg[0] * dt) / (1.0 + sg[0])
        ti1 = (th[1] - bg[1] * dt) / (1.0 + sg[1])
        ti2 = (th[2] - bg[2] * dt) / (1.0 + sg[2])
        vi0 = (dv[0] - ba[0] * dt) / (1.0 + sa[0])
        vi1 = (dv[1] - ba[1] * dt) / (1.0 + sa[1])
        vi2 = (dv[2] - ba[2] * dt) / (1.0 + sa[2])
        r0, r1, r2, r3, r4, r5, r6, r7, r8 = self._r_bi
        tb = (
            r0 * ti0 + r1 * ti1 + r2 * ti2,
            r3 * ti0 + r4 * ti1 + r5 * ti2,
            r6 * ti0 + r7 * ti1 + r8 * ti2,
        )
        vb = (
            r0 * vi0 + r1 * vi1 + r2 * vi2,
            r3 * vi0 + r4 * vi1 + r5 * vi2,
            r6 * vi0 + r7 * vi1 + r8 * vi2,
        )
        inc_b = ImuIncrement(dt, tb, vb)
        v0n, v0e, v0d = s.nav.vel_ned_m_s.tolist()
        nav = propagate(s.nav, inc_b, s.prev_inc if gap is None else None)
        s.set_nav(nav)
        inv_dt = 1.0 / dt
        v1n, v1e, v1d = nav.vel_ned_m_s.tolist()
        an = ((v1n - v0n) * inv_dt, (v1e - v0e) * inv_dt, (v1d - v0d) * inv_dt)
        s.accel_n = an
        rb = s.rate_b = (tb[0] * inv_dt, tb[1] * inv_dt, tb[2] * inv_dt)
        # Acceleration and rate low-passed over ~0.1 s (vibration out) for the time-offset
        # model: their noise would otherwise make H noisy and the estimate wander.
        k, lp, rl = min(1.0, dt / _ACCEL_SMOOTHING_S), s.accel_lp, s.rate_lp
        s.accel_lp = (
            lp[0] + k * (an[0] - lp[0]),
            lp[1] + k * (an[1] - lp[1]),
            lp[2] + k * (an[2] - lp[2]),
        )
        s.rate_lp = (
            rl[0] + k * (rb[0] - rl[0]),
            rl[1] + k * (rb[1] - rl[1]),
            rl[2] + k * (rb[2] - rl[2]),
        )
        s.rate_i = (ti0 * inv_dt, ti1 * inv_dt, ti2 * inv_dt)
        s.prev_inc = inc_b
        s.t_s = t
        if gap is not None:
            assert self._filter is not None
            mat_ni = s.mat_nb @ self._mat_bi
            P_before = self._filter.P
            self._filter.add_noise(ATT, (mat_ni * gap.angle_var_rad2) @ mat_ni.T)
            self._filter.add_noise(VEL, (mat_ni * gap.velocity_var_m2_s2) @ mat_ni.T)
            if self.recorder is not None:  # smoother hook: the gap's noise
                self.recorder.on_noise(P_before, self._filter.P)
        cdth, cdv = s.cov_dth, s.cov_dv
        s.cov_dth = (cdth[0] + ti0, cdth[1] + ti1, cdth[2] + ti2)
        s.cov_dv = (cdv[0] + vi0, cdv[1] + vi1, cdv[2] + vi2)
        s.cov_dt += dt
        if s.cov_dt >= self.config.covariance_interval_s:
            self._propagate_covariance()

    def _imu_psd(self) -> tuple[FloatArray, FloatArray] | None:
        """IMU white-noise densities (gyro, accelerometer) [rad²/s, m²/s³] per imu axis: the
        measured ones (core.adaptation.ImuNoiseMonitor) where above the user's; None before a
        measurement."""
        measured = self._imu_noise.psd
        if measured is None:
            return None
        if measured is not self._measured_psd:
            self._measured_psd = measured
            self._effective_psd = (
                np.maximum(self._gyro_psd, measured[0]),
                np.maximum(self._accel_psd_floor, measured[1]),
            )
        return self._effective_psd

    def _propagate_covariance(self) -> None:
        """Propagate P over the accumulated interval with its mean specific force (NED from the
        velocity change; Coriolis, < 3e-3 m/s², left out of F)."""
        s, kf = self._state, self._filter
        assert s is not None and kf is not None
        if s.cov_dt <= 0.0:
            return
        nav = s.nav
        inv_dt = 1.0 / s.cov_dt
        force_n = (nav.vel_ned_m_s - s.cov_vel0) * inv_dt
        force_n[2] -= earth.normal_gravity_m_s2(nav.lat_rad, nav.height_m)
        vn, ve, vd = nav.vel_ned_m_s.tolist()
        gyro_psd, accel_psd = s.imu_psd or (self._gyro_psd, self._accel_psd_floor)
        kf.set_white_noise(gyro_psd * s.q_scale, accel_psd * s.q_scale)
        P_before = kf.P
        kf.propagate(
            s.cov_dt,
            s.mat_nb @ self._mat_bi,
            force_n,
            np.array(s.cov_dv) * inv_dt,
            np.array(s.cov_dth) * inv_dt,
            nav.lat_rad,
            nav.height_m,
            (vn, ve, vd),
        )
        if self.recorder is not None:  # smoother hook: a covariance step
            self.recorder.on_transition(P_before, kf.phi, kf.P)
        if self.layout.gp is not None:  # the estimate of a Gauss-Markov error decays
            decay = math.exp(-s.cov_dt / self.config.gnss_correlation_time_s)
            e = s.gnss_error
            s.gnss_error = (e[0] * decay, e[1] * decay, e[2] * decay)
        s.cov_dt = 0.0
        s.cov_dth = s.cov_dv = (0.0, 0.0, 0.0)
        s.cov_vel0 = nav.vel_ned_m_s
        if not s.heading_known:
            self._decouple_yaw()

    def _predict(self, t_m: float) -> Prediction:
        """The nominal state carried from the current state to t_m (< one IMU interval)."""
        s = self._state
        assert s is not None
        nav, dt = s.nav, t_m - s.t_s
        rate_b = np.array(s.rate_b)
        if dt == 0.0:
            return Prediction(
                nav.lat_rad,
                nav.lon_rad,
                nav.height_m,
                nav.vel_ned_m_s,
                s.mat_nb,
                rate_b,
                np.array(s.rate_i),
                self.layout,
            )
        vel = nav.vel_ned_m_s + np.array(s.accel_n) * dt
        mean_vel = 0.5 * (nav.vel_ned_m_s + vel)
        r_m, r_n = earth.radii_m(nav.lat_rad)
        rotation = skew(rate_b * dt)
        return Prediction(
            lat_rad=nav.lat_rad + mean_vel[0] * dt / (r_m + nav.height_m),
            lon_rad=nav.lon_rad + mean_vel[1] * dt / ((r_n + nav.height_m) * math.cos(nav.lat_rad)),
            height_m=nav.height_m - mean_vel[2] * dt,
            vel_ned_m_s=vel,
            mat_nb=s.mat_nb @ (np.eye(3) + rotation + 0.5 * rotation @ rotation),
            rate_b=rate_b,
            rate_i=np.array(s.rate_i),
            layout=self.layout,
        )

    def _corrected_rate_b(self, s: _State) -> Vec3:
        """The latest sample's rate, corrected for the estimated gyro errors, base_link FRD."""
        (w0, w1, w2), (b0, b1, b2), (k0, k1, k2) = self._last_sample[0], s.gyro_bias, s.gyro_scale
        c0, c1, c2 = (w0 - b0) / (1.0 + k0), (w1 - b1) / (1.0 + k1), (w2 - b2) / (1.0 + k2)
        r = self._r_bi
        return (
            r[0] * c0 + r[1] * c1 + r[2] * c2,
            r[3] * c0 + r[4] * c1 + r[5] * c2,
            r[6] * c0 + r[7] * c1 + r[8] * c2,
        )

    # --------------------------------------------------------------------- updates

    def _update(self, kind: str, model: Model, live: bool) -> FloatArray | None:
        """Gated update; inject the estimate into the nominal state and return it (None:
        rejected)."""
        kf, s = self._filter, self._state
        assert kf is not None and s is not None
        z, H, R = model
        if not s.heading_known:
            H = H.copy()
            H[:, ATT + 2] = 0.0
        result = kf.update(z, H, R, self._gates[len(z)])
        self._nis[kind] = result.nis  # as first tested, also when a recovery follows
        if kind in _ADAPTING_KINDS and math.isfinite(result.nis):
            s.nis_mean, s.q_scale = adapt_process_noise(s.nis_mean, s.q_scale, result.nis / len(z))
        gated = not result.accepted and math.isfinite(result.nis)
        runs = s.gated_runs
        recover = self.config.gate_recovery_count
        block = _RECOVERY_BLOCKS.get(kind)
        if kind == "gnss_position" and s.gnss_white.share is None:
            block = None  # the receiver's noise is not learnt yet: it, not the state, may be off
        if gated and recover and block is not None and runs.get(kind, 0) + 1 >= recover:
            # The filter has rejected this sensor `recover` times running: its state, not the
            # sensor, is the likelier culprit (a state that went wrong and a covariance too
            # small to admit the fix, e.g. IMU noise far above the model). Grow the whole
            # covariance (attitude, biases, velocity with position: fading memory) by the least
            # factor that makes the innovation typical (NIS = dof), apply it. Only if no factor
            # does (the innovation lies outside what P spans) widen what the sensor measures.
            factor = fading_factor(z, H @ kf.P @ H.T, R, float(len(z)))
            P_before = kf.P
            if math.isfinite(factor):
                kf.scale(factor)
                self._fading = factor
            else:
                kf.widen(z, H, R, block)
            if self.recorder is not None:  # smoother hook: the recovery's noise
                self.recorder.on_noise(P_before, kf.P)
            result = kf.update(z, H, R, math.inf)
            gated = False
            if live:
                self._counters[kind]["recoveries"] += 1
        if gated or runs.get(kind, 0):
            s.gated_runs = {**runs, kind: runs.get(kind, 0) + 1 if gated else 0}
        if live:
            counters = self._counters[kind]
            if result.accepted:
                counters["used"] += 1
            else:
                counters["rejected"] += 1
                counters["gated"] += 1
        if result.dx is not None:
            self._inject(result.dx)
        return result.dx

    def _inject(self, dx: FloatArray) -> None:
        """Closed-loop feedback of an error estimate into the nominal state."""
        s = self._state
        assert s is not None
        if self.recorder is not None:  # smoother hook: the correction of this step
            self.recorder.on_correction(dx)
        d = dx.tolist()
        nav = s.nav
        r_m, r_n = earth.radii_m(nav.lat_rad)
        q_err = quat_from_rotvec(d[ATT], d[ATT + 1], d[ATT + 2])
        quat = quat_normalize(quat_multiply(q_err, _quat(nav.quat_nb)))
        s.set_nav(
            NavState(
                nav.lat_rad + d[POS] / (r_m + nav.height_m),
                nav.lon_rad + d[POS + 1] / ((r_n + nav.height_m) * math.cos(nav.lat_rad)),
                nav.height_m - d[POS + 2],
                nav.vel_ned_m_s + dx[VEL : VEL + 3],
                np.array(quat),
            )
        )
        s.gyro_bias = _add3(s.gyro_bias, d, BG)
        s.accel_bias = _add3(s.accel_bias, d, BA)
        if self.layout.sg is not None:
            s.gyro_scale = _add3(s.gyro_scale, d, self.layout.sg)
        if self.layout.sa is not None:
            s.accel_scale = _add3(s.accel_scale, d, self.layout.sa)
        if self.layout.gp is not None:
            s.gnss_error = _add3(s.gnss_error, d, self.layout.gp)
        if self.layout.mt is not None:
            mt = self.layout.mt
            s.mounting = (s.mounting[0] + d[mt], s.mounting[1] + d[mt + 1])
        if self.layout.td is not None:
            s.time_offset += d[self.layout.td]
        if not s.heading_known:
            self._decouple_yaw()

    def _decouple_yaw(self) -> None:
        """Heading unknown: the yaw error is uncorrelated and its variance fixed."""
        kf = self._filter
        assert kf is not None
        P = kf.P.copy()
        P[ATT + 2, :] = 0.0
        P[:, ATT + 2] = 0.0
        P[ATT + 2, ATT + 2] = _UNKNOWN_YAW_VARIANCE
        kf.P = P

    def _gnss_position(self, pred: Prediction, fix: GnssFixMeasurement, live: bool) -> None:
        s = self._state
        assert s is not None
        if not (fix.valid and np.isfinite(fix.cov_enu_m2).all()):
            if live:
                self._counters["gnss_position"]["rejected"] += 1
            return
        if not s.heading_known and self._too_fast_to_align(pred, live, "gnss_position"):
            return
        white, correlated = self._fix_noise(fix)
        reported = self._reported_variance(fix)
        if self.layout.gp is not None:
            ratio = reported / np.maximum(s.gnss_reported, 1e-12)
            if ratio.max() > _GNSS_NOISE_JUMP or ratio.min() < 1.0 / _GNSS_NOISE_JUMP:
                self._restart_gnss_error(fix, correlated)
            elif not np.array_equal(correlated, s.gnss_variance):
                self._set_gnss_variance(correlated)  # the white/correlated split moved
        antenna_b = self._arms(s)[0]
        antenna_rate_n = pred.vel_ned_m_s + pred.mat_nb @ (skew(s.rate_lp) @ antenna_b)
        model = self._late_imu(
            gnss_position(pred, fix, antenna_b, white, s.gnss_error),
            antenna_rate_n,
            _TIME_OFFSET_MIN_SPEED_M_S,
            np.array(s.accel_lp),
        )
        z, H, _ = model
        kf = self._filter
        assert kf is not None
        predicted = np.einsum("ij,jk,ik->i", H, kf.P, H)
        dx = self._update("gnss_position", model, live)
        s.gnss_white = s.gnss_white.pushed(
            fix.t_s,
            z,
            z if dx is None else z - H @ dx,
            predicted,
            np.einsum("ij,jk,ik->i", H, kf.P, H),
            reported,
        )
        if dx is not None:
            s.last_position_t_s = max(s.last_position_t_s, fix.t_s)

    def _gnss_velocity(self, pred: Prediction, vel: GnssVelocityMeasurement, live: bool) -> None:
        s = self._state
        assert s is not None
        if not s.heading_known:
            if self.config.use_course_heading and self._fast_enough(vel):
                self._heading_from_course(vel, live)
                return
            if self._too_fast_to_align(pred, live, "gnss_velocity"):
                return
        if not self.config.use_gnss_velocity:
            return
        model = gnss_velocity(pred, vel, self._arms(s)[0], self._mat_bi)
        if model is None:
            if live:
                self._counters["gnss_velocity"]["rejected"] += 1
            return
        self._update(
            "gnss_velocity",
            self._late_imu(model, np.array(s.accel_lp), _TIME_OFFSET_MIN_ACCEL_M_S2),
            live,
        )

    def _attitude(self, pred: Prediction, att: AttitudeMeasurement, live: bool) -> None:
        s = self._state
        assert s is not None
        mat_nb = self._measured_mat_nb(att)
        if not s.heading_known:
            yaw_variance = float(att.cov_rpy_rad2[2, 2])
            if math.isfinite(yaw_variance) and yaw_variance < UNKNOWN_ANGLE_VARIANCE:
                self._set_heading(float(euler_rad(mat_nb)[2]), yaw_variance)
                if live:
                    self._counters["attitude"]["used"] += 1
            return
        model = attitude(pred, mat_nb, att.cov_rpy_rad2, s.time_offset, s.mounting)
        if model is None:
            if live:
                self._counters["attitude"]["rejected"] += 1
            return
        self._update("attitude", model, live)

    def _measured_mat_nb(self, att: AttitudeMeasurement) -> FloatArray:
        """Base_link FRD -> NED rotation from an attitude measurement and its mounting."""
        q_enu_base = quat_multiply(_quat(att.quat_enu_flu_xyzw), self._q_a_base)
        quat_nb = _quat_enu_flu(q_enu_base)  # the map is its own inverse
        return mat_from_quat(*quat_nb)

    def _zupt(self, pred: Prediction, _: None, live: bool) -> None:
        self._update("zupt", zupt(pred, self.config.zupt_sigma_m_s), live)

    def _zaru(self, pred: Prediction, payload: tuple[FloatArray, float], live: bool) -> None:
        s = self._state
        assert s is not None
        mean_rate_i, span_s = payload
        earth_rate_b = earth_rate_body_rad_s(pred.mat_nb, pred.lat_rad, s.heading_known)
        variance = self._gyro_psd / max(span_s, 1e-3) + self.config.zaru_sigma_rad_s**2
        if not s.heading_known:
            variance = variance + unknown_earth_rate_rad_s(pred.lat_rad) ** 2
        model = zaru(
            pred, mean_rate_i, self._mat_bi.T @ earth_rate_b, np.array(s.gyro_bias), variance
        )
        self._update("zaru", model, live)

    def _nhc(self, pred: Prediction, _: None, live: bool) -> None:
        s = self._state
        assert s is not None
        model = nhc(pred, self._arms(s)[1], self._mat_bi, self.config.nhc_sigma_m_s, s.mounting)
        self._update("nhc", model, live)

    def _arms(self, s: _State) -> tuple[FloatArray, FloatArray]:
        """(antenna, base_link origin) lever arms from the IMU [m] in the engine's body frame:
        the configured arms (vehicle axes) turned by the residual mounting, (I + [μ×]) l."""
        if self.layout.mt is None or s.mounting == (0.0, 0.0):
            return self._antenna_arm_b, self._base_arm_b
        turn = mounting_skew(s.mounting)  # np.cross costs 10x more
        return (
            self._antenna_arm_b + turn @ self._antenna_arm_b,
            self._base_arm_b + turn @ self._base_arm_b,
        )

    def _late_imu(
        self,
        model: Model,
        rate_n: FloatArray,
        min_rate: float,
        second_n: FloatArray | None = None,
    ) -> Model:
        """A GNSS measurement at its epoch t compared with the state at t + t̂_d, the estimated
        residual IMU time offset (the IMU timeline runs late by it): the prediction moves by
        rate·t̂_d (+ second·t̂_d²/2 when the second derivative is given) and H gets the rate
        at t + t̂_d on δt_d (rate, second: first and second time derivative of the measured
        quantity, NED). Below ``min_rate`` the offset is frozen (H stays 0): the rate is then
        mostly noise, and a noisy H would move the estimate without cause."""
        td = self.layout.td
        s = self._state
        if td is None or s is None:
            return model
        z, H, R = model
        rows = len(z)
        offset = s.time_offset
        shift = rate_n[:rows] * offset
        if second_n is not None:
            shift = shift + second_n[:rows] * (0.5 * offset * offset)
            rate_n = rate_n + second_n * offset
        if float(np.linalg.norm(rate_n[:rows])) >= min_rate:
            H[:, td] = rate_n[:rows]
        return z - shift, H, R

    def _too_fast_to_align(self, pred: Prediction, live: bool, kind: str) -> bool:
        """Heading unknown and moving: GNSS updates would need the yaw; count them rejected."""
        if float(np.hypot(pred.vel_ned_m_s[0], pred.vel_ned_m_s[1])) < _ALIGN_MAX_SPEED_M_S:
            return False
        if live:
            self._counters[kind]["rejected"] += 1
        return True

    # ------------------------------------------------------------------- pseudo-measurements

    def _pseudo_epoch(self, t: float, entry: _Entry) -> None:
        """Stop detection, ZUPT/ZARU or NHC, health checks (live, at the pseudo rate)."""
        s, kf = self._state, self._filter
        assert s is not None and kf is not None
        cfg = self.config
        speed = float(np.linalg.norm(s.nav.vel_ned_m_s))
        stationary = self._detector.evaluate(t, self._recent_gnss_speed(t), speed)
        mean_rate = np.array(self._zaru_sum) / max(self._zaru_count, 1)
        span = t - self._zaru_start_s
        self._start_pseudo_interval(t)
        kinds: list[tuple[str, Any]] = []
        if stationary:
            if cfg.use_zupt:
                kinds.append(("zupt", None))
            if cfg.use_zaru:
                kinds.append(("zaru", (mean_rate, span)))
        elif (
            cfg.use_nhc
            and s.heading_known
            and float(np.hypot(*s.nav.vel_ned_m_s[:2])) > cfg.nhc_min_speed_m_s
        ):
            kinds.append(("nhc", None))
        for kind, payload in kinds:
            record: _Record = (t, _RANK[kind], next(self._sequence), kind, payload)
            entry.measurements.append(record)
            self._apply(record, live=True)
        problem = kf.problem()
        nav = s.nav
        if problem is None and not (
            math.isfinite(nav.lat_rad + nav.lon_rad + nav.height_m)
            and np.isfinite(nav.vel_ned_m_s).all()
            and np.isfinite(nav.quat_nb).all()
        ):
            problem = "non-finite navigation state"
        if problem is not None:
            self._reset(problem)

    def _recent_gnss_speed(self, t: float) -> float | None:
        if self._gnss_speed is None or abs(t - self._gnss_speed[0]) > GNSS_SPEED_MAX_AGE_S:
            return None
        return self._gnss_speed[1]

    # ------------------------------------------------------------------------ alignment

    def _align_epoch(self, t: float) -> None:
        """Before the filter runs: stop detection, levelling, and the start when possible."""
        cfg = self.config
        stationary = self._detector.evaluate(t, self._recent_gnss_speed(t), None)
        self._start_pseudo_interval(t)
        if not stationary:
            self._levelling.reset()
        fix = self._last_fix
        if fix is None or abs(t - fix.t_s) > _ALIGN_FIX_MAX_AGE_S:
            return
        if self._levelling.duration_s >= cfg.alignment_duration_s:
            self._start_static(t, fix)
            return
        vel = self._recent(self._last_velocity, t)
        if stationary or vel is None or not self._fast_enough(vel):
            return
        att = self._recent(self._last_attitude, t)
        if att is not None and float(att.cov_rpy_rad2[2, 2]) < UNKNOWN_ANGLE_VARIANCE:
            self._start_moving(t, fix, vel, att)
        elif self.config.use_course_heading:
            self._start_moving(t, fix, vel, None)

    def _fast_enough(self, vel: GnssVelocityMeasurement) -> bool:
        """GNSS speed at or above ``alignment.course_speed`` (course usable, clearly moving)."""
        speed = float(np.hypot(vel.vel_enu_m_s[0], vel.vel_enu_m_s[1]))
        return speed >= self.config.course_speed_m_s

    @staticmethod
    def _recent(meas: _M | None, t: float) -> _M | None:
        return meas if meas is not None and abs(t - meas.t_s) <= _ALIGN_FIX_MAX_AGE_S else None

    def _start_static(self, t: float, fix: GnssFixMeasurement) -> None:
        """Start the filter after levelling on a standstill."""
        noise = self.config.imu_noise
        lev = self._levelling
        force_b = self._mat_bi @ lev.mean_force_i
        roll, pitch = level(force_b)
        self._check_level(roll, pitch)
        att = self._recent(self._last_attitude, t)
        heading_known = att is not None and float(att.cov_rpy_rad2[2, 2]) < UNKNOWN_ANGLE_VARIANCE
        yaw, yaw_variance = 0.0, _UNKNOWN_YAW_VARIANCE
        if heading_known and att is not None:
            yaw = float(euler_rad(self._measured_mat_nb(att))[2])
            yaw_variance = float(att.cov_rpy_rad2[2, 2])
        quat_nb = quat_from_euler(roll, pitch, yaw)
        mat_nb = mat_from_quat(*quat_nb.tolist())
        lat = math.radians(fix.lat_deg)
        gyro_seed = lev.mean_rate_i - self._mat_bi.T @ earth_rate_body_rad_s(
            mat_nb, lat, heading_known
        )
        seed_var = self._gyro_psd / max(lev.duration_s, 1.0) + np.square(
            noise.gyro_bias_instability
        )
        if not heading_known:
            seed_var = seed_var + unknown_earth_rate_rad_s(lat) ** 2
        g = earth.normal_gravity_m_s2(lat, fix.height_m)
        accel_var = self._accel_bias_variance()
        tilt_var = float(accel_var.max()) / g**2
        self._start(
            t,
            fix,
            quat_nb,
            np.zeros(3),
            np.diag([tilt_var, tilt_var, yaw_variance]),
            (float(gyro_seed[0]), float(gyro_seed[1]), float(gyro_seed[2])),
            seed_var,
            np.full(3, self.config.zupt_sigma_m_s**2),
            heading_known,
        )

    def _check_level(self, roll: float, pitch: float) -> None:
        """Warn (once) when the standstill levels the vehicle tilted beyond
        ``_LEVEL_TILT_WARNING_DEG``: the configured mounting, axis map or accelerometer sign
        does not fit this unit (Aalborg notes §12: the IMU400CC's sign is not settled)."""
        tilt = math.degrees(math.acos(max(-1.0, min(1.0, math.cos(roll) * math.cos(pitch)))))
        if tilt <= _LEVEL_TILT_WARNING_DEG:
            return
        mounting = ", ".join(f"{math.degrees(a):.1f}" for a in self.config.imu_mounting_rpy_rad)
        warning = (
            f"static levelling finds the vehicle tilted {tilt:.0f} deg (roll"
            f" {math.degrees(roll):.0f}, pitch {math.degrees(pitch):.0f}) with"
            f" imu_mounting_rpy_deg [{mounting}]: the IMU is mounted otherwise (upside down ="
            " roll 180) or its axis_map/accel_sign is wrong; check with `gnss_ins calibrate axes`"
        )
        if warning not in self._warnings:
            self._warnings = (*self._warnings, warning)

    def _start_moving(
        self,
        t: float,
        fix: GnssFixMeasurement,
        vel: GnssVelocityMeasurement,
        att: AttitudeMeasurement | None,
    ) -> None:
        """Start the filter in motion: attitude from the receiver, or level + course."""
        noise = self.config.imu_noise
        tilt_var = self.config.moving_tilt_sigma_rad**2
        if att is not None:
            roll, pitch, yaw = euler_rad(self._measured_mat_nb(att))
            cov = np.diag(att.cov_rpy_rad2).copy()
            roll_var = float(cov[0]) if cov[0] < UNKNOWN_ANGLE_VARIANCE else tilt_var
            pitch_var = float(cov[1]) if cov[1] < UNKNOWN_ANGLE_VARIANCE else tilt_var
            if roll_var >= tilt_var:
                roll = 0.0
            if pitch_var >= tilt_var:
                pitch = 0.0
            att_var = np.array([roll_var, pitch_var, float(cov[2])])
        else:
            roll = pitch = 0.0
            yaw, yaw_var = self._course(vel)
            att_var = np.array([tilt_var, tilt_var, yaw_var])
        vel_ned = np.nan_to_num(MAT_ENU_NED @ vel.vel_enu_m_s)
        vel_var = _velocity_variance(vel)
        gyro_var = self._turn_on_variance(
            None if self.calibration is None else self.calibration.gyro.bias_sigma,
            noise.gyro_turn_on_bias,
        ) + np.square(noise.gyro_bias_instability)
        self._start(
            t,
            fix,
            quat_from_euler(roll, pitch, yaw),
            vel_ned,
            np.diag(att_var),
            (0.0, 0.0, 0.0),
            gyro_var,
            vel_var,
            True,
        )
        if att is None:
            self._counters["course_heading"]["used"] += 1

    def _start(
        self,
        t: float,
        fix: GnssFixMeasurement,
        quat_nb: FloatArray,
        vel_ned: FloatArray,
        att_cov: FloatArray,
        gyro_bias: Vec3,
        gyro_bias_var: FloatArray,
        vel_var: FloatArray,
        heading_known: bool,
    ) -> None:
        """Create the filter: position from the fix (moved to t with the velocity)."""
        noise = self.config.imu_noise
        nav = NavState(
            math.radians(fix.lat_deg), math.radians(fix.lon_deg), fix.height_m, vel_ned, quat_nb
        )
        state = _State(t, nav, gyro_bias, heading_known)
        self._state = state
        offset = -(state.mat_nb @ self._antenna_arm_b) + vel_ned * (t - fix.t_s)
        self._move(state, offset)
        kf = ErrorStateFilter(self.layout, noise, self.config.gnss_correlation_time_s)
        n = self.layout.size
        P = np.zeros((n, n))
        P[VEL : VEL + 3, VEL : VEL + 3] = np.diag(vel_var)
        P[ATT : ATT + 3, ATT : ATT + 3] = att_cov
        P[BG : BG + 3, BG : BG + 3] = np.diag(gyro_bias_var)
        P[BA : BA + 3, BA : BA + 3] = np.diag(self._accel_bias_variance())
        if self.layout.mt is not None:
            mt = self.layout.mt
            P[mt : mt + 2, mt : mt + 2] = np.eye(2) * self.config.mounting_sigma_rad**2
        if self.layout.td is not None:
            P[self.layout.td, self.layout.td] = self.config.time_offset_sigma_s**2
        if self.layout.sg is not None:
            P[self.layout.sg : self.layout.sg + 3, self.layout.sg : self.layout.sg + 3] = (
                np.eye(3) * noise.gyro_scale_sigma**2
            )
        if self.layout.sa is not None:
            P[self.layout.sa : self.layout.sa + 3, self.layout.sa : self.layout.sa + 3] = (
                np.eye(3) * noise.accel_scale_sigma**2
            )
        kf.P = P
        self._filter = kf
        self._restart_position(fix)
        zero: Vec3 = (0.0, 0.0, 0.0)
        self._history = [_Entry(t, ImuIncrement(0.0, zero, zero), None, None, self._checkpoint())]
        self._history_t = [t]

    def _reported_variance(self, fix: GnssFixMeasurement) -> FloatArray:
        """The receiver's position variance per NED axis, times gnss_position_noise_scale²."""
        return np.diagonal(ned_cov(fix.cov_enu_m2)) * self.config.gnss_position_noise_scale**2

    def _fix_noise(self, fix: GnssFixMeasurement) -> tuple[FloatArray, FloatArray]:
        """(white covariance NED [m²], correlated variance per NED axis [m²]) of a fix.

        The white part is what the data say (core.adaptation.WhiteNoiseMonitor: consecutive
        innovations), at least ``gnss_noise.white_sigma``² or ``gnss_noise.white_fraction`` of
        the receiver's variance, at most that variance; before the data say anything, the
        floor. The rest is the time-correlated error. A receiver whose epochs scatter more than
        it reports gets its whole covariance scaled up to the measured white part (at most
        ``_MAX_GNSS_INFLATION`` times). Correlations between axes are kept.
        """
        total = ned_cov(fix.cov_enu_m2) * self.config.gnss_position_noise_scale**2
        variance = np.diagonal(total)
        assert self._state is not None
        share = self._state.gnss_white.share
        measured = None if share is None else share * variance
        if self.layout.gp is None:  # all white: no correlated error states
            white = variance
        else:
            floor = np.maximum(self._gnss_white_var_ned, self.config.gnss_white_fraction * variance)
            white = np.minimum(variance, floor)
        if measured is not None:
            white = np.minimum(np.maximum(white, measured), _MAX_GNSS_INFLATION * variance)
        scale = np.sqrt(white / np.maximum(variance, 1e-30))
        return total * np.outer(scale, scale), np.maximum(variance - white, 0.0)

    def _restart_position(self, fix: GnssFixMeasurement) -> None:
        """Position error (and correlated GNSS error) as after taking the position from a fix:
        δp = -(white + correlated error of the fix)."""
        kf = self._filter
        assert kf is not None
        white, correlated = self._fix_noise(fix)
        P = kf.P.copy()
        _restart_block(P, POS, white + np.diag(correlated))
        kf.P = P
        if self.layout.gp is not None:
            self._restart_gnss_error(fix, correlated)
            P = kf.P.copy()
            gp = self.layout.gp
            P[POS : POS + 3, gp : gp + 3] = P[gp : gp + 3, POS : POS + 3] = -np.diag(correlated)
            kf.P = P

    def _restart_gnss_error(self, fix: GnssFixMeasurement, correlated: FloatArray) -> None:
        """A new correlated GNSS error process (start, or the receiver's σ jumped: another fix
        type, e.g. RTK float after an outage): uncorrelated, at its stationary variance."""
        s, kf = self._state, self._filter
        assert s is not None and kf is not None and self.layout.gp is not None
        P_before = kf.P
        P = kf.P.copy()
        _restart_block(P, self.layout.gp, np.diag(correlated))
        kf.P = P
        reported = self._reported_variance(fix)
        s.gnss_reported = (float(reported[0]), float(reported[1]), float(reported[2]))
        s.gnss_error = (0.0, 0.0, 0.0)
        self._set_gnss_variance(correlated)
        if self.recorder is not None:  # smoother hook: the GNSS error states restart
            self.recorder.on_restart(P_before, kf.P, range(self.layout.gp, self.layout.gp + 3))

    def _set_gnss_variance(self, correlated: FloatArray) -> None:
        """Stationary variance of the correlated GNSS error process per NED axis [m²]."""
        s, kf = self._state, self._filter
        assert s is not None and kf is not None
        s.gnss_variance = (float(correlated[0]), float(correlated[1]), float(correlated[2]))
        kf.gnss_variance = s.gnss_variance

    def _accel_bias_variance(self) -> FloatArray:
        noise = self.config.imu_noise
        return self._turn_on_variance(
            None if self.calibration is None else self.calibration.accel.bias_sigma,
            noise.accel_turn_on_bias,
        ) + np.square(noise.accel_bias_instability)

    @staticmethod
    def _turn_on_variance(calibrated_sigma: Vec3 | None, default_sigma: float) -> FloatArray:
        """Variance of the bias left after calibration (its σ) or of the datasheet bias."""
        if calibrated_sigma is None:
            return np.full(3, default_sigma**2)
        return np.square(calibrated_sigma)

    def _course(self, vel: GnssVelocityMeasurement) -> tuple[float, float]:
        """Heading [rad] and its variance from the GNSS course (NTNU notes §8)."""
        east, north = float(vel.vel_enu_m_s[0]), float(vel.vel_enu_m_s[1])
        speed_sq = east * east + north * north
        sigma_sq = 0.5 * float(vel.cov_enu_m2_s2[0, 0] + vel.cov_enu_m2_s2[1, 1])
        return math.atan2(east, north), sigma_sq / speed_sq + _COURSE_EXTRA_VARIANCE

    def _heading_from_course(self, vel: GnssVelocityMeasurement, live: bool) -> None:
        """Heading unknown and fast enough: heading from the course; position and velocity
        restart from the latest fix and this velocity (the INS ran with the wrong heading)."""
        s, kf = self._state, self._filter
        fix = self._last_fix
        assert s is not None and kf is not None
        if fix is None or abs(fix.t_s - vel.t_s) > _ALIGN_FIX_MAX_AGE_S:
            return
        yaw, yaw_var = self._course(vel)
        self._set_heading(yaw, yaw_var)
        vel_ned = np.nan_to_num(MAT_ENU_NED @ vel.vel_enu_m_s)
        nav = s.nav
        fix_nav = NavState(
            math.radians(fix.lat_deg), math.radians(fix.lon_deg), fix.height_m, vel_ned, nav.quat_nb
        )
        s.set_nav(fix_nav)
        self._move(s, -(s.mat_nb @ self._antenna_arm_b) + vel_ned * (s.t_s - fix.t_s))
        P = kf.P.copy()
        _restart_block(P, VEL, np.diag(_velocity_variance(vel)))
        kf.P = P
        self._restart_position(fix)
        s.last_position_t_s = s.t_s
        if live:
            self._counters["course_heading"]["used"] += 1

    def _set_heading(self, yaw: float, yaw_variance: float) -> None:
        """Turn the attitude about the vertical to ``yaw`` keeping the antenna position; the
        heading is known from now on."""
        s, kf = self._state, self._filter
        assert s is not None and kf is not None
        if self.recorder is not None:  # smoother hook: the heading is set, not estimated
            self.recorder.on_break(kf.P)
        turn = float(wrap_angle(np.array(yaw - euler_rad(s.mat_nb)[2])))
        nav = s.nav
        antenna_n = s.mat_nb @ self._antenna_arm_b
        q_turn = quat_from_rotvec(0.0, 0.0, turn)
        quat = quat_normalize(quat_multiply(q_turn, _quat(nav.quat_nb)))
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
        self._move(s, antenna_n - s.mat_nb @ self._antenna_arm_b)
        P = kf.P.copy()
        P[ATT + 2, :] = 0.0
        P[:, ATT + 2] = 0.0
        P[ATT + 2, ATT + 2] = yaw_variance
        kf.P = P
        s.heading_known = True
        s.last_position_t_s = s.t_s

    @staticmethod
    def _move(state: _State, offset_ned_m: FloatArray) -> None:
        """Shift the nominal position by a NED offset [m]."""
        nav = state.nav
        r_m, r_n = earth.radii_m(nav.lat_rad)
        state.set_nav(
            NavState(
                nav.lat_rad + float(offset_ned_m[0]) / (r_m + nav.height_m),
                nav.lon_rad
                + float(offset_ned_m[1]) / ((r_n + nav.height_m) * math.cos(nav.lat_rad)),
                nav.height_m - float(offset_ned_m[2]),
                nav.vel_ned_m_s,
                nav.quat_nb,
            )
        )

    def _state_name(self) -> str:
        s = self._state
        if s is None or not s.heading_known:
            return "aligning"
        if s.t_s - s.last_position_t_s > self.config.degraded_after_s:
            return "degraded"
        return "navigating"


def _restart_block(P: FloatArray, start: int, block: FloatArray) -> None:
    """Set a 3x3 diagonal block of P and clear its correlations (in place on a copy)."""
    P[start : start + 3, :] = 0.0
    P[:, start : start + 3] = 0.0
    P[start : start + 3, start : start + 3] = block


def _velocity_variance(vel: GnssVelocityMeasurement) -> FloatArray:
    """Per NED axis variance of a GNSS velocity, unknown components capped at 1 m²/s²."""
    return np.minimum(np.nan_to_num(np.diagonal(ned_cov(vel.cov_enu_m2_s2)), nan=1.0), 1.0)


def _add3(values: Vec3, dx: list[float], start: int) -> Vec3:
    return (values[0] + dx[start], values[1] + dx[start + 1], values[2] + dx[start + 2])
