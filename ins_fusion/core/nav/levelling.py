"""Static alignment: levelling from the averaged specific force and the gyro-bias seed.

At rest the accelerometers measure only the reaction to gravity, f_b = C_bn (0, 0, -g) in FRD,
so roll and pitch follow from the mean specific force (NTNU notes (2.6), the same as Aalborg
notes §5.5 (7.6)-(7.9) with the signed g; shared/reference/). The gyros measure bias plus the
earth rate; the standstill average minus the earth rate seeds the gyro bias, the single most
effective correction of the Aalborg drives (notes §3.3 "Bias stability findings", §8.3
calibration 03). Without a heading only the vertical earth rate (Ω sin φ) can be removed; the
horizontal part (Ω cos φ ≈ 4e-5 rad/s at 57° N) stays in the seed's uncertainty (gyro compassing
is impossible at the IMU400CC's noise: Aalborg notes §5.3, earth rate ≈ 1/6 of the resolution).
"""

from __future__ import annotations

import math

import numpy as np

from gnss_ins_common.types import FloatArray, Vec3
from ins_fusion.core.compiled import compilable
from ins_fusion.core.nav import earth


def level(mean_force_frd_m_s2: FloatArray) -> tuple[float, float]:
    """(roll, pitch) [rad] of the FRD body from its mean specific force at rest (NTNU (2.6))."""
    fx, fy, fz = (float(v) for v in mean_force_frd_m_s2)
    return math.atan2(-fy, -fz), math.atan2(fx, math.hypot(fy, fz))


@compilable
def earth_rate_body_rad_s(mat_nb: FloatArray, lat_rad: float, heading_known: bool) -> FloatArray:
    """Earth rate seen by a resting body (FRD) [rad/s]; only the vertical part without heading.
    Also inside the compiled ZARU model (core.measurements.stationary.zaru_model)."""
    north, _, down = earth.earth_rate_from_sin_cos(math.sin(lat_rad), math.cos(lat_rad))
    rate_b: FloatArray = mat_nb.T @ np.array((north if heading_known else 0.0, 0.0, down))
    return rate_b


def unknown_earth_rate_rad_s(lat_rad: float) -> float:
    """Horizontal earth rate [rad/s]: the seed's error when the heading is unknown."""
    return earth.EARTH_RATE_RAD_S * math.cos(lat_rad)


class Levelling:
    """Accumulates calibrated samples (imu FRD) during a standstill."""

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        """Start a new standstill."""
        self._rate_sum = [0.0, 0.0, 0.0]
        self._force_sum = [0.0, 0.0, 0.0]
        self.count = 0
        self.start_s = math.nan
        self.end_s = math.nan

    def push(self, t_s: float, rate_i: Vec3, force_i: Vec3) -> None:
        """Add one sample taken at t_s."""
        if self.count == 0:
            self.start_s = t_s
        self.end_s = t_s
        self.count += 1
        for k in range(3):
            self._rate_sum[k] += rate_i[k]
            self._force_sum[k] += force_i[k]

    @property
    def duration_s(self) -> float:
        """Time span of the accumulated samples [s] (0 when empty)."""
        return self.end_s - self.start_s if self.count else 0.0

    @property
    def mean_rate_i(self) -> FloatArray:
        """Mean rate [rad/s], imu FRD."""
        return np.array(self._rate_sum) / max(self.count, 1)

    @property
    def mean_force_i(self) -> FloatArray:
        """Mean specific force [m/s²], imu FRD."""
        return np.array(self._force_sum) / max(self.count, 1)
