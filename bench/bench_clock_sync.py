"""Speed and accuracy of the IMU time stamping on a 10-minute synthetic 134 Hz stream.

The stream is test/support/clock_streams.py's ``simulate``: +100 ppm drift, 1 % single drops and
three runs of 20, exponential receive delays (1 ms mean) with 1 % 20 ms stalls, reads of 1-3
packets. Errors are |host stamp - true sample time| after a 5 s warm-up. The slowest call is the
CPU time of this thread (a preemption on a busy machine does not count); the garbage collector is
off while timing, as its pauses here scale with this script's own heap of results.
"""

from __future__ import annotations

import gc
import sys
import time
from collections.abc import Callable
from itertools import pairwise
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "test"))

from support.clock_streams import FIRST_TIMER, simulate

from gnss_ins_common.clock_sync import EnvelopeClockSync
from imu400cc_driver.device_clock import PACKET_TRANSMISSION_S, TIMER_MODULUS, DeviceClock

SECONDS = 600.0
WARM_UP_S = 5.0


def report(
    name: str, packets: int, elapsed_s: float, slowest_s: float, error_s: np.ndarray
) -> None:
    us = np.abs(error_s) * 1e6
    print(
        f"{name:36s} {packets / elapsed_s:7.0f} packets/s, slowest call {slowest_s * 1e3:5.2f} ms,"
        f" |error| p50 {np.percentile(us, 50):4.1f} us, p99 {np.percentile(us, 99):4.1f} us,"
        f" max {us.max():4.1f} us"
    )


def timed(
    calls: list[tuple[Any, ...]], function: Callable[..., Any]
) -> tuple[list[Any], float, float]:
    """Results, total wall time and slowest call's CPU time [s] of ``function(*args)`` over
    ``calls``."""
    results, slowest = [], 0.0
    gc.collect()
    gc.disable()
    start = time.perf_counter()
    for args in calls:
        t0 = time.thread_time()
        results.append(function(*args))
        slowest = max(slowest, time.thread_time() - t0)
    elapsed = time.perf_counter() - start
    gc.enable()
    return results, elapsed, slowest


def main() -> None:
    stream = simulate(SECONDS, 100.0, seed=0)
    timers = ((FIRST_TIMER - stream.ticks) % TIMER_MODULUS).tolist()
    receive = stream.receive_s.tolist()
    settled = stream.seconds() > WARM_UP_S
    count = len(timers)
    print(f"{count} packets over {SECONDS:.0f} s")

    clock = DeviceClock()
    stamps, elapsed, slowest = timed(list(zip(timers, receive, strict=True)), clock.stamp)
    error = np.array([s.host_stamp_s for s in stamps]) - stream.sample_host_s
    report("DeviceClock.stamp (per packet)", count, elapsed, slowest, error[settled])
    print(
        f"{'':36s} drift {clock.drift_ppm:+.2f} ppm (true +100), jitter {clock.jitter_s * 1e3:.2f}"
        f" ms, dropped {clock.dropped_packets} (true {stream.dropped.sum()}),"
        f" resets {clock.resets}"
    )

    clock = DeviceClock()
    reads = [0, *(np.flatnonzero(np.diff(stream.receive_s)) + 1).tolist(), count]
    calls = [(timers[a:b], receive[a]) for a, b in pairwise(reads)]
    chunks, elapsed, slowest = timed(calls, clock.stamp_chunk)
    error = np.array([s.host_stamp_s for c in chunks for s in c]) - stream.sample_host_s
    report("DeviceClock.stamp_chunk (per read)", count, elapsed, slowest, error[settled])

    sync = EnvelopeClockSync()

    def update_and_map(device_s: float, host_s: float) -> float:
        sync.update(device_s, host_s)
        return sync.to_host(device_s)

    host = (stream.receive_s - PACKET_TRANSMISSION_S).tolist()
    calls = list(zip(stream.device_s.tolist(), host, strict=True))
    mapped, elapsed, slowest = timed(calls, update_and_map)
    error = np.array(mapped) - stream.sample_host_s
    report("EnvelopeClockSync.update + to_host", count, elapsed, slowest, error[settled])


if __name__ == "__main__":
    main()
