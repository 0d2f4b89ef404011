"""The NMEA capture fixtures of test/data/gnss on a simulated serial wire (see make_captures.py).

A capture line is ``<queue time [s]> <sentence>``; on the wire each sentence starts at its queue
time or when the previous one has left, whichever is later, at 10 bits per byte (8N1).
"""

from __future__ import annotations

import random

from gnss_driver.driver import EpochOutput, GnssDriver
from support.paths import TESTS

DATA = TESTS / "data" / "gnss"
CAPTURES = ("mixed_rate_oxts", "ublox_gsv_block", "cut_first_line")


def on_the_wire(name: str, baud: int, start_s: float) -> tuple[bytes, list[float]]:
    """The capture's bytes and the host time [s] at which each byte's stop bit ends."""
    stream, times = bytearray(), []
    byte_s, clock = 10.0 / baud, start_s
    for line in (DATA / f"{name}.nmea").read_text().splitlines():
        queue, text = line.split(" ", 1)
        raw = text.encode("ascii") + b"\r\n"
        clock = max(clock, start_s + float(queue))
        for k in range(len(raw)):
            times.append(clock + (k + 1) * byte_s)
        clock += len(raw) * byte_s
        stream += raw
    return bytes(stream), times


def chunk_ends(times: list[float], max_bytes: int, rng: random.Random | None) -> list[int]:
    """Where reads end: at most ``max_bytes`` (random sizes with ``rng``), and at every pause
    of the line longer than 1 ms (a read returns when the line goes quiet)."""
    ends, start = [], 0
    while start < len(times):
        size = rng.randint(1, max_bytes) if rng is not None else max_bytes
        end = min(start + size, len(times))
        for k in range(start + 1, end):
            if times[k] - times[k - 1] > 1e-3:
                end = k
                break
        ends.append(end)
        start = end
    return ends


def feed(driver: GnssDriver, stream: bytes, times: list[float], ends: list[int]):
    """Outputs of feeding the reads; the idle check runs when each read's first byte arrives
    (as the node's timer would in the pause before it) and once at the end."""
    outputs: list[EpochOutput] = []
    start = 0
    for end in ends:
        outputs += driver.flush_idle(times[start])
        outputs += driver.feed(stream[start:end], times[end - 1])
        start = end
    outputs += driver.flush_idle(times[-1] + 10.0)
    return outputs
