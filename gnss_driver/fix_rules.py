"""What receivers leave out of a fix, and how the solver completes it (no ROS).

- **Satellites used not reported.** NMEA 0183 GGA's and GNS's "number of satellites in use"
  is 00 … 12 (GNS 00 … 99); some receivers (Garmin, Furuno) write ``00`` or leave it empty
  beside a valid fix when they do not report it. A count of 0 or none beside a valid fix is
  "not reported": the count is taken from the epoch's GNS (for a GGA), else from the GSA
  sentences that arrived while the epoch was open (the satellite IDs they list as used, summed
  over one GSA per constellation, NMEA 0183 4.10); else it stays unreported and
  ``min_satellites`` is not applied to it.
- **2-D fixes.** A fix is 2-D when the epoch's GSA says mode 2 (NMEA 0183 GSA field 2:
  1 no fix, 2 2-D, 3 3-D), else when 3 satellites are used (3 pseudoranges solve the
  horizontal position and the clock with the height held: a 3-D fix needs 4), else when its
  only position sentence is RMC or GLL (no height) and no recent altitude is held (below).
  With ``allow_2d_fix`` it is published as a fix whose height is unknown: altitude NaN and
  vertical variance ``HEIGHT_UNKNOWN_VARIANCE_M2`` (gnss_ins_common.navsat); it needs
  ``min_satellites - 1`` satellites (one unknown fewer). Without it, it is NO_FIX.
- **Held altitude.** An epoch whose position comes from RMC or GLL (no height field) takes the
  altitude of the last 3-D fix at most ``HOLD_MAX_MS`` before it, with the vertical variance
  grown by (``HOLD_VERTICAL_RATE_M_S`` × age)²; otherwise the fix is 2-D.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import pynmea2

from gnss_driver.sentences import MS_PER_DAY, text

#: Satellites a 3-D fix needs (latitude, longitude, height and the clock).
SATELLITES_3D = 4
#: GSA fix modes (NMEA 0183 GSA field 2).
GSA_MODE_2D, GSA_MODE_3D = 2, 3
#: An RMC/GLL epoch holds the altitude of a 3-D fix at most this much older [ms].
HOLD_MAX_MS = 2000
#: Growth of a held altitude's σ with its age [m/s]: a road vehicle's climb rate, 40 m/s on a
#: 5 % grade [our choice].
HOLD_VERTICAL_RATE_M_S = 2.0
_GSA_IDS = tuple(f"sv_id{k:02d}" for k in range(1, 13))


def gsa_satellites(gsas: Sequence[pynmea2.GSA]) -> int | None:
    """Satellites used that the GSA sentences list (their non-empty ID fields); None when none
    lists any."""
    used = sum(1 for gsa in gsas for name in _GSA_IDS if text(gsa, name) is not None)
    return used or None


def gsa_mode(gsas: Sequence[pynmea2.GSA]) -> int | None:
    """The best fix mode (1 no fix, 2 2-D, 3 3-D) the GSA sentences state, None if none does."""
    if not gsas:  # most receivers' epochs (cheap: run for every fix)
        return None
    modes = [text(gsa, "mode_fix_type") for gsa in gsas]
    valid = [int(m) for m in modes if m in ("1", "2", "3")]
    return max(valid) if valid else None


def is_2d(gsa_fix_mode: int | None, satellites: int | None) -> bool:
    """Is a valid fix 2-D by its epoch's GSA mode, else by 3 satellites used?"""
    if gsa_fix_mode is not None and gsa_fix_mode >= GSA_MODE_2D:
        return gsa_fix_mode == GSA_MODE_2D
    return satellites == SATELLITES_3D - 1


@dataclass(frozen=True, slots=True)
class HeldAltitude:
    """The altitude of the last 3-D fix: time of day [ms], ellipsoidal height [m], its
    vertical variance [m²]."""

    time_ms: int
    alt_m: float
    var_up_m2: float

    def at(self, time_ms: int) -> tuple[float, float] | None:
        """(altitude [m], grown vertical variance [m²]) for an epoch at ``time_ms``, None when
        the fix is more than ``HOLD_MAX_MS`` older (or newer: a clock jump)."""
        age_ms = (time_ms - self.time_ms) % MS_PER_DAY
        if age_ms > HOLD_MAX_MS:
            return None
        grown = HOLD_VERTICAL_RATE_M_S * age_ms / 1000.0
        return self.alt_m, self.var_up_m2 + grown * grown
