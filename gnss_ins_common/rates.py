"""Sample rates: the sensors' nominal ones, for their drivers and the layers above them, and a
meter of message rates for /diagnostics."""

from __future__ import annotations

from collections import deque
from typing import Final

#: IMU400CC continuous-mode packet rate [Hz] (shared/reference/imu400cc-aalborg-notes.md §2.6,
#: §10).
IMU400CC_RATE_HZ: Final = 134.0


#: Span of a rate reading [s]: over one diagnostics period a 1 Hz receiver counts 0, 1 or 2
#: epochs by the phase of its epochs against the period (and a restarted node's first second
#: holds the epochs the port buffered), so a 1 s window read 2.0 Hz for 1 Hz.
RATE_WINDOW_S: Final = 5.0


class RateMeter:
    """Messages per second over the last ``window_s`` of readings of a running count (0: since
    the previous reading)."""

    def __init__(self, now_s: float, window_s: float = RATE_WINDOW_S) -> None:
        """Start counting at ``now_s`` [s] (any steady clock) from a count of 0."""
        self._window_s = window_s
        self._readings: deque[tuple[float, int]] = deque([(now_s, 0)])

    def rate_hz(self, count: int, now_s: float) -> float:
        """Rate [Hz] of the running total ``count`` over the readings of the last ``window_s``
        (since the start while it is younger)."""
        readings = self._readings
        while len(readings) > 1 and now_s - readings[1][0] >= self._window_s:
            readings.popleft()  # readings[1] still spans the window: the oldest is not needed
        start_s, start_count = readings[0]
        readings.append((now_s, count))
        return (count - start_count) / max(now_s - start_s, 1e-9)

    def settled(self, now_s: float) -> bool:
        """The readings span the whole window (before that a rate may be off by the start)."""
        return now_s - self._readings[0][0] >= self._window_s
