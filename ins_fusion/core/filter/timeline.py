"""The engine's late-measurement timeline: a history of IMU samples with checkpoints, the
measurements filed at them, and the measurements waiting for a later sample.

A measurement stamped t_m belongs to the last history entry at or before t_m. Filed at the
newest entry it is applied at once; filed earlier, the engine rolls back to that entry's
checkpoint and re-propagates the later samples with their measurements (``replay_from`` says
from where; InsEngine._catch_up does it). Measurements newer than the newest sample wait in a
heap (at most ``MAX_PENDING``). Duplicates (same kind and stamp) are counted and dropped;
measurements older than the history are counted ``too_old`` and rejected. The samples of a
compiled run (core.engine.sample_runs) are filed as one ``RunEntries``, their entries built only
where the timeline is read.
"""

from __future__ import annotations

import bisect
import heapq
import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

from gnss_ins_common.types import FloatArray
from ins_fusion.core.filter.adaptation import WhiteNoiseMonitor
from ins_fusion.core.filter.state import FilterState
from ins_fusion.core.filter.status import Counters


class Record(NamedTuple):
    """A measurement in the history. Records sort by stamp, then kind: measurements with the
    same stamp are applied in one order whatever order they arrived in (the arrival sequence
    is unique: the payloads are never compared)."""

    #: Stamp [s].
    t_m: float
    #: Rank of its kind in the timeline's kinds.
    rank: int
    #: Arrival sequence.
    sequence: int
    kind: str
    payload: Any


#: Most measurements waiting for a later IMU sample.
MAX_PENDING = 256

Checkpoint = tuple[FilterState, FloatArray]
"""The nominal state and the error covariance after an IMU sample."""
Noise = tuple[FloatArray, FloatArray]
"""IMU white-noise densities (core.filter.propagation.ImuDensities): gyro, accelerometer."""


@dataclass(frozen=True, slots=True)
class Gap:
    """Uncertainty of the increment that bridges missing IMU samples: variances of the angle
    [rad²] and velocity [m²/s²] increments per imu FRD axis (core.filter.propagation.bridge)."""

    angle_var_rad2: tuple[float, ...]
    velocity_var_m2_s2: tuple[float, ...]


class Entry:
    """One IMU sample in the history: its raw increment (imu FRD, calibrated), the gap it
    bridges (None: none; after one the coning/sculling history restarts), the IMU white-noise
    densities in force at it (core.filter.propagation.ImuDensities), the checkpoint after it and its
    measurements."""

    __slots__ = ("checkpoint", "gap", "inc", "measurements", "noise", "t_s")

    def __init__(
        self,
        t_s: float,
        inc: FloatArray,
        gap: Gap | None,
        noise: Noise | None,
        checkpoint: Checkpoint,
    ) -> None:
        self.t_s = t_s
        self.inc = inc
        self.gap = gap
        self.noise = noise
        self.checkpoint = checkpoint
        self.measurements: list[Record] = []


class RunEntries:
    """The history entries of a compiled run (core.engine.sample_runs), kept as its arrays and built
    one by one only where the timeline is read (a late measurement filed there, a rollback):
    most samples are never read. Entry j: stamp ``t_s[j]``, increment ``incs[j]``, no gap,
    densities ``noises[seen[j]]``, checkpoint (state of ``xs[j]`` with those densities, the
    run's ``gnss_white`` and the gated-update runs in force at j; ``covariances[held[j]]``),
    measurements ``records.get(j)``."""

    __slots__ = (
        "covariances",
        "first",
        "gated",
        "gnss_white",
        "held",
        "incs",
        "noises",
        "records",
        "seen",
        "t_s",
        "xs",
    )

    def __init__(
        self,
        t_s: list[float],
        arrays: tuple[FloatArray, FloatArray],
        noises: tuple[list[Noise | None], list[int]],
        covariances: tuple[Sequence[FloatArray], list[int]],
        books: tuple[WhiteNoiseMonitor, list[tuple[int, dict[str, int]]]],
        records: dict[int, list[Record]],
    ) -> None:
        """``arrays``: increments and state arrays (m, ...); ``noises``: the densities and
        each entry's index in them; ``covariances``: likewise; ``books``: the white-noise
        monitor and (first entry, gated-update runs) from each change on; ``records``: the
        measurements of entries that have some."""
        self.t_s = t_s
        self.incs, self.xs = arrays
        self.noises, self.seen = noises
        self.covariances, self.held = covariances
        self.gnss_white, self.gated = books
        self.records = records
        self.first = 0  # the first entry's number in the timeline (Timeline.extend_run)

    def entry(self, j: int) -> Entry:
        """Entry ``j`` of the run (a new object: the timeline keeps it in place of the run)."""
        noise = self.noises[self.seen[j]]
        at = bisect.bisect_right(self.gated, j, key=lambda change: change[0]) - 1
        state = FilterState.checkpoint_of(self.xs[j], noise, self.gnss_white, self.gated[at][1])
        entry = Entry(
            self.t_s[j], self.incs[j], None, noise, (state, self.covariances[self.held[j]])
        )
        entry.measurements.extend(self.records.get(j, ()))
        return entry


