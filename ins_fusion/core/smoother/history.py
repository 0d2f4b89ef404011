"""What the RTS smoother (core.smoother.rts) needs from one forward run, and its backward pass.

``SmootherHistory`` implements the engine's ``SmootherHooks``. One record per transition (a
covariance step, a restarted state, noise added at one instant): its time, its segment, a
snapshot of the engine's outputs at that moment (the prior x̂_j⁻: a row of numbers, opaque here,
and the Jacobian J of those outputs over some of the error states), P before (P_{j-1}⁺), Φ, P
after (P_j⁻), and the sum c_j of the corrections the updates of that step fed back. The output
of the backward pass at step j is the snapshot's row, J (e_j + c_j) and J P_j^s Jᵀ: the change
that moves the forward outputs onto the smoothed state, and the smoothed output covariance.

Rollbacks: a checkpoint marks how many records existed and the correction of the newest; a
rollback to it drops the later records and restores that correction, so the records always
describe the engine's final timeline (late measurements re-propagated), never the superseded one.

Memory: records per covariance step, not per IMU sample. The newest are kept in memory as
references to the engine's own arrays (they are never modified in place); once more than two
chunks (``chunk_records``) are held, the oldest chunk is packed (P as upper triangles) and
written to disk as one ``.npy`` file in a temporary directory (removed by ``close``), unless a
rollback could still reach it (``horizon_s`` covers the engine's history). The backward pass
reads the chunks back newest first, memory-mapped. With the 20 error states of the default
configuration a record takes 1 074 numbers (8.6 kB); 10–20 records per second of drive.
"""

from __future__ import annotations

import shutil
import tempfile
import weakref
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np

from gnss_ins_common.types import FloatArray, IntArray
from ins_fusion.core.smoother.rts import Smoothed, backward_step


@dataclass(frozen=True)
class Snapshot:
    """The engine's outputs at a transition: stamp t_s [s], ``row`` (values, any meaning),
    ``jacobian`` (len(row'), k): derivatives of the smoothed outputs with respect to the error
    states ``states`` of the history; ``smoothable``: False where the step is not smoothed (the
    heading still unknown)."""

    t_s: float
    row: FloatArray
    jacobian: FloatArray
    smoothable: bool


@dataclass(frozen=True)
class SmoothedEpoch:
    """The backward pass at one record: the snapshot's stamp and row, ``delta`` = J (e + c) (the
    smoothed outputs minus the forward ones, to first order), ``cov`` = J P^s Jᵀ and ``error``
    = e + c, the smoothed error relative to the snapshot's (prior) nominal state."""

    t_s: float
    row: FloatArray
    delta: FloatArray
    cov: FloatArray
    error: FloatArray


class _Record:
    __slots__ = (
        "P_after",
        "P_before",
        "correction",
        "jacobian",
        "phi",
        "row",
        "segment",
        "smoothable",
        "t_s",
    )

    def __init__(
        self,
        segment: int,
        snapshot: Snapshot,
        P_before: FloatArray,
        phi: FloatArray,
        P_after: FloatArray,
        correction: FloatArray,
    ) -> None:
        self.t_s = snapshot.t_s
        self.segment = segment
        self.smoothable = snapshot.smoothable
        self.row = snapshot.row
        self.jacobian = np.array(snapshot.jacobian, dtype=np.float64)  # the engine reuses it
        self.P_before = P_before
        self.phi = phi
        self.P_after = P_after
        self.correction = correction


class _Mark(NamedTuple):
    """History state at a checkpoint: stamp, records so far, the newest one's correction (an
    array replaced, never changed in place) and the segment counter."""

    t_s: float
    records: int
    correction: FloatArray | None
    segment: int


