"""WGS-84 earth model: radii of curvature, normal gravity, earth and transport rates, frames.

Conventions: geodetic latitude/longitude in radians, ellipsoidal height in metres, local-level
frame NED (north, east, down). Functions of latitude accept a float (cheap scalar path used by the
strapdown at the IMU rate) or a numpy array (vectorised path used by the simulator) and return the
same kind. References are to shared/reference/imu400cc-aalborg-notes.md ("Aalborg notes").
"""

from __future__ import annotations

import math
from typing import TypeVar

import numpy as np
import pymap3d

from gnss_ins_common.types import FloatArray
from ins_fusion.core.compiled import compilable

F = TypeVar("F", float, FloatArray)

#: WGS-84 semi-major axis [m] (Aalborg notes §5.1 and §10, App. B.2).
SEMI_MAJOR_AXIS_M = 6378137.0
#: WGS-84 flattening (NIMA TR8350.2; gives the semi-minor axis 6356752.3 m of Aalborg notes §10).
FLATTENING = 1.0 / 298.257223563
#: First eccentricity squared.
ECCENTRICITY_SQ = FLATTENING * (2.0 - FLATTENING)
#: Earth rotation rate [rad/s] (Aalborg notes §5.1 and §10, App. B.2).
EARTH_RATE_RAD_S = 7.292115e-5

_ELLIPSOID = pymap3d.Ellipsoid.from_name("wgs84")


def _sin_cos(lat_rad: F) -> tuple[F, F]:
    if isinstance(lat_rad, float):
        return math.sin(lat_rad), math.cos(lat_rad)
    return np.sin(lat_rad), np.cos(lat_rad)


def radii_m(lat_rad: F) -> tuple[F, F]:
    """Meridian radius R_M and prime-vertical radius R_N [m] at a geodetic latitude.

    R_M = a(1-e²)/(1-e² sin²φ)^(3/2), R_N = a/(1-e² sin²φ)^(1/2): Aalborg notes §5.3, (C-1.18)
    and (C-1.19), where they are called R_N and R_E.
    """
    return radii_from_sin(_sin_cos(lat_rad)[0])


@compilable
def displace(
    lat_rad: float, lon_rad: float, height_m: float, north_m: float, east_m: float, down_m: float
) -> tuple[float, float, float]:
    """The geodetic position (lat, lon [rad], ellipsoidal height [m]) a small NED offset [m]
    away, with the curvature radii at ``lat_rad`` (first order: offsets far below the radii)."""
    r_m, r_n = radii_from_sin(math.sin(lat_rad))
    return (
        lat_rad + north_m / (r_m + height_m),
        lon_rad + east_m / ((r_n + height_m) * math.cos(lat_rad)),
        height_m - down_m,
    )


@compilable
def radii_from_sin(sin_lat: F) -> tuple[F, F]:
    """radii_m from sin φ (the strapdown computes the sine once per sample)."""
    w = 1.0 - ECCENTRICITY_SQ * sin_lat * sin_lat
    r_prime_vertical = SEMI_MAJOR_AXIS_M / w**0.5
    return r_prime_vertical * (1.0 - ECCENTRICITY_SQ) / w, r_prime_vertical


def radii_derivative_m_per_rad(lat_rad: F) -> tuple[F, F]:
    """Derivatives dR_M/dφ and dR_N/dφ [m/rad] of radii_m (used for exact simulated kinematics)."""
    sin_lat, cos_lat = _sin_cos(lat_rad)
    w = 1.0 - ECCENTRICITY_SQ * sin_lat * sin_lat
    d_r_prime_vertical = SEMI_MAJOR_AXIS_M * ECCENTRICITY_SQ * sin_lat * cos_lat / w**1.5
    return 3.0 * (1.0 - ECCENTRICITY_SQ) * d_r_prime_vertical / w, d_r_prime_vertical


def normal_gravity_m_s2(lat_rad: F, height_m: F) -> F:
    """Magnitude of normal gravity (gravitation plus centrifugal) [m/s²], pointing down in NED.

    Farrell & Barth form recommended by Aalborg notes §5.2 (footnote of §5.2.2, checked against
    Fig. C-2: 9.8164 m/s² at 57°, 100 m):
    g = 9.780327(1 + 0.0053024 sin²φ - 0.0000058 sin²2φ) - (3.0877e-6 - 0.0044e-6 sin²φ) h
    + 0.072e-12 h².
    """
    sin_lat, cos_lat = _sin_cos(lat_rad)
    return normal_gravity_from_sin_cos(sin_lat, cos_lat, height_m)


