"""Runs of ordinary IMU samples in one compiled call (core.compiled), for a replay and the node.

An ordinary sample, once the filter runs, needs only the intake with its strapdown step
(core.engine.intake.take_sample), a history entry with its checkpoint and the IMU noise densities in
force and, at an output tick, the solution row (core.output.solution); now and then a covariance
step (Propagator.advanced) and a pseudo-measurement epoch. ``take_run`` takes samples from arrays
until one needs Python: any code of take_sample but an ordinary step (a gap, a restart, a full
detector ring, a sample kept from the step because a measurement is due before it), a
covariance step while the heading is unknown, a pseudo-measurement epoch unless the vehicle is
moving (the heading known, the stop detector idle and the filter's speed vetoing a stop: then
the kernel runs the epoch, its NHC through core.measurements.nhc.nhc_apply and the health check). It
leaves that sample taken for the engine to finish as InsEngine.add_imu would, and hands back
the ordinary samples' increments and states (each a checkpoint), a snapshot of the measured IMU
noise at each of its changes (core.filter.adaptation.ImuNoiseMonitor.adopt) with the snapshot each
sample saw, the covariance after each step or NHC with the one each checkpoint holds, the NHC
updates to book, and the rows of their output ticks, computed with the same kernels in the
same order: the same numbers to the bit. A filter found unusable at an epoch ends the run
(RUN_PROBLEM) for the engine's reset. ``advance_run`` does the same as ``take_run`` for the
history entries a re-propagation after a late measurement steps through, up to the next
covariance step.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from gnss_ins_common.types import BoolArray, FloatArray, IntArray, Vec3
from ins_fusion.core.compiled import jit, plain
from ins_fusion.core.engine.intake import (
    PUSHED,
    REJECTED,
    S_LAST_RATE,
    S_STEP,
    STEPPED,
    IntakeStores,
    put_reading,
    start_pseudo_interval,
    take_sample,
)
from ins_fusion.core.filter.adaptation import B_MEAN, B_VERSION
from ins_fusion.core.filter.eskf import (
    USABLE,
    Columns,
    ErrorStateFilter,
    ProcessModel,
    with_white_noise,
)
from ins_fusion.core.filter.propagation import (
    ImuDensities,
    Propagator,
    advance,
    covariance_step,
    monitored_white_noise,
)
from ins_fusion.core.filter.state import (
    X_COV_DT,
    X_HEADING_KNOWN,
    X_MOUNTING,
    X_Q_SCALE,
    X_SIZE,
    X_T,
    FilterState,
    Geometry,
    filter_problem,
    mounted_arm,
    nav_speeds,
)
from ins_fusion.core.filter.timeline import Record, RunEntries, Timeline
from ins_fusion.core.measurements.gate import Corrections
from ins_fusion.core.measurements.nhc import NHC, nhc_apply, nhc_due
from ins_fusion.core.measurements.stop_detector import StopDetector, vetoed
from ins_fusion.core.nav.strapdown import INCREMENT_SIZE
from ins_fusion.core.output.solution import (
    STATE,
    WIDTH,
    RowFields,
    SolutionBuilder,
    _fill_row,
    state_code,
)
from ins_fusion.core.output.solution_rows import RowBuffer
from ins_fusion.core.settings.config import FusionConfig

#: ``take_run``'s codes when the run ended without a sample for the engine to finish, and
#: after a pseudo-measurement epoch that left the filter unusable (the engine resets it).
RUN_DONE, RUN_PROBLEM = -1, -2
#: Most covariances one run hands back (covariance steps and NHC updates).
STEPS_PER_RUN = 8


class ImuSeries(NamedTuple):
    """IMU samples in arrays, as a replay holds them."""

    t_s: FloatArray  #: stamps [s] (n,)
    rate: FloatArray  #: rates [rad/s] (n, 3), imu_link FLU
    force: FloatArray  #: specific forces [m/s²] (n, 3), imu_link FLU
    ticks: BoolArray  #: an output tick after the sample (n,)


class RunSettings(NamedTuple):
    """What a run starts from besides arrays."""

    start: int  #: first sample of the run
    stop: int  #: the sample after the last one it may take
    due_t: float  #: stamp of the first pending measurement [s] (inf: none)
    pseudo_t: float  #: stamp of the next pseudo-measurement epoch [s]
    detector_idle: bool  #: the stop detector has no stop and no candidate


class RunConstants(NamedTuple):
    """The engine's numbers every run reads (CompiledRuns builds them once)."""

    offset_s: float  #: the IMU time offset taken off each stamp [s]
    interval_s: float  #: the covariance interval [s]
    degraded_after_s: float  #: degraded_after [s]
    period_s: float  #: the pseudo-measurement period [s]
    stop_speed_m_s: float  #: the stop detector's speed threshold [m/s]
    nhc_min_speed_m_s: float  #: nhc_min_speed [m/s]
    use_nhc: bool
    correlation_time_s: float  #: the GNSS error's correlation time [s]
    nhc_sigma_m_s: float  #: NHC σ [m/s]
    nhc_gate: float  #: the NHC's gate


