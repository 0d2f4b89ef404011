"""Plausibility and time-order checks of parsed Q-Free OBU records (no ROS).

A value no sensor of the logger can produce, or a line stamped at or before the previous line of
its stream, is refused as a ``BadLine`` with the reason, so ``gnss_ins import-qfree`` lists and
counts it instead of writing it to the bag (or, for time order, silently sorting it in).
Limits are the largest full-scale settings of the logger's sensors (ST L3G4200D ±2000 °/s, ST
LIS331DLH ±8 g: the ST datasheets, not in gnss-ins-ntnu-notes.md §3), and for GNSS what a road
vehicle's receiver can report.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from typing import TypeVar

from ins_fusion.qfree import logs, mems_conversion

#: Largest plausible specific force per axis [m/s²]: the LIS331DLH's widest range, ±8 g.
MAX_ACCEL_M_S2 = 8.0 * mems_conversion.STANDARD_GRAVITY_M_S2
#: Largest plausible rate per axis [rad/s]: the L3G4200D's widest range, ±2000 °/s.
MAX_RATE_RAD_S = math.radians(2000.0)
#: Plausible ellipsoidal height [m] (below the Dead Sea shore to airliner altitude).
HEIGHT_RANGE_M = (-1000.0, 15000.0)
#: Largest plausible velocity component [m/s] (the 1000-knot GNSS export limit).
MAX_SPEED_M_S = 515.0
#: Largest plausible position sigma [m]; a larger one is no measurement.
MAX_STD_M = 10000.0

StampedT = TypeVar("StampedT", logs.GnssEpoch, logs.MemsSample)


def _bad(stamp: logs.Stamp, reason: str) -> logs.BadLine:
    return logs.BadLine(stamp.source, stamp.line, reason)


def _beyond(values: Iterable[float], limit: float) -> float | None:
    """The first value with ``abs(value) > limit`` (NaN included), else None."""
    return next((v for v in values if not abs(v) <= limit), None)


def mems_problem(sample: logs.MemsSample, accel_unit: str, gyro_unit: str) -> str | None:
    """Why ``sample`` (in the log's ``accel_unit`` / ``gyro_unit``) is implausible, or None."""
    accel = _beyond(sample.accel, MAX_ACCEL_M_S2 / mems_conversion.ACCEL_UNITS[accel_unit])
    if accel is not None:
        return f"accelerometer value {accel:g} {accel_unit} beyond ±8 g"
    rate = _beyond(sample.gyro, MAX_RATE_RAD_S / mems_conversion.GYRO_UNITS[gyro_unit])
    if rate is not None:
        return f"gyro value {rate:g} {gyro_unit} beyond ±2000 deg/s"
    return None


def gnss_problem(epoch: logs.GnssEpoch) -> str | None:
    """Why ``epoch`` holds an implausible height, velocity or sigma, or None (NaN = missing)."""
    low, high = HEIGHT_RANGE_M
    if not low <= epoch.height_m <= high:
        return f"height {epoch.height_m:g} m outside [{low:g}, {high:g}] m"
    speed = _beyond((v for v in epoch.vel_ned_m_s if not math.isnan(v)), MAX_SPEED_M_S)
    if speed is not None:
        return f"velocity component {speed:g} m/s beyond ±{MAX_SPEED_M_S:g} m/s"
    std = next((s for s in epoch.std_ned_m if not math.isnan(s) and not 0 <= s <= MAX_STD_M), None)
    if std is not None:
        return f"position sigma {std:g} m outside [0, {MAX_STD_M:g}] m"
    return None


def refuse(
    records: Sequence[StampedT], problem: Callable[[StampedT], str | None]
) -> tuple[list[StampedT], list[logs.BadLine]]:
    """(the records ``problem`` finds nothing wrong with, a BadLine with the reason for each
    other one), e.g. ``problem`` = ``gnss_problem``."""
    kept: list[StampedT] = []
    refused: list[logs.BadLine] = []
    for record in records:
        reason = problem(record)
        if reason is None:
            kept.append(record)
        else:
            refused.append(_bad(record.stamp, reason))
    return kept, refused


def refuse_time_faults(records: Sequence[StampedT]) -> tuple[list[StampedT], list[logs.BadLine]]:
    """(the records whose stamp is after the last kept one of their stream — same file,
    equipment, drive and leg — and a BadLine per record that repeats it or goes back)."""
    last: dict[tuple[str, int, int, int], logs.Stamp] = {}
    kept: list[StampedT] = []
    refused: list[logs.BadLine] = []
    for record in records:
        s = record.stamp
        key = (s.source, s.equipment_id, s.drive_id, s.leg_id)
        previous = last.get(key)
        if previous is not None and s.utc_ns <= previous.utc_ns:
            back_s = (previous.utc_ns - s.utc_ns) / 1e9
            what = "repeats the time" if back_s == 0 else f"goes back {back_s:g} s from the time"
            refused.append(_bad(s, f"time {what} of line {previous.line}"))
            continue
        last[key] = s
        kept.append(record)
    return kept, refused