class Timeline:
    """History entries (oldest first; ``entry``) and pending measurements (see the module
    docstring)."""

    replay_from: int | None

    def __init__(self, history_s: float, kinds: tuple[str, ...]) -> None:
        """``kinds``: the measurement kinds' names, in the order records of one stamp are
        applied."""
        self._history_s = history_s
        self._rank = {name: rank for rank, name in enumerate(kinds)}
        self._sequence = itertools.count()
        self.clear()

    def clear(self) -> None:
        """Forget every entry and measurement (start, reset)."""
        self._history: list[Entry | RunEntries] = []
        self._history_t: list[float] = []
        self._dropped = 0  # entries pruned since the start: numbers of the entries in a run
        self._pending: list[Record] = []
        self.replay_from = None
        self._fresh: set[int] = set()
        self._seen: dict[str, set[float]] = {name: set() for name in self._rank}

    def start(self, entry: Entry) -> None:
        """The first entry of a running filter."""
        self._history = [entry]
        self._history_t = [entry.t_s]
        self._dropped = 0

    def __len__(self) -> int:
        """Number of entries in the history."""
        return len(self._history)

    def entry(self, k: int) -> Entry:
        """History entry ``k`` (oldest first), built from its run when it is in one."""
        entry = self._history[k]
        if isinstance(entry, RunEntries):
            k %= len(self._history)
            entry = self._history[k] = entry.entry(k + self._dropped - entry.first)
        return entry

    def plain_from(self, k: int) -> tuple[list[FloatArray], Noise | None]:
        """The increments of the entries from ``k`` on with no gap, no measurement and the
        densities of entry ``k`` (none when it has a gap or measurements), and those
        densities; read without building the entries."""
        history, dropped = self._history, self._dropped
        incs: list[FloatArray] = []
        noise: Noise | None = None
        for i in range(k, len(history)):
            slot = history[i]
            if isinstance(slot, RunEntries):
                j = i + dropped - slot.first
                if j in slot.records:
                    break
                this, inc = slot.noises[slot.seen[j]], slot.incs[j]
            else:
                if slot.gap is not None or slot.measurements:
                    break
                this, inc = slot.noise, slot.inc
            if incs and this is not noise:
                break
            noise = this
            incs.append(inc)
        return incs, noise

    def stamps(self, k: int, stop: int) -> list[float]:
        """Stamps of entries ``k`` to ``stop`` - 1 [s]."""
        return self._history_t[k:stop]

    def refile(self, k: int, run: RunEntries, last: Checkpoint | None) -> None:
        """Entries ``k`` on, as many as ``run`` has, replaced by those of ``run`` (the same
        samples re-propagated); the last one with checkpoint ``last`` when given."""
        count = len(run.t_s)
        run.first = self._dropped + k
        self._history[k : k + count] = itertools.repeat(run, count)
        if last is not None:
            entry = self._history[k + count - 1] = run.entry(count - 1)
            entry.checkpoint = last

    def append(self, entry: Entry) -> None:
        """A new IMU sample; entries older than ``history_s`` go (in batches of 1 s)."""
        self._history.append(entry)
        self._history_t.append(entry.t_s)
        self._prune(len(self._history_t) - 1)

    def extend_run(self, run: RunEntries) -> None:
        """``append`` of each entry of a compiled run (in stamp order), in one call."""
        run.first = self._dropped + len(self._history)
        start = len(self._history_t)
        self._history.extend(itertools.repeat(run, len(run.t_s)))
        self._history_t.extend(run.t_s)
        self._prune(start)

    def _prune(self, start: int) -> None:
        """``append``'s pruning after each of the entries from ``start`` to the newest."""
        history_t, history_s = self._history_t, self._history_s
        # While one of them prunes (the newest does when any does: the test is monotonic in t)
        while start < len(history_t) and history_t[0] < history_t[-1] - history_s - 1.0:
            # the first that does: oldest < t - history_s - 1.0, computed as append did
            k = bisect.bisect_right(
                history_t, history_t[0], start, key=lambda t: t - history_s - 1.0
            )
            keep = bisect.bisect_left(history_t, history_t[k] - history_s)
            del self._history[:keep]
            del history_t[:keep]
            self._dropped += keep
            start = k + 1 - keep

    def record(self, kind: str, t_m: float, payload: Any) -> Record:
        """A new record of a measurement."""
        return Record(t_m, self._rank[kind], next(self._sequence), kind, payload)

    def add(
        self, kind: str, t_m: float, payload: Any, counters: Counters, running: bool
    ) -> Record | None:
        """Route a measurement: duplicate, too old, pending, or filed at its stamp. Returns the
        record when it is to be applied now, at the newest sample (live)."""
        kind_counters = counters[kind]
        seen = self._seen[kind]
        if t_m in seen:
            kind_counters["duplicates"] += 1
            return None
        if not running or not math.isfinite(t_m):
            return None  # the alignment reads the latest measurements directly
        if t_m < self._history_t[0]:
            kind_counters["too_old"] += 1
            kind_counters["rejected"] += 1
            return None
        seen.add(t_m)
        if len(seen) > 4 * MAX_PENDING:
            oldest = self._history_t[0]
            self._seen[kind] = {t for t in seen if t >= oldest}
        record = self.record(kind, t_m, payload)
        if t_m > self._history_t[-1]:
            if len(self._pending) >= MAX_PENDING:
                dropped = heapq.heappop(self._pending)
                counters[dropped.kind]["rejected"] += 1
            heapq.heappush(self._pending, record)
            return None
        return record if self.insert(record) else None

    def due_by(self, t_s: float) -> bool:
        """Whether a pending measurement is stamped before ``t_s`` (``due`` would take it)."""
        pending = self._pending
        return bool(pending) and pending[0].t_m < t_s

    def due_stamp(self) -> float:
        """Stamp of the first pending measurement [s] (inf: none): ``due_by(t)`` is this < t."""
        pending = self._pending
        return pending[0].t_m if pending else math.inf

    def due(self, t_s: float) -> list[Record]:
        """Take the pending measurements stamped before ``t_s`` (stamp order)."""
        pending = self._pending
        records = []
        while pending and pending[0].t_m < t_s:
            records.append(heapq.heappop(pending))
        return records

    def insert(self, record: Record) -> bool:
        """File a measurement at the last history entry at or before its stamp. True: it is
        the newest at the newest entry, to be applied now; else re-propagation from that
        entry is due (``replay_from``)."""
        k = bisect.bisect_right(self._history_t, record.t_m) - 1
        entry = self.entry(k)
        newest = not entry.measurements or entry.measurements[-1] < record
        if self.replay_from is None and k == len(self._history) - 1 and newest:
            entry.measurements.append(record)
            return True
        bisect.insort(entry.measurements, record)
        self._fresh.add(record.sequence)
        self.replay_from = k if self.replay_from is None else min(self.replay_from, k)
        return False

    def take_fresh(self, record: Record) -> bool:
        """Whether a record is applied for the first time (then counted: live)."""
        live = record.sequence in self._fresh
        self._fresh.discard(record.sequence)
        return live
