"""Injected GNSS outages: windows of time in which GNSS messages are dropped.

A window is ``START:DURATION`` in seconds, START counted from the first IMU stamp of the bag.
A message is dropped when its header stamp t satisfies start <= t - t0 < start + duration.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True)
class Outage:
    """A GNSS outage: start [s after the first IMU stamp] and duration [s]."""

    start_s: float
    duration_s: float

    @property
    def end_s(self) -> float:
        """End of the window (exclusive) [s after the first IMU stamp]."""
        return self.start_s + self.duration_s

    def contains(self, t_rel_s: float) -> bool:
        """Whether a time [s after the first IMU stamp] lies in the window."""
        return self.start_s <= t_rel_s < self.end_s


def parse_outage(text: str) -> Outage:
    """``START:DURATION`` [s] -> Outage; ValueError with the reason for anything else."""
    parts = text.split(":")
    if len(parts) != 2:
        raise ValueError(f"outage {text!r} is not START:DURATION (seconds)")
    try:
        start, duration = float(parts[0]), float(parts[1])
    except ValueError:
        raise ValueError(f"outage {text!r}: START and DURATION must be numbers") from None
    if not (np.isfinite(start) and start >= 0.0):
        raise ValueError(f"outage {text!r}: START must be a finite number >= 0")
    if not (np.isfinite(duration) and duration > 0.0):
        raise ValueError(f"outage {text!r}: DURATION must be a finite number > 0")
    return Outage(start, duration)


def in_any(t_rel_s: float, outages: Sequence[Outage]) -> bool:
    """Whether a time [s after the first IMU stamp] lies in any of the windows."""
    return any(outage.contains(t_rel_s) for outage in outages)


def mask(t_rel_s: NDArray[np.float64], outages: Sequence[Outage]) -> NDArray[np.bool_]:
    """Element-wise ``in_any`` over an array of times [s after the first IMU stamp]."""
    t = np.asarray(t_rel_s, dtype=np.float64)
    inside = np.zeros(t.shape, dtype=np.bool_)
    for outage in outages:
        inside |= (t >= outage.start_s) & (t < outage.end_s)
    return inside
