"""The caster's sourcetable (NTRIP 2.0 §2.3): its mountpoints (``STR`` lines), nearest first.

A ``STR`` line's fields: STR;mountpoint;identifier;format;format-details;carrier;nav-system;
network;country;latitude;longitude;nmea;solution;generator;compr-encr;authentication;fee;
bitrate;misc. ``CAS`` and ``NET`` lines (casters, networks) are not needed and skipped.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

#: Mean earth radius (IUGG) [km], for great-circle distances.
EARTH_RADIUS_KM = 6371.0088


@dataclass(frozen=True, slots=True)
class Mountpoint:
    """One ``STR`` line; positions NaN when the caster gives none."""

    name: str
    identifier: str
    format: str
    format_details: str
    nav_system: str
    network: str
    country: str
    lat_deg: float
    lon_deg: float
    #: The caster wants the rover's position (GGA) before it sends data (e.g. a VRS).
    nmea_required: bool
    #: "N" none, "B" basic, "D" digest.
    authentication: str


def _float(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        return math.nan


def parse_sourcetable(text: str) -> list[Mountpoint]:
    """The mountpoints of a sourcetable body, in its order (lines up to ``ENDSOURCETABLE``)."""
    found = []
    for line in text.splitlines():
        if line.strip() == "ENDSOURCETABLE":
            break
        fields = line.strip().split(";")
        if fields[0] != "STR" or len(fields) < 2 or not fields[1]:
            continue
        fields += [""] * (19 - len(fields))
        lon = _float(fields[10])
        found.append(
            Mountpoint(
                name=fields[1],
                identifier=fields[2],
                format=fields[3],
                format_details=fields[4],
                nav_system=fields[6],
                network=fields[7],
                country=fields[8],
                lat_deg=_float(fields[9]),
                lon_deg=lon - 360.0 if lon > 180.0 else lon,  # some casters give 0..360
                nmea_required=fields[11].strip() == "1",
                authentication=fields[15],
            )
        )
    return found


def distance_km(lat1_deg: float, lon1_deg: float, lat2_deg: float, lon2_deg: float) -> float:
    """Great-circle distance on the mean sphere [km] (haversine); NaN for a NaN position."""
    phi1, phi2 = math.radians(lat1_deg), math.radians(lat2_deg)
    dphi, dlam = phi2 - phi1, math.radians(lon2_deg - lon1_deg)
    h = math.sin(dphi / 2) ** 2 + math.cos(phi1) * math.cos(phi2) * math.sin(dlam / 2) ** 2
    return 2 * EARTH_RADIUS_KM * math.asin(math.sqrt(1.0 if h > 1.0 else h))  # NaN stays


def by_distance(
    mountpoints: Iterable[Mountpoint], lat_deg: float, lon_deg: float
) -> list[Mountpoint]:
    """``mountpoints`` nearest to (``lat_deg``, ``lon_deg``) first; those without a position
    last, in their order."""

    def key(mp: Mountpoint) -> tuple[bool, float]:
        d = distance_km(lat_deg, lon_deg, mp.lat_deg, mp.lon_deg)
        return (math.isnan(d), 0.0 if math.isnan(d) else d)

    return sorted(mountpoints, key=key)


def describe(
    mountpoints: Sequence[Mountpoint], position: tuple[float, float] | None = None, limit: int = 10
) -> str:
    """E.g. "AAU00DNK (Aalborg, RTCM 3.2, 12 km), ..." for a message: nearest first when the
    ``position`` (lat, lon [deg]) is known, at most ``limit`` of them."""
    if not mountpoints:
        return "none"
    ordered = list(mountpoints) if position is None else by_distance(mountpoints, *position)
    parts = []
    for mp in ordered[:limit]:
        details = [mp.identifier, mp.format]
        if position is not None:
            d = distance_km(*position, mp.lat_deg, mp.lon_deg)
            details.append("" if math.isnan(d) else f"{d:.0f} km")
        text = ", ".join(detail for detail in details if detail)
        parts.append(f"{mp.name} ({text})" if text else mp.name)
    more = len(ordered) - limit
    return ", ".join(parts) + (f" and {more} more" if more > 0 else "")