class _Layout:
    """Column layout of a packed record: t, segment, smoothable, row, J, c, P before (upper
    triangle), Φ, P after (upper triangle)."""

    def __init__(self, size: int, row: int, jacobian: tuple[int, int]) -> None:
        self.size = size
        self.jacobian_shape = jacobian
        self.upper = np.triu_indices(size)
        widths = (
            ("head", 3),
            ("row", row),
            ("jacobian", jacobian[0] * jacobian[1]),
            ("correction", size),
            ("P_before", len(self.upper[0])),
            ("phi", size * size),
            ("P_after", len(self.upper[0])),
        )
        self.slices: dict[str, slice] = {}
        start = 0
        for name, width in widths:
            self.slices[name] = slice(start, start + width)
            start += width
        self.width = start

    def pack(self, records: list[_Record]) -> FloatArray:
        out = np.empty((len(records), self.width))
        sl = self.slices
        for i, r in enumerate(records):
            line = out[i]
            line[sl["head"]] = (r.t_s, r.segment, r.smoothable)
            line[sl["row"]] = r.row
            line[sl["jacobian"]] = r.jacobian.ravel()
            line[sl["correction"]] = r.correction
            line[sl["P_before"]] = r.P_before[self.upper]
            line[sl["phi"]] = r.phi.ravel()
            line[sl["P_after"]] = r.P_after[self.upper]
        return out

    def unpack(self, line: FloatArray) -> _Record:
        sl = self.slices
        t_s, segment, smoothable = line[sl["head"]].tolist()
        snapshot = Snapshot(
            t_s,
            np.array(line[sl["row"]]),
            line[sl["jacobian"]].reshape(self.jacobian_shape),
            bool(smoothable),
        )
        return _Record(
            int(segment),
            snapshot,
            self._symmetric(line[sl["P_before"]]),
            np.array(line[sl["phi"]]).reshape(self.size, self.size),
            self._symmetric(line[sl["P_after"]]),
            np.array(line[sl["correction"]]),
        )

    def _symmetric(self, upper: FloatArray) -> FloatArray:
        P = np.zeros((self.size, self.size))
        P[self.upper] = upper
        P.T[self.upper] = upper
        return P


