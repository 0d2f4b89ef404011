"""GNSS-aided INS engine: the pure fusion core behind ins_fusion_node and ``gnss_ins replay``.

Feed it IMU samples and GNSS/attitude measurements in arrival order; ask for ``solution()`` and
``status()``. It knows nothing of ROS, files or clocks: every time is a message stamp [s].

Pipeline per IMU sample (imu_link FLU, SI, REP-145): calibration (core.nav.calibration, Aalborg
notes (9.1)/(9.2)) -> FRD -> increments (strapdown.SampleIntegrator, interval from the stamps) ->
filter bias/scale correction, mounting rotation imu_link -> base_link and strapdown mechanization
of the IMU point with base_link axes (core.filter.propagation) -> covariance propagation
(core.filter.eskf) -> pseudo-measurements (ZUPT, ZARU, NHC) at ``pseudo_measurement_rate``. An
ordinary sample's part up to the strapdown step (with the stop detector's and noise monitor's
stores) is one compiled call (core.engine.intake); starts, restarts and gaps come back to Python.

Measurements at their own stamps (core.filter.timeline): every IMU sample leaves a history entry
(its increment and a checkpoint of the state after it) for ``history_s`` seconds. A measurement
stamped t_m is applied at the last entry at or before t_m, with the prediction carried from that
entry to t_m by the entry's velocity, acceleration and body rate (less than one IMU interval: the
neglected terms are below 0.1 mm and 1e-5 rad at car dynamics). If later entries exist, the
engine rolls back to that entry's checkpoint, applies the entry's measurements in stamp order and
re-propagates the later samples with their own measurements, once, before the next IMU sample or
output (a fix and its velocity share one re-propagation). Re-propagation (rather than carrying
the correction forward with a transition matrix) is exact for any delay; it costs one strapdown
step per replayed sample, i.e. the latency times 134 samples per epoch: 7 for the Leica's
0.053 s, about 7 % of the samples (measured in bench/bench_fusion_engine.py). Measurements newer
than the latest IMU sample wait for it. Duplicates (same kind and stamp) are ignored and counted;
measurements older than the history are rejected and counted as ``too_old``; a backwards IMU
stamp resets the engine.

Updates (the gate core.measurements.gate; each kind's model and handler in its module of
core.measurements; GNSS noise split core.measurements.gnss_noise) and adaptation
(core.filter.adaptation, docs/fusion.md): the IMU white noise is measured from the samples and
raises the process noise above the user's densities; the GNSS white share is measured from
consecutive innovations; the GNSS normalised innovations scale the process noise while they stay too
large; a gate recovery fades the whole covariance. Optional error states estimate the residual
IMU-to-vehicle mounting (pitch, yaw; with the NHC) and the IMU time offset (``imu_time_offset`` is
taken off every IMU stamp).

Alignment and states (core.engine.startup, core.measurements.heading): 'aligning' while levelling on
a standstill (no solution yet) and while the heading is unknown; 'navigating'; 'degraded' when no
GNSS position was used for ``degraded_after_s``. While the heading is unknown the yaw error is kept
out of the filter (its covariance row and column zeroed): GNSS updates are applied only near
standstill, where the yaw does not enter them except through the lever arm, whose antenna
position the heading initialisation then keeps. The output: core.output.solution.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from gnss_ins_common.types import BoolArray, FloatArray
from ins_fusion.core.engine.intake import (
    S_DUPLICATES,
    S_GAPS,
    S_IMPLAUSIBLE,
    S_LAST_RATE,
    S_LAST_T,
    S_OUT_OF_ORDER,
    S_SAMPLES,
    S_STEP,
    put_reading,
    take_sample,
)
from ins_fusion.core.engine.loop import EngineLoop
from ins_fusion.core.engine.measurement_kinds import MEASUREMENT_NAMES
from ins_fusion.core.engine.sample_runs import RUN_DONE, RUN_PROBLEM, ImuSeries
from ins_fusion.core.filter.records import (
    AttitudeMeasurement,
    GnssFixMeasurement,
    GnssVelocityMeasurement,
    VehicleSpeedMeasurement,
)
from ins_fusion.core.filter.status import EngineStatus
from ins_fusion.core.measurements.attitude import ATTITUDE
from ins_fusion.core.measurements.gnss_position import POSITION
from ins_fusion.core.measurements.gnss_velocity import VELOCITY
from ins_fusion.core.measurements.vehicle_speed import SPEED
from ins_fusion.core.nav.calibration import ImuCalibration
from ins_fusion.core.nav.strapdown import INCREMENT_SIZE
from ins_fusion.core.output.solution import InsSolution, self_calibration, unpack
from ins_fusion.core.output.solution_rows import RowBuffer
from ins_fusion.core.settings.config import FusionConfig
from ins_fusion.core.smoother.rts import SmootherHooks

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
    "VehicleSpeedMeasurement",
]


class InsEngine(EngineLoop):
    """Loosely coupled, closed-loop error-state GNSS/INS (see the module docstring)."""

    def add_imu(
        self,
        t_s: float,
        rate_flu_rad_s: Sequence[float] | FloatArray,
        force_flu_m_s2: Sequence[float] | FloatArray,
    ) -> None:
        """One IMU sample as published by imu400cc_node: imu_link FLU, rad/s and m/s², stamp
        (``imu_time_offset`` is taken off it: the engine runs on the GNSS time base)."""
        t = float(t_s) - self.config.imu_time_offset_s
        timeline = self._timeline
        # The strapdown step goes with the intake unless measurements are due before it.
        ready = self._filter is not None and timeline.replay_from is None and not timeline.due_by(t)
        inc = np.empty(INCREMENT_SIZE)
        buf = self._intake
        put_reading(buf, t, rate_flu_rad_s, force_flu_m_s2)
        buf[S_STEP] = 1.0 if ready else 0.0
        code = take_sample(
            buf,
            self._calibration_table,
            self._integrator.buffer,
            self._detector.ring,
            self._densities.monitor.block,
            self._state.x if ready else self._idle_x,  # type: ignore[union-attr]
            self._geometry.r_bi,
            inc,
        )
        self._finish_sample(t, inc, code)

    def add_imu_series(
        self,
        t_s: FloatArray,
        rate_flu_rad_s: FloatArray,
        force_flu_m_s2: FloatArray,
        ticks: BoolArray,
        span: tuple[int, int],
        rows: RowBuffer,
    ) -> None:
        """Samples ``span`` = (start, stop) of arrays (stamps [s] (n,), rates and forces (n, 3)
        as ``add_imu`` takes them), each as ``add_imu``, and after each sample with ``ticks``
        set its ``solution_row`` (when there is one) appended to ``rows``, with runs of ordinary
        samples compiled (core.engine.sample_runs): how a replay and the node feed the
        engine."""
        k, stop = span
        samples = ImuSeries(t_s, rate_flu_rad_s, force_flu_m_s2, ticks)
        while k < stop:
            if (
                self._filter is None
                or self.datum is None
                or self._smoother_hooks is not None
                or self._timeline.replay_from is not None
            ):
                self.add_imu(t_s[k], rate_flu_rad_s[k], force_flu_m_s2[k])
                self._record_tick(bool(ticks[k]), rows)
                k += 1
                continue
            k = self._take_run(samples, k, stop, rows)

    def _take_run(
        self,
        samples: ImuSeries,
        start: int,
        stop: int,
        rows: RowBuffer,
    ) -> int:
        """One compiled run from sample ``start`` (the filter runs, no re-propagation due), the
        sample that ended it finished here; returns the next sample's index."""
        s, kf = self._state, self._filter
        assert s is not None and kf is not None and self.datum is not None
        pseudo_t = self._next_pseudo_t_s
        k, code, inc, epoch = self._runs.take(
            s, kf, self.datum, pseudo_t, samples, (start, stop), rows
        )
        if epoch is not None:  # what _start_pseudo_interval did at the run's epochs
            self._next_pseudo_t_s, self._zaru_start_s = epoch
        if code == RUN_PROBLEM:
            self._check_health()
            self._record_tick(bool(samples[3][k - 1]), rows)
        elif code != RUN_DONE:
            self._finish_sample(float(samples[0][k - 1]) - self.config.imu_time_offset_s, inc, code)
            self._record_tick(bool(samples[3][k - 1]), rows)
        return k

    def _record_tick(self, tick: bool, rows: RowBuffer) -> None:
        """After a sample taken in Python: its solution row into ``rows`` at an output tick."""
        if tick and (row := self.solution_row()) is not None:
            rows.append(row)

    def add_gnss_fix(self, fix: GnssFixMeasurement) -> None:
        """Antenna position (gnss/fix) at its epoch ``fix.t_s``."""
        if fix.valid and all(map(math.isfinite, (fix.lat_deg, fix.lon_deg, fix.height_m))):
            self._latest.fix = fix
            if self.datum is None:
                self.datum = (fix.lat_deg, fix.lon_deg, fix.height_m)
        self._add(POSITION.name, fix.t_s, fix)

    def add_gnss_velocity(self, vel: GnssVelocityMeasurement) -> None:
        """Antenna velocity (gnss/vel) at its epoch."""
        horizontal = float(np.hypot(vel.vel_enu_m_s[0], vel.vel_enu_m_s[1]))
        if math.isfinite(horizontal):
            self._latest.velocity = vel
            self._latest.gnss_speed = (vel.t_s, horizontal)
        if self.config.use_gnss_velocity or self.config.use_course_heading:
            self._add(VELOCITY.name, vel.t_s, vel)

    def add_vehicle_speed(self, speed: VehicleSpeedMeasurement) -> None:
        """Forward speed of the measuring point (vehicle/speed) at its stamp less
        ``speed.time_offset``; only with ``speed.use`` (the filter then has the speed scale
        state)."""
        config = self.config
        if not config.use_speed:
            raise ValueError("a vehicle speed was given to an engine without speed.use")
        t_s = speed.t_s - config.speed_time_offset_s
        self._add(SPEED.name, t_s, speed if t_s == speed.t_s else replace(speed, t_s=t_s))

    def add_attitude(self, att: AttitudeMeasurement) -> None:
        """Orientation from the attitude receiver (gnss/attitude) at its epoch."""
        if self.config.use_attitude:
            self._latest.attitude = att
            self._add(ATTITUDE.name, att.t_s, att)

    def solution(self) -> InsSolution | None:
        """The fused base_link state at the latest IMU sample; None before the filter starts
        (core.output.solution)."""
        row = self.solution_row()
        return None if row is None else unpack(row)

    def solution_row(self) -> FloatArray | None:
        """``solution()`` as a row of numbers (core.output.solution.WIDTH columns), without building
        the object: what a replay records at every output tick."""
        self._catch_up()
        s, kf = self._state, self._filter
        if s is None or kf is None or self.datum is None:
            return None
        rate_i = self._intake[S_LAST_RATE : S_LAST_RATE + 3]
        return self._output.row(s, kf, self.datum, rate_i, self._state_name())

    def status(self) -> EngineStatus:
        """Counters and diagnostics (see EngineStatus)."""
        self._catch_up()
        state = self._state_name()
        t_s, stationary = float(self._intake[S_LAST_T]), self._detector.stationary
        return EngineStatus(
            state=state,
            measurements={name: dict(c) for name, c in self._counters.items()},
            resets=self._resets,
            last_reset_reason=self._last_reset_reason,
            imu_samples=int(self._intake[S_SAMPLES]),
            imu_gaps=int(self._intake[S_GAPS]),
            imu_duplicates=int(self._intake[S_DUPLICATES]),
            imu_out_of_order=int(self._intake[S_OUT_OF_ORDER]),
            imu_implausible=int(self._intake[S_IMPLAUSIBLE]),
            nis=dict(self._corrections.nis),
            rollbacks=self._rollbacks,
            replayed_samples=self._replayed_samples,
            stationary=stationary,
            adapted=self.adapted_noise(),
            calibration=self.self_calibration(),
            warnings=self._startup.warnings,
            aligning=self._startup.waiting_for(t_s, stationary, self._state is not None)
            if state == "aligning"
            else "",
        )

    def self_calibration(self) -> dict[str, float]:
        """The estimated IMU time offset and residual mounting
        (core.output.solution.self_calibration)."""
        return self_calibration(self.config, self._geometry, self._state, self._filter)

    def adapted_noise(self) -> dict[str, float]:
        """The noise model in use after adaptation (core.filter.adaptation), in user units: gyro ARW
        [deg/√h] and accelerometer VRW [m/s/√h] per imu_link axis (the user's value or the
        measured one, whichever is larger), the measured white GNSS position σ per ENU axis
        [m] (NaN until measured) and the last fading factor of a gate recovery (1 = none)."""
        gyro_psd, accel_psd = self._densities.current() or self._densities.floor
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
        values["fading_factor_last"] = self._corrections.fading
        values["process_noise_scale"] = math.nan if s is None else s.q_scale
        values["gnss_nis_mean"] = math.nan if s is None else s.nis_mean
        return values

    @property
    def smoother_hooks(self) -> SmootherHooks | None:
        """What is told of every covariance change, correction, checkpoint and rollback for the
        RTS smoother (its history, which core.engine.smoothed_solution.attach_history sets);
        None: no smoothing."""
        return self._smoother_hooks

    @smoother_hooks.setter
    def smoother_hooks(self, hooks: SmootherHooks | None) -> None:
        self._smoother_hooks = hooks
        if self._filter is not None:
            self._filter.smoother_hooks = hooks

    @property
    def solution_jacobian(self) -> FloatArray:
        """Jacobian of the last ``solution()`` (core.output.solution.SolutionBuilder.jacobian)."""
        return self._output.jacobian

    @property
    def covariance(self) -> FloatArray | None:
        """Error-state covariance (layout ``self.layout``; NED/FRD, see core.filter.eskf) or
        None."""
        self._catch_up()
        return None if self._filter is None else self._filter.P
