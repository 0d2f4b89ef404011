"""Sample rates: the sensors' nominal ones, for their drivers and the layers above them, and a
meter of message rates for /diagnostics."""

from __future__ import annotations

from typing import Final

#: IMU400CC continuous-mode packet rate [Hz] (shared/reference/imu400cc-aalborg-notes.md §2.6,
#: §10).
IMU400CC_RATE_HZ: Final = 134.0


class RateMeter:
    """Messages per second between successive readings of a running count."""

    def __init__(self, now_s: float) -> None:
        """Start counting at ``now_s`` [s] (any steady clock) from a count of 0."""
        self._start = (now_s, 0)

    def rate_hz(self, count: int, now_s: float) -> float:
        """Rate [Hz] of the running total ``count`` since the previous call (or the start)."""
        start_s, start_count = self._start
        self._start = (now_s, count)
        return (count - start_count) / max(now_s - start_s, 1e-9)
