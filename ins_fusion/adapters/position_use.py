"""Why the fusion is degraded, in numbers, for its status (no ROS).

The engine goes 'degraded' when no GNSS position has been used for ``degraded_after_s``. The
status then says for how long and why: no fix came, the fixes that came were gated by the
innovation test, came too late, or were refused otherwise (the engine's counters of
GNSS positions), or the IMU was silent. ``PositionUse`` keeps the
counts at the last use and compares.
"""

from __future__ import annotations

from collections.abc import Mapping

#: What a state that leaves 'navigating' recovers from, by cause.
AFTER_GNSS_OUTAGE = "a GNSS outage"
AFTER_IMU_GAP = "an IMU gap"


class PositionUse:
    """The node's record of the last GNSS position the engine used (monotonic seconds)."""

    def __init__(self, now_s: float) -> None:
        self._at_use: dict[str, int] = {}  # the counters when the last position was used
        self._used_at_s = now_s
        self._fixes_at_use = 0
        self._imu_gap_at_s: float | None = None

    def update(self, counters: Mapping[str, int], fixes_received: int, now_s: float) -> None:
        """The engine's ``gnss_position`` counters and the fixes the node received so far."""
        if counters.get("used", 0) != self._at_use.get("used", 0):
            self._at_use = dict(counters)
            self._used_at_s = now_s
            self._fixes_at_use = fixes_received

    def imu_gap(self, now_s: float) -> None:
        """The IMU fell silent at ``now_s``."""
        self._imu_gap_at_s = now_s

    def cause(self) -> str:
        """What the state recovers from: an IMU gap since the last position used, or else a GNSS
        outage."""
        gap = self._imu_gap_at_s
        return AFTER_IMU_GAP if gap is not None and gap >= self._used_at_s else AFTER_GNSS_OUTAGE

    def degraded(self, counters: Mapping[str, int], fixes_received: int, now_s: float) -> str:
        """The status message of the 'degraded' state: for how long no position was used, and
        why."""
        since_s = now_s - self._used_at_s
        fixes = fixes_received - self._fixes_at_use
        if self.cause() == AFTER_IMU_GAP:
            why = "the IMU was silent"
        elif fixes <= 0:
            why = "no GNSS fix received"
        else:
            gated, too_old, rejected = (
                counters.get(k, 0) - self._at_use.get(k, 0)
                for k in ("gated", "too_old", "rejected")
            )
            other = rejected - gated - too_old  # fix type, covariance
            refused = [
                text
                for count, text in (
                    (gated, f"{gated} gated by the innovation test"),
                    (too_old, f"{too_old} too old"),
                    (other, f"{other} refused (fix type, covariance)"),
                )
                if count > 0
            ]
            why = f"{fixes} fixes received: " + (", ".join(refused) or "none taken yet")
        return f"degraded: no GNSS position used for {since_s:.0f} s ({why})"
