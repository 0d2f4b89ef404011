"""Exports of a replayed solution (forward or smoothed) for survey and map tools.

Every export holds the solutions past alignment (state not 'aligning'), in time order, of
base_link; times are the solutions' stamps (the ROS clock: UTC when the host clock is).

- CSV (``.csv``): one row per solution, a header line of the column names below; position WGS-84
  latitude/longitude [deg] and ellipsoidal height [m]; velocity ENU [m/s]; REP-103 roll, pitch,
  yaw of base_link in ENU [deg] (z-y'-x''); the 1σ of each, position and velocity along east,
  north, up [m, m/s], the angles from the ENU attitude covariance turned to the level vehicle
  axes [deg] (ins_fusion.replay.metrics.rpy_covariance); and the engine state.
- GPX 1.1 (``.gpx``, through gpxpy): one track of one segment, a point per solution with its
  UTC time and ``ele`` = height above the EGM96 geoid (mean sea level, as GPS receivers write
  it; gnss_driver.geoid), for map tools.
- NMEA 0183 (``.nmea``, through pynmea2): per solution GGA (position, height above the geoid
  and the geoid separation, quality 6 'estimated' while degraded, else 1), RMC (speed over
  ground [knots], course [deg]) and GST (1σ of latitude, longitude and height [m]), talker GP.
"""

from __future__ import annotations

import csv
import datetime
import math
from collections.abc import Sequence
from pathlib import Path

import gpxpy
import gpxpy.gpx
import numpy as np
import pynmea2
from scipy.spatial.transform import Rotation

from gnss_driver import geoid
from gnss_ins_common.types import FloatArray
from ins_fusion.core.engine import InsSolution
from ins_fusion.replay.metrics import rpy_covariance, rpy_deg

#: Export formats by file suffix.
FORMATS = (".csv", ".gpx", ".nmea")
CSV_COLUMNS = (
    "t_s",
    "lat_deg",
    "lon_deg",
    "height_m",
    "vel_e_m_s",
    "vel_n_m_s",
    "vel_u_m_s",
    "roll_deg",
    "pitch_deg",
    "yaw_deg",
    "sigma_e_m",
    "sigma_n_m",
    "sigma_u_m",
    "sigma_vel_e_m_s",
    "sigma_vel_n_m_s",
    "sigma_vel_u_m_s",
    "sigma_roll_deg",
    "sigma_pitch_deg",
    "sigma_yaw_deg",
    "state",
)
_KNOTS_PER_M_S = 3600.0 / 1852.0


def _aligned(solutions: Sequence[InsSolution]) -> list[InsSolution]:
    return [s for s in solutions if s.state != "aligning"]


def _sigma(cov: FloatArray) -> FloatArray:
    """Standard deviations of the diagonal of (n, 3, 3) covariances."""
    return np.sqrt(np.maximum(np.diagonal(cov, axis1=1, axis2=2), 0.0))


def write_csv(path: Path, solutions: Sequence[InsSolution]) -> int:
    """Write the CSV export; returns the rows written."""
    rows = _aligned(solutions)
    rpy = np.zeros((0, 3))
    sigma_rpy = np.zeros((0, 3))
    if rows:
        rpy = rpy_deg(Rotation.from_quat([s.quat_enu_flu_xyzw for s in rows]))
        cov_att = np.array([s.cov_att_enu_rad2 for s in rows])
        sigma_rpy = _sigma(rpy_covariance(cov_att, rpy[:, 2]))
    sigma_pos = _sigma(np.array([s.cov_pos_enu_m2 for s in rows]).reshape(-1, 3, 3))
    sigma_vel = _sigma(np.array([s.cov_vel_enu for s in rows]).reshape(-1, 3, 3))
    with path.open("w", newline="", encoding="utf-8") as file:
        writer = csv.writer(file)
        writer.writerow(CSV_COLUMNS)
        for i, s in enumerate(rows):
            values = [
                *s.vel_enu_m_s,
                *rpy[i],
                *sigma_pos[i],
                *sigma_vel[i],
                *sigma_rpy[i],
            ]
            writer.writerow(
                [
                    f"{s.t_s:.6f}",
                    f"{s.lat_deg:.9f}",
                    f"{s.lon_deg:.9f}",
                    f"{s.height_m:.4f}",
                    *(f"{v:.6g}" for v in values),
                    s.state,
                ]
            )
    return len(rows)


