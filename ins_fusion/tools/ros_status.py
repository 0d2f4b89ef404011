"""The rclpy half of ``gnss_ins status`` (ins_fusion/tools/status.py): a node that takes every
/diagnostics status into a ``Health`` (ins_fusion/runtime/health.py) and, serving, publishes the
view on /gnss_ins/status every PERIOD_S: one DiagnosticStatus for the system ("gnss_ins:
system", the worst level) and one per process, with the values the view shows."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus

from gnss_ins_common.ros_diagnostics import make_status
from ins_fusion.runtime.health import LEVELS, STATUS_TOPIC, Health, Status
from ins_fusion.tools.ros_look import LookNode

#: Seconds between two views (screen refresh, /gnss_ins/status).
PERIOD_S = 1.0
#: Longest spin between two looks at the time [s] (a view is at most this late; a stop request
#: ends the spin at once; each return costs a Python round: 0.1 s slices ~0.15 % of a core).
SPIN_PERIOD_S = 0.5


def _take(health: Health, array: Any) -> None:
    now = time.monotonic()
    for status in array.status:
        values = {kv.key: kv.value for kv in status.values}
        health.add(Status(status.name, status.level[0], status.message, values, now))


def aggregate(view: dict[str, Any]) -> DiagnosticArray:
    """The view as a DiagnosticArray: the system first, then each process."""
    level_byte = {name: bytes([index]) for index, name in enumerate(LEVELS)}
    worst = [n for n, p in view["processes"].items() if p["level"] == view["level"]]
    statuses: list[DiagnosticStatus] = [
        make_status(
            "gnss_ins: system",
            "gnss_ins",
            level_byte[view["level"]],
            view["level"] if view["level"] == "OK" else f"{view['level']}: {', '.join(worst)}",
            {},
        )
    ]
    for name, entry in view["processes"].items():
        values = {"age_s": entry["age_s"], "restarts": entry["restarts"], **entry["values"]}
        statuses.append(
            make_status(
                f"gnss_ins: {name}",
                name,
                level_byte[entry["level"]],
                entry["message"],
                {k: v for k, v in values.items() if v is not None},
            )
        )
    return DiagnosticArray(status=statuses)


def watch(
    health: Health,
    log_dir: Path,
    on_view: Callable[[dict[str, Any]], bool],
    first_after_s: float,
    serve: bool,
) -> None:
    """Collect /diagnostics into ``health``; ``first_after_s`` after the start and then every
    PERIOD_S, read the supervisor file in ``log_dir``, build the view and call ``on_view`` (and,
    serving, publish it) until ``on_view`` returns False or Ctrl-C/SIGTERM."""
    with LookNode("gnss_ins_status", SPIN_PERIOD_S, log_file=serve) as look:
        node = look.node
        node.create_subscription(DiagnosticArray, "/diagnostics", lambda a: _take(health, a), 100)
        publisher = node.create_publisher(DiagnosticArray, STATUS_TOPIC, 10) if serve else None
        due = time.monotonic() + first_after_s
        while not look.stop:
            look.spin(max(0.0, min(SPIN_PERIOD_S, due - time.monotonic())))
            if time.monotonic() < due:
                continue
            due += PERIOD_S
            health.read_supervisor(log_dir)
            view = health.view(time.monotonic())
            if publisher is not None:
                array = aggregate(view)
                array.header.stamp = node.get_clock().now().to_msg()
                publisher.publish(array)
            if not on_view(view):
                break
