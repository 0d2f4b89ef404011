"""Runs of ordinary IMU samples in one compiled call (core.compiled): the replay's fast path.

An ordinary sample, once the filter runs, needs only the intake with its strapdown step
(core.intake.take_sample), a history entry with its checkpoint and the IMU noise densities in
force and, at an output tick, the solution row (core.solution). ``take_run`` takes samples from
arrays until one needs Python: any code of take_sample but an ordinary step (a gap, a restart,
a full detector ring, a sample kept from the step because a measurement is due before it), a
covariance interval that is due, a pseudo-measurement epoch. It leaves that sample taken for
the engine to finish as InsEngine.add_imu would, and hands back the ordinary samples'
increments and states (each a checkpoint), a snapshot of the measured IMU noise at each of its
changes (core.adaptation.ImuNoiseMonitor.adopt) with the snapshot each sample saw, and the rows
of their output ticks, computed with the same kernels in the same order: the same numbers to
the bit. ``advance_run`` does the same for the history entries a re-propagation after a late
measurement steps through.
"""

from __future__ import annotations

import numpy as np

from gnss_ins_common.types import BoolArray, FloatArray, IntArray
from ins_fusion.core.adaptation import B_MEAN, B_VERSION
from ins_fusion.core.compiled import jit
from ins_fusion.core.config import FusionConfig
from ins_fusion.core.eskf import ErrorStateFilter
from ins_fusion.core.intake import PUSHED, REJECTED, S_LAST_RATE, STEPPED, take_sample
from ins_fusion.core.propagation import ImuDensities, Propagator, advance
from ins_fusion.core.solution import STATE, WIDTH, SolutionBuilder, _fill_row
from ins_fusion.core.solution_rows import RowBuffer
from ins_fusion.core.state import (
    X_COV_DT,
    X_HEADING_KNOWN,
    X_LAST_POSITION_T,
    X_SIZE,
    X_T,
    FilterState,
    Geometry,
)
from ins_fusion.core.stop_detector import StopDetector
from ins_fusion.core.strapdown import INCREMENT_SIZE, SampleIntegrator
from ins_fusion.core.timeline import Entry, Timeline

#: ``take_run``'s code when the run ended without a sample for the engine to finish.
RUN_DONE = -1
#: Row STATE values (core.solution.STATES).
_NAVIGATING, _DEGRADED, _ALIGNING = 1.0, 2.0, 0.0


