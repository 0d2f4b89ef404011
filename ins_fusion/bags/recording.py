"""The writing side of a live recording (no rclpy): messages in log-time order, flushed on a
bounded interval, and a guard on the disk's free space.

``RecordingWriter`` is fed by the recorder's subscriptions (``receive``) and driven by its writer
thread (``service``, ``close``). It owns the ``BagWriter``:

- **Order.** Messages of several topics reach the recorder out of log-time order (a GNSS epoch is
  handed over after IMU samples received later). Each is held ``hold_s`` after its receive time,
  then written in log-time order, so every chunk, and a whole file, is in order: an unfinished
  file's complete chunks read like a finished file's. One that arrives later than that is still
  written (counted in ``late``).
- **Flush.** What is written is put on disk (MCAP chunk closed and fsynced, sqlite3 committed) at
  most ``flush_period_s`` later: a kill or power cut loses at most ``hold_s + flush_period_s``.
- **Disk guard.** Every ``DISK_CHECK_PERIOD_S`` the free space of the bag's file system is read
  (statvfs). Below twice the limit: a warning. Below the limit: the current file is closed
  (complete), then by policy the recording stops (the bag closed, readable without ``recover``)
  or the oldest closed files of this recording are deleted, each named in the log, until the free
  space is back above twice the limit; when none is left to delete, it stops.
"""

from __future__ import annotations

import heapq
import os
import re
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from rosbags.interfaces import Qos

from ins_fusion.bags.bag_io import BagWriter
from ins_fusion.bags.summary import utc_text

#: Seconds between two reads of the free disk space.
DISK_CHECK_PERIOD_S = 1.0
#: Default limit of free space: the smaller of these (bytes, fraction of the file system).
DEFAULT_MIN_FREE = "1G,5%"
#: Policies when the free space falls below the limit.
POLICIES = ("stop", "rotate")
_UNITS = {"": 1, "K": 2**10, "M": 2**20, "G": 2**30, "T": 2**40}

#: ``log(level, text)``: the recorder's log (level "info", "warn" or "error").
Log = Callable[[str, str], None]


@dataclass(frozen=True)
class FreeSpace:
    """Free space (bytes available to unprivileged users) and size of a file system."""

    free_bytes: int
    total_bytes: int


def free_space(path: Path) -> FreeSpace:
    """``statvfs`` of the file system holding ``path``."""
    stat = os.statvfs(path)
    return FreeSpace(stat.f_bavail * stat.f_frsize, stat.f_blocks * stat.f_frsize)


@dataclass(frozen=True)
class MinFree:
    """A free-space limit: the smallest of a size in bytes and a fraction of the file system
    (either may be absent); 0 bytes switches the guard off."""

    bytes: int | None
    fraction: float | None

    def limit(self, total_bytes: int) -> int:
        """The limit in bytes on a file system of ``total_bytes``."""
        limits = [b for b in (self.bytes,) if b is not None]
        if self.fraction is not None:
            limits.append(round(self.fraction * total_bytes))
        return min(limits)

    @staticmethod
    def parse(text: str) -> MinFree:
        """``1G``, ``500M``, ``123456``, ``5%`` or both (``1G,5%``); ValueError otherwise."""
        size: int | None = None
        fraction: float | None = None
        for item in text.replace(" ", "").split(","):
            if match := re.fullmatch(r"(\d+(?:\.\d+)?)%", item):
                value = float(match.group(1))
                if not 0 <= value < 100 or fraction is not None:
                    raise ValueError(f"bad percentage {item!r}: one value in [0, 100)")
                fraction = value / 100
            elif match := re.fullmatch(r"(\d+(?:\.\d+)?)([KMGT]?)(?:i?B)?", item, re.IGNORECASE):
                if size is not None:
                    raise ValueError(f"two sizes in {text!r}")
                size = round(float(match.group(1)) * _UNITS[match.group(2).upper()])
            else:
                raise ValueError(f"bad size {item!r}: e.g. 1G, 500M, 5% or 1G,5%")
        return MinFree(size, fraction)


