"""The sample clock of a static IMU record (ins_fusion.bags.imu.ImuRecord) and the checks that
refuse records the Allan analysis cannot use (irregular stamps, non-finite or constant data,
motion).

Axes and units are those of imu/data_raw (REP-145, imu_link FLU): rates [rad/s], specific force
[m/s²]; a level resting unit reads about (0, 0, +9.81) m/s² and the earth rate.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gnss_ins_common.types import FloatArray
from ins_fusion.bags.imu import ImuRecord
from ins_fusion.core.nav.units import DEG, deg_s, mg

#: Largest share of samples that may be missing (dropped packets); the series is joined at the
#: gaps, which the Allan variance tolerates when they are rare.
MAX_MISSING_FRACTION = 0.01
#: A sample interval further than this many nominal periods from a whole number of periods is
#: off the sample grid; up to MAX_MISSING_FRACTION of the intervals may be.
_GRID_TOLERANCE = 0.25
#: Median absolute deviation -> standard deviation of a normal variable.
_MAD_TO_SIGMA = 1.4826
#: Channel names of the static check, in its order.
CHANNELS = ("gyro x", "gyro y", "gyro z", "accel x", "accel y", "accel z", "specific force |f|")


class RecordError(Exception):
    """The record cannot be analysed as asked (the message says why)."""


@dataclass(frozen=True)
class SampleClock:
    """The record's sample rate [Hz] (mean over the record, gaps counted) and the number of
    samples missing in its gaps."""

    rate_hz: float
    missing: int


def sample_clock(t_s: FloatArray) -> SampleClock:
    """Sample rate and missing samples of increasing sample times [s]; RecordError if the times
    do not increase, are off a regular grid or miss more than MAX_MISSING_FRACTION."""
    t = np.asarray(t_s, dtype=np.float64)
    if len(t) < 3:
        raise RecordError(f"{len(t)} samples: nothing to analyse")
    dt = np.diff(t)
    if np.any(dt <= 0.0):
        i = int(np.argmax(dt <= 0.0)) + 1
        raise RecordError(
            f"sample times do not increase at sample {i} (t = {t[i] - t[0]:.6f} s after the "
            "first): are the header stamps set?"
        )
    period = float(np.median(dt))
    steps = np.maximum(np.rint(dt / period), 1.0)
    off_grid = np.abs(dt - steps * period) > _GRID_TOLERANCE * period
    if np.mean(off_grid) > MAX_MISSING_FRACTION:
        raise RecordError(
            f"irregular sample times: {np.mean(off_grid):.1%} of the intervals are off the "
            f"{period * 1e3:.3f} ms grid (at most {MAX_MISSING_FRACTION:.0%})"
        )
    missing = int(np.sum(steps - 1.0))
    if missing > MAX_MISSING_FRACTION * len(t):
        raise RecordError(
            f"{missing} samples missing in gaps ({missing / len(t):.1%} of {len(t)}; at most "
            f"{MAX_MISSING_FRACTION:.0%})"
        )
    return SampleClock((len(t) - 1 + missing) / float(t[-1] - t[0]), missing)


def check_values(record: ImuRecord) -> None:
    """RecordError if a value is not finite or an axis is constant (no noise to analyse)."""
    for name, values in _axes(record):
        if not np.all(np.isfinite(values)):
            raise RecordError(f"{name}: non-finite values (NaN or inf)")
        if np.ptp(values) == 0.0:
            raise RecordError(f"{name}: every sample is {values[0]:g}, nothing to analyse")


def _axes(record: ImuRecord) -> list[tuple[str, FloatArray]]:
    return [(CHANNELS[i], record.rate_flu_rad_s[:, i]) for i in range(3)] + [
        (CHANNELS[3 + i], record.force_flu_m_s2[:, i]) for i in range(3)
    ]


@dataclass(frozen=True)
class StaticLimits:
    """How far the means over window_s [s] may move from their median: rates [rad/s],
    specific force per axis and magnitude [m/s²], or noise_factor times the scatter of the
    window means from one window to the next if that is larger (a noisy sensor)."""

    rate_rad_s: float = deg_s(0.1)
    specific_force_m_s2: float = mg(10.0)
    window_s: float = 10.0
    noise_factor: float = 8.0


def check_static(record: ImuRecord, rate_hz: float, limits: StaticLimits) -> None:
    """RecordError naming every channel (gyro axes, accelerometer axes, specific-force
    magnitude) whose window means move further than the limits: the unit moved, was turned or
    knocked, which no noise term describes."""
    per_window = max(1, round(limits.window_s * rate_hz))
    windows = len(record.t_s) // per_window
    if windows < 2:
        return
    force = record.force_flu_m_s2
    channels = np.column_stack([record.rate_flu_rad_s, force, np.linalg.norm(force, axis=1)])[
        : windows * per_window
    ]
    means = channels.reshape(windows, per_window, -1).mean(axis=1)
    offset = np.abs(means - np.median(means, axis=0))
    steps = np.diff(means, axis=0)
    scatter = (
        _MAD_TO_SIGMA * np.median(np.abs(steps - np.median(steps, axis=0)), axis=0) / np.sqrt(2.0)
    )
    problems = []
    for i, name in enumerate(CHANNELS):
        is_rate = i < 3
        floor = limits.rate_rad_s if is_rate else limits.specific_force_m_s2
        limit = max(floor, limits.noise_factor * float(scatter[i]))
        worst = int(np.argmax(offset[:, i]))
        if offset[worst, i] > limit:
            to_user, unit = (1.0 / DEG, "deg/s") if is_rate else (1.0 / mg(1.0), "mg")
            t = (worst + 0.5) * per_window / rate_hz
            problems.append(
                f"{name} moves {offset[worst, i] * to_user:.3g} {unit} from its median "
                f"(limit {limit * to_user:.3g} {unit}, {limits.window_s:g} s means, around "
                f"{t:.0f} s)"
            )
    if problems:
        raise RecordError(
            "not static: "
            + "; ".join(problems)
            + ". Record the unit untouched on a rigid, level mount (docs/allan.md)."
        )
