"""Leica LLQ grid coordinates -> WGS-84 latitude and longitude through a configured projection.

The rover's LLQ carries the position in the local grid its job is set up for (e.g. ETRS89 /
UTM zone 32N, ``EPSG:25832``, in Denmark; imu400cc-aalborg-notes.md §7.2). pyproj (PROJ and
its EPSG database, shipped in the wheel) turns grid easting and northing [m] into geodetic
coordinates on WGS-84 (``EPSG:4326``). Transformations that need a datum-shift grid file fall
back to PROJ's ballpark transformation (no grid files are downloaded); ETRS89 and WGS-84 agree
to well below a metre.
"""

from __future__ import annotations

import math

from pyproj import CRS, Transformer
from pyproj.exceptions import CRSError

WGS84 = CRS.from_epsg(4326)


def projection_error(crs: str) -> str | None:
    """Why ``crs`` cannot be the LLQ grid (not a known projected CRS), or None."""
    if crs == "":
        return None
    try:
        parsed = CRS.from_user_input(crs)
    except CRSError as exc:
        return f"unknown coordinate reference system {crs!r}: {exc}"
    return None if parsed.is_projected else f"{crs!r} ({parsed.name}) is not a projected CRS"


class GridProjection:
    """Grid (easting, northing) [m] in a projected CRS -> (latitude, longitude) [deg]."""

    def __init__(self, crs: str) -> None:
        """``crs``: anything pyproj's ``CRS.from_user_input`` takes, e.g. ``EPSG:25832``."""
        source = CRS.from_user_input(crs)
        self.name = str(source.name)
        self._transformer = Transformer.from_crs(source, WGS84, always_xy=True)

    def to_lat_lon(self, easting_m: float, northing_m: float) -> tuple[float, float] | None:
        """WGS-84 position [deg]; None when the point is outside the projection's domain."""
        lon, lat = self._transformer.transform(easting_m, northing_m)
        if not (math.isfinite(lat) and math.isfinite(lon)) or abs(lat) > 90.0:
            return None
        return float(lat), float(lon)
