"""The system's health in one view (no rclpy): the latest /diagnostics status of each process of
the vehicle, their restarts (``supervisor.json``, written by ``gnss_ins launch``), one level.

``gnss_ins status`` and its ``--serve`` mode (the aggregate on /gnss_ins/status) feed ``Health``
with every status they receive and ask it for ``view``: per process its level (OK, WARN, ERROR,
or STALE when its last status is older than STALE_AFTER_S or none came), message, age, restarts
and the few values an operator reads (rate against the expected one, fix type, the fusion's state
and σ, the recording's file and free disk). The system's level is the worst of them.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ins_fusion.core.measurements.gnss_position import POSITION
from ins_fusion.runtime.processes import gnss_ins_command

#: The values a recorder's row shows (the vehicle's and one started by hand).
RECORDER_VALUES = ("bag", "files", "messages", "free_bytes", "min_free_bytes")
#: Levels of diagnostic_msgs/DiagnosticStatus, in order of severity.
LEVELS = ("OK", "WARN", "ERROR", "STALE")
OK, WARN, ERROR, STALE = range(4)
#: A process whose last status is older than this is STALE (the nodes report every second).
STALE_AFTER_S = 3.0
#: The topic of the aggregate, and the supervised process that publishes it.
STATUS_TOPIC = "/gnss_ins/status"
STATUS_PROCESS = "status"
#: The supervisor's state file in launch's log directory.
SUPERVISOR_FILE = "supervisor.json"
#: The vehicle's processes: status name prefix -> the values shown, in order.
SHOWN: dict[str, tuple[str, ...]] = {
    "imu400cc_node": ("rate_hz", "expected_rate_hz", "packets", "dropped_packets", "reconnects"),
    "leica_gnss": (
        "last_fix_type",
        "satellites",
        "horizontal_sigma_m",
        "rate_hz",
        "expected_rate_hz",
        "reconnects",
        "rtcm_frames_written",
        "rtcm_age_s",
    ),
    "adu5_gnss": (
        "last_fix_type",
        "satellites",
        "horizontal_sigma_m",
        "rate_hz",
        "expected_rate_hz",
        "attitudes",
        "reconnects",
    ),
    "ins_fusion_node": (
        "state",
        "horizontal_sigma_m",
        f"{POSITION.name}.used",
        "imu_silent_s",
        "resets",
        "outputs_invalid",
    ),
    "recorder": RECORDER_VALUES,
    # a `gnss_ins record` started by hand beside the vehicle's: a row of its own
    "gnss_ins_record": RECORDER_VALUES,
    "ntrip_client": (
        "caster_state",
        "http_status",
        "corrections_age_s",
        "bytes_per_s",
        "frames_per_s",
        "crc_failures",
        "non_rtcm_bytes",
        "gga_sent",
        "reconnects",
        "rover_solution",
    ),
}
#: Processes expected without a supervisor file (the vehicle's four nodes).
DEFAULT_EXPECTED = ("imu400cc_node", "leica_gnss", "adu5_gnss", "ins_fusion_node")


@dataclass(frozen=True)
class Status:
    """One received DiagnosticStatus, as plain values, and when it arrived (monotonic s)."""

    name: str
    level: int
    message: str
    values: Mapping[str, str]
    received_s: float

    @property
    def process(self) -> str:
        """The process the status is about (its name's prefix before ':', the node's name)."""
        return self.name.split(":", 1)[0]


@dataclass
class Health:
    """The latest status of each process and the supervisor's counts."""

    expected: tuple[str, ...] = DEFAULT_EXPECTED
    latest: dict[str, Status] = field(default_factory=dict)
    #: process -> its supervisor entry (pid, restarts, running), from ``supervisor.json``
    supervised: dict[str, dict[str, Any]] = field(default_factory=dict)

    def add(self, status: Status) -> None:
        """A status received; the process's earlier one is replaced."""
        if status.process in SHOWN:
            self.latest[status.process] = status

    def read_supervisor(self, log_dir: Path) -> None:
        """The supervisor's state in ``log_dir``, if launch writes one there: its processes are
        then the expected ones."""
        try:
            state = json.loads((log_dir / SUPERVISOR_FILE).read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return
        processes = state.get("processes") if isinstance(state, dict) else None
        if isinstance(processes, dict):
            self.supervised = {str(k): v for k, v in processes.items() if isinstance(v, dict)}
            self.expected = tuple(name for name in self.supervised if name in SHOWN)

    def unheard(self) -> list[str]:
        """The expected processes not known to have ended that have sent no status since their
        (re)start: a look should listen longer before it calls them silent."""
        return [
            name
            for name in self.expected
            if self.supervised.get(name, {}).get("running") is not False
            and (name not in self.latest or self._restarted_since(name) is not None)
        ]

    def _restarted_since(self, name: str) -> float | None:
        """When the running process started (monotonic s) if its latest status is from the
        process before it, else None."""
        status, started_s = self.latest.get(name), self.supervised.get(name, {}).get("started_s")
        if status is None or not isinstance(started_s, int | float):
            return None
        return float(started_s) if status.received_s < started_s else None

    def view(self, now_s: float) -> dict[str, Any]:
        """The system's state at monotonic ``now_s``: its level and one entry per process (the
        expected ones, then any other that reported)."""
        names = [*self.expected, *(n for n in self.latest if n not in self.expected)]
        processes = {name: self._entry(name, now_s) for name in names}
        worst = max((LEVELS.index(p["level"]) for p in processes.values()), default=STALE)
        return {"level": LEVELS[worst], "processes": processes}

    def _entry(self, name: str, now_s: float) -> dict[str, Any]:
        status = self.latest.get(name)
        supervised = self.supervised.get(name, {})
        entry: dict[str, Any] = {"restarts": supervised.get("restarts")}
        if supervised.get("running") is False:  # ended, launch restarts it (or gave up)
            entry.update(level=LEVELS[ERROR], message="not running", age_s=None, values={})
            return entry
        if (started_s := self._restarted_since(name)) is not None:
            # The process before the restart said it: nothing of the running one yet.
            since_s = now_s - started_s
            level = STALE if since_s > STALE_AFTER_S else WARN
            message = f"restarted {since_s:.0f} s ago, no status since"
            entry.update(level=LEVELS[level], message=message, age_s=None, values={})
            return entry
        if status is None:
            entry.update(level=LEVELS[STALE], message="no status received", age_s=None, values={})
            return entry
        age_s = now_s - status.received_s
        level = STALE if age_s > STALE_AFTER_S else min(status.level, ERROR)
        message = status.message if level != STALE else f"silent for {age_s:.0f} s"
        values = {key: status.values[key] for key in SHOWN[name] if key in status.values}
        entry.update(level=LEVELS[level], message=message, age_s=round(age_s, 2), values=values)
        return entry


def exit_code(view: Mapping[str, Any]) -> int:
    """0 when the system is OK, 1 when something warns, 2 when an error or a silence."""
    return min(LEVELS.index(view["level"]), 2)


def format_view(view: Mapping[str, Any], title: str) -> str:
    """One screen: the system's level, then a line per process."""
    lines = [f"{title}   system: {view['level']}"]
    width = max([len("process"), *(len(name) for name in view["processes"])])
    lines.append(f"  {'process':<{width}}  {'level':<5}  {'age s':>5}  {'restarts':>8}  message")
    for name, entry in view["processes"].items():
        age = "-" if entry["age_s"] is None else f"{entry['age_s']:.1f}"
        restarts = "-" if entry["restarts"] is None else str(entry["restarts"])
        lines.append(
            f"  {name:<{width}}  {entry['level']:<5}  {age:>5}  {restarts:>8}  {entry['message']}"
        )
        if entry["values"]:
            shown = ", ".join(f"{key} {value}" for key, value in entry["values"].items())
            lines.append(f"  {'':<{width}}  {shown}")
    return "\n".join(lines)


def status_command(log_dir: Path | None) -> list[str]:
    """``gnss_ins status --serve``, reading the supervisor file in ``log_dir`` if given."""
    options = ["--log-dir", str(log_dir)] if log_dir is not None else []
    return gnss_ins_command("status", "--serve", *options)


def write_whole(path: Path, text: str) -> None:
    """``path`` holds ``text`` or what it held before, never a part: a hidden scratch file
    renamed over it (not synced: for state files a power cut may lose, never half-write)."""
    scratch = path.with_name(f".{path.name}.writing")
    scratch.write_text(text, encoding="utf-8")
    os.replace(scratch, path)


def write_supervisor_state(log_dir: Path, processes: Mapping[str, Mapping[str, Any]]) -> None:
    """``supervisor.json`` in ``log_dir`` (whole or not at all): pid, restarts and running of
    each supervised process."""
    write_whole(log_dir / SUPERVISOR_FILE, json.dumps({"processes": processes}, indent=1))
