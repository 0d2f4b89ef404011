"""RTCM 3 corrections on their way to the receiver: validated, queued, written in time (no ROS).

A correction stream (network RTK through an NTRIP client, or a base station) arrives as
messages, each of which must hold whole RTCM 3 frames (rtcm_msgs/Message). ``CorrectionQueue``
keeps only the frames whose CRC-24Q is valid, framed afresh for each message (a frame split over
two messages is not a frame; its bytes are counted invalid and never written), in the order
received. Corrections are useful only while fresh: a frame older than ``max_age_s`` when its
turn comes is dropped, never written late; so is everything queued when the port is lost
(``clear``). ``CorrectionWriter`` takes the frames on a thread of its own and writes each whole
frame to the device with one write.
"""

from __future__ import annotations

import collections
import copy
import math
import threading
from collections.abc import Callable
from dataclasses import dataclass, field

from gnss_ins_common.rtcm import RtcmFramer, message_number

#: The longest the writer sleeps without a frame [s] (a frame or ``stop`` wakes it at once).
_IDLE_WAIT_S = 5.0


@dataclass(slots=True)
class CorrectionStats:
    """Counters since start-up: frames in, written and dropped."""

    messages_in: int = 0
    frames_in: int = 0
    #: Bytes of received messages outside valid frames (never written).
    invalid_bytes: int = 0
    #: Candidate frames whose CRC-24Q failed.
    crc_failures: int = 0
    frames_written: int = 0
    bytes_written: int = 0
    #: Frames older than the age limit at their turn, or queued when the port was lost.
    dropped_stale: int = 0
    #: Oldest frames dropped because the queue was full.
    dropped_overflow: int = 0
    #: Frames the link refused (port not ready) or failed to write.
    write_failures: int = 0
    #: Host time of the last frame written [s]; NaN before the first.
    last_written_s: float = math.nan
    #: Frames written per RTCM message number.
    written_by_number: collections.Counter[int] = field(default_factory=collections.Counter)


class CorrectionQueue:
    """Thread-safe queue of valid RTCM 3 frames with their host receive times."""

    def __init__(self, max_age_s: float = 3.0, max_frames: int = 2000) -> None:
        """``max_age_s``: oldest frame still written [s]; ``max_frames``: queue length."""
        self.max_age_s = max_age_s
        self.max_frames = max_frames
        self._frames: collections.deque[tuple[bytes, float]] = collections.deque()
        self._stats = CorrectionStats()
        self._ready = threading.Condition()

    @property
    def stats(self) -> CorrectionStats:
        """A copy of the counters."""
        with self._ready:
            return copy.deepcopy(self._stats)

    def __len__(self) -> int:
        """Frames waiting [frames]."""
        with self._ready:
            return len(self._frames)

    def accept(self, data: bytes, received_s: float) -> int:
        """One received message: queue its valid frames in order; returns how many."""
        framer = RtcmFramer()
        frames = framer.feed(data)
        with self._ready:
            stats = self._stats
            stats.messages_in += 1
            stats.invalid_bytes += framer.stats.skipped_bytes + framer.buffered
            stats.crc_failures += framer.stats.crc_failures
        self.put(frames, received_s)
        return len(frames)

    def put(self, frames: list[bytes], received_s: float) -> None:
        """Queue whole, valid ``frames`` received at host time ``received_s`` [s]; when full,
        the oldest are dropped."""
        if not frames:
            return
        with self._ready:
            self._stats.frames_in += len(frames)
            self._frames.extend((frame, received_s) for frame in frames)
            overflow = len(self._frames) - self.max_frames
            for _ in range(max(0, overflow)):
                self._frames.popleft()
            self._stats.dropped_overflow += max(0, overflow)
            self._ready.notify()

    def wait(self, timeout_s: float) -> bool:
        """Wait up to ``timeout_s`` [s] for a frame (or ``wake``); True when one is queued."""
        with self._ready:
            if not self._frames:
                self._ready.wait(timeout_s)
            return bool(self._frames)

    def wake(self) -> None:
        """End every ``wait`` in progress now (it sees no frame unless one is queued)."""
        with self._ready:
            self._ready.notify_all()

    def take(self, now_s: float) -> bytes | None:
        """The next frame no older than ``max_age_s`` at host time ``now_s`` [s] (older ones are
        dropped); None when none is queued (``wait`` waits for one)."""
        with self._ready:
            while self._frames:
                frame, received_s = self._frames.popleft()
                if now_s - received_s <= self.max_age_s:
                    return frame
                self._stats.dropped_stale += 1
            return None

    def clear(self) -> int:
        """Drop every queued frame (counted stale), e.g. when the port is lost; returns how
        many."""
        with self._ready:
            dropped = len(self._frames)
            self._frames.clear()
            self._stats.dropped_stale += dropped
            return dropped

    def note_write(self, frame: bytes, written_s: float, ok: bool) -> None:
        """Count ``frame`` as written at host time ``written_s`` [s], or its write as failed."""
        with self._ready:
            stats = self._stats
            if not ok:
                stats.write_failures += 1
                return
            stats.frames_written += 1
            stats.bytes_written += len(frame)
            stats.last_written_s = written_s
            stats.written_by_number[message_number(frame)] += 1


class CorrectionWriter:
    """Writes a queue's frames to the device on its own thread, one whole frame per write,
    while the port is ready; while it is not, the queue is kept empty (nothing received before
    or during a loss is written after it)."""

    def __init__(
        self,
        queue: CorrectionQueue,
        *,
        write: Callable[[bytes], bool],
        ready: Callable[[], bool],
        now: Callable[[], float],
        on_written: Callable[[bytes, float], None] | None = None,
    ) -> None:
        """``write(frame)``: True when written (``SerialLink.write``); ``ready()``: the port is
        open and set up; ``now()``: host time [s] on the clock of the receive times;
        ``on_written(frame, host_s)``: after each frame written."""
        self.queue = queue
        self._write = write
        self._ready = ready
        self._now = now
        self._on_written = on_written
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        """Start the writer thread."""
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name="rtcm-writer", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop the writer thread (a write in progress completes)."""
        self._stop.set()
        self.queue.wake()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None

    def _run(self) -> None:
        queue = self.queue
        while not self._stop.is_set():
            if not queue.wait(_IDLE_WAIT_S) or self._stop.is_set():
                continue
            if not self._ready():
                queue.clear()
                continue
            frame = queue.take(self._now())
            if frame is None:
                continue
            ok = self._write(frame)
            written_s = self._now()
            queue.note_write(frame, written_s, ok)
            if ok and self._on_written is not None:
                self._on_written(frame, written_s)
