"""Static and steady-rotation segments of an IMU record, and the means the estimators use.

Detection: a sample is *steady* when, in the window of ``window_s`` centred on it, every axis
of the specific force and of the rate varies less than its threshold (standard deviation) and
the mean of that window differs from the means of the windows just before and after it by less
than the same threshold (no slow tilt or spin-up). Runs of steady samples, trimmed by
``trim_s`` at both ends and at least ``min_duration_s`` long, are segments: *static* when the
magnitude of their mean rate is at most ``static_rate_max_rad_s``, else *rotation* (a rate
table, method D1). Given windows are checked with the same test.

Means and their σ (Aalborg notes §4.4: consecutive samples are not independent; the report
counted independent samples at 75 Hz / 25 Hz): the σ of a segment mean is the batch-means
estimate, the scatter of the means of ``n`` equal blocks (≥ 0.5 s each, at most 30) divided by
√n, which holds for band-limited and coloured noise alike.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np

from gnss_ins_common.types import FloatArray
from ins_fusion.bags.imu import ImuRecord

#: Batch-means blocks: at most this many, each at least MIN_BLOCK_S long (far longer than the
#: correlation of band-limited sensor noise, 6 ms at 25 Hz).
MAX_BLOCKS = 30
MIN_BLOCK_S = 0.5
#: No segment, even a given one, is shorter than this many blocks.
MIN_BLOCKS = 5


class SegmentError(ValueError):
    """A given window is not static/steady, too short or outside the record."""


class Kind(StrEnum):
    """What the unit did during a segment."""

    STATIC = "static"
    ROTATION = "rotation"


@dataclass(frozen=True)
class DetectorSettings:
    """Thresholds of the detection (see the module docstring). Stds per axis: accel
    [m/s²], gyro [rad/s]; static_rate_max_rad_s: largest |mean rate| of a static segment."""

    window_s: float = 1.0
    accel_std_max_m_s2: float = 0.05
    gyro_std_max_rad_s: float = math.radians(1.0)
    static_rate_max_rad_s: float = math.radians(1.0)
    min_duration_s: float = 10.0
    trim_s: float = 1.0


@dataclass(frozen=True)
class Means:
    """Mean specific force [m/s²] and rate [rad/s] over a segment and the σ of each mean,
    imu_link FLU, shape (3,) each."""

    force_m_s2: FloatArray
    force_sigma_m_s2: FloatArray
    rate_rad_s: FloatArray
    rate_sigma_rad_s: FloatArray


@dataclass(frozen=True)
class Segment:
    """Samples [start, stop) of record ``record``, stamped t_start_s .. t_end_s [s since the
    epoch], with their means."""

    record: int
    start: int
    stop: int
    t_start_s: float
    t_end_s: float
    kind: Kind
    means: Means = field(repr=False)
    record_start_s: float = 0.0  #: first stamp of the record [s since the epoch]

    @property
    def duration_s(self) -> float:
        """Length [s]."""
        return self.t_end_s - self.t_start_s

    @property
    def t_mid_s(self) -> float:
        """Centre [s since the epoch]."""
        return 0.5 * (self.t_start_s + self.t_end_s)

    @property
    def where(self) -> str:
        """``bag N, 12.0-72.0 s`` (times after the record's first stamp)."""
        t0, t1 = self.t_start_s - self.record_start_s, self.t_end_s - self.record_start_s
        return f"bag {self.record + 1}, {t0:.1f}-{t1:.1f} s"


def _window_samples(record: ImuRecord, window_s: float) -> int:
    return max(2, round(window_s * record.rate_hz))


def _rolling(values: FloatArray, w: int) -> tuple[FloatArray, FloatArray]:
    """Mean and std of every window of w consecutive rows: shapes (n - w + 1, k)."""
    centred = values - values.mean(axis=0)
    zero = np.zeros((1, values.shape[1]))
    s1 = np.concatenate((zero, np.cumsum(centred, axis=0)))
    s2 = np.concatenate((zero, np.cumsum(centred * centred, axis=0)))
    mean = (s1[w:] - s1[:-w]) / w
    var = (s2[w:] - s2[:-w]) / w - mean * mean
    return mean + values.mean(axis=0), np.sqrt(np.maximum(var, 0.0))


def _window_ok(record: ImuRecord, settings: DetectorSettings) -> tuple[FloatArray, int]:
    """Per window start j: the largest ratio of (std, mean change) to its threshold, and w."""
    w = _window_samples(record, settings.window_s)
    limits = np.array([settings.accel_std_max_m_s2] * 3 + [settings.gyro_std_max_rad_s] * 3)
    values = np.hstack((record.force_flu_m_s2, record.rate_flu_rad_s))
    if len(values) < 3 * w:
        return np.zeros(0), w
    mean, std = _rolling(values, w)
    worst = np.max(std / limits, axis=1)
    change = np.abs(mean[w:] - mean[:-w]) / limits  # window j+w against window j
    step = np.max(change, axis=1)
    # window j is also compared with its neighbours j - w and j + w
    worst[w:] = np.maximum(worst[w:], step)
    worst[:-w] = np.maximum(worst[:-w], step)
    return worst, w


def means(record: ImuRecord, start: int, stop: int) -> Means:
    """Means of samples [start, stop) and their batch-means σ (module docstring)."""
    t = record.t_s[start:stop]
    values = np.hstack((record.force_flu_m_s2[start:stop], record.rate_flu_rad_s[start:stop]))
    duration = float(t[-1] - t[0])
    n_blocks = int(min(MAX_BLOCKS, max(2, math.floor(duration / MIN_BLOCK_S))))
    edges = np.linspace(t[0], t[-1], n_blocks + 1)
    block = np.minimum(np.searchsorted(edges, t, side="right") - 1, n_blocks - 1)
    counts = np.bincount(block, minlength=n_blocks).astype(np.float64)
    sums = np.stack([np.bincount(block, values[:, k], n_blocks) for k in range(6)], axis=1)
    block_means = sums / counts[:, None]
    sigma = block_means.std(axis=0, ddof=1) / math.sqrt(n_blocks)
    mean = values.mean(axis=0)
    return Means(mean[:3], sigma[:3], mean[3:], sigma[3:])


def _segment(record: ImuRecord, index: int, start: int, stop: int, rate_max: float) -> Segment:
    m = means(record, start, stop)
    kind = Kind.STATIC if float(np.linalg.norm(m.rate_rad_s)) <= rate_max else Kind.ROTATION
    t = record.t_s
    return Segment(index, start, stop, float(t[start]), float(t[stop - 1]), kind, m, float(t[0]))


def detect(record: ImuRecord, index: int, settings: DetectorSettings) -> list[Segment]:
    """Static and rotation segments of a record, in time order (module docstring)."""
    worst, w = _window_ok(record, settings)
    steady = np.zeros(len(record.t_s), dtype=bool)
    steady[w // 2 : w // 2 + len(worst)] = worst <= 1.0
    # a gap in the data (dropped samples) ends a segment
    gap = np.flatnonzero(np.diff(record.t_s) > max(settings.window_s, 5.0 / record.rate_hz))
    steady[gap] = False
    edges = np.flatnonzero(np.diff(np.concatenate(([0], steady.astype(np.int8), [0]))))
    segments = []
    for begin, end in zip(edges[::2], edges[1::2], strict=True):
        t0 = record.t_s[begin] + settings.trim_s
        t1 = record.t_s[end - 1] - settings.trim_s
        start = int(np.searchsorted(record.t_s, t0, side="left"))
        stop = int(min(np.searchsorted(record.t_s, t1, side="right"), end))
        if stop - start >= 2 and record.t_s[stop - 1] - record.t_s[start] >= max(
            settings.min_duration_s, MIN_BLOCKS * MIN_BLOCK_S
        ):
            segments.append(_segment(record, index, start, stop, settings.static_rate_max_rad_s))
    return segments


def from_window(
    record: ImuRecord, index: int, t0_s: float, t1_s: float, settings: DetectorSettings
) -> Segment:
    """The segment of a given window [t0_s, t1_s] (s since the record's first stamp), checked:
    long enough and steady throughout (SegmentError says what is wrong)."""
    where = f"window {t0_s:g}:{t1_s:g} s of {record.name}"
    base = float(record.t_s[0])
    start = int(np.searchsorted(record.t_s, base + t0_s, side="left"))
    stop = int(np.searchsorted(record.t_s, base + t1_s, side="right"))
    if t1_s <= t0_s or stop - start < 2:
        raise SegmentError(f"{where}: no samples (record is {record.t_s[-1] - base:.1f} s long)")
    duration = float(record.t_s[stop - 1] - record.t_s[start])
    shortest = max(settings.min_duration_s, MIN_BLOCKS * MIN_BLOCK_S)
    if duration < shortest:
        raise SegmentError(f"{where}: {duration:.1f} s is shorter than the minimum {shortest:g} s")
    part = ImuRecord(
        record.t_s[start:stop],
        record.rate_flu_rad_s[start:stop],
        record.force_flu_m_s2[start:stop],
        name=record.name,
    )
    worst, _ = _window_ok(part, settings)
    if len(worst) and float(worst.max()) > 1.0:
        j = int(np.argmax(worst))
        raise SegmentError(
            f"{where} is not static or steady: near {part.t_s[j] - base:.1f} s the data vary"
            f" {float(worst.max()):.1f} times more than the thresholds (--accel-std-max"
            f" {settings.accel_std_max_m_s2:g} m/s², --gyro-std-max"
            f" {math.degrees(settings.gyro_std_max_rad_s):g} deg/s)"
        )
    return _segment(record, index, start, stop, settings.static_rate_max_rad_s)


def static_only(segments: Sequence[Segment], what: str) -> list[Segment]:
    """The static segments; SegmentError names a rotation segment among them."""
    for s in segments:
        if s.kind is Kind.ROTATION:
            rate = math.degrees(float(np.linalg.norm(s.means.rate_rad_s)))
            raise SegmentError(
                f"{what} needs static segments, but {s.where} rotates at {rate:.2f} deg/s"
                " (--static-rate-max)"
            )
    return list(segments)
