"""A simulated IMU400CC packet stream with a drifting device clock and host receive delays
(used by the clock-sync and device-clock tests and bench/bench_clock_sync.py)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gnss_ins_common.rates import IMU400CC_RATE_HZ
from imu400cc_driver.device_clock import (
    COUNTS_PER_PACKET,
    NOMINAL_TICK_S,
    PACKET_TRANSMISSION_S,
)

HOST_START_S = 1.7e9  # an epoch-sized host clock, to exercise float precision


@dataclass(frozen=True)
class Stream:
    """One simulated IMU400CC run; every array has one entry per delivered packet."""

    ticks: np.ndarray  # device ticks since the first packet (int64)
    sample_host_s: np.ndarray  # true sample time on the host clock [s]
    receive_s: np.ndarray  # host time the read that completed the packet returned [s]
    dropped: np.ndarray  # packets missing right before this one

    @property
    def device_s(self) -> np.ndarray:
        """Device time in nominal ticks [s]."""
        return self.ticks * NOMINAL_TICK_S

    def seconds(self) -> np.ndarray:
        """True sample times since the first packet [s]."""
        return self.sample_host_s - self.sample_host_s[0]

    def stalled(self, start_s: float, duration_s: float) -> Stream:
        """The same run with the reader asleep for ``duration_s`` from ``start_s`` [s]: whatever
        arrived meanwhile is read at once, with the first packet after it."""
        receive = self.receive_s.copy()
        asleep = (receive >= self.sample_host_s[0] + start_s) & (
            receive < self.sample_host_s[0] + start_s + duration_s
        )
        wake = np.flatnonzero(asleep)[-1] + 1
        receive[asleep] = receive[wake]
        return Stream(self.ticks, self.sample_host_s, receive, self.dropped)

    def stamped_late(self, every_s: float, late_s: float) -> Stream:
        """The same run with one read every ``every_s`` [s] stamped ``late_s`` [s] after it
        returned (its thread descheduled between the read and the clock): what arrives
        meanwhile is read, and stamped, 0.1 ms after that."""
        receive = self.receive_s.copy()
        due = receive[0] + every_s
        k = 0
        while k < receive.size:
            read = receive == receive[k]
            if receive[k] >= due:
                late = receive[k] + late_s
                receive[(receive > receive[k]) & (receive <= late)] = late + 1e-4
                receive[read] = late
                due = receive[k] + every_s
            k = int(np.flatnonzero(read)[-1]) + 1
        return Stream(self.ticks, self.sample_host_s, receive, self.dropped)


def simulate(
    seconds: float,
    drift_ppm: float,
    seed: int,
    drop_probability: float = 0.01,
    runs: int = 3,
    run_length: int = 20,
    drift_after_ppm: float | None = None,
) -> Stream:
    """A 134 Hz stream: host = start + (1 + drift) * device time (drift switches to
    ``drift_after_ppm`` half-way when given); the timer latch wobbles by up to ±9 counts (notes
    §2.6); single drops and ``runs`` runs of ``run_length`` (20: longer than one ~7-packet wrap)
    go missing after the first second; each packet
    arrives in order after its wire time plus an exponential delay (1 ms mean) and, 1 % of the
    time, a 20 ms USB stall; the reader often lags, so packets come in reads of 1-3 that share
    the receive time of their last one (never across a pause of over 16 ms)."""
    rng = np.random.default_rng(seed)
    count = round(seconds * IMU400CC_RATE_HZ)
    index = np.arange(count)
    ticks = np.round(index * COUNTS_PER_PACKET).astype(np.int64) + rng.integers(-9, 10, count)
    ticks -= ticks[0]
    device_s = ticks * NOMINAL_TICK_S
    rate = np.full(count, 1.0 + drift_ppm * 1e-6)
    if drift_after_ppm is not None:
        rate[count // 2 :] = 1.0 + drift_after_ppm * 1e-6
    sample_host_s = HOST_START_S + np.concatenate(([0.0], np.cumsum(np.diff(device_s) * rate[1:])))

    keep = rng.random(count) >= drop_probability
    for start in rng.integers(IMU400CC_RATE_HZ, count - 2 * run_length, runs):
        keep[start : start + run_length] = False
    keep[0] = True
    missing_before = np.diff(np.flatnonzero(keep), prepend=0) - 1
    missing_before[0] = 0

    delay = rng.exponential(1e-3, count) + np.where(rng.random(count) < 0.01, 20e-3, 0.0)
    arrival = np.maximum.accumulate(sample_host_s + PACKET_TRANSMISSION_S + delay)[keep]
    receive = np.empty_like(arrival)
    start = 0
    for k, lag in enumerate(np.diff(arrival, append=np.inf)):
        if k - start == 2 or lag > 16e-3 or rng.random() < 0.5:
            receive[start : k + 1] = arrival[k]
            start = k + 1
    return Stream(ticks[keep], sample_host_s[keep], receive, missing_before)


#: The timer of the first App. D.5 example row (notes §2.6).
FIRST_TIMER = 41606
