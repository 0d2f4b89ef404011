"""Start of the filter: from a levelled standstill, or from a vehicle already moving.

Levelling (core.nav.levelling) averages ``alignment.duration`` seconds of a detected standstill for
roll, pitch and the gyro-bias seed; the heading comes from the attitude receiver, or stays
unknown (yaw error kept out of the filter) until the GNSS course gives it. A vehicle that is
already moving starts from attitude or course with roll = pitch = 0 ± the
``alignment.moving_tilt_sigma``. The position comes from the latest fix, moved to the start
with the velocity. Frames: NED, base_link FRD; variances in SI units.
"""

from __future__ import annotations

import math
from typing import TypeVar

import numpy as np

from gnss_ins_common.types import FloatArray, Vec3
from ins_fusion.core.filter.eskf import (
    ATT,
    BA,
    BG,
    VEL,
    ErrorStateFilter,
    StateLayout,
    gyro_asymmetry_sigma,
    gyro_misalignment_variance,
)
from ins_fusion.core.filter.records import (
    AttitudeMeasurement,
    GnssFixMeasurement,
    GnssVelocityMeasurement,
)
from ins_fusion.core.filter.state import UNKNOWN_YAW_VARIANCE, FilterState, Geometry, LatestInputs
from ins_fusion.core.filter.status import Counters
from ins_fusion.core.measurements.common import UNKNOWN_ANGLE_VARIANCE
from ins_fusion.core.measurements.gnss_noise import GnssNoise
from ins_fusion.core.measurements.gnss_velocity import COURSE_HEADING
from ins_fusion.core.measurements.heading import (
    ALIGN_FIX_MAX_AGE_S,
    course,
    fast_enough,
    velocity_variance,
)
from ins_fusion.core.nav import earth
from ins_fusion.core.nav.calibration import ImuCalibration
from ins_fusion.core.nav.levelling import (
    Levelling,
    earth_rate_body_rad_s,
    level,
    unknown_earth_rate_rad_s,
)
from ins_fusion.core.nav.rotation import MAT_ENU_NED, euler_rad, mat_from_quat, quat_from_euler
from ins_fusion.core.nav.strapdown import NavState
from ins_fusion.core.settings.config import FusionConfig

#: A vehicle levelled on a standstill tilted more than this [deg] (roads: < 12°) means the IMU is
#: mounted otherwise than imu_mounting_rpy_deg says, or its axis map or accelerometer sign is
#: wrong (an upside-down unit levels at roll 180°): ``Startup.warnings`` says so.
_LEVEL_TILT_WARNING_DEG = 30.0

Started = tuple[FilterState, ErrorStateFilter]
"""The first nominal state and the filter with its initial covariance."""


