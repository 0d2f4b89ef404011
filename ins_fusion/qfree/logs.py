"""Q-Free OBU text logs: the 35-column GNSS and 14-column MEMS layouts, parsed into records.

Source: shared/reference/gnss-ins-ntnu-notes.md (NTNU road-pricing thesis, Sæstad 2014):
§4 column layouts (appendices 6.1, 6.2; 1-based there, named here), §3 equipment id 6 = NovAtel
SPAN reference, §6 the fallback GNSS accuracy, "Implications" D1 and D8.

Lines are split on commas or semicolons when they contain any, else on whitespace; blank lines
and ``#`` comments are skipped; a missing optional value is empty, ``nan`` or ``-``. Times come
from the UTC date and time columns (4, 5). The MEMS samples stay in the log's units here;
ins_fusion/qfree/mems_conversion.py takes them to SI. Nothing here knows about ROS: the importer
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

from gnss_ins_common.navsat import CovarianceType, NavSatStatus

#: Equipment id of the NovAtel SPAN reference receiver (§3, §4).
REFERENCE_EQUIPMENT_ID = 6
#: Fallback 1-sigma of a GNSS position per axis (m) and velocity (m/s): Table 4.9 (§6).
POSITION_STD_DEFAULT_M = 6.0
VELOCITY_STD_DEFAULT_M_S = 0.43
#: Row-major ENU covariance of a GNSS velocity (m²/s²): the log has no velocity sigma.
_V = VELOCITY_STD_DEFAULT_M_S**2
VELOCITY_COVARIANCE_ENU_M2_S2 = (_V, 0.0, 0.0, 0.0, _V, 0.0, 0.0, 0.0, _V)


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
