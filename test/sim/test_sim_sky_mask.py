"""GNSS outages from a sky-visibility mask, epochs without a fix, UTC-aligned epochs, and the
batched truth the bag writer uses."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gnss_driver.fix_type import FixType
from ins_fusion.core.nav import earth
from ins_fusion.sim.gnss_model import (
    PROFILES,
    GnssErrorModel,
    GnssSchedule,
    SkyMask,
    SkyZone,
    masked_fix,
)
from ins_fusion.sim.scenarios import SURVEY_CAR, seed_test_pattern
from ins_fusion.sim.vehicle import TruthCache, VehicleTruth

TRUTH = VehicleTruth(seed_test_pattern(), SURVEY_CAR)


def _zone_at(t_s: float, radius_m: float, satellites: int) -> SkyZone:
    where = TRUTH.base_link(np.array([t_s]))
    return SkyZone(float(where.lat_rad[0]), float(where.lon_rad[0]), radius_m, satellites)


def test_fewer_satellites_degrade_the_fix_step_by_step():
    assert masked_fix(FixType.RTK_FIXED, None) == FixType.RTK_FIXED
    assert masked_fix(FixType.RTK_FIXED, 9) == FixType.RTK_FIXED
    assert masked_fix(FixType.RTK_FIXED, 5) == FixType.RTK_FLOAT
    assert masked_fix(FixType.RTK_FIXED, 4) == FixType.DGPS
    assert masked_fix(FixType.SPS, 4) == FixType.SPS
    assert masked_fix(FixType.DGPS, 3) == FixType.NO_FIX
    assert masked_fix(FixType.SPS, 9) == FixType.SPS  # never better than the receiver


def test_sky_mask_finds_the_zones_around_a_position():
    zone = _zone_at(150.0, 30.0, 5)
    mask = SkyMask((zone, _zone_at(150.0, 10.0, 2)))
    assert mask.visible_satellites(zone.lat_rad, zone.lon_rad) == 2
    north_20m = zone.lat_rad + 20.0 / 6_370_000.0
    assert mask.visible_satellites(north_20m, zone.lon_rad) == 5
    assert mask.visible_satellites(zone.lat_rad + 40.0 / 6_370_000.0, zone.lon_rad) is None


def test_a_zone_along_the_route_loses_then_degrades_the_rtk_fix():
    """A bridge where the drive stops at the red light (t ≈ 150 s): no fix within 15 m, RTK
    float with 5 satellites within 60 m, float for the re-convergence time after, then fixed."""
    inner, outer = _zone_at(150.0, 15.0, 2), _zone_at(150.0, 60.0, 5)
    profile = PROFILES["leica_rtk"]
    model = GnssErrorModel(
        TRUTH.gnss_truth, profile, GnssSchedule(sky_mask=SkyMask((outer, inner))), seed=1
    )
    epochs = {round(e.t_s): e for e in model.epochs(0.0, 240.0)}
    assert len(epochs) == 240
    antenna = TRUTH.antenna(np.arange(240.0))
    r_meridian, r_prime_vertical = earth.radii_m(inner.lat_rad)
    distance = np.hypot(
        (antenna.lat_rad - inner.lat_rad) * r_meridian,
        (antenna.lon_rad - inner.lon_rad) * r_prime_vertical * math.cos(inner.lat_rad),
    )
    lost = {t for t, e in epochs.items() if e.fix is None}
    assert lost == set(np.flatnonzero(distance <= 15.0))
    assert all(epochs[t].satellites == 2 for t in lost)
    in_outer = set(np.flatnonzero((distance > 15.0) & (distance <= 60.0)))
    assert all(epochs[t].fix.fix_type == FixType.RTK_FLOAT for t in in_outer)
    first = epochs[min(in_outer)].fix
    assert first.satellites == 5
    assert first.hdop == pytest.approx(0.9 * math.sqrt(11 / 5))
    assert first.position_sigma_enu_m == pytest.approx(
        [0.206 * math.sqrt(11 / 5)] * 2 + [0.31 * math.sqrt(11 / 5)], rel=0.01
    )
    # Float for the 30 s re-convergence after leaving the masked area, then fixed again.
    left = max(in_outer | lost)
    after = [t for t in range(left + 1, 240) if epochs[t].fix.fix_type == FixType.RTK_FIXED]
    assert after[0] - left == pytest.approx(profile.reconvergence_s, abs=1)
    assert epochs[100].fix.fix_type == FixType.RTK_FIXED
    assert epochs[100].satellites == 12


def test_the_mask_does_not_change_the_error_sequences_outside_the_zones():
    truth = TruthCache(TRUTH.gnss_truths, TRUTH.gnss_truth)
    truth.fill(np.arange(0.0, 240.0, 0.2))
    zone = _zone_at(150.0, 15.0, 0)
    masked = GnssErrorModel(
        truth, PROFILES["adu5"], GnssSchedule(sky_mask=SkyMask((zone,))), seed=2
    )
    plain = GnssErrorModel(truth, PROFILES["adu5"], seed=2)
    a = {e.t_s: e.fix for e in masked.epochs(0.0, 240.0)}
    b = {f.t_s: f for f in plain.fixes(0.0, 240.0)}
    assert any(fix is None for fix in a.values())
    kept = [t for t, fix in a.items() if fix is not None]
    assert all(a[t].lat_rad == b[t].lat_rad for t in kept)


def test_scheduled_outage_epochs_are_reported_without_a_fix():
    model = GnssErrorModel(
        TRUTH.gnss_truth, PROFILES["leica_rtk"], GnssSchedule(outages=((10.0, 3.0),)), seed=3
    )
    epochs = list(model.epochs(0.0, 20.0))
    assert [e.t_s for e in epochs] == pytest.approx(np.arange(20.0))
    assert [e.t_s for e in epochs if e.fix is None] == [10.0, 11.0, 12.0]
    assert all(e.satellites == 0 for e in epochs if e.fix is None)
    assert all(e.arrival_t_s == pytest.approx(e.t_s + 0.053) for e in epochs)


def test_epochs_fall_on_whole_utc_periods_and_epoch_times_predicts_them():
    start_utc = 1_717_236_000.37
    model = GnssErrorModel(TRUTH.gnss_truth, PROFILES["adu5"], seed=4, utc_at_zero_s=start_utc)
    predicted = model.epoch_times(0.0, 2.0)
    times = [e.t_s for e in model.epochs(0.0, 2.0)]
    assert times == list(predicted)
    assert times[0] == pytest.approx(0.03, abs=1e-6)
    utc = start_utc + np.array(times)
    assert utc * 5 == pytest.approx(np.round(utc * 5), abs=1e-6)
    assert model.epoch_times(0.0, 2.0).size == 0  # all consumed


def test_truth_cache_serves_batches_and_falls_back_to_single_evaluations():
    calls: list[int] = []

    def batch(t: np.ndarray) -> list[float]:
        calls.append(len(t))
        return list(2.0 * t)

    cache = TruthCache(batch, lambda t: -t)
    cache.fill(np.array([0.1, 0.2, 0.3]))
    assert cache(0.2) == pytest.approx(0.4)
    assert cache(0.2 + 1e-8) == pytest.approx(0.4)
    assert cache(0.25) == -0.25
    ahead = TruthCache(batch, lambda t: -t, ahead=np.arange(4) / 4.0)
    assert ahead(1.0) == 2.0 and ahead(1.5) == 3.0 and calls == [3, 4]
    truth = TruthCache(TRUTH.gnss_truths, TRUTH.gnss_truth)
    truth.fill(np.array([100.0, 101.0]))
    assert truth(101.0).lat_rad == TRUTH.gnss_truth(101.0).lat_rad