class Startup:
    """Decides when and how the filter starts (see the module docstring). ``levelling`` is fed
    the standstill samples by the engine; ``warnings`` collects set-up problems, each once."""

    def __init__(
        self,
        config: FusionConfig,
        calibration: ImuCalibration | None,
        geometry: Geometry,
        gnss_noise: GnssNoise,
        layout: StateLayout,
        counters: Counters,
        latest: LatestInputs,
    ) -> None:
        self._config = config
        self._calibration = calibration
        self._geometry = geometry
        self._gnss_noise = gnss_noise
        self._layout = layout
        self._counters = counters
        self._latest = latest
        self._gyro_psd = config.imu_noise.gyro_psd
        self.levelling = Levelling()
        self.warnings: tuple[str, ...] = ()

    def try_start(self, t: float, stationary: bool) -> Started | None:
        """At an alignment epoch t [s]: the started filter, or None while it cannot start."""
        latest = self._latest
        fix = latest.fix
        if fix is None or abs(t - fix.t_s) > ALIGN_FIX_MAX_AGE_S:
            return None
        if self.levelling.duration_s >= self._config.alignment_duration_s:
            return self._start_static(t, fix)
        vel = _recent(latest.velocity, t)
        if stationary or vel is None or not fast_enough(vel, self._config.course_speed_m_s):
            return None
        att = _recent(latest.attitude, t)
        if att is not None and float(att.cov_rpy_rad2[2, 2]) < UNKNOWN_ANGLE_VARIANCE:
            return self._start_moving(t, fix, vel, att)
        if self._config.use_course_heading:
            return self._start_moving(t, fix, vel, None)
        return None

    def waiting_for(self, t: float, stationary: bool, started: bool) -> str:
        """What the alignment waits for at IMU time t [s] (the reason of the state
        'aligning'): a fix, the standstill's levelling, or, ``started``, the heading."""
        course = f"the GNSS course above {self._config.course_speed_m_s:g} m/s"
        if started:
            return f"heading unknown: waiting for the attitude receiver or {course}"
        fix = self._latest.fix
        if fix is None:
            return "no GNSS fix yet"
        if abs(t - fix.t_s) > ALIGN_FIX_MAX_AGE_S:
            return f"last GNSS fix {abs(t - fix.t_s):.1f} s old (at most {ALIGN_FIX_MAX_AGE_S:g} s)"
        needed_s = self._config.alignment_duration_s
        if stationary:
            return f"levelling at rest, {self.levelling.duration_s:.0f} of {needed_s:.0f} s"
        return (
            f"moving before {needed_s:.0f} s at rest: waiting for a standstill, or a heading "
            f"from the attitude receiver or {course}"
        )

    def _start_static(self, t: float, fix: GnssFixMeasurement) -> Started:
        """Start the filter after levelling on a standstill."""
        noise = self._config.imu_noise
        lev = self.levelling
        mat_bi = self._geometry.mat_bi
        force_b = mat_bi @ lev.mean_force_i
        roll, pitch = level(force_b)
        self._check_level(roll, pitch)
        att = _recent(self._latest.attitude, t)
        heading_known = att is not None and float(att.cov_rpy_rad2[2, 2]) < UNKNOWN_ANGLE_VARIANCE
        yaw, yaw_variance = 0.0, UNKNOWN_YAW_VARIANCE
        if heading_known and att is not None:
            yaw = float(euler_rad(self._geometry.measured_mat_nb(att))[2])
            yaw_variance = float(att.cov_rpy_rad2[2, 2])
        quat_nb = quat_from_euler(roll, pitch, yaw)
        mat_nb = mat_from_quat(*quat_nb.tolist())
        lat = math.radians(fix.lat_deg)
        gyro_seed = lev.mean_rate_i - mat_bi.T @ earth_rate_body_rad_s(mat_nb, lat, heading_known)
        seed_var = self._gyro_psd / max(lev.duration_s, 1.0) + np.square(
            noise.gyro_bias_instability
        )
        if not heading_known:
            seed_var = seed_var + unknown_earth_rate_rad_s(lat) ** 2
        g = earth.normal_gravity_m_s2(lat, fix.height_m)
        accel_var = self._accel_bias_variance()
        tilt_var = float(accel_var.max()) / g**2
        return self._start(
            (t, fix, heading_known),
            (quat_nb, np.diag([tilt_var, tilt_var, yaw_variance])),
            (np.zeros(3), np.full(3, self._config.zupt_sigma_m_s**2)),
            ((float(gyro_seed[0]), float(gyro_seed[1]), float(gyro_seed[2])), seed_var),
        )

    def _check_level(self, roll: float, pitch: float) -> None:
        """Warn (once) when the standstill levels the vehicle tilted beyond
        ``_LEVEL_TILT_WARNING_DEG``: the configured mounting, axis map or accelerometer sign
        does not fit this unit (Aalborg notes §12: the IMU400CC's sign is not settled)."""
        tilt = math.degrees(math.acos(max(-1.0, min(1.0, math.cos(roll) * math.cos(pitch)))))
        if tilt <= _LEVEL_TILT_WARNING_DEG:
            return
        mounting = ", ".join(f"{math.degrees(a):.1f}" for a in self._config.imu_mounting_rpy_rad)
        warning = (
            f"static levelling finds the vehicle tilted {tilt:.0f} deg (roll"
            f" {math.degrees(roll):.0f}, pitch {math.degrees(pitch):.0f}) with"
            f" imu_mounting_rpy_deg [{mounting}]: the IMU is mounted otherwise (upside down ="
            " roll 180) or its axis_map/accel_sign is wrong; check with `gnss_ins calibrate axes`"
        )
        if warning not in self.warnings:
            self.warnings = (*self.warnings, warning)

    def _start_moving(
        self,
        t: float,
        fix: GnssFixMeasurement,
        vel: GnssVelocityMeasurement,
        att: AttitudeMeasurement | None,
    ) -> Started:
        """Start the filter in motion: attitude from the receiver, or level + course."""
        tilt_var = self._config.moving_tilt_sigma_rad**2
        if att is not None:
            roll, pitch, yaw = euler_rad(self._geometry.measured_mat_nb(att))
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
            yaw, yaw_var = course(vel)
            att_var = np.array([tilt_var, tilt_var, yaw_var])
        vel_ned = np.nan_to_num(MAT_ENU_NED @ vel.vel_enu_m_s)
        gyro_var = self._gyro_bias_variance()
        started = self._start(
            (t, fix, True),
            (quat_from_euler(roll, pitch, yaw), np.diag(att_var)),
            (vel_ned, velocity_variance(vel)),
            ((0.0, 0.0, 0.0), gyro_var),
        )
        if att is None:
            self._counters[COURSE_HEADING.name]["used"] += 1
        return started

    def _start(
        self,
        start: tuple[float, GnssFixMeasurement, bool],
        attitude: tuple[FloatArray, FloatArray],
        velocity: tuple[FloatArray, FloatArray],
        gyro: tuple[Vec3, FloatArray],
    ) -> Started:
        """Create the filter at ``start`` = (t [s], the fix, whether the heading is known):
        position from the fix (moved to t with the velocity), ``attitude`` = (body -> NED
        quaternion, its 3x3 covariance [rad²]), ``velocity`` = (NED [m/s], variances [m²/s²]),
        ``gyro`` = (bias seed [rad/s], imu FRD, variances)."""
        t, fix, heading_known = start
        quat_nb, att_cov = attitude
        vel_ned, vel_var = velocity
        gyro_bias, gyro_bias_var = gyro
        config = self._config
        noise = config.imu_noise
        nav = NavState(
            math.radians(fix.lat_deg), math.radians(fix.lon_deg), fix.height_m, vel_ned, quat_nb
        )
        state = FilterState(t, nav, gyro_bias, heading_known)
        state.move(-(state.mat_nb @ self._geometry.antenna_arm_b) + vel_ned * (t - fix.t_s))
        layout = self._layout
        calibration = None if self._calibration is None else self._calibration.gyro
        asymmetry_sigma = gyro_asymmetry_sigma(noise, calibration)
        kf = ErrorStateFilter(
            layout,
            noise,
            config.gnss_correlation_time_s,
            gyro_misalignment_variance(noise, calibration),
            asymmetry_sigma,
        )
        n = layout.size
        P = np.zeros((n, n))
        P[VEL : VEL + 3, VEL : VEL + 3] = np.diag(vel_var)
        P[ATT : ATT + 3, ATT : ATT + 3] = att_cov
        P[BG : BG + 3, BG : BG + 3] = np.diag(gyro_bias_var)
        P[BA : BA + 3, BA : BA + 3] = np.diag(self._accel_bias_variance())
        if layout.mt is not None:
            mt = layout.mt
            P[mt : mt + 2, mt : mt + 2] = np.eye(2) * config.mounting_sigma_rad**2
        if layout.td is not None:
            P[layout.td, layout.td] = config.time_offset_sigma_s**2
        if layout.ks is not None:
            P[layout.ks, layout.ks] = config.speed_scale_sigma**2
        if layout.sg is not None:
            P[layout.sg : layout.sg + 3, layout.sg : layout.sg + 3] = (
                np.eye(3) * noise.gyro_scale_sigma**2
            )
        if layout.sa is not None:
            P[layout.sa : layout.sa + 3, layout.sa : layout.sa + 3] = (
                np.eye(3) * noise.accel_scale_sigma**2
            )
        if layout.sr is not None:
            P[layout.sr : layout.sr + 3, layout.sr : layout.sr + 3] = np.diag(
                np.square(asymmetry_sigma)
            )
        kf.P = P
        kf.variance_ceiling = self._variance_ceiling(np.diagonal(P))
        self._gnss_noise.restart_position(state, kf, fix)
        return state, kf

    def _variance_ceiling(self, initial: FloatArray) -> FloatArray:
        """Largest variance of each error state (ErrorStateFilter.variance_ceiling) from the
        initial covariance's diagonal, which holds the priors (datasheet or calibration) of the
        accelerometer biases, scale factors, mounting and time offset: the gyro biases their
        prior too (the start's variance if larger: a levelled start measured them), the attitude
        an unknown angle's; none for position, velocity and the correlated GNSS error."""
        ceiling = initial.copy()
        ceiling[:ATT] = math.inf
        ceiling[ATT : ATT + 3] = np.maximum(ceiling[ATT : ATT + 3], UNKNOWN_YAW_VARIANCE)
        ceiling[BG : BG + 3] = np.maximum(ceiling[BG : BG + 3], self._gyro_bias_variance())
        gp = self._layout.gp
        if gp is not None:
            ceiling[gp : gp + 3] = math.inf
        return ceiling

    def _gyro_bias_variance(self) -> FloatArray:
        noise = self._config.imu_noise
        return _turn_on_variance(
            None if self._calibration is None else self._calibration.gyro.bias_sigma,
            noise.gyro_turn_on_bias,
        ) + np.square(noise.gyro_bias_instability)

    def _accel_bias_variance(self) -> FloatArray:
        noise = self._config.imu_noise
        return _turn_on_variance(
            None if self._calibration is None else self._calibration.accel.bias_sigma,
            noise.accel_turn_on_bias,
        ) + np.square(noise.accel_bias_instability)


_M = TypeVar("_M", AttitudeMeasurement, GnssVelocityMeasurement)


def _recent(meas: _M | None, t: float) -> _M | None:
    return meas if meas is not None and abs(t - meas.t_s) <= ALIGN_FIX_MAX_AGE_S else None


def _turn_on_variance(calibrated_sigma: Vec3 | None, default_sigma: float) -> FloatArray:
    """Variance of the bias left after calibration (its σ) or of the datasheet bias."""
    if calibrated_sigma is None:
        return np.full(3, default_sigma**2)
    return np.square(calibrated_sigma)
