"""Exports of a replayed solution (ins_fusion.replay.export): written, then read back with
independent readers (csv, gpxpy, pynmea2) and compared with the solutions."""

from __future__ import annotations

import csv
import datetime
import math

import gpxpy
import numpy as np
import pynmea2
import pytest
from scipy.spatial.transform import Rotation

from gnss_driver import geoid
from ins_fusion.core.engine.engine import InsSolution
from ins_fusion.replay.export import CSV_COLUMNS, export
from ins_fusion.replay.run import SolutionTrack

T0 = 1_717_236_000.25  # 2024-06-01T10:00:00.25Z


def _solutions() -> list[InsSolution]:
    """A short drive south-west of Aalborg (crossing no hemisphere), the first one aligning,
    the last one degraded."""
    rng = np.random.default_rng(7)
    out = []
    for k in range(6):
        yaw, pitch, roll = 30.0 + 10.0 * k, 2.0 - k, 0.5 * k
        quat = Rotation.from_euler("ZYX", [yaw, pitch, roll], degrees=True).as_quat()
        state = "aligning" if k == 0 else ("degraded" if k == 5 else "navigating")
        a = rng.normal(size=(3, 3, 3)) * [[[0.1]], [[0.02]], [[0.003]]]
        cov = a @ a.transpose(0, 2, 1) + np.eye(3) * 1e-6
        out.append(
            InsSolution(
                t_s=T0 + 0.1 * k,
                lat_deg=57.0148 - 1e-5 * k,
                lon_deg=9.9865 - 2e-5 * k,
                height_m=50.0 + 0.1 * k,
                pos_enu_m=np.zeros(3),
                vel_enu_m_s=np.array([-3.0 - k, 4.0, 0.1 * k]),
                quat_enu_flu_xyzw=quat,
                rate_flu_rad_s=np.zeros(3),
                cov_pos_enu_m2=cov[0],
                cov_vel_enu=cov[1],
                cov_att_enu_rad2=cov[2],
                gyro_bias_flu_rad_s=np.zeros(3),
                accel_bias_flu_m_s2=np.zeros(3),
                state=state,
            )
        )
    return out


def test_csv_round_trip(tmp_path):
    solutions = _solutions()
    path = tmp_path / "s.csv"
    assert (
        export(path, SolutionTrack.from_solutions(solutions), "drive") == 5
    )  # the aligning one is left out
    with path.open(newline="") as file:
        rows = list(csv.DictReader(file))
    assert tuple(rows[0]) == CSV_COLUMNS
    for row, s in zip(rows, solutions[1:], strict=True):
        assert float(row["t_s"]) == pytest.approx(s.t_s, abs=1e-6)
        assert float(row["lat_deg"]) == pytest.approx(s.lat_deg, abs=1e-9)
        assert float(row["lon_deg"]) == pytest.approx(s.lon_deg, abs=1e-9)
        assert float(row["height_m"]) == pytest.approx(s.height_m, abs=1e-4)
        vel = [float(row[f"vel_{a}_m_s"]) for a in "enu"]
        np.testing.assert_allclose(vel, s.vel_enu_m_s, rtol=1e-5)
        yaw, pitch, roll = Rotation.from_quat(s.quat_enu_flu_xyzw).as_euler("ZYX", degrees=True)
        rpy = [float(row[f"{a}_deg"]) for a in ("roll", "pitch", "yaw")]
        np.testing.assert_allclose(rpy, [roll, pitch, yaw], rtol=1e-5)
        sigma = [float(row[f"sigma_{a}_m"]) for a in "enu"]
        np.testing.assert_allclose(sigma, np.sqrt(np.diag(s.cov_pos_enu_m2)), rtol=1e-5)
        sigma_vel = [float(row[f"sigma_vel_{a}_m_s"]) for a in "enu"]
        np.testing.assert_allclose(sigma_vel, np.sqrt(np.diag(s.cov_vel_enu)), rtol=1e-5)
        # Yaw is about up: its σ is that of the rotation about ENU z.
        yaw_sigma = math.degrees(math.sqrt(s.cov_att_enu_rad2[2, 2]))
        assert float(row["sigma_yaw_deg"]) == pytest.approx(yaw_sigma, rel=1e-5)
        assert row["state"] == s.state


def test_gpx_round_trip_with_heights_above_the_geoid(tmp_path):
    solutions = _solutions()
    path = tmp_path / "s.gpx"
    assert export(path, SolutionTrack.from_solutions(solutions), "drive smoothed") == 5
    gpx = gpxpy.parse(path.read_text())
    (track,) = gpx.tracks
    assert track.name == "drive smoothed"
    points = track.segments[0].points
    for point, s in zip(points, solutions[1:], strict=True):
        assert point.latitude == pytest.approx(s.lat_deg, abs=1e-9)
        assert point.longitude == pytest.approx(s.lon_deg, abs=1e-9)
        undulation = geoid.undulation_m(s.lat_deg, s.lon_deg)
        assert 35.0 < undulation < 45.0  # EGM96 near Aalborg
        assert point.elevation == pytest.approx(s.height_m - undulation, abs=1e-4)
        expected = datetime.datetime.fromtimestamp(s.t_s, datetime.UTC)
        assert abs((point.time - expected).total_seconds()) < 1e-6


def test_nmea_round_trip(tmp_path):
    solutions = _solutions()
    path = tmp_path / "s.nmea"
    assert export(path, SolutionTrack.from_solutions(solutions), "drive") == 5
    text = path.read_bytes().decode("ascii")
    assert text.endswith("\r\n")
    sentences = [pynmea2.parse(line) for line in text.splitlines()]  # checks the checksums
    assert [m.sentence_type for m in sentences[:3]] == ["GGA", "RMC", "GST"]
    for k, s in enumerate(solutions[1:]):
        gga, rmc, gst = sentences[3 * k : 3 * k + 3]
        assert gga.latitude == pytest.approx(s.lat_deg, abs=1e-8)
        assert gga.longitude == pytest.approx(s.lon_deg, abs=1e-8)
        assert gga.altitude + float(gga.geo_sep) == pytest.approx(s.height_m, abs=1e-3)
        assert gga.gps_qual == (6 if s.state == "degraded" else 1)
        utc = datetime.datetime.fromtimestamp(s.t_s, datetime.UTC)
        assert gga.timestamp == utc.timetz().replace(microsecond=utc.microsecond // 10000 * 10000)
        assert rmc.datestamp == utc.date()
        east, north = s.vel_enu_m_s[:2]
        assert rmc.spd_over_grnd == pytest.approx(math.hypot(east, north) * 3600 / 1852, abs=1e-3)
        assert rmc.true_course == pytest.approx(
            math.degrees(math.atan2(east, north)) % 360, abs=0.01
        )
        sigma_e, sigma_n, sigma_u = np.sqrt(np.diag(s.cov_pos_enu_m2))
        assert float(gst.std_dev_latitude) == pytest.approx(sigma_n, abs=1e-4)
        assert float(gst.std_dev_longitude) == pytest.approx(sigma_e, abs=1e-4)
        assert float(gst.std_dev_altitude) == pytest.approx(sigma_u, abs=1e-4)


def test_an_unknown_suffix_is_refused(tmp_path):
    with pytest.raises(ValueError, match="unknown export format"):
        export(tmp_path / "s.kml", SolutionTrack.from_solutions(_solutions()), "drive")