class RunFilter(NamedTuple):
    """The filter's side of a run: the covariance at its start and what a step, an NHC and a
    solution row need (core.output.solution.RowModel but the arm turned and the mounting)."""

    P: FloatArray  #: the error covariance at the start (n, n)
    process: ProcessModel  #: ErrorStateFilter.process_model
    floor: tuple[FloatArray, FloatArray]  #: the user's white-noise densities (ImuDensities)
    columns: Columns  #: StateLayout.columns
    mat_bi: FloatArray  #: imu -> body rotation
    base_arm_b: FloatArray  #: base_link lever arm before the mounting turns it [m]
    J: FloatArray  #: the solution rows' Jacobian (written)
    states: IntArray  #: the solution's error states
    arm_bi: FloatArray  #: SolutionBuilder's arm_bi
    mat_enu_ecef: FloatArray  #: the ENU plane's rotation
    origin: Vec3  #: the ENU plane's ECEF origin [m]


class RunOutputs(NamedTuple):
    """What ``take_run`` writes (rows 0 .. m-1 of the per-sample arrays: its ordinary
    samples)."""

    incs: FloatArray  #: each sample's increment; row m: that of the sample left to the engine
    xs: FloatArray  #: the nominal state after each sample
    rows: FloatArray  #: the solution rows of the ticks
    seen: IntArray  #: the noise snapshot each sample saw (-1: the one in force at the start)
    snapshots: FloatArray  #: the noise monitor's version and B_MEAN numbers at each change
    held: IntArray  #: the covariance each sample's checkpoint holds (-1: RunFilter.P)
    covs: FloatArray  #: the covariance after each change (STEPS_PER_RUN, n, n)
    phi: FloatArray  #: the last transition (n, n)
    white: FloatArray  #: the last white-noise densities (2, 3)
    nhcs: FloatArray  #: the NHC of each epoch (rows: sample, accepted, NIS)
    pseudo: FloatArray  #: (next epoch's stamp, start of its ZARU interval) [s]


