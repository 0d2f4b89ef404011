"""When a solution is output: ticks of the output rate on the IMU stamps (no ROS), one rule for
the node (sample by sample, ``OutputClock``) and replay (a whole run at once, ``output_ticks``).

The ticks fall every 1 / ``rate_hz`` from the first IMU stamp; the solution is output at the
first sample at or past each tick, one per tick, so the rate is the configured one on average
and each output lies within one IMU period after its tick: at 134 Hz and 50 Hz, 14.9 or 22.4 ms
apart, 50 a second. (The node's earlier rule, a period after the previous output's sample, gave
every third sample: 44.7 Hz.)
"""

from __future__ import annotations

import math

import numpy as np

from gnss_ins_common.types import BoolArray, FloatArray

#: A stamp this close before an output tick (in output periods) counts as at it: stamps are
#: float seconds since 1970 (about 0.24 µs apart), so k / rate after the first one is not exact.
TICK_TOLERANCE = 1e-3


def output_ticks(t_s: FloatArray, t0_s: float, rate_hz: float) -> BoolArray:
    """Whether a solution is output after each IMU sample (stamps ``t_s`` [s]): at the first
    sample at or past each output tick (``rate_hz`` from ``t0_s``), one per tick."""
    # Sample by sample: output when at or past the next tick, which then becomes the one after
    # the sample's. So a sample is output when its tick (whole output periods since t0_s) is
    # past every earlier sample's (and not before t0_s); stamps that go back or are not numbers
    # output nothing.
    periods = np.floor((t_s - t0_s) * rate_hz + TICK_TOLERANCE)
    latest = np.fmax.accumulate(np.fmax(periods, -1.0))  # NaN left out
    before = np.concatenate(([-1.0], latest[:-1]))
    ticks: BoolArray = periods > before
    return ticks


class OutputClock:
    """``output_ticks`` one sample at a time (the node): ``due(t)``, then ``taken(t)`` when the
    solution was output. A stamp before the last output (a bag played again) starts the ticks
    anew from it."""

    def __init__(self, rate_hz: float) -> None:
        """Ticks every 1 / ``rate_hz`` [Hz] from the first stamp asked about."""
        self.rate_hz = rate_hz
        self._t0_s = math.nan
        self._last_output_s = -math.inf
        self._last_period = -1.0

    def _period(self, t_s: float) -> float:
        return math.floor((t_s - self._t0_s) * self.rate_hz + TICK_TOLERANCE)

    def due(self, t_s: float) -> bool:
        """Whether the sample stamped ``t_s`` [s] is the first at or past the next tick."""
        if math.isnan(self._t0_s) or t_s < self._last_output_s:
            self._t0_s, self._last_output_s, self._last_period = t_s, -math.inf, -1.0
        return self._period(t_s) > self._last_period

    def taken(self, t_s: float) -> None:
        """The solution at the sample stamped ``t_s`` [s] was output."""
        self._last_output_s = t_s
        self._last_period = self._period(t_s)
