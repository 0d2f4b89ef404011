"""ins_fusion.runtime.priority: a look at the running vehicle (gnss_ins status, topics, echo)
runs below the nodes' priority; the daemon's own status server does not."""

from __future__ import annotations

import os
import subprocess
import sys

from support.waiting import wait_for

from ins_fusion.runtime.priority import LOOK_NICENESS
from ins_fusion.runtime.processes import gnss_ins_command


def _niceness(pid: int) -> int | None:
    """Field 19 of /proc/PID/stat (after the command's parenthesis), None once it ended."""
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii") as stat:
            return int(stat.read().rsplit(")", 1)[1].split()[16])
    except (OSError, IndexError, ValueError):
        return None


def test_a_look_lowers_its_own_priority() -> None:
    code = "from ins_fusion.runtime.priority import run_as_a_look; print(run_as_a_look())"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert int(done.stdout) == min(os.nice(0) + LOOK_NICENESS, 19)


def test_gnss_ins_status_runs_as_a_look(tmp_path) -> None:
    look = subprocess.Popen(
        gnss_ins_command("status", "--json", "--wait", "3", "--log-dir", str(tmp_path)),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    expected = min(os.nice(0) + LOOK_NICENESS, 19)
    seen: set[int | None] = set()
    try:

        def niced() -> bool:  # seen at its niceness before it ended
            seen.add(_niceness(look.pid))
            return expected in seen or look.poll() is not None

        wait_for(niced, 30.0, poll_s=0.05)
    finally:
        look.kill()
        look.wait(timeout=10)
    assert expected in seen, seen
