"""Plausibility limits of NMEA fields, and a field reader that counts what it rejects (no I/O).

A field value is used only when it is present, well-formed, finite and inside the physical range
of its kind (``LIMITS``, inclusive, keyed by the pynmea2 / ``sentences`` field name, so one limit
serves every sentence with that field). Anything else is counted per ``<sentence>.<field>``
(``GST.std_dev_latitude``) and treated as absent. This keeps huge, tiny and non-finite values
out of the arithmetic: every published variance is positive and finite.
"""

from __future__ import annotations

import datetime
import math
from collections import Counter
from collections.abc import Callable
from typing import TypeVar

import pynmea2

from gnss_driver.sentences import (
    FieldError,
    date,
    integer,
    lat_lon_deg,
    number,
    sentence_id,
)

T = TypeVar("T", int, float)

KNOTS_TO_M_S = 1852.0 / 3600.0
#: Highest plausible speed over ground [m/s]: the COCOM export limit of GNSS receivers.
MAX_SPEED_M_S = 515.0
#: Smallest accepted standard deviation [m]: 0.1 mm, so its variance (1e-8 m²) stays positive.
MIN_SIGMA_M = 1e-4
#: Largest accepted standard deviation or distance quality figure [m].
MAX_SIGMA_M = 1e5
#: Dilutions of precision below this are not physical; 99.99 is the "no geometry" value.
MIN_DOP, MAX_DOP = 0.01, 99.99
#: Heights [m]: the Dead Sea shore is at -430 m; receivers stop at the 18 km COCOM altitude.
MIN_HEIGHT_M, MAX_HEIGHT_M = -1_000.0, 100_000.0
#: Years a GNSS date may hold (GPS time starts 1980-01-06).
MIN_YEAR, MAX_YEAR = 1980, 2099
SECONDS_PER_WEEK = 604_800.0

#: Field name -> (lowest, highest) accepted value, inclusive.
LIMITS: dict[str, tuple[float, float]] = {
    "gps_qual": (0, 9),
    "num_sats": (0, 99),
    "horizontal_dil": (MIN_DOP, MAX_DOP),
    "hdop": (MIN_DOP, MAX_DOP),
    "vdop": (MIN_DOP, MAX_DOP),
    "altitude": (MIN_HEIGHT_M, MAX_HEIGHT_M),
    "height": (MIN_HEIGHT_M, MAX_HEIGHT_M),
    "geo_sep": (-150.0, 150.0),  # EGM96 spans -107 m .. +86 m
    "rms": (0.0, MAX_SIGMA_M),
    "std_dev_major": (MIN_SIGMA_M, MAX_SIGMA_M),
    "std_dev_minor": (MIN_SIGMA_M, MAX_SIGMA_M),
    "std_dev_latitude": (MIN_SIGMA_M, MAX_SIGMA_M),
    "std_dev_longitude": (MIN_SIGMA_M, MAX_SIGMA_M),
    "std_dev_altitude": (MIN_SIGMA_M, MAX_SIGMA_M),
    "orientation": (-360.0, 360.0),
    "coord_quality": (MIN_SIGMA_M, MAX_SIGMA_M),
    "easting": (-1e8, 1e8),
    "northing": (-1e8, 1e8),
    "spd_over_grnd": (0.0, MAX_SPEED_M_S / KNOTS_TO_M_S),
    "spd_over_grnd_kts": (0.0, MAX_SPEED_M_S / KNOTS_TO_M_S),
    "spd_over_grnd_kmph": (0.0, MAX_SPEED_M_S * 3.6),
    "true_course": (0.0, 360.0),
    "true_track": (0.0, 360.0),
    "heading": (0.0, 360.0),
    "pitch": (-90.0, 90.0),
    "roll": (-180.0, 180.0),
    "mrms": (0.0, 100.0),
    "brms": (0.0, 100.0),
    "reset_flag": (0, 9),
    "time_of_week": (0.0, SECONDS_PER_WEEK),
    "day": (1, 31),
    "month": (1, 12),
    "year": (MIN_YEAR, MAX_YEAR),
}


def within_limits(name: str, value: float) -> bool:
    """Is ``value`` inside the limits of field ``name`` (any value when it has none)?"""
    low, high = LIMITS.get(name, (-math.inf, math.inf))
    return low <= value <= high


class FieldReader:
    """Typed, range-checked field access with counters.

    ``empty_fields`` counts required fields that were empty; ``rejected`` counts malformed or
    implausible values per ``<sentence>.<field>``.
    """

    def __init__(self) -> None:
        self.empty_fields = 0
        self.rejected: Counter[str] = Counter()

    @property
    def bad_fields(self) -> int:
        """All rejected values."""
        return self.rejected.total()

    def reject(self, sentence: pynmea2.NMEASentence, name: str) -> None:
        """Count a rejected value of field ``name``."""
        self.rejected[f"{sentence_id(sentence)}.{name}"] += 1

    def number(
        self, sentence: pynmea2.NMEASentence, name: str, *, required: bool = False
    ) -> float | None:
        """Field ``name`` as a float inside its limits; None when empty or rejected."""
        return self._checked(number, sentence, name, required)

    def integer(
        self, sentence: pynmea2.NMEASentence, name: str, *, required: bool = False
    ) -> int | None:
        """Field ``name`` as an int inside its limits; None when empty or rejected."""
        return self._checked(integer, sentence, name, required)

    def position(self, sentence: pynmea2.NMEASentence) -> tuple[float, float] | None:
        """(latitude, longitude) [deg]; None when empty (counted) or malformed (rejected)."""
        try:
            position = lat_lon_deg(sentence)
        except FieldError:
            self.reject(sentence, "lat_lon")
            return None
        if position is None:
            self.empty_fields += 1
        return position

    def date(self, sentence: pynmea2.NMEASentence) -> datetime.date | None:
        """The UTC date of an RMC / LLQ (``datestamp``) or ZDA (day, month, year) sentence."""
        if isinstance(sentence, pynmea2.ZDA):
            day, month, year = (self.integer(sentence, n) for n in ("day", "month", "year"))
            if day is None or month is None or year is None:
                return None
            try:
                return datetime.date(year, month, day)
            except ValueError:  # 31 April
                self.reject(sentence, "day")
                return None
        try:
            found = date(sentence, "datestamp")
        except FieldError:
            found = None
            self.reject(sentence, "datestamp")
        if found is not None and not MIN_YEAR <= found.year <= MAX_YEAR:
            self.reject(sentence, "datestamp")
            return None
        return found

    def _checked(
        self,
        read: Callable[[pynmea2.NMEASentence, str], T | None],
        sentence: pynmea2.NMEASentence,
        name: str,
        required: bool,
    ) -> T | None:
        try:
            value = read(sentence, name)
        except FieldError:
            self.reject(sentence, name)
            return None
        if value is None:
            if required:
                self.empty_fields += 1
            return None
        if not within_limits(name, value):
            self.reject(sentence, name)
            return None
        return value