class SmootherHistory:
    """Records a forward run through the engine's hooks (see the module docstring).

    ``size``: error-state dimension; ``states``: the error states the snapshots' Jacobians are
    over; ``snapshot``: called at each transition for the engine's current outputs;
    ``horizon_s``: how far back a rollback can go (at least the engine's history) [s];
    ``chunk_records``: records per file on disk; ``directory``: where the temporary directory
    goes (None: the system's).
    """

    def __init__(
        self,
        size: int,
        states: IntArray,
        snapshot: Callable[[], Snapshot],
        horizon_s: float,
        chunk_records: int = 4096,
        directory: Path | None = None,
    ) -> None:
        self.size = size
        self.states = states
        self._snapshot = snapshot
        self._horizon_s = horizon_s
        self._chunk = max(1, chunk_records)
        self._directory = directory
        self._spill_dir: Path | None = None
        self._chunks: list[Path] = []
        self._spilled = 0
        self._layout: _Layout | None = None
        self._recent: list[_Record] = []
        self._marks: deque[_Mark] = deque()
        self._segment = 0
        self._final: dict[int, FloatArray] = {}
        self._eye = np.eye(size)
        self._finalizer: Callable[[], object] | None = None

    # -------------------------------------------------------------------------- the hooks

    def on_transition(self, P_before: FloatArray, phi: FloatArray, P_after: FloatArray) -> None:
        """A covariance propagation (core.smoother.rts.SmootherHooks)."""
        self._append(P_before, phi, P_after)

    def on_restart(self, P_before: FloatArray, P_after: FloatArray, states: range) -> None:
        """Restarted states: Φ = I with their rows zeroed."""
        phi = self._eye.copy()
        phi[states, states] = 0.0
        self._append(P_before, phi, P_after)

    def on_noise(self, P_before: FloatArray, P_after: FloatArray) -> None:
        """Noise added at one instant: Φ = I."""
        self._append(P_before, self._eye, P_after)

    def on_correction(self, dx: FloatArray) -> None:
        """Add an injected estimate to the newest record's correction (none after a break:
        the closed segment ends with the state before it)."""
        if self._recent and self._recent[-1].segment == self._segment:
            newest = self._recent[-1]
            newest.correction = newest.correction + dx

    def on_checkpoint(self, t_s: float) -> None:
        """Remember the history's state at a checkpoint; forget marks beyond the horizon."""
        marks = self._marks
        while marks and marks[-1].t_s >= t_s:
            marks.pop()
        while marks and marks[0].t_s < t_s - self._horizon_s:
            marks.popleft()
        recent = self._recent
        newest = recent[-1].correction if recent else None
        marks.append(_Mark(t_s, self._spilled + len(recent), newest, self._segment))

    def on_rollback(self, t_s: float) -> None:
        """Back to the checkpoint at t_s: drop what followed it."""
        marks = self._marks
        while marks and marks[-1].t_s > t_s:
            marks.pop()
        if not marks or marks[-1].t_s != t_s:
            raise RuntimeError(f"smoother history: no checkpoint at {t_s:.6f} s to roll back to")
        mark = marks[-1]
        keep = mark.records - self._spilled
        if keep < 0:
            raise RuntimeError("smoother history: a rollback reaches records already on disk")
        del self._recent[keep:]
        if self._recent and mark.correction is not None:
            self._recent[-1].correction = mark.correction
        self._segment = mark.segment
        for segment in [s for s in self._final if s >= mark.segment]:
            del self._final[segment]

    def on_break(self, P: FloatArray | None) -> None:
        """Close the segment with the posterior P of its last step (None: unknown)."""
        if P is not None:
            self._final[self._segment] = P
        self._segment += 1

    def on_reset(self, P: FloatArray | None) -> None:
        """A break that no rollback crosses."""
        self.on_break(P)
        self._marks.clear()

    # ---------------------------------------------------------------------------- results

    @property
    def records(self) -> int:
        """Records held (in memory and on disk)."""
        return self._spilled + len(self._recent)

    @property
    def bytes_on_disk(self) -> int:
        """Size of the chunks written so far [bytes]."""
        return sum(path.stat().st_size for path in self._chunks)

    def finish(self, P: FloatArray | None) -> None:
        """End of the run: ``P`` is the posterior of the last step (the engine's covariance)."""
        self.on_reset(P)

    def backward(self) -> Iterator[SmoothedEpoch]:
        """The RTS backward pass over every segment, newest record first; records that are not
        smoothable or not finite are left out (and cut their segment's chain there)."""
        later: Smoothed | None = None
        after: _Record | None = None  # step j's record while step j-1 is computed
        newer_segment: int | None = None
        states = self.states
        for record in self._newest_first():
            last_of_segment = record.segment != newer_segment
            newer_segment = record.segment
            if not record.smoothable:
                later = after = None
                continue
            if after is not None and later is not None and not last_of_segment:
                later = backward_step(
                    later, after.correction, after.P_before, after.phi, after.P_after
                )
            else:  # the chain starts: the forward filter's posterior (or prior) is the answer
                final = self._final.get(record.segment) if last_of_segment else None
                if final is None or not np.isfinite(final).all():
                    final = record.P_after
                later = Smoothed(np.zeros(self.size), final)
            if not (np.isfinite(later.error).all() and np.isfinite(later.cov).all()):
                later = after = None
                continue
            after = record
            error = later.error + record.correction
            J = record.jacobian
            yield SmoothedEpoch(
                record.t_s,
                record.row,
                J @ error[states],
                J @ later.cov[np.ix_(states, states)] @ J.T,
                error,
            )

    def close(self) -> None:
        """Forget the records and delete the chunks on disk (also done when the history is
        garbage-collected)."""
        if self._finalizer is not None:
            self._finalizer()
        self._chunks = []
        self._recent = []
        self._final = {}
        self._marks.clear()

    # ---------------------------------------------------------------------------- storage

    def _append(self, P_before: FloatArray, phi: FloatArray, P_after: FloatArray) -> None:
        record = _Record(
            self._segment, self._snapshot(), P_before, phi, P_after, np.zeros(self.size)
        )
        self._recent.append(record)
        if len(self._recent) >= 2 * self._chunk:
            self._spill()

    def _spill(self) -> None:
        """Write the oldest chunk to disk when no rollback can reach it."""
        oldest_mark = self._marks[0].t_s if self._marks else np.inf
        chunk = self._recent[: self._chunk]
        if chunk[-1].t_s >= oldest_mark:
            return
        if self._layout is None:
            first = chunk[0]
            self._layout = _Layout(self.size, len(first.row), first.jacobian.shape)
        if self._spill_dir is None:
            self._spill_dir = Path(
                tempfile.mkdtemp(prefix="gnss_ins_smoother_", dir=self._directory)
            )
            self._finalizer = weakref.finalize(self, shutil.rmtree, self._spill_dir, True)
        path = self._spill_dir / f"chunk_{len(self._chunks):05d}.npy"
        np.save(path, self._layout.pack(chunk))
        self._chunks.append(path)
        self._spilled += len(chunk)
        del self._recent[: self._chunk]

    def _newest_first(self) -> Iterator[_Record]:
        yield from reversed(self._recent)
        layout = self._layout
        for path in reversed(self._chunks):
            assert layout is not None
            lines = np.load(path, mmap_mode="r")
            for i in range(len(lines) - 1, -1, -1):
                yield layout.unpack(lines[i])
