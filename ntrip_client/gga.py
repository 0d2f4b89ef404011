"""The GGA sentences a client sends to the caster (NTRIP 2.0 §2.2: the rover's position, for a
VRS or the nearest base): a position out of one, a GGA for a fixed position, when to send."""

from __future__ import annotations

import pynmea2

from gnss_driver.reader import frame_sentence

#: The fastest a client may send GGA upstream [s] (casters drop clients sending faster).
MIN_GGA_INTERVAL_S = 1.0
_DAY_S = 86400


def read_gga(sentence: str) -> tuple[int, tuple[float, float] | None] | None:
    """The quality indicator of a GGA sentence whose checksum holds, and its (lat, lon) [deg]
    when it has a fix (quality > 0) and a position; None for any other sentence."""
    try:
        msg = pynmea2.parse(sentence.strip(), check=True)
        if not isinstance(msg, pynmea2.GGA) or msg.gps_qual is None:
            return None
        quality = int(msg.gps_qual)
        if quality <= 0 or not msg.lat or not msg.lon:
            return quality, None
        return quality, (float(msg.latitude), float(msg.longitude))
    except (ValueError, TypeError):  # pynmea2's ParseError and ChecksumError are ValueErrors
        return None


def gga_quality(sentence: str) -> int | None:
    """The quality indicator of a GGA sentence whose checksum holds (``read_gga``)."""
    read = read_gga(sentence)
    return None if read is None else read[0]


def gga_position(sentence: str) -> tuple[float, float] | None:
    """(lat, lon) [deg] of a GGA sentence with a valid checksum and a fix (``read_gga``)."""
    read = read_gga(sentence)
    return None if read is None else read[1]


def _angle(value_deg: float, degree_digits: int) -> str:
    """``value_deg`` as NMEA (d)ddmm.mmmmm, its absolute value."""
    total = round(abs(value_deg) * 60 * 100_000)  # [1e-5 arc minutes], rounded once
    degrees, rest = divmod(total, 60 * 100_000)
    return f"{degrees:0{degree_digits}d}{rest / 100_000:08.5f}"


def fixed_gga(lat_deg: float, lon_deg: float, height_m: float, utc_s: float) -> bytes:
    """A GGA (quality 1, 12 satellites, HDOP 1.0) for a known position, for a caster that wants
    one before the rover's first fix. ``height_m`` is written as the altitude with a geoid
    separation of 0; ``utc_s`` is a UTC time [s] (POSIX time or seconds of the day)."""
    centiseconds = round(utc_s * 100) % (_DAY_S * 100)
    hours, rest = divmod(centiseconds, 3600 * 100)
    minutes, rest = divmod(rest, 60 * 100)
    body = (
        f"GPGGA,{hours:02d}{minutes:02d}{rest / 100:05.2f},"
        f"{_angle(lat_deg, 2)},{'N' if lat_deg >= 0 else 'S'},"
        f"{_angle(lon_deg, 3)},{'E' if lon_deg >= 0 else 'W'},"
        f"1,12,1.0,{height_m:.3f},M,0.000,M,,"
    )
    return frame_sentence(body)


class GgaSchedule:
    """When to send the next GGA: the first as soon as one is available after connecting, then
    every ``interval_s``, and never two within ``MIN_GGA_INTERVAL_S`` (across reconnects too)."""

    def __init__(self, interval_s: float) -> None:
        """ValueError for an interval under ``MIN_GGA_INTERVAL_S`` [s]."""
        if not interval_s >= MIN_GGA_INTERVAL_S:
            raise ValueError(
                f"GGA interval {interval_s} s: at least {MIN_GGA_INTERVAL_S:.0f} s (casters drop"
                " clients that send their position faster)"
            )
        self.interval_s = interval_s
        self._last_s: float | None = None
        self._sent_on_connection = False

    def connected(self) -> None:
        """A new connection: its first GGA is due at once (within the 1 s limit)."""
        self._sent_on_connection = False

    def due(self, now_s: float) -> bool:
        """Whether a GGA should be sent at monotonic time ``now_s`` [s]."""
        if self._last_s is None:
            return True
        wait_s = self.interval_s if self._sent_on_connection else MIN_GGA_INTERVAL_S
        return now_s - self._last_s >= wait_s

    def sent(self, now_s: float) -> None:
        """A GGA went out at ``now_s`` [s]."""
        self._last_s = now_s
        self._sent_on_connection = True
