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

Updates (core.measurements.updates; GNSS noise split core.measurements.gnss_noise) and adaptation
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
from typing import Any

import numpy as np

from gnss_ins_common.types import BoolArray, FloatArray, Vec3
from ins_fusion.core.engine.intake import (
    BACK_RUN_RESET,
    GAP,
    PUSHED,
    REJECTED,
    RESTART,
    RING_FULL,
    S_DUPLICATES,
    S_FORCE,
    S_GAPS,
    S_IMPLAUSIBLE,
    S_LAST_FORCE,
    S_LAST_RATE,
    S_LAST_T,
    S_NOMINAL_DT,
    S_OUT_OF_ORDER,
    S_RATE,
    S_SAMPLES,
    S_ZARU_N,
    S_ZARU_SUM,
    STEPPED,
    forget_stream,
    new_intake,
    record_sample,
    take_sample,
)
from ins_fusion.core.engine.sample_runs import RUN_DONE, RUN_PROBLEM, CompiledRuns
from ins_fusion.core.engine.startup import Startup
from ins_fusion.core.engine.warm_up import warm_up
from ins_fusion.core.filter.eskf import ErrorStateFilter, StateLayout
from ins_fusion.core.filter.propagation import ImuDensities, Propagator, bridge
from ins_fusion.core.filter.records import (
    AttitudeMeasurement,
    GnssFixMeasurement,
    GnssVelocityMeasurement,
)
from ins_fusion.core.filter.state import (
    X_COV_VEL0,
    X_NAV,
    X_SIZE,
    FilterState,
    Geometry,
    LatestInputs,
)
from ins_fusion.core.filter.status import MEASUREMENT_NAMES, EngineStatus, new_counters
from ins_fusion.core.filter.timeline import Checkpoint, Entry, Gap, Record, Timeline
from ins_fusion.core.measurements.fused import FusedUpdates
from ins_fusion.core.measurements.gnss_noise import GnssNoise
from ins_fusion.core.measurements.stop_detector import GNSS_SPEED_MAX_AGE_S, StopDetector
from ins_fusion.core.measurements.updates import Corrections
from ins_fusion.core.nav.calibration import T_SIZE as CALIBRATION_SIZE
from ins_fusion.core.nav.calibration import ImuCalibration
from ins_fusion.core.nav.strapdown import INCREMENT_SIZE, NAV_SIZE, SampleIntegrator, increment
from ins_fusion.core.nav.units import STANDARD_GRAVITY_M_S2
from ins_fusion.core.output.solution import InsSolution, SolutionBuilder, self_calibration, unpack
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
]