@compilable
def normal_gravity_from_sin_cos(sin_lat: F, cos_lat: F, height_m: F) -> F:
    """normal_gravity_m_s2 from sin φ and cos φ."""
    sin_sq = sin_lat * sin_lat
    sin_2lat_sq = 4.0 * sin_sq * cos_lat * cos_lat
    return (
        9.780327 * (1.0 + 0.0053024 * sin_sq - 0.0000058 * sin_2lat_sq)
        - (3.0877e-6 - 0.0044e-6 * sin_sq) * height_m
        + 0.072e-12 * height_m * height_m
    )


def earth_rate_ned_rad_s(lat_rad: F) -> tuple[F, F, F]:
    """Earth rotation rate ω_ie in NED [rad/s]: Ω(cos φ, 0, -sin φ) (Aalborg notes §5.3, C-1.10)."""
    sin_lat, cos_lat = _sin_cos(lat_rad)
    return earth_rate_from_sin_cos(sin_lat, cos_lat)


@compilable
def earth_rate_from_sin_cos(sin_lat: F, cos_lat: F) -> tuple[F, F, F]:
    """earth_rate_ned_rad_s from sin φ and cos φ."""
    return EARTH_RATE_RAD_S * cos_lat, 0.0 * cos_lat, -EARTH_RATE_RAD_S * sin_lat


def transport_rate_ned_rad_s(lat_rad: F, height_m: F, vel_n_m_s: F, vel_e_m_s: F) -> tuple[F, F, F]:
    """Transport rate ω_en (rotation of NED relative to the earth) in NED [rad/s].

    (v_E/(R_N+h), -v_N/(R_M+h), -v_E tan φ/(R_N+h)): Aalborg notes §5.3 (C-1.12) with the third
    component corrected to -v_E tan φ (notes §5.3 and §12 item 8).
    """
    sin_lat, cos_lat = _sin_cos(lat_rad)
    r_meridian, r_prime_vertical = radii_from_sin(sin_lat)
    return transport_rate_from(
        sin_lat, cos_lat, r_meridian, r_prime_vertical, height_m, vel_n_m_s, vel_e_m_s
    )


@compilable
def transport_rate_from(
    sin_lat: F,
    cos_lat: F,
    r_meridian_m: F,
    r_prime_vertical_m: F,
    height_m: F,
    vel_n_m_s: F,
    vel_e_m_s: F,
) -> tuple[F, F, F]:
    """transport_rate_ned_rad_s from sin φ, cos φ and the radii."""
    rate_e = vel_e_m_s / (r_prime_vertical_m + height_m)
    return rate_e, -vel_n_m_s / (r_meridian_m + height_m), -rate_e * sin_lat / cos_lat


def mat_en(lat_rad: F, lon_rad: F) -> FloatArray:
    """Rotation matrix NED -> ECEF (columns are the N, E, D unit vectors in ECEF).

    Shape (3, 3) for scalar input, (n, 3, 3) for arrays. The transpose of NTNU notes (2.4).
    """
    sin_lat, cos_lat = _sin_cos(lat_rad)
    sin_lon, cos_lon = _sin_cos(lon_rad)
    zero = 0.0 * sin_lat
    rows = (
        (-sin_lat * cos_lon, -sin_lon, -cos_lat * cos_lon),
        (-sin_lat * sin_lon, cos_lon + zero, -cos_lat * sin_lon),
        (cos_lat, zero, -sin_lat),
    )
    mat = np.array(rows, dtype=np.float64)
    return mat if mat.ndim == 2 else np.moveaxis(mat, 2, 0)


def geodetic_to_ecef(lat_rad: F, lon_rad: F, height_m: F) -> FloatArray:
    """Geodetic (WGS-84) -> ECEF position [m]; shape (3,) or (n, 3)."""
    x, y, z = pymap3d.geodetic2ecef(lat_rad, lon_rad, height_m, _ELLIPSOID, deg=False)
    return np.stack(np.broadcast_arrays(x, y, z), axis=-1).astype(np.float64)


