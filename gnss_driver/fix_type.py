"""The fix type of an NMEA epoch and what it means for sensor_msgs/NavSatStatus (no ROS).

``FixType`` numbers the GGA quality indicator (0 no fix, 1 SPS, 2 DGPS, 3 PPS, 4 RTK fixed, 5 RTK
float, 6 dead reckoning, 7 manual, 8 simulator); the mode letters of RMC/GLL/VTG and of GNS's
per-system field (NMEA 2.3+, 4.10) and LLQ's quality map onto it. Which sentence of an epoch
decides is the solver's choice (``solution``).
"""

from __future__ import annotations

from enum import IntEnum

from gnss_ins_common.navsat import NavSatStatus


class FixType(IntEnum):
    """GGA quality indicator values."""

    NO_FIX = 0
    SPS = 1
    DGPS = 2
    PPS = 3
    RTK_FIXED = 4
    RTK_FLOAT = 5
    ESTIMATED = 6
    MANUAL = 7
    SIMULATION = 8


#: Fix types that are measured positions.
VALID_FIX_TYPES = frozenset(
    {FixType.SPS, FixType.DGPS, FixType.PPS, FixType.RTK_FIXED, FixType.RTK_FLOAT}
)

#: RMC / GLL / VTG mode letters (NMEA 2.3+) -> fix type.
MODE_FIX = {
    "A": FixType.SPS,
    "D": FixType.DGPS,
    "P": FixType.PPS,
    "R": FixType.RTK_FIXED,
    "F": FixType.RTK_FLOAT,
    "E": FixType.ESTIMATED,
    "M": FixType.MANUAL,
    "S": FixType.SIMULATION,
    "N": FixType.NO_FIX,
}


#: Fix type -> NavSatStatus, as ros-drivers' nmea_navsat_driver maps GGA quality: DGPS counts as
#: SBAS-augmented, RTK as ground-based augmentation.
NAV_SAT_STATUS = {
    FixType.SPS: NavSatStatus.FIX,
    FixType.PPS: NavSatStatus.FIX,
    FixType.DGPS: NavSatStatus.SBAS_FIX,
    FixType.RTK_FLOAT: NavSatStatus.GBAS_FIX,
    FixType.RTK_FIXED: NavSatStatus.GBAS_FIX,
}

#: LLQ GPS quality -> fix type: 1 navigation fix, 2 RTK float, 3 RTK fixed (notes §7.2).
LLQ_FIX = {1: FixType.SPS, 2: FixType.RTK_FLOAT, 3: FixType.RTK_FIXED}
#: GNS mode letters from the best fix to the weakest valid one.
GNS_MODE_RANK = "RFPDA"


def gns_fix_type(modes: str | None) -> FixType:
    """The best fix type among a GNS sentence's per-system mode letters (GPS, GLONASS, Galileo,
    BeiDou, ...; NMEA 0183 4.10), NO_FIX when none is valid."""
    for letter in GNS_MODE_RANK:
        if modes is not None and letter in modes:
            return MODE_FIX[letter]
    return FixType.NO_FIX


def gga_fix_type(quality: int) -> FixType:
    """The fix type of a GGA quality indicator, NO_FIX for a value NMEA does not define."""
    try:
        return FixType(quality)
    except ValueError:
        return FixType.NO_FIX
