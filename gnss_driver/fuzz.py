"""Valid-checksum NMEA sentences with arbitrary field values, for robustness tests (no I/O).

``TEMPLATES`` holds one well-formed sentence body per type the driver reads; ``mutate`` replaces
some of its fields (and may drop or add trailing ones) and ``frame_sentence`` gives it a correct
checksum, so the reader passes it on and only the field checks stand between the value and the
arithmetic. ``FuzzSource`` draws such sentences from a seeded ``random.Random`` (the bench and
the live pty fuzz); the property tests draw them with hypothesis from the same templates and
``SPECIAL_VALUES``.
"""

from __future__ import annotations

import math
import random
import string

from gnss_driver.driver import EpochOutput
from gnss_driver.fix_type import VALID_FIX_TYPES
from gnss_driver.plausibility import MAX_SPEED_M_S
from gnss_driver.reader import frame_sentence

#: One valid body (no ``$``, no checksum) per sentence type, all of 12:35:19 UTC.
TEMPLATES: tuple[str, ...] = (
    "GPGGA,123519.00,4807.038,N,01131.000,W,1,08,0.9,545.4,M,46.9,M,,",
    "GPRMC,123519.00,A,4807.038,N,01131.000,W,022.4,084.4,230394,003.1,W,A",
    "GPGST,123519.00,0.006,0.023,0.020,273.6,0.023,0.020,0.031",
    "GPZDA,123519.00,23,03,1994,00,00",
    "GPVTG,054.7,T,034.4,M,005.5,N,010.2,K,A",
    "GPHDT,274.07,T",
    "GNGNS,123519.00,4807.038,N,01131.000,W,AAN,12,0.9,545.4,46.9,,",
    "GPGLL,4807.038,N,01131.000,W,123519.00,A,A",
    "GPGSA,A,3,04,05,,09,12,,,24,,,,,2.5,1.3,2.1",
    "PASHR,PAT,123519.00,4807.038,N,01131.000,W,+00545.40,274.07,+01.00,-02.00,0.0021,0.0123,0",
    "PASHR,ATT,218137.0,274.07,+01.00,-02.00,0.0021,0.0123,0",
    "GPLLQ,123519.00,032394,651234.567,M,6212345.678,M,3,12,0.025,76.69,M",
)

#: Field values that broke or strained parsers before: empty, signs, non-finite, huge, tiny,
#: overflowing integers, letters where numbers belong and numbers where letters belong.
SPECIAL_VALUES: tuple[str, ...] = (
    "",
    " ",
    "0",
    "-0",
    "00",
    "-1",
    "0.000",
    "1e-200",
    "1e200",
    "-1e200",
    "1e306",
    "1e309",
    "nan",
    "NaN",
    "inf",
    "-inf",
    "Infinity",
    "1" + "0" * 20,
    "9" * 40,
    "235960",
    "246060.00",
    "123519.1234567",
    "320299",
    "999999",
    "4807.038",
    "9999.999",
    "18000.000",
    "+",
    "-",
    ".",
    "1..2",
    "0x1F",
    "A",
    "V",
    "N",
    "S",
    "W",
    "E",
    "T",
    "M",
    "K",
    "ATT",
    "PAT",
)

#: Printable ASCII a field may hold: no ``,`` (field separator), ``*`` or ``$`` (framing).
FIELD_CHARACTERS = "".join(c for c in string.printable[:95] if c not in ",*$")


def fields_of(template: str) -> list[str]:
    """The comma-separated fields of a body (the address first)."""
    return template.split(",")


def build(fields: list[str]) -> bytes:
    """A framed sentence with a correct checksum from its fields."""
    return frame_sentence(",".join(fields))


class FuzzSource:
    """Seeded generator of fuzzed, valid-checksum sentences (see the module docstring)."""

    def __init__(self, seed: int = 0) -> None:
        self.rng = random.Random(seed)

    def value(self) -> str:
        """One field value: a special value, a random number or random printable text."""
        rng = self.rng
        kind = rng.random()
        if kind < 0.4:
            return rng.choice(SPECIAL_VALUES)
        if kind < 0.7:
            return f"{rng.uniform(-9.99, 9.99):.3f}e{rng.randint(-320, 320)}"
        if kind < 0.85:
            return str(rng.randint(-(10**25), 10**25))
        return "".join(rng.choices(FIELD_CHARACTERS, k=rng.randint(1, 12)))

    def sentence(self) -> bytes:
        """A template with 1 to 3 fields replaced, sometimes cut short or extended."""
        rng = self.rng
        fields = fields_of(rng.choice(TEMPLATES))
        first = 2 if fields[0] == "PASHR" else 1  # keep the address (and the PASHR subtype)
        for _ in range(rng.randint(1, 3)):
            fields[rng.randrange(first, len(fields))] = self.value()
        shape = rng.random()
        if shape < 0.05:
            del fields[rng.randrange(first, len(fields)) :]
        elif shape < 0.1:
            fields.append(self.value())
        return build(fields)


def output_problems(out: EpochOutput) -> list[str]:
    """What is wrong with a published epoch: non-finite values, covariances that are not
    positive (semi-)definite, speeds above ``MAX_SPEED_M_S``; empty when it is sound."""
    problems = []
    if not math.isfinite(out.stamp_s):
        problems.append(f"stamp {out.stamp_s}")
    fix = out.fix
    if fix is not None and fix.fix_type in VALID_FIX_TYPES:
        ee, en, nn, up = fix.cov_enu_m2[0], fix.cov_enu_m2[1], fix.cov_enu_m2[4], fix.cov_enu_m2[8]
        if not (abs(fix.lat_deg) <= 90.0 and abs(fix.lon_deg) <= 180.0):
            problems.append(f"position {fix.lat_deg}, {fix.lon_deg}")
        if not all(math.isfinite(c) for c in fix.cov_enu_m2) or min(ee, nn, up) <= 0.0:
            problems.append(f"fix covariance {fix.cov_enu_m2}")
        elif en * en > ee * nn:
            problems.append(f"fix covariance not positive definite {fix.cov_enu_m2}")
        if math.isinf(fix.alt_m):
            problems.append(f"altitude {fix.alt_m}")
    vel = out.velocity
    if vel is not None:
        if not all(math.isfinite(v) for v in (*vel.vel_enu_m_s, *vel.cov_enu)):
            problems.append(f"velocity {vel}")
        elif math.hypot(*vel.vel_enu_m_s) > MAX_SPEED_M_S * (1.0 + 1e-9):
            problems.append(f"speed {vel.vel_enu_m_s}")
        if min(vel.cov_enu[0], vel.cov_enu[4]) <= 0.0:
            problems.append(f"velocity covariance {vel.cov_enu}")
    att = out.attitude
    if att is not None:
        quat = att.orientation.quat_enu_flu_xyzw
        cov = att.orientation.cov_rpy_rad2
        if not all(math.isfinite(v) for v in (*quat, *cov)) or abs(math.hypot(*quat) - 1) > 1e-9:
            problems.append(f"attitude {att}")
        elif min(cov[0], cov[4], cov[8]) <= 0.0:
            problems.append(f"attitude covariance {cov}")
    return problems
