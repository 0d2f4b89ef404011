"""Silent processes of ``gnss_ins launch``: a process that stops reporting on /diagnostics (hung
in a call, deadlocked, stopped) without ending is killed, so that the supervisor starts it again.

The status server (``gnss_ins status --serve``, started by launch) hears every /diagnostics
status. Every second it writes ``heard.json`` in launch's log directory (``write_heard``): when
it wrote, since when it listens, and when each process's last status arrived, all in monotonic
seconds (CLOCK_MONOTONIC: one clock for every process of the machine, unmoved by a clock set
from GNSS or NTP). ``silent`` reads that against each supervised process's start:

- a process that has reported since its start is silent when its last status is older than
  ``after_s`` (the nodes report every second);
- one that has not reported since its start gets ``START_GRACE_S`` first (after an install or
  an update the fusion node compiles its kernels for minutes before its first status);
- nothing is decided about the nodes while ``heard.json`` is older than ``FRESH_S`` or the
  server has listened for less than ``after_s``: a server that stopped hearing must not get every
  node killed. The server itself is silent when its file is older than ``after_s``; a file
  dated after now (written before a reboot: monotonic time starts again) counts as none.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from ins_fusion.runtime.health import write_whole

#: The status server's file in launch's log directory.
HEARD_FILE = "heard.json"
#: Older than this [s], heard.json says nothing about the nodes.
FRESH_S = 3.0
#: Seconds a (re)started process has for its first status.
START_GRACE_S = 300.0


@dataclass(frozen=True)
class Heard:
    """What the status server heard, in monotonic seconds: when it wrote this, since when it
    listens, and process -> when its last status arrived."""

    written_s: float
    since_s: float
    last_status_s: Mapping[str, float]


def write_heard(log_dir: Path, heard: Heard) -> None:
    """``heard.json`` in ``log_dir``, whole or not at all."""
    document = {
        "written_s": heard.written_s,
        "since_s": heard.since_s,
        "last_status_s": dict(heard.last_status_s),
    }
    write_whole(log_dir / HEARD_FILE, json.dumps(document))


def read_heard(log_dir: Path) -> Heard | None:
    """``heard.json`` of ``log_dir``; None when absent or not readable as such."""
    try:
        document = json.loads((log_dir / HEARD_FILE).read_text(encoding="utf-8"))
        last = {str(k): float(v) for k, v in document["last_status_s"].items()}
        return Heard(float(document["written_s"]), float(document["since_s"]), last)
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return None


def silent(
    started_s: Mapping[str, float],
    reporting: frozenset[str],
    server: str,
    heard: Heard | None,
    now_s: float,
    after_s: float,
) -> dict[str, str]:
    """The processes to kill as silent: name -> why. ``started_s``: each running process's
    (re)start [monotonic s]; ``reporting``: those that publish /diagnostics; ``server``: the
    status server's name."""
    found: dict[str, str] = {}
    if heard is not None and heard.written_s > now_s:  # of a boot before this one
        heard = None
    if server in started_s:
        reported = heard is not None and heard.since_s >= started_s[server]
        quiet_s = now_s - (heard.written_s if heard is not None and reported else started_s[server])
        if quiet_s > (after_s if reported else START_GRACE_S):
            found[server] = f"no {HEARD_FILE} for {quiet_s:.1f} s"
    if heard is None or now_s - heard.written_s > FRESH_S or now_s - heard.since_s < after_s:
        return found
    for name, start_s in started_s.items():
        if name not in reporting:
            continue
        last_s = heard.last_status_s.get(name)
        reported = last_s is not None and last_s >= start_s
        quiet_s = now_s - (last_s if last_s is not None and reported else start_s)
        if reported and quiet_s > after_s:
            found[name] = f"no status on /diagnostics for {quiet_s:.1f} s"
        elif not reported and quiet_s > START_GRACE_S:
            found[name] = f"no status on /diagnostics in {quiet_s:.0f} s since its start"
    return found
