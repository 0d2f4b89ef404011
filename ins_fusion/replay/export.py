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
from pathlib import Path

import gpxpy
import gpxpy.gpx
import numpy as np
import pynmea2
from scipy.spatial.transform import Rotation

from gnss_driver import geoid
from gnss_ins_common.types import FloatArray
from ins_fusion.core.output import solution_rows as cols
from ins_fusion.replay.metrics import rpy_covariance, rpy_deg
from ins_fusion.replay.run import SolutionTrack

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


def _sigma(cov: FloatArray) -> FloatArray:
    """Standard deviations of the diagonal of (n, 3, 3) covariances."""
    return np.sqrt(np.maximum(np.diagonal(cov, axis1=1, axis2=2), 0.0))


def write_csv(path: Path, track: SolutionTrack) -> int:
    """Write the CSV export; returns the rows written."""
    keep = track.aligned
    rows = track.rows[keep]
    rpy = rpy_deg(Rotation.from_quat(rows[:, cols.QUAT])) if len(rows) else np.zeros((0, 3))
    sigma_rpy = _sigma(rpy_covariance(track.cov_att_enu_rad2[keep], rpy[:, 2]))
    numbers = np.hstack(
        (
            rows[:, cols.VEL],
            rpy,
            _sigma(track.cov_pos_enu_m2[keep]),
            _sigma(track.cov_vel_enu[keep]),
            sigma_rpy,
        )
    )
    with path.open("w", newline="", encoding="utf-8") as file:
        writer = csv.writer(file)
        writer.writerow(CSV_COLUMNS)
        for row, values in zip(rows, numbers, strict=True):
            writer.writerow(
                [
                    f"{row[cols.T]:.6f}",
                    f"{row[cols.LAT]:.9f}",
                    f"{row[cols.LON]:.9f}",
                    f"{row[cols.HEIGHT]:.4f}",
                    *(f"{v:.6g}" for v in values),
                    cols.STATES[int(row[cols.STATE])],
                ]
            )
    return len(rows)


def _utc(t_s: float) -> datetime.datetime:
    return datetime.datetime.fromtimestamp(t_s, datetime.UTC)


def write_gpx(path: Path, track: SolutionTrack, name: str) -> int:
    """Write the GPX export (a track named ``name``); returns the points written."""
    gpx = gpxpy.gpx.GPX()
    gpx.creator = "gnss_ins replay"
    gpx_track = gpxpy.gpx.GPXTrack(name=name)
    segment = gpxpy.gpx.GPXTrackSegment()
    gpx_track.segments.append(segment)
    gpx.tracks.append(gpx_track)
    rows = track.rows[track.aligned]
    for row in rows:
        lat, lon, height = float(row[cols.LAT]), float(row[cols.LON]), float(row[cols.HEIGHT])
        msl = height - geoid.undulation_m(lat, lon)
        point = gpxpy.gpx.GPXTrackPoint(
            round(lat, 9), round(lon, 9), round(msl, 4), _utc(float(row[cols.T]))
        )
        segment.points.append(point)
    path.write_text(gpx.to_xml(version="1.1"), encoding="utf-8")
    return len(rows)


def _nmea_angle(value_deg: float, width: int, signs: str) -> tuple[str, str]:
    """NMEA (d)ddmm.mmmmmmm field and hemisphere letter of an angle [deg]."""
    minutes = round(abs(value_deg) * 60.0, 7)
    whole = int(minutes // 60.0)
    return f"{whole:0{width}d}{minutes - 60.0 * whole:010.7f}", signs[value_deg < 0.0]


def _nmea_sentences(row: FloatArray, cov_pos_enu_m2: FloatArray) -> list[str]:
    utc = _utc(float(row[cols.T]))
    clock = f"{utc:%H%M%S}.{utc.microsecond // 10000:02d}"
    lat_deg, lon_deg, height = float(row[cols.LAT]), float(row[cols.LON]), float(row[cols.HEIGHT])
    lat, lat_hemisphere = _nmea_angle(lat_deg, 2, "NS")
    lon, lon_hemisphere = _nmea_angle(lon_deg, 3, "EW")
    separation = geoid.undulation_m(lat_deg, lon_deg)
    quality = "6" if cols.STATES[int(row[cols.STATE])] == "degraded" else "1"
    east, north = row[cols.VEL][:2].tolist()
    course = math.degrees(math.atan2(east, north)) % 360.0
    speed = math.hypot(east, north) * _KNOTS_PER_M_S
    sigma_e, sigma_n, sigma_u = _sigma(cov_pos_enu_m2[None])[0]
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
            f"{height - separation:.4f}",
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


def write_nmea(path: Path, track: SolutionTrack) -> int:
    """Write the NMEA export (GGA, RMC, GST per solution, CRLF); returns the epochs written."""
    keep = track.aligned
    rows, covs = track.rows[keep], track.cov_pos_enu_m2[keep]
    with path.open("w", newline="", encoding="ascii") as file:
        for row, cov in zip(rows, covs, strict=True):
            file.writelines(sentence + "\r\n" for sentence in _nmea_sentences(row, cov))
    return len(rows)


def export(path: Path, track: SolutionTrack, name: str) -> int:
    """Write ``track`` in the format of ``path``'s suffix (FORMATS); returns the epochs."""
    suffix = path.suffix.lower()
    if suffix == ".csv":
        return write_csv(path, track)
    if suffix == ".gpx":
        return write_gpx(path, track, name)
    if suffix == ".nmea":
        return write_nmea(path, track)
    raise ValueError(f"{path}: unknown export format (suffix one of {', '.join(FORMATS)})")
