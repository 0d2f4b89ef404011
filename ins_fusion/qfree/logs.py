"""Q-Free OBU text logs: the 35-column GNSS and 14-column MEMS layouts, parsed and converted.

Source: shared/reference/gnss-ins-ntnu-notes.md (NTNU road-pricing thesis, Sæstad 2014):
§4 column layouts (appendices 6.1, 6.2; 1-based there, named here), §3 sensors (ST L3G4200D gyro
in milli-degrees/s, ST LIS331DLH accelerometer in milli-g, equipment id 6 = NovAtel SPAN
reference), §5 unit conversions and mounting rotations (the thesis's own, different for the
accelerometer and the gyro: ``thesis_transforms``) and §4 its 1.24 s IMU delay, §11 the gyro
sign flip above ~0.57 rad/s (a signed 16-bit wrap of the mdps value), "Implications" D1–D4 and
D8.

Lines are split on commas or semicolons when they contain any, else on whitespace; blank lines
and ``#`` comments are skipped; a missing optional value is empty, ``nan`` or ``-``. Times come
from the UTC date and time columns (4, 5). Nothing here knows about ROS: the importer
(ins_fusion/tools/import_qfree.py) turns these records into messages.
"""

from __future__ import annotations

import calendar
import math
import re
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Generic, NamedTuple, TypeVar

import numpy as np
from numpy.typing import NDArray

from gnss_ins_common.navsat import CovarianceType, NavSatStatus

#: Equipment id of the NovAtel SPAN reference receiver (§3, §4).
REFERENCE_EQUIPMENT_ID = 6
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
#: Fallback 1-sigma of a GNSS position per axis (m) and velocity (m/s): Table 4.9 (§6).
POSITION_STD_DEFAULT_M = 6.0
VELOCITY_STD_DEFAULT_M_S = 0.43
#: Row-major ENU covariance of a GNSS velocity (m²/s²): the log has no velocity sigma.
_V = VELOCITY_STD_DEFAULT_M_S**2
VELOCITY_COVARIANCE_ENU_M2_S2 = (_V, 0.0, 0.0, 0.0, _V, 0.0, 0.0, 0.0, _V)
#: Per-sample variances at rest on the bench, sensor axes x, y, z: gyro (rad/s)² Table 4.4,
#: accelerometer (m/s²)² Table 4.5 (§11; printed there with unit-less exponents).
GYRO_VARIANCE_RAD2_S2 = (7.02e-6, 5.14e-6, 7.36e-6)
ACCEL_VARIANCE_M2_S4 = (1.877e-4, 2.189e-4, 3.517e-4)

_MISSING = {"", "nan", "-", "na"}
_SEPARATORS = re.compile(r"\s*[,;]\s*")


class Column(NamedTuple):
    """One column of a layout (position in the tuple = column number − 1)."""

    name: str
    unit: str
    required: bool


#: Columns 1–8, common to both layouts.
COMMON_COLUMNS: tuple[Column, ...] = (
    Column("equipment_id", "", True),
    Column("drive_id", "", True),
    Column("leg_id", "", True),
    Column("date", "yyyy-mm-dd UTC", True),
    Column("time", "hh:mm:ss.fff UTC", True),
    Column("gps_week", "week", False),
    Column("gps_tow", "s", False),
    Column("obu_time", "s", False),
)

#: Appendix 6.1, GPS raw data (35 columns).
GNSS_COLUMNS: tuple[Column, ...] = (
    *COMMON_COLUMNS,
    Column("good", "1 good / 0 bad", True),
    Column("fix_type", "", False),
    Column("latitude", "deg", True),
    Column("longitude", "deg", True),
    Column("height_ellipsoid", "m", True),
    Column("height_msl", "m", False),
    Column("speed_over_ground", "m/s", False),
    Column("course_over_ground", "deg", False),
    Column("yaw", "deg/s (as printed)", False),
    Column("pitch", "deg/s (as printed)", False),
    Column("roll", "deg/s (as printed)", False),
    Column("horizontal_error", "m", False),
    Column("vertical_error", "m", False),
    Column("std_north", "m", False),
    Column("std_east", "m", False),
    Column("std_down", "m", False),
    Column("hdop", "", False),
    Column("pdop", "", False),
    Column("vel_north", "m/s", False),
    Column("vel_east", "m/s", False),
    Column("vel_down", "m/s", False),
    Column("satellites", "", False),
    Column("signal_quality", "", False),
    Column("sbas_active", "", False),
    Column("integrity_north", "m", False),
    Column("integrity_east", "m", False),
    Column("integrity_down", "m", False),
)