class RecordingWriter:
    """Holds, orders, writes, flushes and guards (see the module docstring). Every method runs
    on the thread that owns ``writer`` (the recorder's writer thread, fed through a queue)."""

    def __init__(
        self,
        writer: BagWriter,
        log: Log,
        *,
        hold_s: float,
        flush_period_s: float,
        min_free: MinFree,
        policy: str = "stop",
        statvfs: Callable[[Path], FreeSpace] = free_space,
    ) -> None:
        if policy not in POLICIES:
            raise ValueError(f"policy {policy!r}: one of {', '.join(POLICIES)}")
        self.writer, self.log = writer, log
        self.hold_ns = round(hold_s * 1e9)
        self.flush_period_s = flush_period_s
        self.min_free, self.policy, self.statvfs = min_free, policy, statvfs
        #: why the disk guard stopped the recording, its bag closed (None: it did not)
        self.stopped: str | None = None
        #: messages written after a later one had been (arrived more than ``hold_s`` late)
        self.late = 0
        #: files deleted by the disk guard
        self.deleted: list[Path] = []
        self.free: FreeSpace | None = None
        self._held: list[tuple[int, int, str, bytes]] = []  # heap of (receive ns, seq, ...)
        self._seq = 0
        self._last_written_ns = 0
        self._flush_due: float | None = None  # monotonic time of the next flush
        self._next_disk_check = 0.0
        #: free space below twice the limit
        self.low_disk = False
        self._gap_reported = writer.resumed_end_ns == 0

    def declare(self, topic: str, msgtype: str, qos: Sequence[Qos]) -> None:
        """A new topic of the recording."""
        self.writer.add_topic(topic, msgtype, qos)

    def receive(self, topic: str, receive_ns: int, data: bytes) -> None:
        """A message received at ``receive_ns`` (system clock, ns): held, written later."""
        heapq.heappush(self._held, (receive_ns, self._seq, topic, data))
        self._seq += 1

    def service(self, now_ns: int | None = None, monotonic: float | None = None) -> float:
        """Write what has been held long enough, flush and check the disk when due; returns the
        seconds until the next call is needed."""
        now_ns = time.time_ns() if now_ns is None else now_ns
        monotonic = time.monotonic() if monotonic is None else monotonic
        if self.stopped is None:
            self._release(now_ns - self.hold_ns, monotonic)
        if self._flush_due is not None and monotonic >= self._flush_due:
            self.writer.flush()
            self._flush_due = None
        if monotonic >= self._next_disk_check:
            self._next_disk_check = monotonic + DISK_CHECK_PERIOD_S
            self._check_disk()
        waits = [self._next_disk_check - monotonic]
        if self._held:
            waits.append((self._held[0][0] + self.hold_ns - now_ns) / 1e9)
        if self._flush_due is not None:
            waits.append(self._flush_due - monotonic)
        return max(0.0, min(waits))

    def close(self) -> None:
        """Write everything held, close the bag."""
        if self.stopped is None:
            self._release(None, time.monotonic())
        self.writer.close()

    def _release(self, until_ns: int | None, monotonic: float) -> None:
        """Write the held messages received at or before ``until_ns`` (None: all)."""
        written = False
        while self._held and (until_ns is None or self._held[0][0] <= until_ns):
            receive_ns, _, topic, data = heapq.heappop(self._held)
            if receive_ns < self._last_written_ns:
                self.late += 1
            elif not self._gap_reported:
                self._gap_reported = True
                gap_s = (receive_ns - self.writer.resumed_end_ns) / 1e9
                self.log("warn", f"recording continued: gap of {gap_s:.3f} s since its last data")
            self._last_written_ns = max(self._last_written_ns, receive_ns)
            self.writer.write(topic, receive_ns, data)
            written = True
        if written and self._flush_due is None:
            self._flush_due = monotonic + self.flush_period_s

    def _check_disk(self) -> None:
        self.free = self.statvfs(self.writer.path)
        limit = self.min_free.limit(self.free.total_bytes)
        if limit <= 0 or self.stopped is not None:
            return
        if self.free.free_bytes >= 2 * limit:
            self.low_disk = False
            return
        if not self.low_disk:
            self.low_disk = True
            self.log(
                "warn",
                f"disk space low: {_size(self.free.free_bytes)} free on the bag's"
                f" file system, the recording stops or rotates at {_size(limit)}",
            )
        if self.free.free_bytes >= limit:
            return
        self.writer.start_new_file()  # the current file closed, complete
        if self.policy == "rotate":
            self._rotate(limit)
        if self.free.free_bytes < limit:
            self._release(None, time.monotonic())
            self.writer.close()
            self.stopped = (
                f"free disk space {_size(self.free.free_bytes)} below the limit {_size(limit)}:"
                f" recording stopped, {self.writer.path} closed (complete)"
            )
            self.log("error", self.stopped)

    def _rotate(self, limit: int) -> None:
        """Delete the oldest closed files until the free space is above twice ``limit``."""
        assert self.free is not None
        while self.free.free_bytes < 2 * limit and len(self.writer.files) > 1:
            removed = self.writer.remove_oldest_file()
            if removed is None:
                break
            path, start_ns, end_ns = removed
            self.deleted.append(path)
            self.log(
                "warn",
                f"disk space below {_size(limit)}: deleted the oldest file {path.name}"
                f" ({utc_text(start_ns)} .. {utc_text(end_ns)}) of this recording",
            )
            self.free = self.statvfs(self.writer.path)


def _size(n_bytes: int) -> str:
    """``1.5 GiB``, ``300.0 MiB``, ``12.0 KiB``."""
    for unit, scale in (("GiB", 2**30), ("MiB", 2**20)):
        if abs(n_bytes) >= scale:
            return f"{n_bytes / scale:.1f} {unit}"
    return f"{n_bytes / 2**10:.1f} KiB"