def ecef_to_geodetic(pos_ecef_m: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """ECEF position [m], shape (3,) or (n, 3) -> (lat_rad, lon_rad, height_m) on WGS-84.

    pymap3d's closed form; its round trip with geodetic_to_ecef is good to a few nanometres.
    """
    pos = np.asarray(pos_ecef_m, dtype=np.float64)
    lat, lon, height = pymap3d.ecef2geodetic(
        pos[..., 0], pos[..., 1], pos[..., 2], _ELLIPSOID, deg=False
    )
    shape = pos.shape[:-1]
    return _as_array(lat, shape), _as_array(lon, shape), _as_array(height, shape)


def geodetic_to_enu(
    lat_rad: F, lon_rad: F, height_m: F, lat0_rad: float, lon0_rad: float, height0_m: float
) -> FloatArray:
    """Geodetic -> local ENU [m] of the tangent plane at (lat0, lon0, h0); shape (3,) or (n, 3)."""
    e, n, u = pymap3d.geodetic2enu(
        lat_rad, lon_rad, height_m, lat0_rad, lon0_rad, height0_m, _ELLIPSOID, deg=False
    )
    return np.stack(np.broadcast_arrays(e, n, u), axis=-1).astype(np.float64)


class TangentPlane:
    """ENU coordinates [m] in the tangent plane at a fixed datum, one point at a time.

    The closed form of ``geodetic_to_enu`` with the datum's ECEF position and rotation computed
    once: pymap3d's scalar call costs ~35 µs (argument handling, generic array code), too much
    for a per-output conversion in the fusion engine; this one costs a few µs and agrees with it
    to micrometres (test_earth.py).
    """

    def __init__(self, lat0_rad: float, lon0_rad: float, height0_m: float) -> None:
        """Datum: WGS-84 latitude, longitude [rad] and ellipsoidal height [m]."""
        self.datum = (lat0_rad, lon0_rad, height0_m)
        #: ECEF position of the datum [m] and the ECEF -> ENU rotation (read by compiled code).
        self.origin = ecef_from_geodetic(lat0_rad, lon0_rad, height0_m)
        sin_lat, cos_lat = math.sin(lat0_rad), math.cos(lat0_rad)
        sin_lon, cos_lon = math.sin(lon0_rad), math.cos(lon0_rad)
        self.mat_enu_ecef = np.array(
            [
                [-sin_lon, cos_lon, 0.0],
                [-sin_lat * cos_lon, -sin_lat * sin_lon, cos_lat],
                [cos_lat * cos_lon, cos_lat * sin_lon, sin_lat],
            ]
        )

    def enu(self, lat_rad: float, lon_rad: float, height_m: float) -> FloatArray:
        """ENU position [m] of a geodetic point relative to the datum."""
        x, y, z = ecef_from_geodetic(lat_rad, lon_rad, height_m)
        x0, y0, z0 = self.origin
        enu: FloatArray = self.mat_enu_ecef @ np.array((x - x0, y - y0, z - z0))
        return enu


@compilable
def ecef_from_geodetic(
    lat_rad: float, lon_rad: float, height_m: float
) -> tuple[float, float, float]:
    """ECEF position [m] of a geodetic point (scalar form of geodetic_to_ecef)."""
    sin_lat, cos_lat = math.sin(lat_rad), math.cos(lat_rad)
    r_n = SEMI_MAJOR_AXIS_M / math.sqrt(1.0 - ECCENTRICITY_SQ * sin_lat * sin_lat)
    return (
        (r_n + height_m) * cos_lat * math.cos(lon_rad),
        (r_n + height_m) * cos_lat * math.sin(lon_rad),
        (r_n * (1.0 - ECCENTRICITY_SQ) + height_m) * sin_lat,
    )


def enu_to_geodetic(
    pos_enu_m: FloatArray, lat0_rad: float, lon0_rad: float, height0_m: float
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Local ENU [m] of the tangent plane at (lat0, lon0, h0) -> (lat_rad, lon_rad, height_m)."""
    pos = np.asarray(pos_enu_m, dtype=np.float64)
    lat, lon, height = pymap3d.enu2geodetic(
        pos[..., 0], pos[..., 1], pos[..., 2], lat0_rad, lon0_rad, height0_m, _ELLIPSOID, deg=False
    )
    shape = pos.shape[:-1]
    return _as_array(lat, shape), _as_array(lon, shape), _as_array(height, shape)


def _as_array(value: object, shape: tuple[int, ...]) -> FloatArray:
    """pymap3d output as a float array of the input's shape (it may drop 1-element axes)."""
    return np.asarray(value, dtype=np.float64).reshape(shape)
