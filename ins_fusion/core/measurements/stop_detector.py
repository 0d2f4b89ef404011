"""Stop (standstill) detector for ZUPT, ZARU and levelling (no ROS).

NTNU notes §7 (shared/reference/gnss-ins-ntnu-notes.md): engine and road vibration make the
accelerometer variance much larger when moving than when stopped; the thesis thresholds
var(a_x) + var(a_y) over a 1 s window at 0.048 (m/s²)². Its detector had only false negatives
but recommended adding the gyro variance and the GNSS speed, hysteresis and a minimum duration
(§7, §14 items 18-19, "Implications" D6), because a false positive (ZUPT while moving) is the
dangerous error. Here a stop needs all of:

- var(f_x) + var(f_y) of base_link over the window below ``accel_variance``,
- var(ω_x) + var(ω_y) + var(ω_z) below ``gyro_variance``,
- the GNSS speed (when one arrived within the last two seconds) and the filter's speed (once it
  runs) below ``speed_m_s``; the speed veto is what stops a smooth, vibration-free cruise (as in
  simulated data) from looking like a stop,

- the mean horizontal specific force of base_link over the last quarter of the window within
  ``accel_change`` of its mean over the window (at the start of a stop) or of its value when the
  stop began (during the stop): a standstill has a constant specific force, and this catches the
  smooth start of a vehicle whose variance and speed are still small,

for ``min_duration_s``; a stop ends as soon as one quantity exceeds ``hysteresis`` times its
threshold.
"""

from __future__ import annotations

import math

import numpy as np

from gnss_ins_common.types import FloatArray, Vec3
from ins_fusion.core.compiled import compilable, jit
from ins_fusion.core.settings.config import StopDetectorConfig

#: A GNSS speed older than this no longer vetoes or confirms a stop [s].
GNSS_SPEED_MAX_AGE_S = 2.0
#: Samples per second of window the sample ring holds at first (it doubles when a faster IMU
#: fills it).
_RING_RATE_HZ = 400.0
#: Sample ring layout: row 0 holds (index of the next row to write, rows held, window [s]);
#: rows 1.. the samples (t [s], ω (3) [rad/s], f (3) [m/s²]; imu FRD), a ring (the detector
#: grows it when it is full, before a sample would overwrite the oldest).
_HEAD, _COUNT, _WINDOW = 0, 1, 2


class StopDetector:
    """Decides standstill from a window of IMU samples and the latest speeds."""

    def __init__(self, config: StopDetectorConfig, mat_bi: FloatArray) -> None:
        """``mat_bi``: imu FRD -> base_link FRD rotation applied to the specific force."""
        self.config = config
        self._mat_bi = np.array(mat_bi, dtype=np.float64)
        self.ring = np.zeros((int(config.window_s * _RING_RATE_HZ) + 2, 7))
        self.ring[0, _WINDOW] = config.window_s
        self._candidate_since: float | None = None
        self._stop_force: FloatArray | None = None
        self.stationary = False
        self.accel_variance = float("nan")
        self.gyro_variance = float("nan")
        self.accel_change = float("nan")

    @property
    def idle(self) -> bool:
        """No stop and no stop candidate (``vetoed``)."""
        return not self.stationary and self._candidate_since is None and self._stop_force is None

    def reset(self) -> None:
        """Forget the window and the decision."""
        self.ring[0, _HEAD] = self.ring[0, _COUNT] = 0.0
        self._candidate_since = None
        self._stop_force = None
        self.stationary = False

    def push(self, t_s: float, rate_i: Vec3, force_i: Vec3) -> None:
        """Add a calibrated sample (imu FRD) at time t_s."""
        if ring_push(self.ring, t_s, *rate_i, *force_i):
            self.grow()

    def grow(self) -> None:
        """Double the sample ring (``ring_push`` found it full: a faster IMU than planned)."""
        window = self.window()
        ring = np.zeros((2 * self.ring.shape[0] - 1, 7))
        ring[0] = self.ring[0]
        ring[1 : 1 + len(window)] = window
        ring[0, _HEAD] = len(window)
        self.ring = ring

    def window(self) -> FloatArray:
        """The samples of the window, oldest first (rows t, ω, f)."""
        ring = self.ring
        capacity = ring.shape[0] - 1
        head, count = int(ring[0, _HEAD]), int(ring[0, _COUNT])
        return ring[1 + np.arange(head - count, head) % capacity]

    def evaluate(
        self, t_s: float, gnss_speed_m_s: float | None, ins_speed_m_s: float | None
    ) -> bool:
        """Update and return the decision at t_s; speeds are None when unknown."""
        cfg = self.config
        if ins_speed_m_s is not None and vetoed(self.idle, ins_speed_m_s, cfg.speed_m_s):
            return False
        factor = cfg.hysteresis if self.stationary else 1.0
        slow = all(s is None or s < cfg.speed_m_s * factor for s in (gnss_speed_m_s, ins_speed_m_s))
        ring = self.ring
        capacity = ring.shape[0] - 1
        count = int(ring[0, _COUNT])
        first_t = ring[1 + (int(ring[0, _HEAD]) - count) % capacity, 0]
        full = count > 2 and first_t <= t_s - 0.9 * cfg.window_s
        window_force = None
        if slow and full:  # the IMU only matters when no speed vetoes the stop
            stats = window_statistics(ring, self._mat_bi)
            window_force = np.array(stats[0:2])
            reference = window_force if self._stop_force is None else self._stop_force
            self.accel_change = math.hypot(stats[2] - reference[0], stats[3] - reference[1])
            self.accel_variance, self.gyro_variance = stats[4], stats[5]
        candidate = (
            window_force is not None
            and self.accel_variance < cfg.accel_variance * factor
            and self.gyro_variance < cfg.gyro_variance * factor
            and self.accel_change < cfg.accel_change_m_s2 * factor
        )
        if not candidate:
            self._candidate_since = None
            self._stop_force = None
            self.stationary = False
        elif not self.stationary:
            if self._candidate_since is None:
                self._candidate_since = t_s
            self.stationary = t_s - self._candidate_since >= cfg.min_duration_s
            if self.stationary:
                self._stop_force = window_force
        return self.stationary


