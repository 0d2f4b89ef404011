"""Measurement updates of the engine: the gated update with its recovery, and one handler per
measurement kind (GNSS position and velocity, attitude, ZUPT, ZARU, NHC) that builds the model
(core.measurements.models), corrects for the estimated IMU time offset and feeds the estimate back.

Every handler takes the current nominal state, the filter, the prediction to the measurement's
stamp, the payload and ``live`` (first application: counted; a re-propagation is not).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from gnss_ins_common.types import FloatArray
from ins_fusion.core.filter.adaptation import adapt_process_noise, fading_factor
from ins_fusion.core.filter.eskf import ATT, POS, VEL, ErrorStateFilter
from ins_fusion.core.filter.records import (
    AttitudeMeasurement,
    GnssFixMeasurement,
    GnssVelocityMeasurement,
    Prediction,
)
from ins_fusion.core.filter.state import X_BG, FilterState, Geometry, LatestInputs, inject
from ins_fusion.core.filter.status import Counters
from ins_fusion.core.filter.update_algebra import chi2_threshold, projected_variance
from ins_fusion.core.measurements.gnss_noise import NOISE_MOVED, NOISE_RESTART, GnssNoise
from ins_fusion.core.measurements.heading import fast_enough, heading_from_course, set_heading
from ins_fusion.core.measurements.models import (
    UNKNOWN_ANGLE_VARIANCE,
    Model,
    attitude,
    gnss_position,
    gnss_velocity,
    nhc,
    zaru,
    zupt,
)
from ins_fusion.core.nav.levelling import unknown_earth_rate_rad_s
from ins_fusion.core.nav.rotation import euler_rad, skew
from ins_fusion.core.settings.config import FusionConfig

#: The measurements whose normalised innovations scale the IMU process noise (adaptation.py).
_ADAPTING_KINDS = frozenset({"gnss_position", "gnss_velocity"})
#: The error states a gate recovery widens, per sensor measurement (Corrections.update); the
#: pseudo-measurements (ZUPT, ZARU, NHC) are constraints a real vehicle can break (a skid),
#: so their rejections stay rejections.
_RECOVERY_BLOCKS = {"gnss_position": POS, "gnss_velocity": VEL, "attitude": ATT}
#: While the heading is unknown, GNSS updates are applied only below this speed [m/s].
_ALIGN_MAX_SPEED_M_S = 1.0
#: The time offset is observed only above these rates of the measured quantity: speed [m/s]
#: for positions, acceleration [m/s²] for velocities (core.measurements.models for attitude).
_TIME_OFFSET_MIN_SPEED_M_S = 1.0
_TIME_OFFSET_MIN_ACCEL_M_S2 = 0.3

Handler = Callable[[FilterState, ErrorStateFilter, Prediction, Any, bool], None]


class Corrections:
    """The measurement updates (see the module docstring). ``counters`` and ``nis`` are the
    engine's (updated in place); ``fading`` is the last gate recovery's factor (1 = none)."""

    def __init__(
        self,
        config: FusionConfig,
        geometry: Geometry,
        gnss_noise: GnssNoise,
        counters: Counters,
        latest: LatestInputs,
    ) -> None:
        self._config = config
        self._geometry = geometry
        self._gnss_noise = gnss_noise
        self._counters = counters
        self._latest = latest
        self._gates = {dof: chi2_threshold(config.gate_probability, dof) for dof in (1, 2, 3)}
        self._gyro_psd = config.imu_noise.gyro_psd
        self.nis = dict.fromkeys(counters, math.nan)
        self.fading = 1.0
        self.handlers: dict[str, Handler] = {
            "gnss_position": self._gnss_position,
            "gnss_velocity": self._gnss_velocity,
            "attitude": self._attitude,
            "zupt": self._zupt,
            "zaru": self._zaru,
            "nhc": self._nhc,
        }

    def update(
        self, s: FilterState, kf: ErrorStateFilter, kind: str, model: Model, live: bool
    ) -> FloatArray | None:
        """Gated update; inject the estimate into the nominal state and return it (None:
        rejected)."""
        z, H, R = model
        if not s.heading_known:
            H = H.copy()
            H[:, ATT + 2] = 0.0
        result = kf.update(z, H, R, self._gates[len(z)])
        nis = result.nis  # booked as first tested, also when a recovery follows
        gated = not result.accepted and math.isfinite(nis)
        recover = self._config.gate_recovery_count
        block = _RECOVERY_BLOCKS.get(kind)
        if kind == "gnss_position" and not s.gnss_white.ready:
            block = None  # the receiver's noise is not learnt yet: it, not the state, may be off
        recovered = False
        if gated and recover and block is not None and s.gated_runs.get(kind, 0) + 1 >= recover:
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
                self.fading = factor
            else:
                kf.widen(z, H, R, block)
            if kf.recorder is not None:  # smoother hook: the recovery's noise
                kf.recorder.on_noise(P_before, kf.P)
            result = kf.update(z, H, R, math.inf)
            recovered = True
        self.book(s, kind, (result.accepted, nis), len(z), live, recovered)
        if result.dx is not None:
            inject(s, kf, result.dx)
        return result.dx

    def gate(self, dof: int) -> float:
        """The gate on the NIS of a measurement of ``dof`` rows."""
        return self._gates[dof]

    def book(
        self,
        s: FilterState,
        kind: str,
        outcome: tuple[bool, float],
        rows: int,
        live: bool,
        recovered: bool = False,
    ) -> None:
        """The books of an update of ``kind`` with ``rows`` rows, made by ``update`` or by a
        compiled update (core.measurements: no gate recovery there): its NIS (``outcome``:
        accepted, NIS as first tested), the process-noise adaptation of a GNSS update, the runs
        of gated updates in ``s`` and, ``live``, its counters (``recovered``: a gate recovery
        admitted it)."""
        accepted, nis = outcome
        self.nis[kind] = nis
        if kind in _ADAPTING_KINDS and math.isfinite(nis):
            s.nis_mean, s.q_scale = adapt_process_noise(s.nis_mean, s.q_scale, nis / rows)
        gated = not (accepted or recovered) and math.isfinite(nis)
        runs = s.gated_runs
        if gated or runs.get(kind, 0):
            s.gated_runs = {**runs, kind: runs.get(kind, 0) + 1 if gated else 0}
        if live:
            counters = self._counters[kind]
            if recovered:
                counters["recoveries"] += 1
            if accepted:
                counters["used"] += 1
            else:
                counters["rejected"] += 1
                counters["gated"] += 1

    def reject(self, kind: str, live: bool) -> None:
        """A measurement of ``kind`` not used: counted rejected when ``live``."""
        if live:
            self._counters[kind]["rejected"] += 1

    def _gnss_position(
        self,
        s: FilterState,
        kf: ErrorStateFilter,
        pred: Prediction,
        fix: GnssFixMeasurement,
        live: bool,
    ) -> None:
        if not (fix.valid and np.isfinite(fix.cov_enu_m2).all()):
            self.reject("gnss_position", live)
            return
        if not s.heading_known and self.too_fast_to_align(pred, live, "gnss_position"):
            return
        noise = self._gnss_noise
        white, correlated, reported, action = noise.position_noise(s, fix)
        if action == NOISE_RESTART:
            noise.restart_error(s, kf, correlated, reported)
        elif action == NOISE_MOVED:  # the white/correlated split moved
            noise.set_correlated_variance(s, kf, correlated)
        antenna_b = self._geometry.arms(s)[0]
        model = gnss_position(pred, fix, antenna_b, white, s.gnss_error)
        if kf.layout.td is not None:
            antenna_rate_n = pred.vel_ned_m_s + pred.mat_nb @ (skew(s.rate_lp) @ antenna_b)
            model = _late_imu(
                s, kf, model, antenna_rate_n, _TIME_OFFSET_MIN_SPEED_M_S, np.array(s.accel_lp)
            )
        z, H, _ = model
        predicted = projected_variance(H, kf.P)
        dx = self.update(s, kf, "gnss_position", model, live)
        s.gnss_white = s.gnss_white.pushed_fix(fix.t_s, z, H, dx, kf.P, predicted, reported)
        if dx is not None:
            s.last_position_t_s = max(s.last_position_t_s, fix.t_s)

    def _gnss_velocity(
        self,
        s: FilterState,
        kf: ErrorStateFilter,
        pred: Prediction,
        vel: GnssVelocityMeasurement,
        live: bool,
    ) -> None:
        config = self._config
        if not s.heading_known:
            if config.use_course_heading and fast_enough(vel, config.course_speed_m_s):
                applied = heading_from_course(
                    s, kf, self._geometry, self._gnss_noise, self._latest.fix, vel
                )
                if applied and live:
                    self._counters["course_heading"]["used"] += 1
                return
            if self.too_fast_to_align(pred, live, "gnss_velocity"):
                return
        if not config.use_gnss_velocity:
            return
        geometry = self._geometry
        model = gnss_velocity(pred, vel, geometry.arms(s)[0], geometry.mat_bi)
        if model is None:
            self.reject("gnss_velocity", live)
            return
        if kf.layout.td is not None:
            model = _late_imu(s, kf, model, np.array(s.accel_lp), _TIME_OFFSET_MIN_ACCEL_M_S2)
        self.update(s, kf, "gnss_velocity", model, live)

    def _attitude(
        self,
        s: FilterState,
        kf: ErrorStateFilter,
        pred: Prediction,
        att: AttitudeMeasurement,
        live: bool,
    ) -> None:
        mat_nb = self._geometry.measured_mat_nb(att)
        if not s.heading_known:
            yaw_variance = float(att.cov_rpy_rad2[2, 2])
            if math.isfinite(yaw_variance) and yaw_variance < UNKNOWN_ANGLE_VARIANCE:
                set_heading(s, kf, self._geometry, float(euler_rad(mat_nb)[2]), yaw_variance)
                if live:
                    self._counters["attitude"]["used"] += 1
            return
        model = attitude(pred, mat_nb, att.cov_rpy_rad2, s.time_offset, s.mounting)
        if model is None:
            self.reject("attitude", live)
            return
        self.update(s, kf, "attitude", model, live)

    def _zupt(
        self, s: FilterState, kf: ErrorStateFilter, pred: Prediction, _: None, live: bool
    ) -> None:
        self.update(s, kf, "zupt", zupt(pred, self._config.zupt_sigma_m_s), live)

    def _zaru(
        self,
        s: FilterState,
        kf: ErrorStateFilter,
        pred: Prediction,
        payload: tuple[FloatArray, float],
        live: bool,
    ) -> None:
        mean_rate_i, span_s = payload
        variance = self.zaru_variance(span_s)
        if not s.heading_known:
            variance = variance + unknown_earth_rate_rad_s(pred.lat_rad) ** 2
        rates_i = (mean_rate_i, s.x[X_BG : X_BG + 3])
        model = zaru(pred, rates_i, self._geometry.mat_bi, variance, s.heading_known)
        self.update(s, kf, "zaru", model, live)

    def zaru_variance(self, span_s: float) -> FloatArray:
        """The variances [rad²/s²] of a ZARU over ``span_s`` [s] at rest with the heading known:
        the gyro's white noise averaged over it and the configured σ."""
        return self._gyro_psd / max(span_s, 1e-3) + self._config.zaru_sigma_rad_s**2

    def _nhc(
        self, s: FilterState, kf: ErrorStateFilter, pred: Prediction, _: None, live: bool
    ) -> None:
        geometry = self._geometry
        model = nhc(
            pred, geometry.arms(s)[1], geometry.mat_bi, self._config.nhc_sigma_m_s, s.mounting
        )
        self.update(s, kf, "nhc", model, live)

    def too_fast_to_align(self, pred: Prediction, live: bool, kind: str) -> bool:
        """Heading unknown and moving: GNSS updates would need the yaw; count them rejected."""
        if float(np.hypot(pred.vel_ned_m_s[0], pred.vel_ned_m_s[1])) < _ALIGN_MAX_SPEED_M_S:
            return False
        self.reject(kind, live)
        return True


def _late_imu(
    s: FilterState,
    kf: ErrorStateFilter,
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
    mostly noise, and a noisy H would move the estimate without cause. Only with the time
    offset state."""
    td = kf.layout.td
    assert td is not None
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
