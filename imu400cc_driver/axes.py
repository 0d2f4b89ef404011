"""Device axes and signs -> REP-103/REP-145 ``imu_link`` (FLU, SI units), and back (no I/O).

The IMU400CC platform frame is FRD (x forward, y right, z down; notes §1.4, §12 item 2), with
rates positive by the right-hand rule about each device axis. App. D.5 reads about +1 g on a_z
with the unit level and at rest (notes §2.7, §12 item 1), i.e. the device reports minus the
specific force: ``accel_sign = -1`` undoes that. With the defaults a level, resting unit reads
(0, 0, +9.81) m/s^2 in FLU. Both signs must be confirmed on hardware (notes §11.1 item 5).
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Final

import numpy as np
from numpy.typing import ArrayLike, NDArray

from imu400cc_driver.protocol import RawPacket, Scaling

#: FLU axis i of imu_link = this device axis (FRD device; notes §1.4, §11.1 item 5).
DEFAULT_AXIS_SPEC: Final[tuple[str, str, str]] = ("x", "-y", "-z")
#: Device accelerometer output = -specific force (App. D.5; notes §12 item 1). Unverified.
DEFAULT_ACCEL_SIGN: Final = -1.0
#: Standard gravity [m/s^2] used to turn the device's g into m/s^2 (notes §11.1 item 4).
STANDARD_GRAVITY_M_S2: Final = 9.80665

_AXIS_NAMES: Final = "xyz"
_AXIS_TERM: Final = re.compile(r"([+-]?)([xyz])")


@dataclass(frozen=True, slots=True)
class AxisMap:
    """Signed permutation: FLU axis i = ``signs[i]`` * device axis ``indices[i]``."""

    indices: tuple[int, int, int]
    signs: tuple[float, float, float]

    def __post_init__(self) -> None:
        if sorted(self.indices) != [0, 1, 2] or any(s not in (1.0, -1.0) for s in self.signs):
            raise ValueError(f"not a signed permutation: {self.indices!r}, {self.signs!r}")

    @classmethod
    def from_spec(cls, spec: Sequence[str]) -> AxisMap:
        """Parse e.g. ``["x", "-y", "-z"]``: spec[i] is the device axis (optionally signed) that
        is FLU axis i. Exactly three terms, each of x, y, z once; ValueError otherwise."""
        if isinstance(spec, str) or len(spec) != 3:
            raise ValueError(f"axis spec needs three terms like ['x', '-y', '-z'], got {spec!r}")
        matches = [_AXIS_TERM.fullmatch(str(term).strip().lower()) for term in spec]
        axes = {m.group(2) for m in matches if m is not None}
        if None in matches or len(axes) != 3:
            raise ValueError(
                f"axis spec {list(spec)!r}: each of x, y, z exactly once, optionally signed + or -"
            )
        (i0, s0), (i1, s1), (i2, s2) = (
            (_AXIS_NAMES.index(m.group(2)), -1.0 if m.group(1) == "-" else 1.0)
            for m in matches
            if m is not None
        )
        return cls(indices=(i0, i1, i2), signs=(s0, s1, s2))

    @property
    def spec(self) -> tuple[str, str, str]:
        """The canonical spec, e.g. ``("x", "-y", "-z")``."""
        s0, s1, s2 = (
            ("-" if sign < 0 else "") + _AXIS_NAMES[index]
            for index, sign in zip(self.indices, self.signs, strict=True)
        )
        return (s0, s1, s2)

    @property
    def matrix(self) -> NDArray[np.float64]:
        """3x3 matrix M with ``v_flu = M @ v_device``."""
        matrix = np.zeros((3, 3))
        matrix[[0, 1, 2], list(self.indices)] = self.signs
        return matrix

    @property
    def proper(self) -> bool:
        """True for a rotation (det +1). A reflection is only right for a left-handed device
        frame, which App. B.5 (y left, z down) would imply against §7.4 (notes §12 item 2)."""
        return bool(np.linalg.det(self.matrix) > 0)

    def to_flu(self, vec: ArrayLike) -> NDArray[np.float64]:
        """Device-axis vector(s), shape (..., 3), in imu_link FLU axes."""
        device = _as_vectors(vec)
        flu: NDArray[np.float64] = device[..., list(self.indices)] * np.asarray(self.signs)
        return flu

    def from_flu(self, vec: ArrayLike) -> NDArray[np.float64]:
        """Inverse of to_flu: FLU vector(s), shape (..., 3), in device axes."""
        flu = _as_vectors(vec)
        device = np.empty_like(flu)
        device[..., list(self.indices)] = flu * np.asarray(self.signs)
        return device


def _as_vectors(vec: ArrayLike) -> NDArray[np.float64]:
    array = np.asarray(vec, dtype=np.float64)
    if array.ndim == 0 or array.shape[-1] != 3:
        raise ValueError(f"expected 3-vectors (shape (..., 3)), got shape {array.shape}")
    return array


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


def packet_to_measurement(
    raw: RawPacket,
    scaling: Scaling,
    axis_map: AxisMap,
    accel_sign: float,
    gravity_m_s2: float = STANDARD_GRAVITY_M_S2,
) -> ImuMeasurement:
    """Device counts -> imu_link FLU, rad/s, m/s^2 and degC (notes §2.4, §11.1 items 4-5)."""
    m_s2_per_g = _m_s2_per_device_g(accel_sign, gravity_m_s2)
    rate = axis_map.to_flu(np.radians(scaling.rate_dps(raw.rates)))
    force = axis_map.to_flu(scaling.accel_g(raw.accels)) * m_s2_per_g
    return ImuMeasurement(rate, force, float(scaling.temperature_c(raw.temperature)), raw.timer)


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
    """Inverse of packet_to_measurement (for the emulator): nearest counts, clipped to the field
    ranges; use the Scaling ``*_counts`` methods to learn whether a value saturated."""
    m_s2_per_g = _m_s2_per_device_g(accel_sign, gravity_m_s2)
    rate_dps = np.degrees(axis_map.from_flu(_vector3(rate_flu_rad_s, "rate_flu_rad_s")))
    force = _vector3(specific_force_flu_m_s2, "specific_force_flu_m_s2")
    r = scaling.rate_counts(rate_dps).counts.tolist()
    a = scaling.accel_counts(axis_map.from_flu(force) / m_s2_per_g).counts.tolist()
    temperature = int(scaling.temperature_counts(temperature_c).counts)
    return RawPacket((r[0], r[1], r[2]), (a[0], a[1], a[2]), temperature, timer)
