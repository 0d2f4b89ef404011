"""What the NTRIP node reports (no ROS): the rover's last GGA and the correction link's level.

``RoverGga`` keeps the rover's latest GGA with a position (the one sent upstream) and its
solution type from the GGA quality indicator (NMEA 0183 v4.1: 0 no fix, 1 SPS, 2 DGPS, 4 RTK
fixed, 5 RTK float, ...). ``assess`` turns the client's counters into a diagnostic level and a
message that says why: ERROR while the caster refuses the request or the mountpoint is unknown,
WARN while (re)connecting or when the newest correction is older than the limit, OK otherwise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ntrip_client.client import CasterState, ClientStats
from ntrip_client.gga import read_gga

#: GGA quality indicator -> the rover's solution type as status shows it.
SOLUTIONS = {
    0: "no fix",
    1: "SPS",
    2: "DGPS",
    3: "PPS",
    4: "RTK fixed",
    5: "RTK float",
    6: "dead reckoning",
    7: "manual",
    8: "simulation",
}
OK, WARN, ERROR = "OK", "WARN", "ERROR"


@dataclass
class RoverGga:
    """The rover's latest GGA sentences (``note``) as the caster and the operator need them."""

    #: The newest GGA with a position, with CR LF, as it is sent upstream; None before one.
    sentence: bytes | None = None
    #: The solution type of the newest GGA of any quality ("-" before one).
    solution: str = "-"
    #: GGA sentences seen, and those with a position.
    seen: int = 0
    with_position: int = 0

    def note(self, text: str) -> None:
        """One sentence the rover sent, as received (any type; only GGAs whose checksum holds
        count)."""
        read = read_gga(text)
        if read is None:
            return
        quality, position = read
        self.seen += 1
        self.solution = SOLUTIONS.get(quality, f"quality {quality}")
        if position is not None:
            self.with_position += 1
            self.sentence = text.strip().encode("ascii") + b"\r\n"


def corrections_age_s(stats: ClientStats, now_s: float) -> float:
    """Seconds since the newest valid frame arrived (NaN before the first)."""
    last = stats.last_frame_monotonic_s
    return math.nan if last is None else now_s - last


def assess(stats: ClientStats, now_s: float, age_warn_s: float) -> tuple[str, str]:
    """The level (OK, WARN, ERROR) and message of the correction link at ``now_s`` (the
    client's monotonic clock) [s]."""
    age = corrections_age_s(stats, now_s)
    state = stats.state
    if state is CasterState.REFUSED:
        return ERROR, f"caster refused the request: {stats.reason or stats.last_error}"
    if state is CasterState.UNKNOWN_MOUNTPOINT:
        return ERROR, stats.last_error or "unknown mountpoint"
    if state is not CasterState.CONNECTED:
        why = f": {stats.last_error}" if stats.last_error else ""
        return WARN, f"{state.value}{why}"
    if math.isnan(age):
        return WARN, "connected, no corrections yet"
    if age > age_warn_s:
        return WARN, f"corrections {age:.1f} s old (limit {age_warn_s:g} s)"
    return OK, f"corrections {age:.1f} s old"
