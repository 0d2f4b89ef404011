"""Proprietary NMEA sentences as pynmea2 classes, and typed access to sentence fields.

Importing this module registers, the pynmea2 way (class definition through its metaclass):

- ``ASHRPAT``: Ashtech ``$PASHR,PAT``, the ADU5 position and attitude sentence; fields in the
  order of imu400cc-aalborg-notes.md §7.3 (Fig. F-5, [Thales 2000, p. 98]).
- ``ASHRATT``: Ashtech ``$PASHR,ATT`` as the ADU5 sends it: GPS seconds of week, heading, pitch,
  roll, MRMS, BRMS, reset flag [external: Ashtech ADU2/ADU5 manuals, the same order as
  pynmeagps' ``ASHRATT`` table]. pynmea2 1.19 registers its ``ASHRATT`` (the RT300
  ``$PASHR,hhmmss.ss,heading,T,...`` sentence, which has no ``ATT`` field) under the same key, so
  a real ``$PASHR,ATT`` would be misread with the time of week as the heading. This class takes
  over the ``ATT`` key; pynmea2 still parses RT300 sentences with its own class.
- ``ASHRACK`` / ``ASHRNAK``: the ``$PASHR,ACK*3D`` / ``$PASHR,NAK*30`` answers to ``$PASHS``.
- ``LLQ``: Leica Local Position and Quality, talker-independent (``GPLLQ``, ``GNLLQ``, ...):
  UTC time, date, grid easting, M, grid northing, M, GPS quality, satellites, coordinate
  quality [m], height, M (notes §7.2, [Leica 2002, App. E]). The date is ``mmddyy`` in Leica's
  own manuals (their example ``111414`` is 14 Nov 2014); Trimble documents ``ddmmyy`` for its
  copy of the sentence. We follow Leica.

pynmea2 returns an empty field as None (typed fields) or '' and a malformed one as the raw
string; the helpers below turn that into ``None`` for "empty" and ``FieldError`` for "malformed".
"""

from __future__ import annotations

import datetime
import math
import re
from decimal import Decimal

import pynmea2
from pynmea2.nmea_utils import timestamp
from pynmea2.types.proprietary import ash

SECONDS_PER_DAY = 86_400
MS_PER_DAY = SECONDS_PER_DAY * 1000


def _mmddyy(text: str) -> datetime.date:
    """Leica LLQ date ``mmddyy`` (two-digit years as ``strptime`` maps them: 69..99 -> 19xx)."""
    return datetime.datetime.strptime(text, "%m%d%y").date()


#: The attitude fields PAT and ATT share, in order (notes §7.3).
_ATTITUDE_FIELDS = (
    ("Heading (deg)", "heading", float),
    ("Pitch (deg)", "pitch", float),
    ("Roll (deg)", "roll", float),
    ("Attitude phase measurement RMS error MRMS (m)", "mrms", float),
    ("Attitude baseline length RMS error BRMS (m)", "brms", float),
    ("Attitude reset flag", "reset_flag", int),
)


class ASHRPAT(ash.ASH):  # type: ignore[misc]
    """``$PASHR,PAT``: ADU5 position of antenna 1 and attitude (notes §7.3, Fig. F-5).

    Angles in degrees in the ADU5 body reference frame (X right, Y forward, Z up): heading from
    true north, pitch about X, roll about Y. MRMS and BRMS in metres; reset flag 0 = good
    attitude, 1 = rough estimate or bad attitude.
    """

    fields = (
        ("R", "_r"),
        ("Subtype", "subtype"),
        ("UTC time of position", "timestamp", timestamp),
        ("Latitude", "lat"),
        ("Latitude Direction", "lat_dir"),
        ("Longitude", "lon"),
        ("Longitude Direction", "lon_dir"),
        ("Altitude (m)", "altitude", float),
        *_ATTITUDE_FIELDS,
    )


class ASHRATT(ash.ASH):  # type: ignore[misc]
    """``$PASHR,ATT``: ADU5 attitude stamped with GPS seconds of week (see the module doc)."""

    fields = (
        ("R", "_r"),
        ("Subtype", "subtype"),
        ("GPS time of week (s)", "time_of_week", float),
        *_ATTITUDE_FIELDS,
    )


class ASHRACK(ash.ASH):  # type: ignore[misc]
    """``$PASHR,ACK``: the receiver accepted the last ``$PASHS`` command (notes §7.3)."""

    fields = (("R", "_r"), ("Subtype", "subtype"))


class ASHRNAK(ash.ASH):  # type: ignore[misc]
    """``$PASHR,NAK``: the receiver rejected the last ``$PASHS`` command."""

    fields = (("R", "_r"), ("Subtype", "subtype"))


class LLQ(pynmea2.TalkerSentence):  # type: ignore[misc]
    """``$--LLQ``: Leica Local Position and Quality (see the module doc).

    GPS quality: 0 invalid, 1 navigation fix without real-time corrections, 2 real-time
    position with float ambiguities, 3 real-time position with fixed ambiguities.
    """

    fields = (
        ("UTC time of position", "timestamp", timestamp),
        ("UTC date mmddyy", "datestamp", _mmddyy),
        ("Grid easting (m)", "easting", float),
        ("Easting unit", "easting_unit"),
        ("Grid northing (m)", "northing", float),
        ("Northing unit", "northing_unit"),
        ("GPS quality", "gps_qual", int),
        ("Satellites used", "num_sats", int),
        ("Coordinate quality (m)", "coord_quality", float),
        ("Height (m)", "height", float),
        ("Height unit", "height_unit"),
    )