@jit
def take_run(
    stores: tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray],
    r_bi: FloatArray,
    samples: tuple[FloatArray, FloatArray, FloatArray, BoolArray],
    start: int,
    stop: int,
    limits: tuple[float, float, float, float, float],
    outs: tuple[FloatArray, FloatArray, FloatArray, IntArray, FloatArray],
    row_model: tuple[FloatArray, FloatArray, IntArray, FloatArray, FloatArray, FloatArray],
    mounting: tuple[float, float],
    origin: tuple[float, float, float],
) -> tuple[int, int, int, int, int]:
    """Take samples ``start`` .. ``stop`` - 1 of ``samples`` (stamps [s], rates [rad/s] and
    forces [m/s²] (n, 3) imu_link FLU, output tick after each sample) until one needs the
    engine (module docstring).

    ``stores``: the intake array, calibration table, sample integrator, detector ring, noise
    monitor block and nominal state x (take_sample's arguments); ``limits``: the IMU time
    offset [s] taken off each stamp, the stamp of the first pending measurement (inf: none),
    of the next pseudo-measurement epoch, the covariance interval [s], degraded_after [s].
    ``outs``: ``incs`` / ``xs`` the increment and state after each ordinary sample (rows 0 ..
    m-1; row m the increment of the sample left to the engine), ``rows`` the solution rows of
    the ticks (``row_model``: J, P, the solution states, base_link lever arm, arm_bi and the
    ENU plane's rotation, with ``mounting`` and ``origin`` as SolutionBuilder.row gives them),
    ``seen`` the noise snapshot each ordinary sample saw (-1: the one in force at the start),
    ``snapshots`` the noise monitor's version and B_MEAN numbers at each change.
    Returns (next sample index, code of the sample left to the engine or RUN_DONE, m, rows
    written, snapshots written)."""
    buf, table, integrator, ring, block, x = stores
    t_s, rate, force, ticks = samples
    offset_s, due_t, pseudo_t, interval_s, degraded_after_s = limits
    incs, xs, rows, seen, snapshots = outs
    J, P, states, arm_b, arm_bi, mat_enu_ecef = row_model
    version = block[B_VERSION]
    m = 0
    r = 0
    v = 0
    for i in range(start, stop):
        t = t_s[i] - offset_s
        code = take_sample(
            buf,
            table,
            integrator,
            ring,
            block,
            x,
            r_bi,
            incs[m],
            t,
            rate[i, 0],
            rate[i, 1],
            rate[i, 2],
            force[i, 0],
            force[i, 1],
            force[i, 2],
            not due_t < t,
        )
        if code != REJECTED:
            plain = code == PUSHED + STEPPED and x[X_COV_DT] < interval_s and t < pseudo_t
            if not plain:
                return i + 1, code, m, r, v
            if block[B_VERSION] != version:
                version = block[B_VERSION]
                snapshots[v, 0] = version
                snapshots[v, 1:] = block[B_MEAN : B_MEAN + 6]
                v += 1
            seen[m] = v - 1
            xs[m, :] = x
            m += 1
        if ticks[i]:
            row = rows[r]
            rate_i = buf[S_LAST_RATE : S_LAST_RATE + 3]
            _fill_row(
                row, J, x, P, states, arm_b, r_bi, arm_bi, rate_i, mounting, origin, mat_enu_ecef
            )
            if x[X_HEADING_KNOWN] == 0.0:
                row[STATE] = _ALIGNING
            elif x[X_T] - x[X_LAST_POSITION_T] > degraded_after_s:
                row[STATE] = _DEGRADED
            else:
                row[STATE] = _NAVIGATING
            r += 1
    return stop, RUN_DONE, m, r, v


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
    stamped ``t_s`` (core.propagation.advance), its state after each into ``xs``, until the
    covariance interval ``interval_s`` [s] is due; returns the increments taken."""
    for i in range(len(t_s)):
        advance(x, incs[i], r_bi, False, t_s[i])
        xs[i, :] = x
        if x[X_COV_DT] >= interval_s:
            return i + 1
    return len(t_s)


class CompiledRuns:
    """The engine's side of the two kernels: their arguments from the engine's stores, and the
    history entries, checkpoints and rows they return (InsEngine owns one; module docstring)."""

    def __init__(
        self,
        config: FusionConfig,
        geometry: Geometry,
        arrays: tuple[FloatArray, FloatArray],
        sensors: tuple[SampleIntegrator, StopDetector, ImuDensities],
        filtering: tuple[Propagator, SolutionBuilder, Timeline],
    ) -> None:
        """``arrays``: the intake (core.intake S_* layout) and calibration table."""
        self._config = config
        self._r_bi = geometry.r_bi
        self._intake, self._table = arrays
        self._integrator, self._detector, self._densities = sensors
        self._propagator, self._output, self._timeline = filtering

    def take(
        self,
        s: FilterState,
        kf: ErrorStateFilter,
        datum_deg: tuple[float, float, float],
        pseudo_t_s: float,
        samples: tuple[FloatArray, FloatArray, FloatArray, BoolArray],
        span: tuple[int, int],
        rows: RowBuffer,
    ) -> tuple[int, int, FloatArray]:
        """``take_run`` over ``span`` of ``samples`` (the filter runs, no re-propagation due;
        ``pseudo_t_s``: stamp of the next pseudo-measurement epoch [s]): the ordinary samples'
        history entries appended to the timeline, their rows to ``rows``.
        Returns (next sample index, code of the sample left to the engine or RUN_DONE, that
        sample's increment)."""
        start, stop = span
        n = stop - start
        incs, xs, out = np.empty((n, INCREMENT_SIZE)), np.empty((n, X_SIZE)), np.empty((n, WIDTH))
        seen, snapshots = np.empty(n, dtype=np.int64), np.empty((n, 7))
        densities = self._densities
        noise = densities.current()
        model, mounting, origin = self._output.model(s, kf, datum_deg)
        config = self._config
        limits = (
            config.imu_time_offset_s,
            self._timeline.due_stamp(),
            pseudo_t_s,
            config.covariance_interval_s,
            config.degraded_after_s,
        )
        stores = (
            self._intake,
            self._table,
            self._integrator.buffer,
            self._detector.ring,
            self._densities.monitor.block,
            s.x,
        )
        outs = (incs, xs, out, seen, snapshots)
        k, code, m, r, v = take_run(
            stores, self._r_bi, samples, start, stop, limits, outs, model, mounting, origin
        )
        # What ImuDensities.current read, Propagator.advanced and InsEngine._checkpoint did
        # after each sample.
        noises: list[tuple[FloatArray, FloatArray] | None] = [
            densities.adopt(snapshot[0], snapshot[1:]) for snapshot in snapshots[:v]
        ]
        if m:
            noises.append(noise)  # [-1]: the densities at the start
            s.changed()
            P = kf.P
            entries = []
            for j in range(m):
                noise = noises[seen[j]]
                checkpoint = (s.with_x(xs[j], noise), P)
                entries.append(Entry(float(xs[j, X_T]), incs[j], None, noise, checkpoint))
            self._timeline.extend(entries)
            s.imu_psd = noise
        for j in range(r):
            rows.append(out[j])
        return k, code, incs[m] if code != RUN_DONE else incs[0]

    def repropagate(
        self, s: FilterState, kf: ErrorStateFilter, entries: list[Entry], start: int
    ) -> int:
        """Re-propagate ``entries[start:]`` while they have no gap, no measurement and the same
        noise (``advance_run``), as InsEngine._step and _checkpoint would one by one (no
        smoother attached); returns the index of the next entry."""
        noise = entries[start].noise
        stop = start + 1
        while stop < len(entries):
            entry = entries[stop]
            if entry.gap is not None or entry.measurements or entry.noise is not noise:
                break
            stop += 1
        run = entries[start:stop]
        xs = np.empty((len(run), X_SIZE))
        interval_s = self._config.covariance_interval_s
        incs = np.array([e.inc for e in run])
        count = advance_run(s.x, incs, np.array([e.t_s for e in run]), self._r_bi, interval_s, xs)
        s.imu_psd = noise  # what Propagator.advanced does after each step
        s.changed()
        due = bool(s.x[X_COV_DT] >= interval_s)
        P = kf.P
        for j in range(count - 1 if due else count):
            run[j].checkpoint = (s.with_x(xs[j], noise), P)
        if due:
            self._propagator.propagate_covariance(s, kf)
            run[count - 1].checkpoint = (s.copy(), kf.P)
        return start + count
