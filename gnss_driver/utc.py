"""Full UTC times from NMEA times of day: the date, midnight rollover, GPS time of week.

Most sentences carry only ``hhmmss.ss``. The date comes from the epoch's own RMC, ZDA or LLQ
when it has one; otherwise the last known date is carried on, advanced by a day when the time of
day falls back by more than half a day (midnight rollover). A receiver that never sends a date
(ADU5 PAT, a GGA-only receiver) gets the UTC date of the host clock nearest to the time of day.
"""

from __future__ import annotations

import datetime
from dataclasses import dataclass
from enum import StrEnum

from gnss_driver.sentences import MS_PER_DAY, SECONDS_PER_DAY

_UNIX_EPOCH = datetime.date(1970, 1, 1)
_HALF_DAY_MS = MS_PER_DAY // 2
_ONE_DAY = datetime.timedelta(days=1)
#: GPS weeks are counted in seconds from Sunday 00:00:00 GPS time.
SECONDS_PER_WEEK = 7 * SECONDS_PER_DAY


class DateSource(StrEnum):
    """Where the date of an epoch came from."""

    RECEIVER = "receiver"  # RMC / ZDA / LLQ in this epoch, or carried on from one
    HOST = "host"  # the host clock (the receiver never sent a date)


@dataclass(frozen=True, slots=True)
class UtcTime:
    """A resolved epoch time: seconds since 1970-01-01 UTC and where its date came from."""

    utc_s: float
    date_source: DateSource


def gps_time_of_week_to_time_of_day_ms(time_of_week_s: float, gps_utc_leap_s: int) -> int:
    """UTC time of day [ms] of a GPS time of week [s] (GPS time is ahead of UTC by the leap
    seconds: 18 s since 2017-01-01 [external: IERS Bulletin C])."""
    return round((time_of_week_s - gps_utc_leap_s) * 1000) % MS_PER_DAY


class UtcResolver:
    """Turns (time of day, optional date) into a full UTC time; see the module docstring."""

    def __init__(self) -> None:
        self.rollovers = 0
        self._date: datetime.date | None = None
        self._source = DateSource.HOST
        self._time_of_day_ms = 0

    def reset(self) -> None:
        """Forget the date (e.g. after a reconnect: the receiver may have been swapped)."""
        self._date = None

    def resolve(
        self, time_of_day_ms: int, date: datetime.date | None, host_time_s: float
    ) -> UtcTime:
        """Full UTC time of an epoch at ``time_of_day_ms`` [ms since midnight]; ``date`` is the
        epoch's own date if it had one, ``host_time_s`` the host clock [s since 1970, UTC]."""
        if date is not None:
            self._source = DateSource.RECEIVER
        elif self._date is not None:
            date = self._date
            if time_of_day_ms < self._time_of_day_ms - _HALF_DAY_MS:
                date += _ONE_DAY
                self.rollovers += 1
            elif time_of_day_ms > self._time_of_day_ms + _HALF_DAY_MS:
                date -= _ONE_DAY  # a late epoch from before midnight
        else:
            host_day = datetime.date.fromordinal(
                _UNIX_EPOCH.toordinal() + int(host_time_s // SECONDS_PER_DAY)
            )
            date = min(
                (host_day - _ONE_DAY, host_day, host_day + _ONE_DAY),
                key=lambda d: abs(_utc_s(d, time_of_day_ms) - host_time_s),
            )
            self._source = DateSource.HOST
        self._date = date
        self._time_of_day_ms = time_of_day_ms
        return UtcTime(_utc_s(date, time_of_day_ms), self._source)


def _utc_s(date: datetime.date, time_of_day_ms: int) -> float:
    return (date - _UNIX_EPOCH).days * SECONDS_PER_DAY + time_of_day_ms / 1000.0