@jit
def take_run(
    stores: IntakeStores,
    x: FloatArray,
    r_bi: FloatArray,
    series: ImuSeries,
    settings: RunSettings,
    constants: RunConstants,
    filtering: RunFilter,
    outs: RunOutputs,
) -> tuple[int, int, int, int, int, int, int]:
    """Take the samples ``settings.start`` .. ``stop`` of ``series`` until one needs the
    engine (module docstring), with the intake's ``stores``, the nominal state ``x`` and
    ``r_bi`` as take_sample takes them. Returns (next sample index, code of the sample left to
    the engine, RUN_DONE or RUN_PROBLEM, m, rows written, snapshots written, covariances
    written, NHC updates)."""
    t_s, rate, force, ticks = series
    buf, table, integrator, ring, block = stores
    start, stop, due_t, pseudo_t, detector_idle = settings
    (
        offset_s,
        interval_s,
        degraded_after_s,
        period_s,
        stop_speed_m_s,
        nhc_min_speed_m_s,
        use_nhc,
        correlation_time_s,
        nhc_sigma_m_s,
        nhc_gate,
    ) = constants
    P, process, floor, columns, mat_bi, base_arm_b, J, states, arm_bi, mat_enu_ecef, origin = (
        filtering
    )
    incs, xs, rows, seen, snapshots, held, covs, phi_out, white_out, nhcs, pseudo_out = outs
    has_mounting = columns.mt >= 0
    arm_b = mounted_arm(base_arm_b, x, has_mounting)
    version = block[B_VERSION]
    m = r = v = c = e = 0
    for i in range(start, stop):
        t = t_s[i] - offset_s
        put_reading(buf, t, rate[i], force[i])
        buf[S_STEP] = 0.0 if due_t < t else 1.0
        code = take_sample(buf, table, integrator, ring, block, x, r_bi, incs[m])
        if code != REJECTED:
            due = x[X_COV_DT] >= interval_s
            epoch = t >= pseudo_t
            heading_known = x[X_HEADING_KNOWN] != 0.0
            if (
                code != PUSHED + STEPPED
                or c + 2 > len(covs)
                or (due and not heading_known)
                or (
                    epoch
                    and not (
                        heading_known and vetoed(detector_idle, nav_speeds(x)[1], stop_speed_m_s)
                    )
                )
            ):
                return i + 1, code, m, r, v, c, e
            if block[B_VERSION] != version:
                version = block[B_VERSION]
                snapshots[v, 0] = version
                snapshots[v, 1:] = block[B_MEAN : B_MEAN + 6]
                v += 1
            seen[m] = v - 1
            if due:  # Propagator.advanced with the heading known
                gyro, accel = monitored_white_noise(block, floor, x[X_Q_SCALE])
                model = with_white_noise(process, gyro, accel)
                P, phi = covariance_step(P, x, mat_bi, model, columns, correlation_time_s)
                phi_out[:, :] = phi
                white_out[0, :], white_out[1, :] = gyro, accel
                covs[c] = P
                c += 1
            held[m] = c - 1
            xs[m, :] = x
            m += 1
            if epoch:  # InsEngine._pseudo_epoch, moving (the detector decides no stop)
                pseudo_t = start_pseudo_interval(buf, t, period_s)
                pseudo_out[0], pseudo_out[1] = pseudo_t, t
                if nhc_due(x, use_nhc, nhc_min_speed_m_s):  # NhcUpdate.fused
                    gyro, accel = monitored_white_noise(block, floor, x[X_Q_SCALE])
                    stepped, phi, accepted, nis, P = nhc_apply(
                        P,
                        x,
                        t,
                        with_white_noise(process, gyro, accel),
                        (mat_bi, arm_b),
                        columns,
                        (
                            correlation_time_s,
                            nhc_sigma_m_s,
                            nhc_gate,
                            len(P),
                        ),
                    )
                    if stepped:
                        phi_out[:, :] = phi
                    white_out[0, :], white_out[1, :] = gyro, accel
                    covs[c] = P
                    c += 1
                    nhcs[e, 0], nhcs[e, 1], nhcs[e, 2] = m - 1, accepted, nis
                    e += 1
                    arm_b = mounted_arm(base_arm_b, x, has_mounting)
                if filter_problem(P, x) != USABLE:  # InsEngine._check_health
                    return i + 1, RUN_PROBLEM, m, r, v, c, e
        if ticks[i]:
            row = rows[r]
            rate_i = buf[S_LAST_RATE : S_LAST_RATE + 3]
            mounting = (x[X_MOUNTING], x[X_MOUNTING + 1]) if has_mounting else (0.0, 0.0)
            row_model: RowFields = (J, P, states, arm_b, arm_bi, mat_enu_ecef, mounting, origin)
            _fill_row(row, x, row_model, r_bi, rate_i)
            row[STATE] = state_code(x, degraded_after_s)
            r += 1
    return stop, RUN_DONE, m, r, v, c, e


