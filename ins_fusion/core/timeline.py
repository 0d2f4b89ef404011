"""The engine's late-measurement timeline: a history of IMU samples with checkpoints, the
measurements filed at them, and the measurements waiting for a later sample.

A measurement stamped t_m belongs to the last history entry at or before t_m. Filed at the
newest entry it is applied at once; filed earlier, the engine rolls back to that entry's
checkpoint and re-propagates the later samples with their measurements (``replay_from`` says
from where; InsEngine._catch_up does it). Measurements newer than the newest sample wait in a
heap (at most ``MAX_PENDING``). Duplicates (same kind and stamp) are counted and dropped;
measurements older than the history are counted ``too_old`` and rejected.
"""

from __future__ import annotations

import bisect
import heapq
import itertools
import math
from dataclasses import dataclass
from typing import Any

from gnss_ins_common.types import FloatArray
from ins_fusion.core.state import FilterState
from ins_fusion.core.status import MEASUREMENT_NAMES, Counters

#: A measurement in the history: (stamp, rank of its kind in MEASUREMENT_NAMES, arrival
#: sequence, kind, payload). Records sort by stamp, then kind: measurements with the same stamp
#: are applied in one order whatever order they arrived in.
Record = tuple[float, int, int, str, Any]
_RANK = {name: rank for rank, name in enumerate(MEASUREMENT_NAMES)}
#: Most measurements waiting for a later IMU sample.
MAX_PENDING = 256

Checkpoint = tuple[FilterState, FloatArray]
"""The nominal state and the error covariance after an IMU sample."""


@dataclass(frozen=True, slots=True)
class Gap:
    """Uncertainty of the increment that bridges missing IMU samples: variances of the angle
    [rad²] and velocity [m²/s²] increments per imu FRD axis (core.propagation.bridge)."""

    angle_var_rad2: tuple[float, ...]
    velocity_var_m2_s2: tuple[float, ...]


class Entry:
    """One IMU sample in the history: its raw increment (imu FRD, calibrated), the gap it
    bridges (None: none; after one the coning/sculling history restarts), the IMU white-noise
    densities in force at it (core.propagation.ImuDensities), the checkpoint after it and its
    measurements."""

    __slots__ = ("checkpoint", "gap", "inc", "measurements", "noise", "t_s")

    def __init__(
        self,
        t_s: float,
        inc: FloatArray,
        gap: Gap | None,
        noise: tuple[FloatArray, FloatArray] | None,
        checkpoint: Checkpoint,
    ) -> None:
        self.t_s = t_s
        self.inc = inc
        self.gap = gap
        self.noise = noise
        self.checkpoint = checkpoint
        self.measurements: list[Record] = []


class Timeline:
    """History entries (oldest first) and pending measurements (see the module docstring)."""

    history: list[Entry]
    replay_from: int | None

    def __init__(self, history_s: float) -> None:
        self._history_s = history_s
        self._sequence = itertools.count()
        self.clear()

    def clear(self) -> None:
        """Forget every entry and measurement (start, reset)."""
        self.history = []
        self._history_t: list[float] = []
        self._pending: list[Record] = []
        self.replay_from = None
        self._fresh: set[int] = set()
        self._seen: dict[str, set[float]] = {name: set() for name in MEASUREMENT_NAMES}

    def start(self, entry: Entry) -> None:
        """The first entry of a running filter."""
        self.history = [entry]
        self._history_t = [entry.t_s]

    def append(self, entry: Entry) -> None:
        """A new IMU sample; entries older than ``history_s`` go (in batches of 1 s)."""
        self.history.append(entry)
        self._history_t.append(entry.t_s)
        t = entry.t_s
        if self._history_t[0] < t - self._history_s - 1.0:
            keep = bisect.bisect_left(self._history_t, t - self._history_s)
            del self.history[:keep]
            del self._history_t[:keep]

    def extend(self, entries: list[Entry]) -> None:
        """``append`` of each of ``entries`` (in stamp order), in one call."""
        history_t = self._history_t
        self.history.extend(entries)
        history_t.extend([entry.t_s for entry in entries])
        for entry in entries:  # append's pruning after each entry
            t = entry.t_s
            if history_t[0] < t - self._history_s - 1.0:
                keep = bisect.bisect_left(history_t, t - self._history_s)
                del self.history[:keep]
                del history_t[:keep]

    def record(self, kind: str, t_m: float, payload: Any) -> Record:
        """A new record of a measurement."""
        return (t_m, _RANK[kind], next(self._sequence), kind, payload)

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
                counters[dropped[3]]["rejected"] += 1
            heapq.heappush(self._pending, record)
            return None
        return record if self.insert(record) else None

    def due_by(self, t_s: float) -> bool:
        """Whether a pending measurement is stamped before ``t_s`` (``due`` would take it)."""
        pending = self._pending
        return bool(pending) and pending[0][0] < t_s

    def due_stamp(self) -> float:
        """Stamp of the first pending measurement [s] (inf: none): ``due_by(t)`` is this < t."""
        pending = self._pending
        return pending[0][0] if pending else math.inf

    def due(self, t_s: float) -> list[Record]:
        """Take the pending measurements stamped before ``t_s`` (stamp order)."""
        pending = self._pending
        records = []
        while pending and pending[0][0] < t_s:
            records.append(heapq.heappop(pending))
        return records

    def insert(self, record: Record) -> bool:
        """File a measurement at the last history entry at or before its stamp. True: it is
        the newest at the newest entry, to be applied now; else re-propagation from that
        entry is due (``replay_from``)."""
        k = bisect.bisect_right(self._history_t, record[0]) - 1
        entry = self.history[k]
        newest = not entry.measurements or entry.measurements[-1] < record
        if self.replay_from is None and k == len(self.history) - 1 and newest:
            entry.measurements.append(record)
            return True
        bisect.insort(entry.measurements, record)
        self._fresh.add(record[2])
        self.replay_from = k if self.replay_from is None else min(self.replay_from, k)
        return False

    def take_fresh(self, record: Record) -> bool:
        """Whether a record is applied for the first time (then counted: live)."""
        sequence = record[2]
        live = sequence in self._fresh
        self._fresh.discard(sequence)
        return live
