"""Fixes that receivers report incompletely (gnss_driver.fix_rules through the driver core).

The sentences follow NMEA 0183 (GGA satellites in use 00-12, GNS 00-99, GSA mode 1/2/3 and up
to 12 satellite IDs used, one GSA per constellation in 4.10; RMC and GLL carry no height), as
Garmin's GPS 18x and Furuno's GN-87 manuals print them: a valid GGA with ``00`` or an empty
count where the receiver does not report it, the same epoch's GNS with its own count.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from support.nmea_sentences import ALT, GSA_GLONASS, GSA_GPS, gga, gll, gns, rmc

from gnss_driver.driver import DriverConfig, GnssDriver
from gnss_driver.fix_rules import HOLD_VERTICAL_RATE_M_S, gsa_mode, gsa_satellites
from gnss_driver.fix_type import FixType
from gnss_driver.reader import NmeaReader
from gnss_driver.reader import frame_sentence as nmea
from gnss_driver.solution import GnssFix, SolutionConfig
from gnss_ins_common.navsat import HEIGHT_UNKNOWN_VARIANCE_M2, NavSatStatus

T0 = 1_700_000_000.0


def fixes(epochs: list[list[str]], config: SolutionConfig | None = None):
    """Each epoch's sentences written at 1 s intervals, the line idle after each: the fixes."""
    driver = GnssDriver(
        DriverConfig(baud=115200, epoch_idle_s=0.1, solution=config or SolutionConfig())
    )
    out: list[GnssFix] = []
    for k, bodies in enumerate(epochs):
        t = T0 + k
        results = driver.feed(b"".join(nmea(b) for b in bodies), t)
        results += driver.flush_idle(t + 0.5)
        out += [r.fix for r in results if r.fix is not None]
    assert driver.stats.internal_errors == 0
    return out, driver


def sentences(*bodies: str) -> list:
    return [read.sentence for read in NmeaReader().feed(b"".join(nmea(b) for b in bodies))]


def test_gsa_lists_satellites_used_per_constellation_and_the_fix_mode():
    gsas = sentences(GSA_GPS.format(3), GSA_GLONASS.format(3))
    assert gsa_satellites(gsas) == 7 and gsa_mode(gsas) == 3
    assert gsa_satellites(sentences("GPGSA,A,1,,,,,,,,,,,,,,,")) is None
    assert gsa_mode(sentences("GPGSA,A,2,04,05,09,,,,,,,,,,2.5,1.3,2.1")) == 2
    assert gsa_satellites([]) is None and gsa_mode([]) is None


@pytest.mark.parametrize("quality", [1, 2])
def test_a_count_of_00_is_not_reported_and_taken_from_the_epochs_gns(quality):
    (fix,), driver = fixes([[gga(19, quality, "00"), gns(19)]])
    assert fix.fix_type is FixType(quality) and fix.satellites == 11
    assert fix.status is (NavSatStatus.FIX if quality == 1 else NavSatStatus.SBAS_FIX)
    assert fix.alt_m == pytest.approx(ALT) and not fix.two_d
    assert driver.solver.stats.satellites_unreported == 1
    assert driver.solver.stats.too_few_satellites == 0


def test_a_count_of_00_is_taken_from_the_gsas_that_arrive_with_the_epoch():
    epoch = [gga(19, 1, "00"), GSA_GPS.format(3), GSA_GLONASS.format(3), rmc(19)]
    (fix,), _ = fixes([epoch])
    assert fix.satellites == 7 and fix.fix_type is FixType.SPS and not fix.two_d


@pytest.mark.parametrize("sats", ["", "00"])
def test_an_unreported_count_is_not_held_against_min_satellites(sats):
    (fix,), driver = fixes([[gga(19, 1, sats)]], SolutionConfig(min_satellites=12))
    assert fix.fix_type is FixType.SPS and fix.satellites is None
    assert np.isfinite(fix.cov_enu_m2).all() and fix.alt_m == pytest.approx(ALT)
    assert driver.solver.stats.satellites_unreported == 1


def test_no_fix_with_00_stays_no_fix():
    (fix,), _ = fixes([[gga(19, 0, "00"), gns(19)]])
    assert fix.fix_type is FixType.NO_FIX and math.isnan(fix.lat_deg)


def _is_2d(fix: GnssFix) -> bool:
    """Published 2-D: horizontal position and covariance, altitude NaN, vertical unknown."""
    cov = np.reshape(fix.cov_enu_m2, (3, 3))
    return (
        fix.two_d
        and fix.status >= NavSatStatus.FIX
        and math.isfinite(fix.lat_deg)
        and math.isfinite(fix.lon_deg)
        and math.isnan(fix.alt_m)
        and cov[2, 2] == HEIGHT_UNKNOWN_VARIANCE_M2
        and not cov[2, :2].any()
        and cov[0, 0] == cov[1, 1] > 0.0
    )


