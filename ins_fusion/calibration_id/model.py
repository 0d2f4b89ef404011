"""What the estimators know of the laboratory and of the sensor's slow errors.

Site: local gravity and earth rate. Aalborg notes §4.2 use g_l^LL = 1.0017 g at φ = 57° and
earth rate Ω = 7.292115e-5 rad/s (§10); here normal gravity at the latitude and height
(core.nav.earth, the Farrell formula of §5.2) unless a measured value is given. In imu_link terms a
unit at rest reads the specific force +g along the local up (REP-145) and the earth rate
Ω (0, cos φ, sin φ) in ENU.

Bias instability: the Gauss-Markov part of the bias (stationary σ, correlation time τ) moves the
means of segments taken minutes apart; the estimators treat it as correlated observation noise,
Cov(k, l) = σ² exp(-|t_k - t_l| / τ) between the segment centres (Aalborg §3.3 found a
day-to-day gyro-bias scatter of 0.01-0.02 °/s, larger than the white-noise prediction of §4.4).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from gnss_ins_common.types import FloatArray, Vec3
from ins_fusion.calibration_id.segments import Segment
from ins_fusion.core.nav.earth import EARTH_RATE_RAD_S, normal_gravity_m_s2


@dataclass(frozen=True)
class Site:
    """Latitude [rad] (earth rate) and local gravity [m/s²] of the laboratory."""

    latitude_rad: float
    gravity_m_s2: float

    @classmethod
    def at(
        cls, latitude_deg: float, height_m: float = 0.0, gravity_m_s2: float | None = None
    ) -> Site:
        """Site at a latitude [deg] and height [m]; gravity from the normal gravity formula
        unless given."""
        lat = math.radians(latitude_deg)
        g = normal_gravity_m_s2(lat, height_m) if gravity_m_s2 is None else gravity_m_s2
        return cls(lat, float(g))

    @property
    def earth_rate_enu_rad_s(self) -> FloatArray:
        """Earth rotation in the local ENU frame [rad/s]."""
        lat = self.latitude_rad
        return np.array([0.0, EARTH_RATE_RAD_S * math.cos(lat), EARTH_RATE_RAD_S * math.sin(lat)])


@dataclass(frozen=True)
class BiasInstability:
    """Gauss-Markov bias per axis: stationary σ and correlation time [s], gyro [rad/s] and
    accelerometer [m/s²] (the fusion node's imu_noise parameters give one time for both)."""

    gyro_rad_s: Vec3 = (0.0, 0.0, 0.0)
    accel_m_s2: Vec3 = (0.0, 0.0, 0.0)
    gyro_correlation_time_s: float = 300.0
    accel_correlation_time_s: float = 300.0

    def covariance(self, segments: Sequence[Segment], triad: str, axis: int) -> FloatArray:
        """Covariance of the bias part of the segment means of one axis (module docstring)."""
        gyro = triad == "gyro"
        sigma = (self.gyro_rad_s if gyro else self.accel_m_s2)[axis]
        tau = self.gyro_correlation_time_s if gyro else self.accel_correlation_time_s
        t = np.array([s.t_mid_s for s in segments])
        return np.asarray(sigma * sigma * np.exp(-np.abs(t[:, None] - t[None, :]) / tau))

    def gyro_correlation(self, a: Segment, b: Segment) -> float:
        """Correlation of the gyro bias between the centres of two segments."""
        return math.exp(-abs(a.t_mid_s - b.t_mid_s) / self.gyro_correlation_time_s)
