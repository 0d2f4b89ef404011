"""Device axes and signs -> REP-103/REP-145 ``imu_link`` (FLU, SI units), and back (no I/O).

The IMU400CC platform frame is FRD (x forward, y right, z down; notes §1.4, §12 item 2), with
rates positive by the right-hand rule about each device axis. The example packets of App. D.5
read about +1 g on a_z; the report does not say how the unit stood, so reading them as "level,
upright, at rest" (the device reports minus the specific force, ``accel_sign = -1`` undoes it)
is this project's assumption (notes §2.7, §12 item 1). With the defaults a level, resting unit reads
(0, 0, +9.81) m/s^2 in FLU. Both signs must be confirmed on hardware (notes §11.1 item 5).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Final

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gnss_ins_common.axes import AxisMap
from imu400cc_driver.protocol import (
    TEMPERATURE_C_PER_COUNT,
    TEMPERATURE_OFFSET_C,
    RawPacket,
    Scaling,
)

#: FLU axis i of imu_link = this device axis (FRD device; notes §1.4, §11.1 item 5).
DEFAULT_AXIS_SPEC: Final[tuple[str, str, str]] = ("x", "-y", "-z")
#: Device accelerometer output = -specific force: our assumption from the App. D.5 example rows
#: (the report does not say the unit was upright; notes §12 item 1). Unverified.
DEFAULT_ACCEL_SIGN: Final = -1.0
#: Standard gravity [m/s^2] used to turn the device's g into m/s^2 (notes §11.1 item 4).
STANDARD_GRAVITY_M_S2: Final = 9.80665
#: Radians per degree, the factor of numpy's ``radians``.
_RAD_PER_DEG: Final = math.pi / 180.0


@dataclass(frozen=True, slots=True, eq=False)
class ImuMeasurement:
    """One packet in imu_link (FLU) and SI units; ``timer`` is the raw device timer count."""

    rate_flu_rad_s: NDArray[np.float64]
    """Angular rate, shape (3,) [rad/s], right-hand rule about the FLU axes."""
    specific_force_flu_m_s2: NDArray[np.float64]
    """Specific force, shape (3,) [m/s^2]; (0, 0, +g) for a level unit at rest (REP-145)."""
    temperature_c: float
    """Sensor temperature [degC], (D-4)."""
    timer: int
    """uint16 down-counting device timer (notes §2.6)."""


def _m_s2_per_device_g(accel_sign: float, gravity_m_s2: float) -> float:
    """FLU specific force [m/s^2] per device accelerometer unit [g] (sign included)."""
    if accel_sign not in (1.0, -1.0):
        raise ValueError(f"accel_sign must be +1 or -1, got {accel_sign!r}")
    if not (np.isfinite(gravity_m_s2) and gravity_m_s2 > 0):
        raise ValueError(f"gravity_m_s2 must be finite and > 0, got {gravity_m_s2!r}")
    return accel_sign * gravity_m_s2


def _vector3(vec: ArrayLike, name: str) -> NDArray[np.float64]:
    array = np.asarray(vec, dtype=np.float64)
    if array.shape != (3,):
        raise ValueError(f"{name} must have shape (3,), got {array.shape}")
    return array


class PacketConverter:
    """Device counts -> imu_link FLU, rad/s, m/s^2 and degC (notes §2.4, §11.1 items 4-5), with
    the factors of a unit's scaling and mounting worked out once: the driver converts every
    packet. Each value is ``count * per_count`` [deg/s, g], then * pi/180 for a rate, then the
    axis sign, then for a specific force ``accel_sign * gravity``: the rounding of the
    element-wise ``Scaling`` and ``AxisMap`` methods (test_imu_axes.py)."""

    def __init__(
        self,
        scaling: Scaling,
        axis_map: AxisMap,
        accel_sign: float,
        gravity_m_s2: float = STANDARD_GRAVITY_M_S2,
    ) -> None:
        """The conversion of ``scaling``'s counts through ``axis_map`` (FLU axis i = sign i x
        device axis i); ValueError for an ``accel_sign`` other than ±1 or a gravity not > 0."""
        self._m_s2_per_g = _m_s2_per_device_g(accel_sign, gravity_m_s2)
        self._dps = scaling.dps_per_count
        self._g = scaling.g_per_count
        self._indices = axis_map.indices
        self._signs = axis_map.signs

    def __call__(self, raw: RawPacket) -> ImuMeasurement:
        """The measurement of one packet."""
        i, j, k = self._indices
        si, sj, sk = self._signs
        dps, rad, g, m_s2 = self._dps, _RAD_PER_DEG, self._g, self._m_s2_per_g
        w, a = raw.rates, raw.accels
        rate = np.array((w[i] * dps * rad * si, w[j] * dps * rad * sj, w[k] * dps * rad * sk))
        force = np.array((a[i] * g * si * m_s2, a[j] * g * sj * m_s2, a[k] * g * sk * m_s2))
        celsius = raw.temperature * TEMPERATURE_C_PER_COUNT + TEMPERATURE_OFFSET_C
        return ImuMeasurement(rate, force, celsius, raw.timer)


def measurement_to_packet(
    rate_flu_rad_s: ArrayLike,
    specific_force_flu_m_s2: ArrayLike,
    temperature_c: float,
    timer: int,
    scaling: Scaling,
    axis_map: AxisMap,
    accel_sign: float,
    gravity_m_s2: float = STANDARD_GRAVITY_M_S2,
) -> RawPacket:
    """Inverse of ``PacketConverter`` (for the emulator): nearest counts, clipped to the field
    ranges; use the Scaling ``*_counts`` methods to learn whether a value saturated."""
    m_s2_per_g = _m_s2_per_device_g(accel_sign, gravity_m_s2)
    rate_dps = np.degrees(axis_map.from_flu(_vector3(rate_flu_rad_s, "rate_flu_rad_s")))
    force = _vector3(specific_force_flu_m_s2, "specific_force_flu_m_s2")
    r = scaling.rate_counts(rate_dps).counts.tolist()
    a = scaling.accel_counts(axis_map.from_flu(force) / m_s2_per_g).counts.tolist()
    temperature = int(scaling.temperature_counts(temperature_c).counts)
    return RawPacket((r[0], r[1], r[2]), (a[0], a[1], a[2]), temperature, timer)
