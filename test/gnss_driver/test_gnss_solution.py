"""Fix, covariance, velocity and ADU5 attitude of one epoch (gnss_driver.solution/attitude).

Expected values are worked out by hand in the comments.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gnss_driver.attitude import (
    UNKNOWN_VARIANCE,
    AttitudeConfig,
    AttitudeConverter,
    brf_angles,
    brf_rotation,
)
from gnss_driver.epoch import Epoch
from gnss_driver.fix_type import FixType
from gnss_driver.reader import NmeaReader
from gnss_driver.reader import frame_sentence as nmea
from gnss_driver.solution import EpochSolver, SolutionConfig, UereTable
from gnss_ins_common.navsat import CovarianceType, NavSatStatus

GGA_SPS = "GPGGA,184353.07,1929.045,S,02410.506,E,1,04,2.6,100.00,M,-33.9,M,,0000"
GGA_FLOAT = "GPGGA,123519.00,4807.038,N,01131.000,W,5,10,0.9,545.4,M,46.9,M,1.2,0001"
GST = "GPGST,172814.0,0.006,0.023,0.020,273.6,0.023,0.020,0.031"
LLQ_RTK = "GPLLQ,123519.00,051005,,M,,M,3,12,0.025,76.69,M"
PAT_BODY = "PASHR,PAT,123519.20,5702.12345,N,00959.54321,E,+00076.69,{},{},{},{},{},{}"


def solve(*bodies: str, solver: EpochSolver | None = None):
    solver = solver or EpochSolver(SolutionConfig(), AttitudeConverter(AttitudeConfig()))
    epoch = Epoch(0)
    for read in NmeaReader().feed(b"".join(nmea(b) for b in bodies)):
        epoch.add(read.sentence, read.wire_bytes, 0.0)
    return solver.solve(epoch), solver


def cov(fix) -> np.ndarray:
    return np.array(fix.cov_enu_m2).reshape(3, 3)


def test_sps_fix_with_hdop_times_uere():
    (solution, _) = solve(GGA_SPS)
    fix = solution.fix
    assert fix.fix_type is FixType.SPS
    assert (fix.lat_deg, fix.lon_deg) == pytest.approx((-19.4840833333, 24.1751))
    assert fix.alt_m == pytest.approx(66.1)  # 100.00 MSL + (-33.9) geoid separation
    # HDOP 2.6 x UERE 6 m = 15.6 m horizontal: 15.6^2 / 2 per axis; VDOP 2 x 2.6 -> 31.2 m.
    assert np.diag(cov(fix)) == pytest.approx([121.68, 121.68, 973.44])
    assert fix.cov_type is CovarianceType.APPROXIMATED
    assert (fix.accuracy_source, fix.position_source, fix.satellites) == ("HDOP", "GGA", 4)


def test_rtk_float_uses_its_own_uere_and_gsa_vdop():
    solver = EpochSolver(
        SolutionConfig(UereTable(rtk_float=0.5)), AttitudeConverter(AttitudeConfig())
    )
    solver.note_gsa(
        next(iter(NmeaReader().feed(nmea("GPGSA,A,3,04,05,,,,,,,,,,,2.0,0.9,1.5")))).sentence
    )
    (solution, _) = solve(GGA_FLOAT, solver=solver)
    fix = solution.fix
    assert fix.fix_type is FixType.RTK_FLOAT
    assert fix.alt_m == pytest.approx(592.3)  # 545.4 + 46.9
    # (0.9 x 0.5)^2 / 2 = 0.10125; vertical (VDOP 1.5 x 0.5)^2 = 0.5625.
    assert np.diag(cov(fix)) == pytest.approx([0.10125, 0.10125, 0.5625])


def test_gst_wins_and_takes_the_correlation_from_its_ellipse():
    (solution, _) = solve(GGA_FLOAT, GST, LLQ_RTK)
    c = cov(solution.fix)
    # sigma_lon 0.020 -> E, sigma_lat 0.023 -> N, sigma_alt 0.031 -> U.
    assert np.diag(c) == pytest.approx([0.0004, 0.000529, 0.000961])
    # Ellipse a 0.023, b 0.020 along 273.6 deg: sin -0.998027, cos 0.062791;
    # EE = a^2 sin^2 + b^2 cos^2 = 5.2854e-4, NN = a^2 cos^2 + b^2 sin^2 = 4.0051e-4,
    # EN = (a^2 - b^2) sin cos = -8.0840e-6, rho = EN / sqrt(EE NN) = -0.017571;
    # C_EN = rho x 0.020 x 0.023 = -8.0826e-6.
    assert c[0, 1] == c[1, 0] == pytest.approx(-8.0826e-6, rel=1e-3)
    assert solution.fix.cov_type is CovarianceType.KNOWN
    assert solution.fix.accuracy_source == "GST"


def test_gst_without_ellipse_or_altitude_falls_back_part_by_part():
    partial = "GPGST,172814.0,0.006,,,,0.023,0.020,"
    (with_llq, _) = solve(GGA_FLOAT, partial, LLQ_RTK)
    # Vertical from LLQ: CQ 0.025 = sigma_h + sigma_v, sigma_v = 0.6 x 0.025 = 0.015.
    assert np.diag(cov(with_llq.fix)) == pytest.approx([0.0004, 0.000529, 0.000225])
    assert with_llq.fix.cov_type is CovarianceType.DIAGONAL_KNOWN
    (alone, _) = solve(GGA_FLOAT, partial)
    # Vertical from HDOP 0.9 x 2 x UERE(float) 0.5 = 0.9 m.
    assert cov(alone.fix)[2, 2] == pytest.approx(0.81)
    assert alone.fix.cov_type is CovarianceType.APPROXIMATED


def test_llq_coordinate_quality_split_per_the_notes():
    (solution, _) = solve(GGA_FLOAT, LLQ_RTK)
    # CQ 0.025 m: sigma_h = 0.4 CQ = 0.010 -> 0.010^2 / 2 per axis; sigma_v = 0.015.
    assert np.diag(cov(solution.fix)) == pytest.approx([5e-5, 5e-5, 2.25e-4])
    assert solution.fix.accuracy_source == "LLQ"
    assert solution.fix.cov_type is CovarianceType.DIAGONAL_KNOWN
    # The split is an assumption: the user sets it (f = 0.5: sigma_h = sigma_v = 0.0125 m).
    even = EpochSolver(
        SolutionConfig(llq_horizontal_fraction=0.5), AttitudeConverter(AttitudeConfig())
    )
    (split, _) = solve(GGA_FLOAT, LLQ_RTK, solver=even)
    assert np.diag(cov(split.fix)) == pytest.approx([0.0125**2 / 2, 0.0125**2 / 2, 0.0125**2])


@pytest.mark.parametrize(
    "bodies",
    [
        ("GPGGA,,,,,,0,00,99.99,,,,,,",),
        ("GPGGA,123519.00,4807.038,N,01131.000,W,0,00,99.9,545.4,M,46.9,M,,",),
        ("GPGGA,123519.00,4807.038,N,01131.000,W,6,05,2.0,545.4,M,46.9,M,,",),  # dead reckoning
        ("GPRMC,123519.00,V,4807.038,N,01131.000,W,,,051005,,,N",),
        ("GPGLL,4807.038,N,01131.000,W,123519.00,V,N",),
    ],
)
def test_no_fix_never_carries_a_position(bodies):
    (solution, solver) = solve(*bodies)
    fix = solution.fix
    assert fix.fix_type is FixType.NO_FIX
    assert all(math.isnan(v) for v in (fix.lat_deg, fix.lon_deg, fix.alt_m))
    assert fix.cov_type is CovarianceType.UNKNOWN
    assert solver.stats.no_fix == 1


def test_missing_geoid_separation_is_taken_from_egm96():
    (solution, solver) = solve("GPGGA,123519.00,4807.038,N,01131.000,W,4,10,0.9,545.4,M,,M,,")
    assert solution.fix.fix_type is FixType.RTK_FIXED
    # EGM96 N at 48.1173 N, 11.5167 W: 54.262 m on the 5' grid of the egm96 package.
    assert solution.fix.alt_m == pytest.approx(545.4 + 54.262, abs=0.05)
    assert solver.stats.geoid_altitudes == 1 and solver.fields.empty_fields == 0
    (no_msl, _) = solve("GPGGA,123519.00,4807.038,N,01131.000,W,4,10,0.9,,M,,M,,")
    assert math.isnan(no_msl.fix.alt_m)


@pytest.mark.parametrize(
    ("modes", "fix_type", "service"),
    [
        ("AAN", FixType.SPS, 1 | 2),  # GPS and GLONASS autonomous, Galileo none
        ("DAA", FixType.DGPS, 1 | 2 | 8),
        ("NRNF", FixType.RTK_FIXED, 2 | 4),  # GLONASS RTK fixed, BeiDou float
        ("NNN", FixType.NO_FIX, 1),
    ],
)
def test_gns_is_a_position_source_with_its_mode_letters(modes, fix_type, service):
    (solution, _) = solve(
        f"GNGNS,123519.00,4807.038,N,01131.000,W,{modes},12,0.9,545.4,46.9,,",
        "GNGLL,4807.038,N,01131.000,W,123519.00,A,A",
    )
    fix = solution.fix
    assert fix.fix_type is fix_type and fix.service == service
    if fix_type is not FixType.NO_FIX:
        assert fix.position_source == "GNS" and fix.satellites == 12
        assert fix.alt_m == pytest.approx(545.4 + 46.9)
        # HDOP 0.9 of the GNS x UERE.
        uere = UereTable().for_fix(fix_type)
        assert cov(fix)[0, 0] == pytest.approx((0.9 * uere) ** 2 / 2)


def test_gns_with_too_few_satellites_is_no_fix():
    (solution, solver) = solve("GNGNS,123519.00,4807.038,N,01131.000,W,AA,02,0.9,545.4,46.9,,")
    assert solution.fix.fix_type is FixType.NO_FIX and solver.stats.too_few_satellites == 1


def test_rmc_position_with_mode_letters_and_pat_position():
    (rmc, _) = solve("GPRMC,235959.50,A,3351.000,S,07040.500,W,010.0,090.0,311224,,,D")
    assert rmc.fix.fix_type is FixType.DGPS and math.isnan(rmc.fix.alt_m)
    assert rmc.fix.position_source == "RMC"
    (pat, _) = solve(PAT_BODY.format("045.000", "+01.00", "-02.00", "0.0021", "0.0123", "0"))
    assert pat.fix.fix_type is FixType.SPS
    assert pat.fix.alt_m == 76.69
    assert pat.fix.position_source == "PASHR,PAT"
    (pat_rmc_void, _) = solve(
        PAT_BODY.format("045.000", "+01.00", "-02.00", "0.0021", "0.0123", "0"),
        "GPRMC,123519.20,V,,,,,,,051005,,,N",
    )
    assert pat_rmc_void.fix.fix_type is FixType.NO_FIX


@pytest.mark.parametrize(
    ("bodies", "status", "service"),
    [
        ((GGA_SPS,), NavSatStatus.FIX, 1),
        (("GPGGA,123519.00,4807.038,N,01131.000,W,2,10,0.9,545.4,M,46.9,M,1.2,0001",), 1, 1),
        ((GGA_FLOAT, "GLGST,123519.00,0.006,,,,0.023,0.020,0.031"), NavSatStatus.GBAS_FIX, 3),
        ((GGA_FLOAT.replace("GPGGA", "GNGGA"),), NavSatStatus.GBAS_FIX, 1),
        ((GGA_FLOAT.replace("GPGGA", "GAGGA"),), NavSatStatus.GBAS_FIX, 8),
        (("GPGGA,,,,,,0,00,99.99,,,,,,",), NavSatStatus.NO_FIX, 1),
    ],
)
def test_nav_sat_status_and_service(bodies, status, service):
    # DGPS -> SBAS_FIX and RTK -> GBAS_FIX as in nmea_navsat_driver; GN names no system.
    fix = solve(*bodies)[0].fix
    assert (fix.status, fix.service) == (status, service)


# ---- velocity ---------------------------------------------------------------------------------
def test_vtg_velocity_in_enu_with_unknown_vertical():
    (solution, _) = solve("GPVTG,054.7,T,034.4,M,005.5,N,010.2,K,A")
    vel = solution.velocity
    # 10.2 km/h = 2.8333 m/s at 54.7 deg from north: E = 2.8333 sin, N = 2.8333 cos.
    assert vel.vel_enu_m_s == pytest.approx((2.31239, 1.63726, 0.0), abs=1e-5)
    c = np.array(vel.cov_enu).reshape(3, 3)
    assert np.diag(c) == pytest.approx([0.0025, 0.0025, UNKNOWN_VARIANCE])


def test_rmc_velocity_knots_and_invalid_or_incomplete_velocities():
    (rmc, _) = solve("GPRMC,235959.50,A,3351.000,S,07040.500,W,010.0,090.0,311224,,,D")
    assert rmc.velocity.vel_enu_m_s == pytest.approx((5.144444, 0.0, 0.0), abs=1e-6)
    assert solve("GPVTG,,T,,M,,N,,K,N")[0].velocity is None
    (no_course, solver) = solve("GPVTG,,T,,M,003.0,N,005.6,K,A")
    assert no_course.velocity is None and solver.fields.empty_fields == 1
    (standing, _) = solve("GPVTG,,T,,M,000.0,N,000.0,K,A")
    assert standing.velocity.vel_enu_m_s == (0.0, 0.0, 0.0)


# ---- attitude ---------------------------------------------------------------------------------
def _axes(quat_xyzw) -> np.ndarray:
    return Rotation.from_quat(quat_xyzw).as_matrix()  # columns: FLU x, y, z in ENU


def test_adu5_angle_conventions_in_enu_flu():
    conv = AttitudeConverter(AttitudeConfig())
    # Heading 90 (east), level: FLU = ENU, identity.
    assert _axes(conv.convert(90.0, 0.0, 0.0).quat_enu_flu_xyzw) == pytest.approx(
        np.eye(3), abs=1e-12
    )
    # Heading 0 (north): ENU yaw +90 deg.
    north = Rotation.from_quat(conv.convert(0.0, 0.0, 0.0).quat_enu_flu_xyzw)
    assert north.as_euler("ZYX", degrees=True) == pytest.approx([90.0, 0.0, 0.0], abs=1e-9)
    # Heading 45, pitch +1 (nose up), roll -2 (right side up, left side down).
    r = _axes(conv.convert(45.0, 1.0, -2.0).quat_enu_flu_xyzw)
    forward, left = r[:, 0], r[:, 1]
    c1 = math.cos(math.radians(1.0))
    assert forward == pytest.approx(
        [math.sqrt(0.5) * c1, math.sqrt(0.5) * c1, math.sin(math.radians(1.0))]
    )
    assert left[2] == pytest.approx(math.sin(math.radians(-2.0)) * c1)  # sin(roll) cos(pitch)


def test_brf_angles_round_trip():
    for angles in [(0.0, 0.0, 0.0), (359.5, -12.0, 7.5), (123.4, 45.0, -30.0)]:
        assert brf_angles(brf_rotation(*angles)) == pytest.approx(angles)


def test_offsets_removed_by_the_driver():
    # The antenna frame sits pitched 1.14 and rolled -1.48 deg on a level car heading north.
    conv = AttitudeConverter(AttitudeConfig(offsets_deg=(0.0, 1.14, -1.48)))
    level_north = Rotation.from_euler("z", 90, degrees=True)
    got = Rotation.from_quat(conv.convert(0.0, 1.14, -1.48).quat_enu_flu_xyzw)
    assert (got * level_north.inv()).magnitude() < 1e-12


def test_pat_attitude_covariance_nominal_and_scaled():
    (good, _) = solve(PAT_BODY.format("045.000", "+01.00", "-02.00", "0.0021", "0.0123", "0"))
    c = np.array(good.attitude.orientation.cov_rpy_rad2).reshape(3, 3)
    # roll 0.24, pitch 0.14, yaw 0.07 deg (notes §7.3), as rad^2.
    expected = [math.radians(s) ** 2 for s in (0.24, 0.14, 0.07)]
    assert np.diag(c) == pytest.approx(expected)
    assert good.attitude.orientation.scale == 1.0
    # MRMS 12 mm > 5 mm: sigmas x 2.4; BRMS 0.10 > 0.04 would give 2.5 (the larger wins).
    (bad, solver) = solve(PAT_BODY.format("045.000", "+01.00", "-02.00", "0.0120", "0.1000", "0"))
    assert bad.attitude.orientation.scale == pytest.approx(2.5)
    assert np.diag(np.array(bad.attitude.orientation.cov_rpy_rad2).reshape(3, 3)) == pytest.approx(
        [v * 6.25 for v in expected]
    )
    assert solver.stats.attitude_degraded == 1


def test_reset_flag_and_missing_angles_suppress_the_attitude():
    (reset, solver) = solve(PAT_BODY.format("045.000", "+01.00", "-02.00", "0.0021", "0.0123", "1"))
    assert reset.attitude is None and solver.stats.attitude_resets == 1
    assert reset.fix is not None  # the position is still good
    (empty, solver) = solve(PAT_BODY.format("", "", "", "", "", ""))
    assert empty.attitude is None and solver.stats.attitude_resets == 0
    (att, _) = solve("PASHR,ATT,345123.5,123.4,1.2,-0.5,0.0021,0.012,0")
    assert att.attitude.source == "PASHR,ATT" and att.fix is None


def test_hdt_gives_heading_only():
    (solution, _) = solve("GPHDT,090.0,T")
    orientation = solution.attitude.orientation
    assert _axes(orientation.quat_enu_flu_xyzw) == pytest.approx(np.eye(3), abs=1e-12)
    c = np.array(orientation.cov_rpy_rad2).reshape(3, 3)
    assert np.diag(c) == pytest.approx(
        [UNKNOWN_VARIANCE, UNKNOWN_VARIANCE, math.radians(0.07) ** 2]
    )


def utm_northing_on_the_central_meridian(lat_deg: float) -> float:
    """k0 x the GRS80 meridian arc (the classical series; independent of PROJ)."""
    a, f, k0 = 6_378_137.0, 1 / 298.257222101, 0.9996
    e2 = f * (2 - f)
    e4, e6 = e2 * e2, e2 * e2 * e2
    phi = math.radians(lat_deg)
    arc = a * (
        (1 - e2 / 4 - 3 * e4 / 64 - 5 * e6 / 256) * phi
        - (3 * e2 / 8 + 3 * e4 / 32 + 45 * e6 / 1024) * math.sin(2 * phi)
        + (15 * e4 / 256 + 45 * e6 / 1024) * math.sin(4 * phi)
        - (35 * e6 / 3072) * math.sin(6 * phi)
    )
    return k0 * arc


def test_llq_grid_position_through_the_configured_projection():
    northing = utm_northing_on_the_central_meridian(57.0)
    body = f"GPLLQ,123519.00,051005,500000.000,M,{northing:.3f},M,3,12,0.025,76.69,M"
    solver = EpochSolver(
        SolutionConfig(llq_projection="EPSG:25832"), AttitudeConverter(AttitudeConfig())
    )
    (solution, _) = solve(body, solver=solver)
    fix = solution.fix
    # ETRS89 / UTM zone 32N: easting 500 km is the 9 deg E central meridian.
    assert (fix.lat_deg, fix.lon_deg) == pytest.approx((57.0, 9.0), abs=1e-7)
    assert fix.fix_type is FixType.RTK_FIXED and fix.position_source == "LLQ"
    assert fix.alt_m == pytest.approx(76.69) and fix.satellites == 12
    assert fix.accuracy_source == "LLQ"
    # Without a projection LLQ gives no position; GGA wins over LLQ when both are there.
    (no_grid, _) = solve(body)
    assert no_grid.fix is None
    (both, _) = solve(GGA_FLOAT, body, solver=solver)
    assert both.fix.position_source == "GGA"


def test_llq_grid_position_outside_the_projection_or_in_feet_is_rejected():
    solver = EpochSolver(
        SolutionConfig(llq_projection="EPSG:25832"), AttitudeConverter(AttitudeConfig())
    )
    (far, _) = solve("GPLLQ,123519.00,051005,9e7,M,9e7,M,3,12,0.025,76.69,M", solver=solver)
    (feet, _) = solve("GPLLQ,123519.00,051005,5e5,f,6e6,f,3,12,0.025,76.69,M", solver=solver)
    assert far.fix.fix_type is FixType.NO_FIX and feet.fix.fix_type is FixType.NO_FIX
    assert solver.fields.rejected["LLQ.easting"] == 1
    assert solver.fields.rejected["LLQ.easting_unit"] == 1