@compilable
def vetoed(idle: bool, ins_speed_m_s: float, threshold_m_s: float) -> bool:
    """Whether ``StopDetector.evaluate`` decides 'no stop' from the filter's speed alone and
    leaves the detector as it is: ``idle`` (no stop, no candidate) and that speed at or above
    the ``threshold_m_s`` [m/s] (the compiled runs of core.engine.sample_runs take such
    epochs)."""
    return idle and ins_speed_m_s >= threshold_m_s


@jit
def ring_push(
    ring: FloatArray, t_s: float, wx: float, wy: float, wz: float, fx: float, fy: float, fz: float
) -> bool:
    """StopDetector.push on its sample ring: file the sample, drop those older than the window
    before it. True when the ring is full (grow it before the next sample, which would
    overwrite the oldest)."""
    capacity: int = ring.shape[0] - 1
    head, count = int(ring[0, _HEAD]), int(ring[0, _COUNT])
    row = ring[1 + head]
    row[0], row[1], row[2], row[3], row[4], row[5], row[6] = t_s, wx, wy, wz, fx, fy, fz
    head = (head + 1) % capacity
    count = min(count + 1, capacity)
    start = t_s - ring[0, _WINDOW]
    while ring[1 + (head - count) % capacity, 0] < start:
        count -= 1
    ring[0, _HEAD], ring[0, _COUNT] = head, count
    return count == capacity


@jit
def window_statistics(
    ring: FloatArray, mat_bi: FloatArray
) -> tuple[float, float, float, float, float, float]:
    """Of the samples in the ring (StopDetector.evaluate): the mean horizontal specific force
    of base_link (x, y; ``mat_bi`` imu -> base_link) over the window and over its last quarter
    [m/s²], var(f_x) + var(f_y) [(m/s²)²] and var(ω_x) + var(ω_y) + var(ω_z) [(rad/s)²]."""
    capacity = ring.shape[0] - 1
    head, count = int(ring[0, _HEAD]), int(ring[0, _COUNT])
    rows = np.empty((count, 5))  # f_x, f_y of base_link, ω (3)
    for i in range(count):
        sample = ring[1 + (head - count + i) % capacity]
        for c in range(2):
            rows[i, c] = (
                sample[4] * mat_bi[c, 0] + sample[5] * mat_bi[c, 1] + sample[6] * mat_bi[c, 2]
            )
        rows[i, 2], rows[i, 3], rows[i, 4] = sample[1], sample[2], sample[3]
    means = np.zeros(5)
    for i in range(count):
        means += rows[i]
    means /= count
    variances = np.zeros(5)
    for i in range(count):
        d = rows[i] - means
        variances += d * d
    variances /= count
    recent = max(1, count // 4)
    fx = fy = 0.0
    for i in range(count - recent, count):
        fx += rows[i, 0]
        fy += rows[i, 1]
    return (
        means[0],
        means[1],
        fx / recent,
        fy / recent,
        variances[0] + variances[1],
        variances[2] + variances[3] + variances[4],
    )
