"""What the engine reports besides the solution: the counters of its measurement kinds and the
diagnostics snapshot (``EngineStatus``)."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

#: Counters kept per measurement kind ('rejected' includes 'gated' and 'too_old').
COUNTERS = ("used", "rejected", "gated", "too_old", "duplicates", "recoveries")

Counters = dict[str, dict[str, int]]
"""{measurement kind: {counter: n}} (the engine's kinds x COUNTERS)."""


def new_counters(kinds: Iterable[str]) -> Counters:
    """Every counter of each of ``kinds`` (names, core.engine.measurement_kinds) at zero."""
    return {name: dict.fromkeys(COUNTERS, 0) for name in kinds}


@dataclass(frozen=True)
class EngineStatus:
    """Diagnostics: state, per-measurement counters ({name: {counter: n}}, COUNTERS), resets
    with the reason of the last one, IMU samples/gaps/duplicate stamps/samples skipped for a
    stamp in the past (out of order) or a value beyond the unit's range (implausible, also
    counted as gaps), the last normalised
    innovation squared per measurement, rollbacks and re-propagated samples for late
    measurements, the stop detector's decision, and the noise the filter adapted to
    (``adapted``, flat names with units; InsEngine.adapted_noise) and the self-calibration
    (``calibration``; InsEngine.self_calibration); ``warnings``: set-up problems the data show
    (e.g. a unit levelled far from its configured mounting), each once, for the log;
    ``aligning``: what the alignment waits for while the state is 'aligning' (else empty)."""

    state: str
    measurements: Counters
    resets: int
    last_reset_reason: str
    imu_samples: int
    imu_gaps: int
    imu_duplicates: int
    imu_out_of_order: int
    imu_implausible: int
    nis: dict[str, float]
    rollbacks: int
    replayed_samples: int
    stationary: bool
    adapted: dict[str, float]
    calibration: dict[str, float]
    warnings: tuple[str, ...] = ()
    aligning: str = ""
