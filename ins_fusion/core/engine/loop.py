"""The parts of the engine and its loop under ``InsEngine``'s inputs and outputs
(core.engine.engine): the IMU stream's starts, gaps and restarts after the compiled intake, the
history with its checkpoints and the re-propagation after a late measurement, the application
of a measurement (fused kernel or general handler), the pseudo-measurement and alignment
epochs, and the engine's state name.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from gnss_ins_common.types import FloatArray, Vec3
from ins_fusion.core.compiled import kernel_array
from ins_fusion.core.engine.intake import (
    BACK_RUN_RESET,
    GAP,
    PUSHED,
    REJECTED,
    RESTART,
    RING_FULL,
    S_FORCE,
    S_LAST_FORCE,
    S_LAST_RATE,
    S_LAST_T,
    S_NOMINAL_DT,
    S_RATE,
    S_ZARU_N,
    S_ZARU_SUM,
    STEPPED,
    IntakeStores,
    forget_stream,
    new_intake,
    record_sample,
    start_pseudo_interval,
)
from ins_fusion.core.engine.measurement_kinds import MEASUREMENT_NAMES, kinds_of, updates_of
from ins_fusion.core.engine.sample_runs import CompiledRuns
from ins_fusion.core.engine.startup import Startup
from ins_fusion.core.filter.eskf import ErrorStateFilter, StateLayout, problem_text
from ins_fusion.core.filter.propagation import ImuDensities, Propagator, bridge
from ins_fusion.core.filter.state import (
    X_COV_VEL0,
    X_SIZE,
    X_VEL,
    FilterState,
    Geometry,
    LatestInputs,
    filter_problem,
    nav_speeds,
)
from ins_fusion.core.filter.status import new_counters
from ins_fusion.core.filter.timeline import Checkpoint, Entry, Gap, Record, Timeline
from ins_fusion.core.measurements.gate import Corrections, EngineParts
from ins_fusion.core.measurements.gnss_noise import GnssNoise
from ins_fusion.core.measurements.nhc import NHC, nhc_due
from ins_fusion.core.measurements.stationary import ZARU, ZUPT
from ins_fusion.core.measurements.stop_detector import GNSS_SPEED_MAX_AGE_S, StopDetector
from ins_fusion.core.nav.calibration import T_SIZE as CALIBRATION_SIZE
from ins_fusion.core.nav.calibration import ImuCalibration
from ins_fusion.core.nav.strapdown import SampleIntegrator, increment
from ins_fusion.core.nav.units import STANDARD_GRAVITY_M_S2
from ins_fusion.core.output.solution import STATES, SolutionBuilder, state_code
from ins_fusion.core.settings.config import FusionConfig
from ins_fusion.core.smoother.rts import SmootherHooks


class EngineLoop:
    """What ``InsEngine`` is made of and the loop behind its methods (see the module
    docstring and core.engine.engine's)."""

    _filter: ErrorStateFilter | None
    _state: FilterState | None
    _next_pseudo_t_s: float
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
            config.use_speed and config.speed_scale_sigma > 0.0,
            noise.gyro_asymmetry_sigma > 0.0,
        )
        geometry = self._geometry = Geometry(config, self.layout)
        self.datum: tuple[float, float, float] | None = config.datum_deg
        self._counters = new_counters(kinds_of(config))
        self._latest = LatestInputs()
        gnss_noise = GnssNoise(config, self.layout)
        self._densities = ImuDensities(noise.gyro_psd, noise.accel_psd)
        self._propagator = Propagator(config, geometry, self._densities)
        corrections = self._corrections = Corrections(config, self._counters)
        parts = EngineParts(geometry, self._propagator, corrections, gnss_noise, self._latest)
        corrections.handlers.update(updates_of(config, parts))
        self._startup = Startup(
            config, calibration, geometry, gnss_noise, self.layout, self._counters, self._latest
        )
        self._output = SolutionBuilder(geometry, self.layout)
        self._timeline = Timeline(config.history_s, MEASUREMENT_NAMES)
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
        self._smoother_hooks: SmootherHooks | None = None
        self._runs = CompiledRuns(
            config,
            geometry,
            (self._intake_stores, self._detector, self._densities),
            (self._propagator, self._output, self._timeline, self._corrections),
        )
        self._clear()

    def _intake_stores(self) -> IntakeStores:
        """The intake's arrays as they are now (the detector's ring grows: never kept)."""
        return IntakeStores(
            self._intake,
            self._calibration_table,
            self._integrator.buffer,
            self._detector.ring,
            self._densities.monitor.block,
        )

    def _finish_sample(self, t: float, inc: FloatArray, code: int) -> None:
        """What follows the intake of a sample at ``t`` with its result ``code``."""
        if code >= PUSHED:
            self._advance(t, inc, None, code)
        elif code != REJECTED:
            self._take_exception(t, code)

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
        buf = self._intake
        wx, wy, wz = buf[S_RATE : S_RATE + 3].tolist()
        fx, fy, fz = buf[S_FORCE : S_FORCE + 3].tolist()
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

    def _clear(self) -> None:
        """Forget everything but the counters and the datum (start, reset)."""
        if self._smoother_hooks is not None:  # smoother hook: the filter starts again
            self._smoother_hooks.on_reset(None if self._filter is None else self._filter.P)
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
        buf = self._intake
        wx, wy, wz = buf[S_LAST_RATE : S_LAST_RATE + 3].tolist()
        fx, fy, fz = buf[S_LAST_FORCE : S_LAST_FORCE + 3].tolist()
        return (wx, wy, wz), (fx, fy, fz)

    def _start_pseudo_interval(self, t: float) -> None:
        self._next_pseudo_t_s = start_pseudo_interval(self._intake, t, self._pseudo_period_s)
        self._zaru_start_s = t

    def _checkpoint(self) -> Checkpoint:
        assert self._state is not None and self._filter is not None
        if self._smoother_hooks is not None:  # smoother hook: what a rollback to here keeps
            self._smoother_hooks.on_checkpoint(self._state.t_s)
        return self._state.copy(), self._filter.P

    def _restore(self, checkpoint: Checkpoint) -> None:
        assert self._filter is not None
        if self._smoother_hooks is not None:  # smoother hook: drop what the rollback undoes
            self._smoother_hooks.on_rollback(checkpoint[0].t_s)
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
            if self._smoother_hooks is None and (after := self._runs.repropagate(s, kf, i)) > i:
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
        s, kf = self._state, self._filter
        assert s is not None and kf is not None
        update = self._corrections.handlers[record.kind]
        if update.fused(s, kf, (record.t_m, record.payload), live):
            return  # in one kernel
        self._propagator.propagate_covariance(s, kf)
        prediction = self._propagator.predict(s, kf, record.t_m)
        update(s, kf, prediction, record.payload, live)
        x = s.x  # the covariance interval goes on from the corrected velocity
        x[X_COV_VEL0 : X_COV_VEL0 + 3] = x[X_VEL : X_VEL + 3]

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

    def _pseudo_epoch(self, t: float, entry: Entry) -> None:
        """Stop detection, ZUPT/ZARU or NHC, health checks (live, at the pseudo rate)."""
        s, kf = self._state, self._filter
        assert s is not None and kf is not None
        cfg = self.config
        stationary = self._detector.evaluate(t, self._recent_gnss_speed(t), nav_speeds(s.x)[1])
        buf = self._intake
        mean_rate = buf[S_ZARU_SUM : S_ZARU_SUM + 3] / max(int(buf[S_ZARU_N]), 1)
        span = t - self._zaru_start_s
        self._start_pseudo_interval(t)
        kinds: list[tuple[str, Any]] = []
        if stationary:
            if cfg.use_zupt:
                kinds.append((ZUPT.name, None))
            if cfg.use_zaru:
                kinds.append((ZARU.name, (mean_rate, span)))
        elif nhc_due(s.x, cfg.use_nhc, cfg.nhc_min_speed_m_s):
            kinds.append((NHC.name, None))
        for kind, payload in kinds:
            record = self._timeline.record(kind, t, payload)
            entry.measurements.append(record)
            self._apply(record, live=True)
        self._check_health()

    def _check_health(self) -> None:
        """After a pseudo-measurement epoch: reset when the filter is unusable."""
        s, kf = self._state, self._filter
        assert s is not None and kf is not None
        problem = problem_text(filter_problem(kernel_array(kf.P), s.x))
        if problem is not None:
            self._reset(problem)

    def _recent_gnss_speed(self, t: float) -> float | None:
        speed = self._latest.gnss_speed
        if speed is None or abs(t - speed[0]) > GNSS_SPEED_MAX_AGE_S:
            return None
        return speed[1]

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
        self._filter.smoother_hooks = self._smoother_hooks
        zero: Vec3 = (0.0, 0.0, 0.0)
        self._timeline.start(Entry(t, increment(0.0, zero, zero), None, None, self._checkpoint()))

    def _state_name(self) -> str:
        s = self._state
        return "aligning" if s is None else STATES[state_code(s.x, self.config.degraded_after_s)]
