"""NMEA sentence bodies of one receiver position, to be framed with
``gnss_driver.reader.frame_sentence``."""

from __future__ import annotations

#: 545.4 m above mean sea level + 46.9 m geoid separation.
ALT = 592.3


def gga(second: int, quality: int = 1, sats: str = "08") -> str:
    return f"GPGGA,1235{second:02d}.00,4807.038,N,01131.000,E,{quality},{sats},0.9,545.4,M,46.9,M,,"


def gns(second: int, sats: str = "11") -> str:
    return f"GNGNS,1235{second:02d}.00,4807.038,N,01131.000,E,AA,{sats},0.9,545.4,46.9,,"


def rmc(second: int) -> str:
    return f"GPRMC,1235{second:02d}.00,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W,A"


def gll(second: int) -> str:
    return f"GPGLL,4807.038,N,01131.000,E,1235{second:02d}.00,A,A"


#: GPS satellites 04 05 09 12 24 and GLONASS 65 66 used: 7 (NMEA 0183 4.10, one GSA a system).
GSA_GPS = "GPGSA,A,{},04,05,09,12,24,,,,,,,,2.5,1.3,2.1"


GSA_GLONASS = "GLGSA,A,{},65,66,,,,,,,,,,,2.5,1.3,2.1"
