"""Conversions between the user-facing IMU noise units and SI.

User-facing units follow KF-GINS and the datasheets quoted in shared/reference: angle random walk
in deg/sqrt(h), velocity random walk in m/s/sqrt(h), gyro bias in deg/h or deg/s, accelerometer
bias in mg, scale factors in ppm or %. Internally everything is SI: rad/sqrt(s) for ARW, m/s/sqrt(s)
for VRW (both = noise density per sqrt(Hz)), rad/s, m/s², and plain fractions.

A white-noise density N sampled at f_s has a per-sample standard deviation N*sqrt(f_s); an
increment over dt has N*sqrt(dt) (shared/reference/mems-noise-oslo-notes.md, "Implications", R1).
"""

from __future__ import annotations

import math

#: Standard gravity [m/s²], the conventional value behind "1 g" and "mg" (CGPM 1901;
#: shared/reference/gnss-ins-ntnu-notes.md, "Implications", D2).
STANDARD_GRAVITY_M_S2 = 9.80665

DEG = math.pi / 180.0
_SQRT_HOUR_S = 60.0  # sqrt(3600 s)
_HOUR_S = 3600.0


def deg_sqrt_h(value: float) -> float:
    """Angle random walk: deg/sqrt(h) -> rad/sqrt(s) (= rad/s/sqrt(Hz))."""
    return value * DEG / _SQRT_HOUR_S


def to_deg_sqrt_h(value_rad_sqrt_s: float) -> float:
    """Angle random walk: rad/sqrt(s) -> deg/sqrt(h)."""
    return value_rad_sqrt_s / DEG * _SQRT_HOUR_S


def m_s_sqrt_h(value: float) -> float:
    """Velocity random walk: m/s/sqrt(h) -> m/s/sqrt(s) (= m/s²/sqrt(Hz))."""
    return value / _SQRT_HOUR_S


def to_m_s_sqrt_h(value_m_s_sqrt_s: float) -> float:
    """Velocity random walk: m/s/sqrt(s) -> m/s/sqrt(h)."""
    return value_m_s_sqrt_s * _SQRT_HOUR_S


def deg_h(value: float) -> float:
    """Angular rate: deg/h -> rad/s."""
    return value * DEG / _HOUR_S


def to_deg_h(value_rad_s: float) -> float:
    """Angular rate: rad/s -> deg/h."""
    return value_rad_s / DEG * _HOUR_S


def deg_s(value: float) -> float:
    """Angular rate: deg/s -> rad/s."""
    return value * DEG


def mg(value: float) -> float:
    """Acceleration: milli-g -> m/s² (1 g = STANDARD_GRAVITY_M_S2)."""
    return value * 1e-3 * STANDARD_GRAVITY_M_S2


def ppm(value: float) -> float:
    """Scale factor: parts per million -> fraction."""
    return value * 1e-6


def percent(value: float) -> float:
    """Scale factor: per cent -> fraction."""
    return value * 1e-2
