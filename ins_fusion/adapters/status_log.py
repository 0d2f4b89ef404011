"""What ins_fusion_node says on the console about its diagnostics (pure: no ROS).

``StatusLog.update`` compares each EngineStatus with the last one and returns the lines to log:
state changes (WARN into degraded, INFO otherwise), filter resets with the last reason, IMU stamps
that went back, IMU gaps beyond ``gap_rate_hz`` and each set-up warning of the engine once
(``EngineStatus.warnings``, e.g. a unit levelled upside down). Each kind is logged at most once per
``interval_s``; what happens in between is summed into the next line.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ins_fusion.core.engine.engine import EngineStatus

INFO, WARN = "info", "warning"


@dataclass
class StatusLog:
    """Turns successive statuses into rate-limited (level, message) console lines."""

    interval_s: float = 10.0
    gap_rate_hz: float = 0.5
    _state: str = ""
    _start_s: float | None = None
    _counts: dict[str, int] = field(default_factory=dict)
    _logged_at: dict[str, float] = field(default_factory=dict)
    _warnings: int = 0

    def _due(self, kind: str, count: int, now_s: float, min_rate_hz: float = 0.0) -> int:
        """Events of ``kind`` since its last line when a line is due and they come at least at
        ``min_rate_hz`` (over the time since that line, at least ``interval_s``); else 0."""
        new = count - self._counts.get(kind, 0)
        last = self._logged_at.get(kind)
        if new <= 0 or (last is not None and now_s - last < self.interval_s):
            return 0
        window = now_s - (last if last is not None else (self._start_s or now_s))
        if new < min_rate_hz * max(window, self.interval_s):
            return 0
        self._counts[kind], self._logged_at[kind] = count, now_s
        return new

    def update(self, status: EngineStatus, now_s: float) -> list[tuple[str, str]]:
        """Lines for what changed since the last call (``now_s``: a monotonic clock [s])."""
        if self._start_s is None:
            self._start_s = now_s
        lines: list[tuple[str, str]] = []
        if status.state != self._state:
            level = WARN if status.state == "degraded" else INFO
            was = f" (was {self._state})" if self._state else ""
            lines.append((level, f"state {status.state}{was}"))
            self._state = status.state
        if resets := self._due("resets", status.resets, now_s):
            lines.append((WARN, f"{resets} filter reset(s); last: {status.last_reset_reason}"))
        if back := self._due("back", status.imu_out_of_order, now_s):
            lines.append((WARN, f"{back} IMU sample(s) with a stamp before the previous one"))
        if gaps := self._due("gaps", status.imu_gaps, now_s, self.gap_rate_hz):
            lines.append((WARN, f"{gaps} IMU gap(s) (lost or implausible samples, bridged)"))
        lines += [(WARN, warning) for warning in status.warnings[self._warnings :]]
        self._warnings = len(status.warnings)
        return lines
