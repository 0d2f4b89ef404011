"""gnss_driver.corrections: RTCM 3 frames validated, queued and written in time (no ROS)."""

from __future__ import annotations

import random
import threading

from hypothesis import given, settings
from hypothesis import strategies as st
from support.waiting import wait_for

from gnss_driver.corrections import CorrectionQueue, CorrectionWriter
from gnss_ins_common.rtcm import PREAMBLE, make_frame, message_number


def _frames(count: int, seed: int = 1) -> list[bytes]:
    """Frames of random payloads whose message numbers are 1001.. (12 bits, then noise)."""
    rng = random.Random(seed)
    frames = []
    for i in range(count):
        number = 1001 + i
        body = bytes(rng.randrange(256) for _ in range(rng.randrange(2, 60)))
        frames.append(make_frame(bytes((number >> 4, (number & 0xF) << 4 | body[0] & 0xF)) + body))
    return frames


def _taken(queue: CorrectionQueue, now_s: float) -> list[bytes]:
    out = []
    while (frame := queue.take(now_s)) is not None:
        out.append(frame)
    return out


def test_accept_queues_only_the_valid_frames_in_order():
    frames = _frames(4)
    bad_crc = bytearray(frames[2])
    bad_crc[-1] ^= 0x01
    message = b"HTTP noise" + frames[0] + b"\r\n" + frames[1] + bytes(bad_crc) + frames[3] + b"x"
    queue = CorrectionQueue()
    assert queue.accept(message, 100.0) == 3
    assert _taken(queue, 100.0) == [frames[0], frames[1], frames[3]]
    stats = queue.stats
    assert (stats.messages_in, stats.frames_in, stats.crc_failures) == (1, 3, 1)
    assert stats.invalid_bytes == len(b"HTTP noise\r\nx") + len(bad_crc)
    assert [message_number(f) for f in frames] == [1001, 1002, 1003, 1004]


def test_a_frame_split_over_two_messages_is_not_a_frame():
    first, split, last = _frames(3)
    queue = CorrectionQueue()
    assert queue.accept(first + split[:10], 1.0) == 1
    assert queue.accept(split[10:] + last, 1.0) == 1
    assert _taken(queue, 1.0) == [first, last]
    assert queue.stats.invalid_bytes == len(split)


def test_frames_older_than_the_age_limit_at_their_turn_are_dropped():
    old, fresh = _frames(2)
    queue = CorrectionQueue(max_age_s=3.0)
    queue.put([old], 10.0)
    queue.put([fresh], 12.0)
    assert queue.take(13.5) == fresh  # old: 3.5 s > 3 s at its turn
    assert queue.stats.dropped_stale == 1
    queue.put([old], 10.0)
    assert queue.take(13.0) == old  # exactly the limit: still written


def test_overflow_drops_the_oldest_and_clear_drops_everything():
    frames = _frames(5)
    queue = CorrectionQueue(max_frames=3)
    queue.put(frames, 0.0)
    assert queue.stats.dropped_overflow == 2 and len(queue) == 3
    assert queue.take(0.0) == frames[2]
    assert queue.clear() == 2
    assert queue.take(0.0) is None
    assert queue.stats.dropped_stale == 2


def _waiting(queue: CorrectionQueue) -> bool:
    """Whether a thread waits in ``queue.wait`` (its condition's waiters: CPython's)."""
    return bool(queue._ready._waiters)  # type: ignore[attr-defined]


def test_wait_ends_when_another_thread_queues_a_frame_or_wakes_it():
    (frame,) = _frames(1)
    queue = CorrectionQueue()
    waited: list[bool] = []
    waiter = threading.Thread(target=lambda: waited.append(queue.wait(30.0)))
    waiter.start()
    queue.put([frame], 0.0)
    waiter.join(timeout=30.0)
    assert waited == [True] and queue.take(0.0) == frame
    assert queue.take(0.0) is None  # nothing more
    waiter = threading.Thread(target=lambda: waited.append(queue.wait(30.0)))
    waiter.start()
    wait_for(lambda: _waiting(queue), 30.0)
    queue.wake()
    waiter.join(timeout=30.0)
    assert not waiter.is_alive() and waited == [True, False]


class _Device:
    """A link stand-in: written frames, and whether it is ready."""

    def __init__(self) -> None:
        self.ready = threading.Event()
        self.written: list[bytes] = []

    def write(self, data: bytes) -> bool:
        if not self.ready.is_set():
            return False
        self.written.append(data)
        return True


def test_writer_writes_whole_frames_in_order_and_nothing_from_before_a_loss():
    frames = _frames(6)
    device, published = _Device(), []
    queue = CorrectionQueue()
    writer = CorrectionWriter(
        queue,
        write=device.write,
        ready=device.ready.is_set,
        now=lambda: 0.0,
        on_written=lambda frame, _s: published.append(frame),
    )
    writer.start()
    try:
        queue.put(frames[:2], 0.0)  # the port is not ready: dropped
        assert wait_for(lambda: queue.stats.dropped_stale == 2, 10.0)
        device.ready.set()
        queue.accept(b"".join(frames[2:]), 0.0)
        assert wait_for(lambda: len(device.written) == 4, 10.0)
    finally:
        writer.stop()
    assert device.written == frames[2:] == published
    stats = queue.stats
    assert stats.frames_written == 4 and stats.bytes_written == sum(map(len, frames[2:]))
    assert stats.last_written_s == 0.0 and stats.write_failures == 0
    assert sorted(stats.written_by_number) == [1003, 1004, 1005, 1006]


_GARBAGE = st.binary(max_size=40).map(lambda b: b.replace(bytes((PREAMBLE,)), b""))


@settings(max_examples=200, deadline=None)
@given(pieces=st.lists(st.tuples(_GARBAGE, st.integers(0, 5)), max_size=8))
def test_any_garbage_between_frames_leaves_exactly_the_frames(pieces):
    frames = _frames(6, seed=7)
    message = b"".join(garbage + frames[i] for garbage, i in pieces)
    queue = CorrectionQueue(max_frames=100)
    queue.accept(message, 0.0)
    assert _taken(queue, 0.0) == [frames[i] for _, i in pieces]
    assert queue.stats.invalid_bytes == sum(len(garbage) for garbage, _ in pieces)
