"""The sourcetable's mountpoints, nearest first, and the GGA helpers the client sends upstream."""

from __future__ import annotations

import math

import pytest

from gnss_driver.reader import frame_sentence
from ntrip_client.gga import GgaSchedule, fixed_gga, gga_position
from ntrip_client.sourcetable import by_distance, describe, distance_km, parse_sourcetable

TABLE = """\
CAS;caster.example;2101;Example;Agency;0;DNK;56.00;10.00;0.0.0.0;0;http://example
NET;EXA;Agency;B;N;http://example;none;x@example;none
STR;AAU00DNK;Aalborg;RTCM 3.2;1004(1),1005(10);2;GPS+GLO;EXA;DNK;57.01;9.99;0;0;gen;none;B;N;9600;
STR;CPH00DNK;Copenhagen;RTCM 3.3;1077(1);2;GPS;EXA;DNK;55.68;12.57;1;0;gen;none;B;N;9600;
STR;NOPOS;;RTCM 3;;;;;;;;0
STR;WEST;West;RTCM 3.2;;2;GPS;EXA;USA;40.0;255.0;1;0;gen;none;N;N;1
ENDSOURCETABLE
STR;AFTER;After;RTCM 3.2;;2;GPS;EXA;DNK;57;10;0;0;gen;none;B;N;1;
"""


def test_str_lines_parse_up_to_the_end():
    found = parse_sourcetable(TABLE)
    assert [mp.name for mp in found] == ["AAU00DNK", "CPH00DNK", "NOPOS", "WEST"]
    aalborg, copenhagen, nopos, west = found
    assert (aalborg.identifier, aalborg.format, aalborg.lat_deg, aalborg.lon_deg) == (
        "Aalborg",
        "RTCM 3.2",
        57.01,
        9.99,
    )
    assert not aalborg.nmea_required and copenhagen.nmea_required
    assert aalborg.authentication == "B" and aalborg.country == "DNK"
    assert math.isnan(nopos.lat_deg) and math.isnan(nopos.lon_deg)
    assert west.lon_deg == pytest.approx(-105.0)  # 0..360 east longitudes come back to +-180


def test_nearest_first_and_unknown_positions_last():
    found = parse_sourcetable(TABLE)
    assert [mp.name for mp in by_distance(found, 55.7, 12.5)] == [
        "CPH00DNK",
        "AAU00DNK",
        "WEST",
        "NOPOS",
    ]
    assert [mp.name for mp in by_distance(found, 57.0, 10.0)][:2] == ["AAU00DNK", "CPH00DNK"]


def test_distance_is_great_circle_km():
    assert distance_km(0, 0, 0, 1) == pytest.approx(111.19, abs=0.01)
    assert distance_km(57.01, 9.99, 55.68, 12.57) == pytest.approx(218, abs=2)
    assert math.isnan(distance_km(0, 0, math.nan, math.nan))


def test_describe_for_a_message():
    found = parse_sourcetable(TABLE)
    text = describe(found, (57.0, 10.0), limit=2)
    assert text == "AAU00DNK (Aalborg, RTCM 3.2, 1 km), CPH00DNK (Copenhagen, RTCM 3.3, 216 km)" + (
        " and 2 more"
    )
    assert describe(found).startswith("AAU00DNK (Aalborg, RTCM 3.2), CPH00DNK")
    assert "NOPOS (RTCM 3)" in describe(found)
    assert describe([]) == "none"


@pytest.mark.parametrize(
    ("lat", "lon"), [(57.0148, 9.9865), (-33.8688, -151.2093), (0.0, 0.0), (89.99999, 179.99999)]
)
def test_fixed_gga_gives_its_position_back(lat, lon):
    sentence = fixed_gga(lat, lon, 50.0, 1_700_000_000.25)
    assert sentence.endswith(b"\r\n")
    position = gga_position(sentence.decode())
    assert position == pytest.approx((lat, lon), abs=1e-6)


def test_fixed_gga_time_of_day():
    assert fixed_gga(0, 0, 0, 86399.996).startswith(b"$GPGGA,000000.00,")
    assert fixed_gga(0, 0, 0, 3723.5).startswith(b"$GPGGA,010203.50,")


@pytest.mark.parametrize(
    "sentence",
    [
        "$GPGGA,123519,4807.038,N,01131.000,E,0,08,0.9,545.4,M,46.9,M,,",  # no fix
        "$GPGGA,123519,,,,,1,08,0.9,545.4,M,46.9,M,,",  # no position
        "$GPRMC,123519,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W",  # not a GGA
    ],
)
def test_gga_without_a_position_gives_none(sentence):
    assert gga_position(frame_sentence(sentence[1:]).decode()) is None


def test_gga_with_a_bad_or_no_checksum_gives_none():
    good = frame_sentence("GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,")
    assert gga_position(good.decode()) == pytest.approx((48.1173, 11.516667), abs=1e-6)
    assert gga_position(good.decode().split("*")[0]) is None
    assert gga_position(good.decode().replace("*", "*0")[:-4] + "00") is None


def test_gga_schedule_first_at_once_then_every_interval_never_within_a_second():
    schedule = GgaSchedule(10.0)
    assert schedule.due(0.0)
    schedule.sent(0.0)
    assert not schedule.due(9.9) and schedule.due(10.0)
    schedule.connected()  # a new connection wants one at once, but not within 1 s of the last
    assert not schedule.due(0.5) and schedule.due(1.0)
    schedule.sent(1.0)
    assert not schedule.due(10.9) and schedule.due(11.0)


@pytest.mark.parametrize("interval", [0.5, 0.0, -1.0, math.nan])
def test_gga_interval_under_a_second_is_refused(interval):
    with pytest.raises(ValueError, match="at least 1 s"):
        GgaSchedule(interval)