def test_three_satellites_make_a_2d_fix_published_with_the_height_unknown():
    (fix,), driver = fixes([[gga(19, 1, "03")]])
    assert _is_2d(fix) and fix.satellites == 3 and fix.status is NavSatStatus.FIX
    assert fix.cov_enu_m2[0] == pytest.approx((0.9 * 6.0) ** 2 / 2)  # HDOP x SPS UERE
    assert driver.solver.stats.fixes_2d == 1 and driver.solver.stats.too_few_satellites == 0
    (fix,), driver = fixes([[gga(19, 1, "03")]], SolutionConfig(allow_2d_fix=False))
    assert fix.fix_type is FixType.NO_FIX and driver.solver.stats.rejected_2d == 1


def test_gsa_mode_2_makes_a_2d_fix_and_mode_3_a_3d_one():
    (fix,), _ = fixes([[gga(19, 1, "05"), GSA_GPS.format(2)]])
    assert _is_2d(fix) and fix.satellites == 5
    (fix,), _ = fixes([[gga(19, 1, "05"), GSA_GPS.format(3)]])
    assert not fix.two_d and fix.alt_m == pytest.approx(ALT)


def test_a_2d_fix_needs_one_satellite_fewer_than_min_satellites():
    config = SolutionConfig(min_satellites=6)
    (two_d, three_d, too_few), driver = fixes(
        [
            [gga(19, 1, "05"), GSA_GPS.format(2)],
            [gga(20, 1, "05"), GSA_GPS.format(3)],
            [gga(21, 1, "03")],
        ],
        config,
    )
    assert _is_2d(two_d)
    assert three_d.fix_type is FixType.NO_FIX and too_few.fix_type is FixType.NO_FIX
    assert driver.solver.stats.too_few_satellites == 2


@pytest.mark.parametrize("heightless", [rmc, gll])
def test_rmc_or_gll_epochs_hold_the_altitude_of_a_3d_fix_up_to_2_s(heightless):
    epochs = [[gga(19)], [heightless(20)], [heightless(21)], [heightless(22)]]
    (first, one_s, two_s, three_s), driver = fixes(epochs)
    up = first.cov_enu_m2[8]  # VDOP 2 x HDOP 0.9 x UERE 6 m
    assert up == pytest.approx((2 * 0.9 * 6.0) ** 2)
    for held, age in ((one_s, 1.0), (two_s, 2.0)):
        assert held.alt_m == pytest.approx(ALT) and not held.two_d
        assert held.cov_enu_m2[8] == pytest.approx(up + (HOLD_VERTICAL_RATE_M_S * age) ** 2)
        assert held.cov_enu_m2[0] == held.cov_enu_m2[4] == 6.0**2 / 2  # no HDOP: 1 x UERE
    assert _is_2d(three_s)
    assert driver.solver.stats.held_altitudes == 2


def test_a_2d_fix_holds_no_altitude_for_the_next_rmc():
    (_, two_d, held), _ = fixes([[gga(18)], [gga(19, 1, "03")], [rmc(20)]])
    assert _is_2d(two_d)
    assert held.alt_m == pytest.approx(ALT)  # from 18, 2 s before: the 2-D fix gave none
    (_, two_d, later), _ = fixes([[gga(18)], [gga(19, 1, "03")], [rmc(21)]])
    assert _is_2d(later)


@settings(max_examples=300, deadline=None)
@given(
    quality=st.sampled_from([0, 1, 2, 4, 5, 6]),
    sats=st.sampled_from(["", "00", "01", "02", "03", "04", "07", "12"]),
    gns_sats=st.sampled_from([None, "", "00", "03", "11"]),
    mode=st.sampled_from([None, 1, 2, 3]),
    min_satellites=st.integers(0, 12),
    allow_2d=st.booleans(),
)
def test_every_published_fix_is_sound_and_follows_the_rules(
    quality, sats, gns_sats, mode, min_satellites, allow_2d
):
    epoch = [gga(19, quality, sats)]
    if gns_sats is not None:
        epoch.append(gns(19, gns_sats))
    if mode is not None:
        epoch.append(GSA_GPS.format(mode))
    config = SolutionConfig(min_satellites=min_satellites, allow_2d_fix=allow_2d)
    (fix,), _ = fixes([epoch], config)
    if quality in (0, 6):
        assert fix.fix_type is FixType.NO_FIX
        return
    reported = int(sats) if sats not in ("", "00") else None
    if reported is None and gns_sats not in (None, "", "00"):
        reported = int(gns_sats)
    if reported is None and mode is not None:
        reported = 5  # the GSA's list
    assert fix.satellites == (reported if fix.fix_type is not FixType.NO_FIX else None)
    two_d = mode == 2 or (mode != 3 and reported == 3)
    needed = min_satellites - (1 if two_d else 0)
    published = (allow_2d or not two_d) and (reported is None or reported >= needed)
    assert (fix.fix_type is not FixType.NO_FIX) == published
    if published:
        assert fix.two_d == two_d
        assert _is_2d(fix) if two_d else fix.alt_m == pytest.approx(ALT)
        cov = np.reshape(fix.cov_enu_m2, (3, 3))
        assert np.isfinite(cov).all() and (np.linalg.eigvalsh(cov) > 0).all()
