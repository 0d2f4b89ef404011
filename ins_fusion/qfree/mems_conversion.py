"""Q-Free MEMS samples in SI units in imu_link: the log's units, mountings, the thesis's own
transforms and the gyro's 16-bit wrap.

Source: shared/reference/gnss-ins-ntnu-notes.md (NTNU road-pricing thesis, Sæstad 2014): §3
sensors (ST L3G4200D gyro in milli-degrees/s, ST LIS331DLH accelerometer in milli-g), §5 unit
conversions and mounting rotations (the thesis's own, different for the accelerometer and the
gyro: ``thesis_transforms``) and §4 its 1.24 s IMU delay, §11 the gyro sign flip above ~0.57
rad/s (a signed 16-bit wrap of the mdps value) and the bench variances, "Implications" D2–D4.
The samples come from the parser of the logs (ins_fusion/qfree/logs.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ins_fusion.qfree.logs import MemsSample

#: Standard gravity, m/s² per g: the default mg → m/s² factor (D2; the thesis used 9.82171·0.97396).
STANDARD_GRAVITY_M_S2 = 9.80665
#: m/s² per accelerometer unit of the log.
ACCEL_UNITS: dict[str, float] = {"mg": STANDARD_GRAVITY_M_S2 / 1000.0, "g": STANDARD_GRAVITY_M_S2}
#: rad/s per gyro unit of the log.
GYRO_UNITS: dict[str, float] = {"mdps": math.radians(1e-3), "dps": math.radians(1.0)}
#: The gyro value wraps modulo 2^16 mdps (§11 [note]: 32767 mdps = 0.5719 rad/s is the onset).
GYRO_WRAP_PERIOD_RAD_S = 65536 * GYRO_UNITS["mdps"]
#: A gap longer than this (s), a time going backwards, or a new equipment/drive/leg starts a new
#: segment: gyro unwrapping restarts there (the sensor may have been power-cycled, §3).
SEGMENT_GAP_S = 1.0
#: Per-sample variances at rest on the bench, sensor axes x, y, z: gyro (rad/s)² Table 4.4,
#: accelerometer (m/s²)² Table 4.5 (§11; printed there with unit-less exponents).
GYRO_VARIANCE_RAD2_S2 = (7.02e-6, 5.14e-6, 7.36e-6)
ACCEL_VARIANCE_M2_S4 = (1.877e-4, 2.189e-4, 3.517e-4)


@dataclass(frozen=True, slots=True)
class GyroWrap:
    """A jump of more than half the 16-bit period between consecutive gyro samples (log units)."""

    source: str
    line: int
    axis: str
    before: float
    after: float

    def __str__(self) -> str:
        return f"{self.source}:{self.line}: gyro {self.axis} {self.before:g} -> {self.after:g}"


@dataclass(frozen=True)
class ImuSeries:
    """MEMS samples in SI units in the output frame (each sensor's SensorTransform applied):
    times (the UTC columns plus the time shift) [ns], specific force (m/s², N×3), angular rate
    (rad/s, N×3), and the per-sample variances per output axis, gain²·diag(M·Σ·Mᵀ) of the bench
    values (Tables 4.4/4.5)."""

    utc_ns: NDArray[np.int64]
    accel_m_s2: NDArray[np.float64]
    rate_rad_s: NDArray[np.float64]
    accel_variance_m2_s4: NDArray[np.float64]
    rate_variance_rad2_s2: NDArray[np.float64]
    wraps: list[GyroWrap]


def mounting_rotation(roll_deg: float, pitch_deg: float, yaw_deg: float) -> NDArray[np.float64]:
    """Rotation matrix R = Rz(yaw)·Ry(pitch)·Rx(roll) (active, right-handed) applied to the
    log's sensor vectors: v_out = R·v_sensor."""
    from scipy.spatial.transform import Rotation  # lazy: keeps `gnss_ins --help` fast

    rotation = Rotation.from_euler("xyz", [roll_deg, pitch_deg, yaw_deg], degrees=True)
    return np.asarray(rotation.as_matrix(), dtype=np.float64)


@dataclass(frozen=True)
class SensorTransform:
    """Log values of one triad to imu_link: v = gain · u · matrix · v_log, u the SI value of the
    log ``unit`` (a key of ACCEL_UNITS or GYRO_UNITS). matrix: 3×3, a mounting rotation or any
    other matrix (the thesis's gyro transform is a reflection); gain: an extra scale."""

    unit: str
    matrix: NDArray[np.float64]
    gain: float = 1.0

    @classmethod
    def mounted(cls, unit: str, mounting_deg: tuple[float, float, float]) -> SensorTransform:
        """Unit conversion and mounting_rotation(roll, pitch, yaw) [deg]."""
        return cls(unit, mounting_rotation(*mounting_deg))

    def apply(self, values: NDArray[np.float64], units: dict[str, float]) -> NDArray[np.float64]:
        """Log values (N×3) in SI in the output frame (N×3)."""
        return np.asarray(values * (self.gain * units[self.unit]) @ self.matrix.T)

    def variances(self, variance: tuple[float, float, float]) -> NDArray[np.float64]:
        """Per output axis: gain²·diag(M·diag(variance)·Mᵀ) of per sensor axis SI variances."""
        return np.asarray(self.gain**2 * np.diag(self.matrix @ np.diag(variance) @ self.matrix.T))


# The thesis's own transforms (NTNU notes §5, thesis appendix 6.5), with its elementary
# matrices (2.1)-(2.3) as printed, into its body frame b (x forward, y right, z down):
#   fis_b = Rz(π)·Ry(o2)·Rx(o3) · 0.97396·9.82171·acc/1000       (acc in mg)
#   ois_b = deg2rad(Rz(0)·Ry(o2)·Rx(-o3) · (-gyro/1000))           (gyro in mdps)
#: orientation(2), orientation(3) of the thesis's program: mount pitch 25.10°, roll -1.04° [rad].
THESIS_MOUNT_PITCH_RAD = 0.438057067391664
THESIS_MOUNT_ROLL_RAD = -0.01816728115647
#: Its accelerometer factor, 0.97396 · 9.82171 m/s² per g, as a gain on the mg unit.
THESIS_ACCEL_GAIN = 0.97396 * 9.82171 / STANDARD_GRAVITY_M_S2
#: Its IMU data were delayed by 1.24 s (62 samples at 50 Hz) to meet the late GNSS (§4).
THESIS_LATENCY_S = 1.24
#: The thesis's b frame (FRD) to imu_link (FLU).
_FRD_TO_FLU = np.diag([1.0, -1.0, -1.0])


def thesis_rx(a: float) -> NDArray[np.float64]:
    """(2.1) as printed."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, s], [0.0, -s, c]])


def thesis_ry(b: float) -> NDArray[np.float64]:
    """(2.2) as printed."""
    c, s = math.cos(b), math.sin(b)
    return np.array([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]])


def thesis_rz(g: float) -> NDArray[np.float64]:
    """(2.3) as printed."""
    c, s = math.cos(g), math.sin(g)
    return np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])


def thesis_transforms() -> tuple[SensorTransform, SensorTransform]:
    """(accelerometer, gyro) transforms that reproduce the thesis's program lines above, then
    take its b frame (FRD) to imu_link (FLU). The gyro's matrix is the negated rotation, a
    reflection (det -1): the thesis's axis handling, kept as it is (notes §14 item 8)."""
    pitch, roll = THESIS_MOUNT_PITCH_RAD, THESIS_MOUNT_ROLL_RAD
    accel = thesis_rz(math.pi) @ thesis_ry(pitch) @ thesis_rx(roll)
    gyro = -(thesis_rz(0.0) @ thesis_ry(pitch) @ thesis_rx(-roll))
    return (
        SensorTransform("mg", _FRD_TO_FLU @ accel, THESIS_ACCEL_GAIN),
        SensorTransform("mdps", _FRD_TO_FLU @ gyro),
    )


def segment_ids(samples: list[MemsSample]) -> NDArray[np.int64]:
    """Segment number per sample: a new one at a new equipment/drive/leg, a gap longer than
    SEGMENT_GAP_S or a time going backwards."""
    ids = np.zeros(len(samples), dtype=np.int64)
    for k in range(1, len(samples)):
        a, b = samples[k - 1].stamp, samples[k].stamp
        dt_s = (b.utc_ns - a.utc_ns) / 1e9
        new = (a.equipment_id, a.drive_id, a.leg_id) != (b.equipment_id, b.drive_id, b.leg_id)
        ids[k] = ids[k - 1] + int(new or not 0.0 <= dt_s <= SEGMENT_GAP_S)
    return ids


def unwrap_gyro(
    gyro: NDArray[np.float64], segments: NDArray[np.int64], period: float
) -> tuple[NDArray[np.float64], list[tuple[int, int]]]:
    """Undo the modulo-``period`` wrap of each axis within each segment (``numpy.unwrap``).

    Returns the unwrapped rates (same units) and the (sample index, axis) of every jump of more
    than period/2 between consecutive samples — a physical change that large in one sample
    period (32.8 deg/s in 20 ms for the 16-bit mdps wrap) does not happen in a car.
    """
    out = gyro.copy()
    jumps: list[tuple[int, int]] = []
    for segment in np.unique(segments):
        (index,) = np.nonzero(segments == segment)
        block = gyro[index]
        out[index] = np.unwrap(block, period=period, axis=0)
        rows, axes = np.nonzero(np.abs(np.diff(block, axis=0)) > period / 2)
        jumps.extend((int(index[r + 1]), int(a)) for r, a in zip(rows, axes, strict=True))
    return out, sorted(jumps)


def imu_series(
    samples: list[MemsSample],
    *,
    accel: SensorTransform | None = None,
    gyro: SensorTransform | None = None,
    unwrap: bool = True,
    time_shift_s: float = 0.0,
) -> ImuSeries:
    """Convert MEMS samples (in file order) to SI in the output frame with each sensor's
    transform (default: mg and mdps, unrotated), their times shifted by time_shift_s [s] (the
    thesis: +1.24 s). Gyro wraps are always reported; they are undone (in log units, before the
    transform) when ``unwrap``."""
    accel = accel or SensorTransform("mg", np.eye(3))
    gyro = gyro or SensorTransform("mdps", np.eye(3))
    if accel.unit not in ACCEL_UNITS or gyro.unit not in GYRO_UNITS:
        raise ValueError(f"unknown unit {accel.unit!r} or {gyro.unit!r}")
    accel_log = np.array([s.accel for s in samples], dtype=np.float64).reshape(-1, 3)
    gyro_log = np.array([s.gyro for s in samples], dtype=np.float64).reshape(-1, 3)
    period = GYRO_WRAP_PERIOD_RAD_S / GYRO_UNITS[gyro.unit]
    unwrapped, jumps = unwrap_gyro(gyro_log, segment_ids(samples), period)
    wraps = [
        GyroWrap(
            samples[i].stamp.source,
            samples[i].stamp.line,
            "xyz"[axis],
            float(gyro_log[i - 1, axis]),
            float(gyro_log[i, axis]),
        )
        for i, axis in jumps
    ]
    shift_ns = round(time_shift_s * 1e9)
    return ImuSeries(
        utc_ns=np.array([s.stamp.utc_ns + shift_ns for s in samples], dtype=np.int64),
        accel_m_s2=accel.apply(accel_log, ACCEL_UNITS),
        rate_rad_s=gyro.apply(unwrapped if unwrap else gyro_log, GYRO_UNITS),
        accel_variance_m2_s4=accel.variances(ACCEL_VARIANCE_M2_S4),
        rate_variance_rad2_s2=gyro.variances(GYRO_VARIANCE_RAD2_S2),
        wraps=wraps,
    )