#: Appendix 6.2, MEMS raw data (14 columns); units are those of the default --accel-unit and
#: --gyro-unit.
MEMS_COLUMNS: tuple[Column, ...] = (
    *COMMON_COLUMNS,
    Column("accel_x", "mg", True),
    Column("accel_y", "mg", True),
    Column("accel_z", "mg", True),
    Column("gyro_x", "mdps", True),
    Column("gyro_y", "mdps", True),
    Column("gyro_z", "mdps", True),
)


class LineError(ValueError):
    """A line that does not fit its layout (the message says why)."""


@dataclass(frozen=True, slots=True)
class BadLine:
    """A rejected line: file, 1-based line number, reason."""

    source: str
    line: int
    reason: str

    def __str__(self) -> str:
        return f"{self.source}:{self.line}: {self.reason}"


@dataclass(frozen=True, slots=True)
class Stamp:
    """Columns 1–8 of a line; ``utc_ns`` = date + time columns in ns since the Unix epoch."""

    source: str
    line: int
    equipment_id: int
    drive_id: int
    leg_id: int
    utc_ns: int
    gps_week: float
    gps_tow_s: float
    obu_time_s: float


@dataclass(frozen=True, slots=True)
class GnssEpoch:
    """One GNSS line: geodetic position (deg, m above the WGS-84 ellipsoid), NED velocity (m/s)
    and 1-sigma NED position (m), NaN where the log has no value."""

    stamp: Stamp
    good: bool
    fix_type: float
    latitude_deg: float
    longitude_deg: float
    height_m: float
    std_ned_m: tuple[float, float, float]
    vel_ned_m_s: tuple[float, float, float]
    hdop: float
    satellites: float
    sbas: bool

    @property
    def status(self) -> NavSatStatus:
        """NO_FIX when the good flag (column 9) is 0, SBAS_FIX with SBAS active (column 32),
        else FIX. The fix type (column 10) is not mapped: its codes are not documented."""
        if not self.good:
            return NavSatStatus.NO_FIX
        return NavSatStatus.SBAS_FIX if self.sbas else NavSatStatus.FIX

    @property
    def vel_enu_m_s(self) -> tuple[float, float, float] | None:
        """REP-103 ENU velocity (v_E, v_N, −v_D), or None without a complete velocity (E6 data)."""
        north, east, down = self.vel_ned_m_s
        if not all(math.isfinite(v) for v in self.vel_ned_m_s):
            return None
        return (east, north, -down)

    @property
    def position_covariance_enu_m2(self) -> tuple[tuple[float, ...], CovarianceType]:
        """Row-major 3×3 ENU covariance (m²): diag(sE², sN², sD²) from columns 22–24
        (DIAGONAL_KNOWN), else the Table 4.9 default (6 m)² per axis (APPROXIMATED)."""
        north, east, down = self.std_ned_m
        if all(math.isfinite(s) and s > 0 for s in self.std_ned_m):
            e, n, u, kind = east, north, down, CovarianceType.DIAGONAL_KNOWN
        else:
            e = n = u = POSITION_STD_DEFAULT_M
            kind = CovarianceType.APPROXIMATED
        return (e * e, 0.0, 0.0, 0.0, n * n, 0.0, 0.0, 0.0, u * u), kind


@dataclass(frozen=True, slots=True)
class MemsSample:
    """One MEMS line, in the log's units (accelerometer mg or g, gyro mdps or dps)."""

    stamp: Stamp
    accel: tuple[float, float, float]
    gyro: tuple[float, float, float]


RecordT = TypeVar("RecordT", GnssEpoch, MemsSample)


@dataclass
class ParsedLog(Generic[RecordT]):
    """Records of one file in file order, the rejected lines, and the count of skipped
    (blank or comment) lines."""

    records: list[RecordT]
    bad_lines: list[BadLine]
    skipped: int


def split_fields(text: str) -> list[str]:
    """Fields of a line: comma/semicolon separated if it has any, else whitespace separated."""
    text = text.strip()
    return _SEPARATORS.split(text) if ("," in text or ";" in text) else text.split()


def utc_ns(date: str, clock: str) -> int:
    """``yyyy-mm-dd`` + ``hh:mm:ss[.fff]`` (UTC) → integer ns since the Unix epoch (exact)."""
    try:
        day = time.strptime(date, "%Y-%m-%d")
        hours, minutes, seconds = clock.split(":")
        whole, dot, fraction = seconds.partition(".")
        h, m, s = int(hours), int(minutes), int(whole)
        if dot and not fraction.isdigit():
            raise ValueError
        if not (0 <= h < 24 and 0 <= m < 60 and 0 <= s < 61):
            raise ValueError
    except ValueError:
        raise LineError(f"bad UTC date/time {date!r} {clock!r}") from None
    nanos = int(fraction.ljust(9, "0")[:9]) if fraction else 0
    return (calendar.timegm(day) + 3600 * h + 60 * m + s) * 1_000_000_000 + nanos