class InsEngine:
    """Loosely coupled, closed-loop error-state GNSS/INS (see the module docstring)."""

    _filter: ErrorStateFilter | None
    _state: FilterState | None
    _next_pseudo_t_s: float
    _zaru_start_s: float

    def __init__(self, config: FusionConfig, calibration: ImuCalibration | None = None) -> None:
        """``calibration`` overrides ``config.calibration_file`` (empty file name = none)."""
        self.config = config
        #: Seconds spent readying the compiled kernels (core.engine.warm_up; 0 after the first
        #: engine).
        self.warm_up_s = warm_up()
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
        geometry = self._geometry = Geometry(config, self.layout)
        self.datum: tuple[float, float, float] | None = config.datum_deg
        self._counters = new_counters()
        self._latest = LatestInputs()
        gnss_noise = GnssNoise(config, self.layout)
        self._densities = ImuDensities(noise.gyro_psd, noise.accel_psd)
        self._propagator = Propagator(config, geometry, self._densities)
        self._corrections = Corrections(config, geometry, gnss_noise, self._counters, self._latest)
        self._fused = FusedUpdates(
            config, geometry, self._propagator, self._corrections, gnss_noise
        )
        self._startup = Startup(
            config, calibration, geometry, gnss_noise, self.layout, self._counters, self._latest
        )
        self._output = SolutionBuilder(geometry, self.layout)
        self._timeline = Timeline(config.history_s)
        self._pseudo_period_s = 1.0 / config.pseudo_measurement_rate_hz
        self._resets = 0
        self._last_reset_reason = ""
        range_margin = 1.1  # calibration and scale errors may carry a reading past the range
        self._intake = new_intake(
            math.radians(config.imu_range_rate_deg_s) * range_margin,
            config.imu_range_accel_g * STANDARD_GRAVITY_M_S2 * range_margin,
            calibration is not None,
        )
        self._calibration_table = (
            calibration.table if calibration is not None else np.zeros(CALIBRATION_SIZE)
        )
        self._idle_x = np.zeros(X_SIZE)  # the intake's state argument while it does not step
        self._rollbacks = 0
        self._replayed_samples = 0
        self._detector = StopDetector(config.stop_detector, geometry.mat_bi)
        self._integrator = SampleIntegrator()
        self._recorder: SmootherHooks | None = None
        self._runs = CompiledRuns(
            config,
            geometry,
            (self._intake, self._calibration_table),
            (self._integrator, self._detector, self._densities),
            (self._propagator, self._output, self._timeline, self._corrections),
        )
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
        timeline = self._timeline
        # The strapdown step goes with the intake unless measurements are due before it.
        ready = self._filter is not None and timeline.replay_from is None and not timeline.due_by(t)
        inc = np.empty(INCREMENT_SIZE)
        code = take_sample(
            self._intake,
            self._calibration_table,
            self._integrator.buffer,
            self._detector.ring,
            self._densities.monitor.block,
            self._state.x if ready else self._idle_x,  # type: ignore[union-attr]
            self._geometry.r_bi,
            inc,
            t,
            float(rate_flu_rad_s[0]),
            float(rate_flu_rad_s[1]),
            float(rate_flu_rad_s[2]),
            float(force_flu_m_s2[0]),
            float(force_flu_m_s2[1]),
            float(force_flu_m_s2[2]),
            ready,
        )
        self._finish_sample(t, inc, code)

    def _finish_sample(self, t: float, inc: FloatArray, code: int) -> None:
        """What follows the intake of a sample at ``t`` with its result ``code``."""
        if code >= PUSHED:
            self._advance(t, inc, None, code)
        elif code != REJECTED:
            self._take_exception(t, code)

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
        set its ``solution_row`` (when there is one) appended to ``rows``: what a replay does
        sample by sample, with runs of ordinary samples compiled (core.engine.sample_runs)."""
        k, stop = span
        samples = (t_s, rate_flu_rad_s, force_flu_m_s2, ticks)
        while k < stop:
            if (
                self._filter is None
                or self.datum is None
                or self._recorder is not None
                or self._timeline.replay_from is not None
            ):
                self.add_imu(t_s[k], rate_flu_rad_s[k], force_flu_m_s2[k])
                self._record_tick(bool(ticks[k]), rows)
                k += 1
                continue
            k = self._take_run(samples, k, stop, rows)

    def _take_run(
        self,
        samples: tuple[FloatArray, FloatArray, FloatArray, BoolArray],
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

    def _take_exception(self, t: float, code: int) -> None:
        """A sample that starts or restarts the stream, or ends a gap (core.engine.intake codes)."""
        buf = self._intake
        rate_i, force_i = self._sample()
        last = float(buf[S_LAST_T])
        if code == RESTART:
            self._reset(
                f"IMU stamp went back by {last - t:.3f} s for {BACK_RUN_RESET} samples in a row"
            )
        dt = t - last
        if code != GAP or dt > self.config.imu_gap_reset_s:
            if code == GAP:
                self._reset(f"IMU gap of {dt:.3f} s")
            self._start_stream(t, rate_i, force_i)
            return
        inc, gap = bridge(dt, self._last_sample, rate_i, force_i)
        self._integrator.reset()  # the coning/sculling history restarts at this sample
        self._integrator.push(last + dt, rate_i, force_i)
        self._densities.monitor.reset()
        flags = record_sample(buf, self._detector.ring, self._densities.monitor.block, t)
        self._advance(t, inc, gap, flags)

    def _sample(self) -> tuple[Vec3, Vec3]:
        """The sample just taken (rate [rad/s], specific force [m/s²]; calibrated, imu FRD)."""
        wx, wy, wz, fx, fy, fz = self._intake[S_RATE : S_FORCE + 3].tolist()
        return (wx, wy, wz), (fx, fy, fz)

    def _advance(self, t: float, inc: FloatArray, gap: Gap | None, flags: int) -> None:
        """After the intake of a sample (``flags``: core.engine.intake): a full detector ring grows,
        then levelling and alignment, or the strapdown step (unless the intake did it), the
        history entry and the pseudo-measurements."""
        if flags & RING_FULL:
            self._detector.grow()
        if self._filter is None:
            if self._detector.stationary:
                self._startup.levelling.push(t, *self._sample())
            if t >= self._next_pseudo_t_s:
                self._align_epoch(t)
            return
        noise = self._densities.current()
        if flags & STEPPED:
            s, kf = self._state, self._filter
            assert s is not None
            self._propagator.advanced(s, kf, None, noise)
        else:
            self._catch_up()
            for record in self._timeline.due(t):
                if self._timeline.insert(record):
                    self._apply(record, live=True)
            self._catch_up()
            self._step(inc, gap, t, noise)
        entry = Entry(t, inc, gap, noise, self._checkpoint())
        self._timeline.append(entry)
        if t >= self._next_pseudo_t_s:
            self._pseudo_epoch(t, entry)

    def add_gnss_fix(self, fix: GnssFixMeasurement) -> None:
        """Antenna position (gnss/fix) at its epoch ``fix.t_s``."""
        if fix.valid and all(map(math.isfinite, (fix.lat_deg, fix.lon_deg, fix.height_m))):
            self._latest.fix = fix
            if self.datum is None:
                self.datum = (fix.lat_deg, fix.lon_deg, fix.height_m)
        self._add("gnss_position", fix.t_s, fix)

    def add_gnss_velocity(self, vel: GnssVelocityMeasurement) -> None:
        """Antenna velocity (gnss/vel) at its epoch."""
        horizontal = float(np.hypot(vel.vel_enu_m_s[0], vel.vel_enu_m_s[1]))
        if math.isfinite(horizontal):
            self._latest.velocity = vel
            self._latest.gnss_speed = (vel.t_s, horizontal)
        if self.config.use_gnss_velocity or self.config.use_course_heading:
            self._add("gnss_velocity", vel.t_s, vel)

    def add_attitude(self, att: AttitudeMeasurement) -> None:
        """Orientation from the attitude receiver (gnss/attitude) at its epoch."""
        if self.config.use_attitude:
            self._latest.attitude = att
            self._add("attitude", att.t_s, att)

    # ---------------------------------------------------------------------------- outputs

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
        return EngineStatus(
            state=self._state_name(),
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
            stationary=self._detector.stationary,
            adapted=self.adapted_noise(),
            calibration=self.self_calibration(),
            warnings=self._startup.warnings,
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
    def recorder(self) -> SmootherHooks | None:
        """The RTS smoother's recorder told of every covariance change, correction, checkpoint
        and rollback (core.engine.smoothed_solution.attach_recorder sets it); None: no smoothing."""
        return self._recorder

    @recorder.setter
    def recorder(self, recorder: SmootherHooks | None) -> None:
        self._recorder = recorder
        if self._filter is not None:
            self._filter.recorder = recorder

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

    # --------------------------------------------------------------- stream and history

    def _clear(self) -> None:
        """Forget everything but the counters and the datum (start, reset)."""
        if self._recorder is not None:  # smoother hook: the filter starts again
            self._recorder.on_reset(None if self._filter is None else self._filter.P)
        self._filter = None
        self._state = None
        self._timeline.clear()
        forget_stream(self._intake)
        self._next_pseudo_t_s = math.inf
        self._zaru_start_s = 0.0
        latest = self._latest
        latest.fix = latest.velocity = latest.attitude = latest.gnss_speed = None
        self._detector.reset()
        self._densities.monitor.reset()
        self._startup.levelling.reset()
        self._integrator.reset()

    def _reset(self, reason: str) -> None:
        self._resets += 1
        self._last_reset_reason = reason
        self._clear()

    def _start_stream(self, t: float, rate_i: Vec3, force_i: Vec3) -> None:
        """First sample after start or reset: no interval yet."""
        self._integrator.reset()
        self._integrator.push(t, rate_i, force_i)
        buf = self._intake
        buf[S_LAST_T] = t
        buf[S_LAST_RATE : S_LAST_RATE + 3] = rate_i
        buf[S_LAST_FORCE : S_LAST_FORCE + 3] = force_i
        buf[S_NOMINAL_DT] = math.inf
        self._detector.push(t, rate_i, force_i)
        self._start_pseudo_interval(t)

    @property
    def _last_sample(self) -> tuple[Vec3, Vec3]:
        """The last accepted sample (rate [rad/s], specific force [m/s²], imu FRD)."""
        wx, wy, wz, fx, fy, fz = self._intake[S_LAST_RATE : S_LAST_FORCE + 3].tolist()
        return (wx, wy, wz), (fx, fy, fz)

    def _start_pseudo_interval(self, t: float) -> None:
        self._next_pseudo_t_s = (
            math.floor(t / self._pseudo_period_s) + 1.0
        ) * self._pseudo_period_s
        self._intake[S_ZARU_SUM : S_ZARU_N + 1] = 0.0
        self._zaru_start_s = t

    def _checkpoint(self) -> Checkpoint:
        assert self._state is not None and self._filter is not None
        if self._recorder is not None:  # smoother hook: what a rollback to here keeps
            self._recorder.on_checkpoint(self._state.t_s)
        return self._state.copy(), self._filter.P

    def _restore(self, checkpoint: Checkpoint) -> None:
        assert self._filter is not None
        if self._recorder is not None:  # smoother hook: drop what the rollback undoes
            self._recorder.on_rollback(checkpoint[0].t_s)
        self._state = checkpoint[0].copy()
        self._filter.P = checkpoint[1]
        self._filter.gnss_variance = self._state.gnss_variance

    def _add(self, kind: str, t_m: float, payload: Any) -> None:
        """Route a measurement through the timeline; apply it now when it is the newest."""
        record = self._timeline.add(kind, t_m, payload, self._counters, self._filter is not None)
        if record is not None:
            self._apply(record, live=True)

    def _catch_up(self) -> None:
        """Roll back to the earliest entry with a late measurement and re-propagate; deferred
        until the next IMU sample or output, so measurements arriving together (a fix and its
        velocity) share one re-propagation."""
        timeline = self._timeline
        k = timeline.replay_from
        if k is None:
            return
        timeline.replay_from = None
        self._rollbacks += 1
        entry = timeline.entry(k)
        self._restore(entry.checkpoint)
        self._apply_entry(entry)
        s, kf = self._state, self._filter
        assert s is not None and kf is not None
        i, stop = k + 1, len(timeline)
        while i < stop:
            if self._recorder is None and (after := self._runs.repropagate(s, kf, i)) > i:
                i = after  # a run of entries without gap or measurement
                continue
            entry = timeline.entry(i)
            self._step(entry.inc, entry.gap, entry.t_s, entry.noise)
            entry.checkpoint = self._checkpoint()
            self._apply_entry(entry)
            i += 1
        self._replayed_samples += stop - k - 1

    def _apply_entry(self, entry: Entry) -> None:
        """Apply an entry's measurements in stamp order; new ones are counted."""
        for record in entry.measurements:
            self._apply(record, self._timeline.take_fresh(record))

    def _apply(self, record: Record, live: bool) -> None:
        """Propagate P to the current sample, apply the measurement, restart the interval."""
        t_m, _, _, kind, payload = record
        s, kf = self._state, self._filter
        assert s is not None and kf is not None
        if self._fused.applied(s, kf, (kind, t_m, payload), live):  # in one kernel
            return
        self._propagator.propagate_covariance(s, kf)
        self._corrections.handlers[kind](s, kf, self._propagator.predict(s, kf, t_m), payload, live)
        x = s.x  # the covariance interval goes on from the corrected velocity
        x[X_COV_VEL0 : X_COV_VEL0 + 3] = x[X_NAV + 3 : X_NAV + 6]

    def _step(
        self,
        inc: FloatArray,
        gap: Gap | None,
        t: float,
        noise: tuple[FloatArray, FloatArray] | None,
    ) -> None:
        s, kf = self._state, self._filter
        assert s is not None and kf is not None
        self._propagator.step(s, kf, inc, gap, t, noise)

    # ------------------------------------------------------------------- pseudo-measurements

    def _pseudo_epoch(self, t: float, entry: Entry) -> None:
        """Stop detection, ZUPT/ZARU or NHC, health checks (live, at the pseudo rate)."""
        s, kf = self._state, self._filter
        assert s is not None and kf is not None
        cfg = self.config
        x = s.x  # navigation at X_NAV (core.nav.strapdown.NAV_SIZE): position, velocity, attitude
        vn, ve, vd = x[X_NAV + 3], x[X_NAV + 4], x[X_NAV + 5]
        horizontal = math.hypot(vn, ve)
        speed = math.hypot(horizontal, vd)
        stationary = self._detector.evaluate(t, self._recent_gnss_speed(t), speed)
        buf = self._intake
        mean_rate = buf[S_ZARU_SUM : S_ZARU_SUM + 3] / max(int(buf[S_ZARU_N]), 1)
        span = t - self._zaru_start_s
        self._start_pseudo_interval(t)
        kinds: list[tuple[str, Any]] = []
        if stationary:
            if cfg.use_zupt:
                kinds.append(("zupt", None))
            if cfg.use_zaru:
                kinds.append(("zaru", (mean_rate, span)))
        elif cfg.use_nhc and s.heading_known and horizontal > cfg.nhc_min_speed_m_s:
            kinds.append(("nhc", None))
        for kind, payload in kinds:
            record = self._timeline.record(kind, t, payload)
            entry.measurements.append(record)
            self._apply(record, live=True)
        self._check_health()

    def _check_health(self) -> None:
        """After a pseudo-measurement epoch: reset when the filter is unusable."""
        s, kf = self._state, self._filter
        assert s is not None and kf is not None
        problem = kf.problem()
        nav = s.x[X_NAV : X_NAV + NAV_SIZE].tolist()
        if problem is None and not all(map(math.isfinite, nav)):
            problem = "non-finite navigation state"
        if problem is not None:
            self._reset(problem)

    def _recent_gnss_speed(self, t: float) -> float | None:
        speed = self._latest.gnss_speed
        if speed is None or abs(t - speed[0]) > GNSS_SPEED_MAX_AGE_S:
            return None
        return speed[1]

    # ------------------------------------------------------------------------ alignment

    def _align_epoch(self, t: float) -> None:
        """Before the filter runs: stop detection, levelling, and the start when possible."""
        stationary = self._detector.evaluate(t, self._recent_gnss_speed(t), None)
        self._start_pseudo_interval(t)
        if not stationary:
            self._startup.levelling.reset()
        started = self._startup.try_start(t, stationary)
        if started is None:
            return
        self._state, self._filter = started
        self._filter.recorder = self._recorder
        zero: Vec3 = (0.0, 0.0, 0.0)
        self._timeline.start(Entry(t, increment(0.0, zero, zero), None, None, self._checkpoint()))

    def _state_name(self) -> str:
        s = self._state
        if s is None or not s.heading_known:
            return "aligning"
        if s.t_s - s.last_position_t_s > self.config.degraded_after_s:
            return "degraded"
        return "navigating"