def _utc(t_s: float) -> datetime.datetime:
    return datetime.datetime.fromtimestamp(t_s, datetime.UTC)


def write_gpx(path: Path, solutions: Sequence[InsSolution], name: str) -> int:
    """Write the GPX export (a track named ``name``); returns the points written."""
    gpx = gpxpy.gpx.GPX()
    gpx.creator = "gnss_ins replay"
    track = gpxpy.gpx.GPXTrack(name=name)
    segment = gpxpy.gpx.GPXTrackSegment()
    track.segments.append(segment)
    gpx.tracks.append(track)
    rows = _aligned(solutions)
    for s in rows:
        msl = s.height_m - geoid.undulation_m(s.lat_deg, s.lon_deg)
        segment.points.append(
            gpxpy.gpx.GPXTrackPoint(
                round(s.lat_deg, 9), round(s.lon_deg, 9), round(msl, 4), _utc(s.t_s)
            )
        )
    path.write_text(gpx.to_xml(version="1.1"), encoding="utf-8")
    return len(rows)


def _nmea_angle(value_deg: float, width: int, signs: str) -> tuple[str, str]:
    """NMEA (d)ddmm.mmmmmmm field and hemisphere letter of an angle [deg]."""
    minutes = round(abs(value_deg) * 60.0, 7)
    whole = int(minutes // 60.0)
    return f"{whole:0{width}d}{minutes - 60.0 * whole:010.7f}", signs[value_deg < 0.0]


def _nmea_sentences(s: InsSolution) -> list[str]:
    utc = _utc(s.t_s)
    clock = f"{utc:%H%M%S}.{utc.microsecond // 10000:02d}"
    lat, lat_hemisphere = _nmea_angle(s.lat_deg, 2, "NS")
    lon, lon_hemisphere = _nmea_angle(s.lon_deg, 3, "EW")
    separation = geoid.undulation_m(s.lat_deg, s.lon_deg)
    quality = "6" if s.state == "degraded" else "1"
    east, north = float(s.vel_enu_m_s[0]), float(s.vel_enu_m_s[1])
    course = math.degrees(math.atan2(east, north)) % 360.0
    speed = math.hypot(east, north) * _KNOTS_PER_M_S
    sigma_e, sigma_n, sigma_u = _sigma(np.asarray(s.cov_pos_enu_m2)[None])[0]
    gga = pynmea2.GGA(
        "GP",
        "GGA",
        (
            clock,
            lat,
            lat_hemisphere,
            lon,
            lon_hemisphere,
            quality,
            "",
            "",
            f"{s.height_m - separation:.4f}",
            "M",
            f"{separation:.3f}",
            "M",
            "",
            "",
        ),
    )
    rmc = pynmea2.RMC(
        "GP",
        "RMC",
        (
            clock,
            "A",
            lat,
            lat_hemisphere,
            lon,
            lon_hemisphere,
            f"{speed:.3f}",
            f"{course:.2f}",
            f"{utc:%d%m%y}",
            "",
            "",
            "E" if quality == "6" else "A",
        ),
    )
    gst = pynmea2.GST(
        "GP",
        "GST",
        (clock, "", "", "", "", f"{sigma_n:.4f}", f"{sigma_e:.4f}", f"{sigma_u:.4f}"),
    )
    return [str(gga), str(rmc), str(gst)]


def write_nmea(path: Path, solutions: Sequence[InsSolution]) -> int:
    """Write the NMEA export (GGA, RMC, GST per solution, CRLF); returns the epochs written."""
    rows = _aligned(solutions)
    with path.open("w", newline="", encoding="ascii") as file:
        for s in rows:
            file.writelines(sentence + "\r\n" for sentence in _nmea_sentences(s))
    return len(rows)


def export(path: Path, solutions: Sequence[InsSolution], name: str) -> int:
    """Write ``solutions`` in the format of ``path``'s suffix (FORMATS); returns the epochs."""
    suffix = path.suffix.lower()
    if suffix == ".csv":
        return write_csv(path, solutions)
    if suffix == ".gpx":
        return write_gpx(path, solutions, name)
    if suffix == ".nmea":
        return write_nmea(path, solutions)
    raise ValueError(f"{path}: unknown export format (suffix one of {', '.join(FORMATS)})")
