"""``gnss_ins status``: the vehicle's health on one screen, refreshed every second.

Reads every /diagnostics status (the four nodes and the recorder) and the supervisor file of
``gnss_ins launch`` in its log directory (restarts); prints per process its level, age,
restarts, message and the values an operator reads (ins_fusion/runtime/health.py). ``--json``
prints once, after ``--wait`` seconds of listening, for scripts and health checks; ``--once``
the same as text. The exit code is 0 when the system is OK, 1 when something warns, 2 on an
error or a process that is silent. ``--serve`` runs as a service that publishes the same view on
/gnss_ins/status (diagnostic_msgs/DiagnosticArray), as ``gnss_ins launch`` starts it, and writes
what it heard when to ``heard.json`` there (launch's watchdog, ins_fusion/runtime/watchdog.py).

rclpy is imported only when listening starts (this module is loaded by ``gnss_ins --help``).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from ins_fusion.runtime.health import Health, exit_code, format_view
from ins_fusion.runtime.priority import run_as_a_look
from ins_fusion.runtime.processes import default_log_dir
from ins_fusion.runtime.watchdog import HEARD_FILE, Heard, write_heard

#: How much longer than --wait a look (--json, --once) listens while a running process has sent
#: no status yet [s]: under load the discovery of one node once took longer than the 4 s (a
#: running Leica node shown STALE, "no status received", exit 2, in 1 of 22 looks).
UNHEARD_WAIT_S = 6.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Command-line options of ``gnss_ins status``."""
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument("--json", action="store_true", help="print the view once as JSON")
    mode.add_argument("--once", action="store_true", help="print the view once as text")
    mode.add_argument(
        "--serve", action="store_true", help="publish the view on /gnss_ins/status until stopped"
    )
    parser.add_argument(
        "--wait",
        type=float,
        default=4.0,
        metavar="S",
        help="seconds of listening before the first view (discovery takes a second or two, "
        "then the nodes report every second); --json and --once listen up to "
        f"{UNHEARD_WAIT_S:g} s longer while a running process has not reported yet",
    )
    parser.add_argument(
        "--log-dir",
        type=Path,
        help="gnss_ins launch's log directory, for the restarts (default: launch's default)",
    )


def run(args: argparse.Namespace) -> int:
    """Listen and show (exit code: module docstring)."""
    if not args.serve:  # a look, not the daemon's server: below the nodes (runtime.priority)
        run_as_a_look()
    from ins_fusion.tools.ros_status import watch

    log_dir = args.log_dir if args.log_dir is not None else default_log_dir()
    health = Health()
    last: dict[str, Any] = {}
    since_s = time.monotonic()

    def on_view(view: dict[str, Any]) -> bool:
        late_s = time.monotonic() - since_s - args.wait
        if (args.json or args.once) and health.unheard() and late_s < UNHEARD_WAIT_S:
            return True  # a running process not heard yet: discovery is slow on a busy machine
        last.update(view)
        if args.serve:
            heard = {name: status.received_s for name, status in health.latest.items()}
            try:
                write_heard(log_dir, Heard(time.monotonic(), since_s, heard))
            except OSError as exc:  # launch's watchdog then leaves the nodes alone
                print(f"gnss_ins status: cannot write {HEARD_FILE}: {exc}", file=sys.stderr)
            return True
        if args.json:
            print(json.dumps(view, indent=1))
            return False
        title = f"gnss_ins status {datetime.now(UTC):%Y-%m-%dT%H:%M:%SZ}"
        if not args.once and sys.stdout.isatty():
            print("\x1b[H\x1b[2J", end="")  # a refreshed screen
        print(format_view(view, title), flush=True)
        return not args.once

    watch(health, log_dir, on_view, args.wait, args.serve)
    return exit_code(last) if last else 2