@jit
def advance_run(
    x: FloatArray,
    incs: FloatArray,
    t_s: FloatArray,
    r_bi: FloatArray,
    interval_s: float,
    xs: FloatArray,
) -> int:
    """Advance the nominal state ``x`` over the increments ``incs`` (n, INCREMENT_SIZE; no gap)
    stamped ``t_s`` (core.filter.propagation.advance), its state after each into ``xs``, until the
    covariance interval ``interval_s`` [s] is due; returns the increments taken."""
    for i in range(len(t_s)):
        advance(x, incs[i], r_bi, False, t_s[i])
        xs[i, :] = x
        if x[X_COV_DT] >= interval_s:
            return i + 1
    return len(t_s)


class CompiledRuns:
    """The engine's side of the two kernels: their arguments from the engine's stores, and the
    history entries, checkpoints, NHC books and rows they return (InsEngine owns one; module
    docstring)."""

    def __init__(
        self,
        config: FusionConfig,
        geometry: Geometry,
        sensors: tuple[Callable[[], IntakeStores], StopDetector, ImuDensities],
        filtering: tuple[Propagator, SolutionBuilder, Timeline, Corrections],
    ) -> None:
        """``sensors``: the engine's intake stores as they are now, its stop detector and IMU
        densities."""
        self._config = config
        self._geometry = geometry
        self._stores, self._detector, self._densities = sensors
        self._propagator, self._output, self._timeline, self._corrections = filtering
        self._constants = RunConstants(
            config.imu_time_offset_s,
            config.covariance_interval_s,
            config.degraded_after_s,
            1.0 / config.pseudo_measurement_rate_hz,
            config.stop_detector.speed_m_s,
            config.nhc_min_speed_m_s,
            config.use_nhc,
            config.gnss_correlation_time_s,
            config.nhc_sigma_m_s,
            self._corrections.gate(2),
        )

    def take(
        self,
        s: FilterState,
        kf: ErrorStateFilter,
        datum_deg: tuple[float, float, float],
        pseudo_t_s: float,
        samples: ImuSeries,
        span: tuple[int, int],
        rows: RowBuffer,
    ) -> tuple[int, int, FloatArray, tuple[float, float] | None]:
        """``take_run`` over ``span`` of ``samples`` (the filter runs, no re-propagation due;
        ``pseudo_t_s``: stamp of the next pseudo-measurement epoch [s]): the ordinary samples'
        history entries appended to the timeline, the NHC of their epochs booked, their rows
        to ``rows``. Returns (next sample index, code of the sample left to the engine,
        RUN_DONE or RUN_PROBLEM, that sample's increment, (next pseudo-measurement epoch,
        start of its ZARU interval) [s] when the run took an epoch)."""
        start, stop = span
        n = stop - start
        incs, xs, out = np.empty((n, INCREMENT_SIZE)), np.empty((n, X_SIZE)), np.empty((n, WIDTH))
        seen, snapshots = np.empty(n, dtype=np.int64), np.empty((n, 7))
        held, covs = np.empty(n, dtype=np.int64), np.empty((STEPS_PER_RUN, *kf.P.shape))
        # The filter's transition stays as it is unless a covariance step replaces it.
        phi, white, nhcs = np.array(kf.phi), np.empty((2, 3)), np.empty((n, 3))
        pseudo = np.array([pseudo_t_s, math.nan])
        densities = self._densities
        noise = densities.current()
        # The run turns the configured base_link arm by the mounting itself (mounted_arm).
        row_model = self._output.model(s, kf, datum_deg)
        geometry = self._geometry
        settings = RunSettings(
            start, stop, self._timeline.due_stamp(), pseudo_t_s, self._detector.idle
        )
        filtering = RunFilter(
            row_model.P,
            kf.process_model(),
            densities.floor,
            kf.layout.columns,
            geometry.mat_bi,
            geometry.base_arm_b,
            row_model.J,
            row_model.states,
            row_model.arm_bi,
            row_model.mat_enu_ecef,
            row_model.origin,
        )
        outs = RunOutputs(incs, xs, out, seen, snapshots, held, covs, phi, white, nhcs, pseudo)
        k, code, m, r, v, c, e = take_run(
            plain(self._stores()),
            s.x,
            geometry.r_bi,
            plain(samples),
            plain(settings),
            plain(self._constants),
            plain(filtering),
            plain(outs),
        )
        # What ImuDensities.current read, Propagator.advanced, InsEngine._checkpoint and the
        # NHC's books (NhcUpdate.fused) did after each sample.
        noises: list[tuple[FloatArray, FloatArray] | None] = [
            densities.adopt(snapshot[0], snapshot[1:]) for snapshot in snapshots[:v]
        ]
        if m:
            noises.append(noise)  # [-1]: the densities at the start
            covariances = [*covs[:c], kf.P]  # [-1]: the covariance at the start
            s.changed()
            timeline, corrections = self._timeline, self._corrections
            records: dict[int, list[Record]] = {}
            gated = [(0, s.gated_runs)]
            stamps = xs[:m, X_T].tolist()
            for at, accepted, nis in nhcs[:e].tolist():  # (sample, accepted, NIS) in order
                j = int(at)
                records[j] = [timeline.record(NHC.name, stamps[j], None)]
                corrections.book(s, NHC, (bool(accepted), nis), 2, True)
                if s.gated_runs is not gated[-1][1]:  # from the next entry on
                    gated.append((j + 1, s.gated_runs))
            seen_by = seen[:m].tolist()
            timeline.extend_run(
                RunEntries(
                    stamps,
                    (incs, xs),
                    (noises, seen_by),
                    (covariances, held[:m].tolist()),
                    (s.gnss_white, gated),
                    records,
                )
            )
            s.imu_psd = noises[seen_by[-1]]  # the densities of the last entry
            if c:  # what the last step left in the filter
                kf.P, kf.phi = covariances[c - 1], phi
                kf.set_white_noise(white[0], white[1])
        rows.append(out[:r])
        epoch = None if math.isnan(pseudo[1]) else (float(pseudo[0]), float(pseudo[1]))
        return k, code, incs[m] if code != RUN_DONE else incs[0], epoch

    def repropagate(self, s: FilterState, kf: ErrorStateFilter, k: int) -> int:
        """Re-propagate history entries from ``k`` on while they have no gap, no measurement
        and the same densities (``Timeline.plain_from``; ``advance_run`` up to each due
        covariance step), as InsEngine._step and _checkpoint would one by one (no smoother
        attached), and file them again as runs; returns the index of the next entry (``k``
        when entry ``k`` is not such)."""
        timeline = self._timeline
        taken, noise = timeline.plain_from(k)
        if not taken:
            return k
        incs = np.array(taken)
        stamps = timeline.stamps(k, k + len(taken))
        t_s = np.array(stamps)
        interval_s = self._config.covariance_interval_s
        done = 0
        while done < len(taken):
            xs = np.empty((len(taken) - done, X_SIZE))
            count = advance_run(s.x, incs[done:], t_s[done:], self._geometry.r_bi, interval_s, xs)
            s.imu_psd = noise  # what Propagator.advanced does after each step
            s.changed()
            last = None
            P = kf.P
            books = (s.gnss_white, [(0, s.gated_runs)])
            if s.x[X_COV_DT] >= interval_s:  # the last one's checkpoint follows the step
                self._propagator.propagate_covariance(s, kf)
                last = (s.copy(), kf.P)
            held = ([P], [0] * count)
            run = RunEntries(
                stamps[done : done + count],
                (incs[done:], xs),
                ([noise], [0] * count),
                held,
                books,
                {},
            )
            timeline.refile(k + done, run, last)
            done += count
        return k + done
