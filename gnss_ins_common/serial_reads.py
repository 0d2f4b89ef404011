"""Reads of a serial port gathered into one raw-record message, and split again (no ROS).

A driver publishes what it reads from its port (``imu/raw``, gnss_ins_msgs/SerialChunk) so that a
recording can be decoded again. One message per read cost the IMU node and the recorder one
middleware message each for 134 reads a second; a message now carries the reads of up to
``ReadBatch.period_ns``: their bytes one after the other (``data``), where each read ends in them
(``read_ends``) and each read's host time (``read_times_ns``), so that every read is rebuilt
exactly (``split_reads``) and fed to the driver core as the node fed it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field


@dataclass(frozen=True)
class ReadsRecord:
    """The fields of one raw-record message: the reads' bytes, their ends in them, their times."""

    data: bytes
    #: end offset of each read in ``data`` (increasing; the last is ``len(data)``)
    read_ends: list[int]
    #: host time of each read [ns since the epoch, ROS time]
    read_times_ns: list[int]


@dataclass
class ReadBatch:
    """Reads waiting to be published together: ``add`` says when the batch is due (its first
    read ``period_ns`` old or ``max_reads`` reads), ``take`` empties it."""

    period_ns: int
    max_reads: int
    _chunks: list[bytes] = field(default_factory=list)
    _times_ns: list[int] = field(default_factory=list)

    def __post_init__(self) -> None:
        if self.period_ns < 0 or self.max_reads < 1:
            raise ValueError(f"period_ns >= 0 and max_reads >= 1, got {self}")

    def __len__(self) -> int:
        return len(self._chunks)

    def add(self, chunk: bytes, time_ns: int) -> bool:
        """One read of ``chunk`` at ``time_ns`` [ns]; True when the batch is due."""
        self._chunks.append(chunk)
        self._times_ns.append(time_ns)
        return self.due(time_ns)

    def due(self, now_ns: int) -> bool:
        """The batch holds reads and its first is ``period_ns`` old at ``now_ns``, or it is
        full."""
        return bool(self._chunks) and (
            len(self._chunks) >= self.max_reads or now_ns - self._times_ns[0] >= self.period_ns
        )

    def take(self) -> ReadsRecord | None:
        """The batch as one record (None when empty), the batch emptied."""
        if not self._chunks:
            return None
        ends, end = [], 0
        for chunk in self._chunks:
            end += len(chunk)
            ends.append(end)
        record = ReadsRecord(b"".join(self._chunks), ends, self._times_ns)
        self._chunks, self._times_ns = [], []
        return record


def split_reads(
    data: bytes, read_ends: Sequence[int], read_times_ns: Sequence[int], stamp_ns: int
) -> list[tuple[bytes, int]]:
    """The reads of a raw-record message as (bytes, host time [ns]). A message of one read may
    leave ``read_ends`` and ``read_times_ns`` empty: ``data`` read at ``stamp_ns`` (its header
    stamp). ValueError when the ends do not cut ``data`` or the times do not match them."""
    if len(read_ends) == 0 and len(read_times_ns) == 0:  # numpy arrays (rosbags) or lists
        return [(bytes(data), stamp_ns)]
    ends = [int(e) for e in read_ends]
    if len(ends) != len(read_times_ns):
        raise ValueError(f"{len(ends)} read ends for {len(read_times_ns)} read times")
    if ends != sorted(ends) or ends[-1] != len(data) or ends[0] < 0:
        raise ValueError(f"read ends {ends[:5]}... do not cut {len(data)} bytes in order")
    starts = [0, *ends[:-1]]
    return [(bytes(data[a:b]), int(t)) for a, b, t in zip(starts, ends, read_times_ns, strict=True)]