class FieldError(ValueError):
    """A field is present but cannot be read as the value it should hold."""


def number(sentence: pynmea2.NMEASentence, name: str) -> float | None:
    """Field ``name`` as a finite float; None when empty, FieldError when malformed."""
    value = getattr(sentence, name)
    if value is None or value == "":
        return None
    if isinstance(value, bool) or not isinstance(value, int | float | Decimal | str):
        raise FieldError(f"{name}={value!r}")
    try:
        result = float(value)
    except ValueError as exc:
        raise FieldError(f"{name}={value!r}") from exc
    if not math.isfinite(result):
        raise FieldError(f"{name}={value!r}")
    return result


#: An NMEA integer field's text.
_INTEGER = re.compile(r"[+-]?\d+")


def integer(sentence: pynmea2.NMEASentence, name: str) -> int | None:
    """Field ``name`` as an int; None when empty, FieldError when malformed."""
    value = getattr(sentence, name)
    if value is None or value == "":
        return None
    if isinstance(value, int) and not isinstance(value, bool):
        return value
    if isinstance(value, str) and _INTEGER.fullmatch(value.strip()):
        return int(value)
    raise FieldError(f"{name}={value!r}")


def text(sentence: pynmea2.NMEASentence, name: str) -> str | None:
    """Field ``name`` as stripped text; None when empty."""
    value = getattr(sentence, name)
    if value is None:
        return None
    result = str(value).strip()
    return result or None


def time_of_day_ms(sentence: pynmea2.NMEASentence, name: str = "timestamp") -> int | None:
    """UTC time-of-day field in milliseconds since midnight; None when empty."""
    value = getattr(sentence, name)
    if value is None or value == "":
        return None
    if not isinstance(value, datetime.time):
        raise FieldError(f"{name}={value!r}")
    seconds = (value.hour * 60 + value.minute) * 60 + value.second
    return seconds * 1000 + round(value.microsecond / 1000)


def date(sentence: pynmea2.NMEASentence, name: str = "datestamp") -> datetime.date | None:
    """Date field; None when empty, FieldError when malformed."""
    value = getattr(sentence, name)
    if value is None or value == "":
        return None
    if not isinstance(value, datetime.date):
        raise FieldError(f"{name}={value!r}")
    return value


#: An NMEA ddmm.mmmm / dddmm.mmmm coordinate: whole degrees, minutes.
_DEGREES_MINUTES = re.compile(r"(\d+)(\d\d(?:\.\d+)?)")


def _angle(
    dm: str | None, hemisphere: str | None, positive: str, negative: str, limit: float
) -> float | None:
    if dm is None and hemisphere is None:
        return None
    if dm is None or hemisphere not in (positive, negative):
        raise FieldError(f"coordinate {dm!r} {hemisphere!r}")
    match = _DEGREES_MINUTES.fullmatch(dm)
    if match is None or float(match.group(2)) >= 60.0:
        raise FieldError(f"coordinate {dm!r}")
    degrees = int(match.group(1)) + float(match.group(2)) / 60.0
    if degrees > limit:
        raise FieldError(f"coordinate {dm!r} beyond {limit} deg")
    return -degrees if hemisphere == negative else degrees


def lat_lon_deg(sentence: pynmea2.NMEASentence) -> tuple[float, float] | None:
    """(latitude, longitude) in signed degrees (north, east positive) from ``ddmm.mmm,N`` fields.

    None when all four fields are empty; FieldError when only some are present or a value is
    out of range (pynmea2's ``LatLonFix`` would return 0 for a missing hemisphere).
    """
    lat = _angle(text(sentence, "lat"), text(sentence, "lat_dir"), "N", "S", 90.0)
    lon = _angle(text(sentence, "lon"), text(sentence, "lon_dir"), "E", "W", 180.0)
    if lat is None and lon is None:
        return None
    if lat is None or lon is None:
        raise FieldError("latitude or longitude missing")
    return lat, lon


#: pynmea2's address regex reads any ``ttXXQ,`` address with data as a malformed query sentence
#: (``GPLLQ,...`` -> talker GP, listener LL, query), so such talker sentences are built here.
_QUERY_LOOKALIKE = re.compile(r"\$?([A-Z]{2})([A-Z]{2}Q),(.*)", re.DOTALL)


def parse(line: str) -> pynmea2.NMEASentence:
    """Parse one sentence (checksum, if any, NOT verified here) with pynmea2's registry.

    Raises pynmea2.SentenceTypeError for an unregistered talker sentence and other exceptions
    (pynmea2 raises ParseError, IndexError, ...) for malformed text.
    """
    match = _QUERY_LOOKALIKE.fullmatch(line.split("*", 1)[0])
    if match is not None:
        cls = pynmea2.TalkerSentence.sentence_types.get(match.group(2))
        if cls is not None:
            return cls(match.group(1), match.group(2), match.group(3).split(","))
    return pynmea2.parse(line, check=False)


def sentence_id(sentence: pynmea2.NMEASentence) -> str:
    """Short type name for counters: ``GGA``, ``LLQ``, ``PASHR,PAT``, ``PGRME``, ..."""
    if isinstance(sentence, pynmea2.TalkerSentence):
        return str(sentence.sentence_type)
    if isinstance(sentence, ash.ASH):
        # $PASHR,<subtype>,... except the RT300 attitude sentence, whose second field is a time.
        subtype = sentence.data[1] if len(sentence.data) > 1 else ""
        return f"PASHR,{subtype}" if subtype.isalpha() else "PASHR"
    if isinstance(sentence, pynmea2.ProprietarySentence):
        return f"P{sentence.manufacturer}"
    return type(sentence).__name__
