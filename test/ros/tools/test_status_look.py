"""gnss_ins status --json (a look) never calls a running process silent only because it was
not heard within --wait: a node whose first status comes after --wait (discovery on a busy
machine) is shown with that status; a process that ended is not waited for."""

from __future__ import annotations

import json
import subprocess
import time
from pathlib import Path

import pytest
from support.ros_harness import other_process

from ins_fusion.runtime.health import write_supervisor_state
from ins_fusion.runtime.processes import gnss_ins_command

pytestmark = pytest.mark.ros

#: A leica_gnss that reports OK every 0.5 s, its first status DELAY_S after it starts.
LATE_NODE = """
import sys, time
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
rclpy.init()
node = rclpy.create_node("leica_gnss")
publisher = node.create_publisher(DiagnosticArray, "/diagnostics", 10)
first = time.monotonic() + float(sys.argv[1])
def report():
    if time.monotonic() >= first:
        status = DiagnosticStatus(level=b"\\x00", name="leica_gnss: GNSS leica", message="late OK")
        publisher.publish(DiagnosticArray(status=[status]))
node.create_timer(0.5, report)
"""
DELAY_S, WAIT_S = 4.0, 1.0


def test_a_running_node_first_heard_after_the_wait_is_shown_with_its_status(tmp_path: Path):
    with other_process(LATE_NODE, str(DELAY_S)) as node:
        write_supervisor_state(
            tmp_path,
            {
                "leica_gnss": {
                    "pid": node.pid,
                    "restarts": 0,
                    "running": True,
                    "started_s": time.monotonic() - 1.0,
                },
                "adu5_gnss": {"pid": 1, "restarts": 2, "running": False, "started_s": 0.0},
            },
        )
        look = subprocess.run(
            gnss_ins_command("status", "--json", "--wait", str(WAIT_S), "--log-dir", str(tmp_path)),
            capture_output=True,
            text=True,
            timeout=60,
        )
    view = json.loads(look.stdout)
    assert view["processes"]["leica_gnss"]["level"] == "OK", view
    assert view["processes"]["leica_gnss"]["message"] == "late OK"
    assert view["processes"]["adu5_gnss"]["message"] == "not running"
    assert look.returncode == 2  # the ended ADU5 node is an error