def _values(fields: list[str], layout: tuple[Column, ...]) -> dict[str, float]:
    """Numeric columns by name (NaN where missing); raises LineError naming the column."""
    values: dict[str, float] = {}
    for number, (column, text) in enumerate(zip(layout, fields, strict=True), start=1):
        if column.name in ("date", "time"):
            continue
        if text.lower() in _MISSING:
            if column.required:
                raise LineError(f"column {number} ({column.name}) is missing")
            values[column.name] = math.nan
            continue
        try:
            value = float(text)
        except ValueError:
            raise LineError(f"column {number} ({column.name}): {text!r} is not a number") from None
        if not math.isfinite(value) and column.required:
            raise LineError(f"column {number} ({column.name}) is {text!r}")
        values[column.name] = value
    return values


def _stamp(source: str, line: int, fields: list[str], values: dict[str, float]) -> Stamp:
    ids = [values["equipment_id"], values["drive_id"], values["leg_id"]]
    if any(v != int(v) for v in ids):
        raise LineError(f"equipment/drive/leg ids must be integers, got {fields[:3]}")
    return Stamp(
        source,
        line,
        int(ids[0]),
        int(ids[1]),
        int(ids[2]),
        utc_ns(fields[3], fields[4]),
        values["gps_week"],
        values["gps_tow"],
        values["obu_time"],
    )


def parse_gnss_line(text: str, source: str = "<gnss>", line: int = 0) -> GnssEpoch:
    """One 35-column GNSS line (appendix 6.1); raises LineError."""
    fields = split_fields(text)
    if len(fields) != len(GNSS_COLUMNS):
        raise LineError(f"expected {len(GNSS_COLUMNS)} columns, got {len(fields)}")
    v = _values(fields, GNSS_COLUMNS)
    if v["good"] not in (0.0, 1.0):
        raise LineError(f"column 9 (good): expected 0 or 1, got {fields[8]!r}")
    if not (-90.0 <= v["latitude"] <= 90.0 and -180.0 <= v["longitude"] <= 180.0):
        raise LineError(f"latitude/longitude out of range: {fields[10]} {fields[11]}")
    return GnssEpoch(
        stamp=_stamp(source, line, fields, v),
        good=v["good"] == 1.0,
        fix_type=v["fix_type"],
        latitude_deg=v["latitude"],
        longitude_deg=v["longitude"],
        height_m=v["height_ellipsoid"],
        std_ned_m=(v["std_north"], v["std_east"], v["std_down"]),
        vel_ned_m_s=(v["vel_north"], v["vel_east"], v["vel_down"]),
        hdop=v["hdop"],
        satellites=v["satellites"],
        sbas=v["sbas_active"] == 1.0,
    )


def parse_mems_line(text: str, source: str = "<mems>", line: int = 0) -> MemsSample:
    """One 14-column MEMS line (appendix 6.2); raises LineError."""
    fields = split_fields(text)
    if len(fields) != len(MEMS_COLUMNS):
        raise LineError(f"expected {len(MEMS_COLUMNS)} columns, got {len(fields)}")
    v = _values(fields, MEMS_COLUMNS)
    return MemsSample(
        stamp=_stamp(source, line, fields, v),
        accel=(v["accel_x"], v["accel_y"], v["accel_z"]),
        gyro=(v["gyro_x"], v["gyro_y"], v["gyro_z"]),
    )


def parse_log(
    lines: Iterable[str], source: str, parse_line: Callable[[str, str, int], RecordT]
) -> ParsedLog[RecordT]:
    """Every line of a log through ``parse_line``; bad lines are collected, never raised."""
    log: ParsedLog[RecordT] = ParsedLog([], [], 0)
    for number, text in enumerate(lines, start=1):
        stripped = text.strip()
        if not stripped or stripped.startswith("#"):
            log.skipped += 1
            continue
        try:
            log.records.append(parse_line(stripped, source, number))
        except LineError as exc:
            log.bad_lines.append(BadLine(source, number, str(exc)))
    return log


def parse_gnss(lines: Iterable[str], source: str) -> ParsedLog[GnssEpoch]:
    """A GNSS log (35 columns), see parse_log."""
    return parse_log(lines, source, parse_gnss_line)


def parse_mems(lines: Iterable[str], source: str) -> ParsedLog[MemsSample]:
    """A MEMS log (14 columns), see parse_log."""
    return parse_log(lines, source, parse_mems_line)


# --------------------------------------------------------------------------------------------
# MEMS → SI, gyro wrap, mounting
# --------------------------------------------------------------------------------------------


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
