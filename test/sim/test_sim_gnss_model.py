"""GNSS error model: noise levels, outages, fix types, latency, outliers, ADU5 attitude."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gnss_driver.fix_type import FixType
from ins_fusion.bags.topics import GNSS_FIX
from ins_fusion.core.nav import earth
from ins_fusion.core.nav.rotation import euler_from_quat, quat_nb_from_enu_flu
from ins_fusion.sim.drive import Simulation, SimulationConfig
from ins_fusion.sim.gnss_model import (
    FIX_NOISE,
    PROFILES,
    GnssErrorModel,
    GnssFix,
    GnssSchedule,
)
from ins_fusion.sim.scenarios import SURVEY_CAR, seed_test_pattern
from ins_fusion.sim.vehicle import GnssTruth, TruthCache, VehicleTruth

TRUTH = VehicleTruth(seed_test_pattern(), SURVEY_CAR)
#: TRUTH.gnss_truth answered from 10 s batches on a 0.1 s grid (every epoch of the receivers
#: here): the same truth, ~50x faster than one evaluation per call (test durations). A batch's
#: look-ahead past the end of the drive gets the last truth (no test asks for those times).
TRUTH_AT = TruthCache(
    lambda t: TRUTH.gnss_truths(np.minimum(t, TRUTH.duration_s)),
    TRUTH.gnss_truth,
    ahead=np.arange(0.0, 10.0, 0.1),
)


def _errors_ned(fixes: list[GnssFix]) -> np.ndarray:
    out = []
    for fix in fixes:
        truth = TRUTH_AT(fix.t_s)
        r_m, r_n = earth.radii_m(truth.lat_rad)
        out.append(
            [
                (fix.lat_rad - truth.lat_rad) * (r_m + truth.height_m),
                (fix.lon_rad - truth.lon_rad) * (r_n + truth.height_m) * math.cos(truth.lat_rad),
                truth.height_m - fix.height_m,
            ]
        )
    return np.array(out)


def test_a_truth_cache_is_filled_with_the_epochs_times_in_one_batch():
    batches: list[int] = []

    def batch(t_s: np.ndarray) -> list[GnssTruth]:
        batches.append(len(t_s))
        return TRUTH.gnss_truths(t_s)

    def single(t_s: float) -> GnssTruth:
        raise AssertionError(f"truth evaluated on its own at {t_s} s")

    model = GnssErrorModel(TruthCache(batch, single), PROFILES["leica_rtk"], seed=1)
    assert len(list(model.fixes(0.0, 20.0))) == 20
    assert len(list(model.fixes(20.0, 30.0))) == 10
    assert batches == [20, 10]


def test_rtk_fixes_have_centimetre_noise_and_no_vertical_velocity():
    model = GnssErrorModel(TRUTH_AT, PROFILES["leica_rtk"], seed=1)
    fixes = list(model.fixes(0.0, 240.0))
    assert [f.t_s for f in fixes] == pytest.approx(np.arange(240.0))
    assert all(f.fix_type == FixType.RTK_FIXED for f in fixes)
    assert all(f.arrival_t_s == pytest.approx(f.t_s + 0.053) for f in fixes)
    errors = _errors_ned([f for f in fixes if not f.outlier])
    rms = np.sqrt((errors**2).mean(axis=0))
    # 2 cm / 3 cm (Aalborg notes §7.2), loosely: 240 correlated samples.
    assert rms[:2] == pytest.approx([0.02, 0.02], rel=0.5)
    assert rms[2] == pytest.approx(0.03, rel=0.5)
    assert fixes[0].position_sigma_enu_m == pytest.approx([0.0198, 0.0198, 0.0297], abs=1e-4)
    assert fixes[0].velocity_sigma_enu_m_s[:2] == pytest.approx([0.05, 0.05])
    assert all(math.isnan(f.vel_enu_m_s[2]) for f in fixes)


def test_outage_then_float_until_reconverged_then_scheduled_fix_changes():
    schedule = GnssSchedule(
        outages=((100.0, 20.0),), fix_changes=((200.0, FixType.DGPS), (220.0, FixType.NO_FIX))
    )
    model = GnssErrorModel(TRUTH_AT, PROFILES["leica_rtk"], schedule, seed=2)
    fixes = {round(f.t_s): f for f in model.fixes(0.0, 240.0)}
    assert not any(100 <= t < 120 for t in fixes)
    assert fixes[99].fix_type == FixType.RTK_FIXED
    assert {fixes[t].fix_type for t in range(120, 150)} == {FixType.RTK_FLOAT}
    assert fixes[150].fix_type == FixType.RTK_FIXED
    assert fixes[200].fix_type == FixType.DGPS
    assert max(fixes) == 219


def test_stand_alone_errors_are_metres_and_time_correlated():
    model = GnssErrorModel(TRUTH_AT, PROFILES["qfree_obu"], seed=3)
    fixes = [f for f in model.fixes(0.0, 240.0) if not f.outlier]
    assert fixes[0].arrival_t_s - fixes[0].t_s == pytest.approx(1.24)  # NTNU notes §3
    north = _errors_ned(fixes)[:, 0]
    assert 0.3 < np.abs(north).max() < 20.0
    lag1 = np.corrcoef(north[:-1], north[1:])[0, 1]
    assert lag1 > 0.9  # a 300 s Gauss-Markov wander dominates the white part


def test_outliers_occur_at_the_configured_rate():
    profile = PROFILES["qfree_obu"]
    still = TRUTH_AT(30.0)
    model = GnssErrorModel(lambda t: still, profile, seed=4)
    fixes = list(model.fixes(0.0, 3000.0))
    rate = np.mean([f.outlier for f in fixes])
    assert rate == pytest.approx(profile.outlier_probability, abs=0.01)


def test_adu5_attitude_noise():
    profile = PROFILES["adu5"]
    model = GnssErrorModel(TRUTH_AT, profile, seed=5)
    fixes = list(model.fixes(60.0, 180.0))
    assert len(fixes) == 5 * 120
    diffs = []
    for fix in fixes:
        assert fix.quat_enu_flu is not None
        true_q = quat_nb_from_enu_flu(TRUTH_AT(fix.t_s).quat_enu_flu)
        diff = euler_from_quat(quat_nb_from_enu_flu(fix.quat_enu_flu)) - euler_from_quat(true_q)
        diffs.append((diff + math.pi) % (2 * math.pi) - math.pi)
    std = np.degrees(np.std(diffs, axis=0))
    assert std == pytest.approx([0.24, 0.14, 0.1], rel=0.1)  # Aalborg notes §7.3
    assert Rotation.from_quat(fixes[0].quat_enu_flu).magnitude() > 0.0


def test_reproducible_and_independent_of_how_the_epochs_are_requested():
    schedule = GnssSchedule(outages=((30.0, 5.0),))
    one = GnssErrorModel(TRUTH_AT, PROFILES["adu5"], schedule, seed=9)
    two = GnssErrorModel(TRUTH_AT, PROFILES["adu5"], schedule, seed=9)
    whole = list(one.fixes(0.0, 60.0))
    pieces = list(two.fixes(0.0, 12.3)) + list(two.fixes(12.3, 60.0))
    assert [f.lat_rad for f in whole] == [f.lat_rad for f in pieces]
    assert all(
        np.array_equal(a.quat_enu_flu, b.quat_enu_flu) for a, b in zip(whole, pieces, strict=True)
    )
    other = list(GnssErrorModel(TRUTH_AT, PROFILES["adu5"], schedule, seed=10).fixes(0, 60))
    assert [f.lat_rad for f in other] != [f.lat_rad for f in whole]


def test_fix_noise_table_is_ordered_by_quality():
    order = [FixType.RTK_FIXED, FixType.RTK_FLOAT, FixType.DGPS, FixType.SPS]
    sigmas = [FIX_NOISE[f].position_sigma_ned_m[0] for f in order]
    assert sigmas == sorted(sigmas)


@pytest.mark.parametrize("name", ["leica_rtk", "adu5"])
def test_noise_scale_zero_gives_exact_fixes_with_the_same_reports(name):
    schedule = GnssSchedule(outages=((100.0, 20.0),))
    exact, half, full = (
        list(
            GnssErrorModel(TRUTH_AT, PROFILES[name], schedule, seed=6, noise_scale=scale).fixes(
                60.0, 180.0
            )
        )
        for scale in (0.0, 0.5, 1.0)
    )
    assert np.abs(_errors_ned(exact)).max() < 1e-6
    assert _errors_ned(half) == pytest.approx(0.5 * _errors_ned(full), abs=1e-6)
    for a, b in zip(exact, full, strict=True):
        assert (a.t_s, a.fix_type, a.outlier) == (b.t_s, b.fix_type, b.outlier)
        assert np.array_equal(a.position_sigma_enu_m, b.position_sigma_enu_m)
        truth = TRUTH_AT(a.t_s)
        up = a.vel_enu_m_s[2]  # NaN: the Leica outputs no vertical velocity
        assert a.vel_enu_m_s[:2] == pytest.approx(truth.vel_enu_m_s[:2], abs=1e-9)
        assert math.isnan(up) or up == pytest.approx(truth.vel_enu_m_s[2], abs=1e-9)
        if a.quat_enu_flu is not None:
            assert abs(np.dot(a.quat_enu_flu, truth.quat_enu_flu)) == pytest.approx(1.0, abs=1e-12)


def test_simulation_gnss_noise_scale_zero_gives_the_true_antenna_position():
    sim = Simulation(SimulationConfig(duration_s=80.0, gnss_noise_scale=0.0, seed=3, adu5=False))
    fixes = [e.message for e in sim.gnss_events(60.0, 80.0) if e.topic == GNSS_FIX]
    assert len(fixes) == 20
    for fix in fixes:
        stamp_s = fix.header.stamp.sec + fix.header.stamp.nanosec * 1e-9
        truth = sim.vehicle.gnss_truth(stamp_s - sim.config.start_ns * 1e-9)
        r_m, r_n = earth.radii_m(truth.lat_rad)
        north = (math.radians(fix.latitude) - truth.lat_rad) * r_m
        east = (math.radians(fix.longitude) - truth.lon_rad) * r_n * math.cos(truth.lat_rad)
        assert math.hypot(north, east) < 1e-3  # NMEA prints 1e-7 arc minutes (0.2 mm)
        assert fix.altitude == pytest.approx(truth.height_m, abs=1e-3)
