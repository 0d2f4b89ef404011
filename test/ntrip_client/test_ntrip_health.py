"""What ntrip_node reports, without ROS: the correction link's level and message from the
client's counters (``assess``) and the rover's solution from its GGA sentences (``RoverGga``)."""

from __future__ import annotations

import math

import pytest

from gnss_driver.reader import frame_sentence
from ntrip_client.client import CasterState, ClientStats
from ntrip_client.health import ERROR, OK, WARN, RoverGga, assess, corrections_age_s

NOW_S = 1000.0
AGE_WARN_S = 5.0


def _gga(quality: int, position: bool = True) -> str:
    where = "5700.888,N,00959.190,E" if position else ",,,"
    body = f"GPGGA,120000.00,{where},{quality},12,0.8,10.0,M,40.0,M,1.0,0001"
    return frame_sentence(body).decode().strip()


@pytest.mark.parametrize(
    ("stats", "level", "said"),
    [
        (
            ClientStats(CasterState.REFUSED, 401, "401 Unauthorized"),
            ERROR,
            "caster refused the request: 401 Unauthorized",
        ),
        (
            ClientStats(CasterState.UNKNOWN_MOUNTPOINT, 404, last_error="mountpoint 'X' is not"),
            ERROR,
            "mountpoint 'X' is not",
        ),
        (
            ClientStats(CasterState.RECONNECTING, last_error="no data for 10 s"),
            WARN,
            "reconnecting: no data for 10 s",
        ),
        (ClientStats(CasterState.CONNECTING), WARN, "connecting"),
        (ClientStats(CasterState.CONNECTED), WARN, "connected, no corrections yet"),
        (
            ClientStats(CasterState.CONNECTED, last_frame_monotonic_s=NOW_S - 7.5),
            WARN,
            "corrections 7.5 s old (limit 5 s)",
        ),
        (
            ClientStats(CasterState.CONNECTED, last_frame_monotonic_s=NOW_S - 0.4),
            OK,
            "corrections 0.4 s old",
        ),
    ],
    ids=["refused", "unknown-mountpoint", "reconnecting", "connecting", "no-frame", "old", "ok"],
)
def test_the_level_says_refused_reconnecting_and_old_corrections(stats, level, said):
    assert assess(stats, NOW_S, AGE_WARN_S) == (level, said)


def test_the_corrections_age_is_since_the_newest_frame():
    assert math.isnan(corrections_age_s(ClientStats(), NOW_S))
    stats = ClientStats(CasterState.CONNECTED, last_frame_monotonic_s=NOW_S - 2.25)
    assert corrections_age_s(stats, NOW_S) == 2.25


def test_the_rover_s_solution_and_the_gga_sent_upstream():
    rover = RoverGga()
    rover.note("$GPVTG,054.7,T,034.4,M,005.5,N,010.2,K*48")  # not a GGA: not counted
    rover.note(_gga(0, position=False))
    assert (rover.solution, rover.seen, rover.with_position, rover.sentence) == (
        "no fix",
        1,
        0,
        None,
    )
    for quality, name in ((1, "SPS"), (2, "DGPS"), (5, "RTK float"), (4, "RTK fixed")):
        rover.note(_gga(quality))
        assert rover.solution == name
    assert rover.sentence == _gga(4).encode() + b"\r\n"  # the newest with a position
    rover.note(_gga(4).replace("*", "*0"))  # a broken checksum changes nothing
    assert (rover.seen, rover.with_position) == (5, 4)
