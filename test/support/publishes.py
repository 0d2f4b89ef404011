"""Whether a node a docs page starts publishes: run by the docs test beside the page's line marked
Ctrl-C (the block's ``until=`` option, test/support/docs_pages.py), which is interrupted once
this script has ended. Exit status 0 once COUNT messages of TYPE arrived on TOPIC (with
``--value KEY=VALUE``: /diagnostics arrays with a status holding that value), 1 when they did
not within the time limit. Prints one line with what it heard either way.

    .venv/bin/python test/support/publishes.py TOPIC TYPE [--count N] [--value K=V] [--timeout S]
"""

from __future__ import annotations

import argparse
import importlib
import sys
import time
from typing import Any

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import qos_profile_sensor_data


def _message_type(name: str) -> type:
    """``sensor_msgs/msg/Imu`` -> the class."""
    package, kind, message = name.split("/")
    return getattr(importlib.import_module(f"{package}.{kind}"), message)  # type: ignore[no-any-return]


def _holds(msg: Any, key: str, value: str) -> bool:
    return any(kv.key == key and kv.value == value for s in msg.status for kv in s.values)


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("topic")
    parser.add_argument("type")
    parser.add_argument("--count", type=int, default=1)
    parser.add_argument("--value", default=None, help="KEY=VALUE of a /diagnostics status")
    parser.add_argument("--timeout", type=float, default=60.0, help="[s]")
    args = parser.parse_args(argv)
    key, _, value = (args.value or "").partition("=")
    heard = [0]

    def received(msg: Any) -> None:
        if args.value is None or _holds(msg, key, value):
            heard[0] += 1

    rclpy.init()
    node = rclpy.create_node("docs_publishes")
    node.create_subscription(
        _message_type(args.type), args.topic, received, qos_profile_sensor_data
    )
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    deadline = time.monotonic() + args.timeout
    try:
        while heard[0] < args.count and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.1)
    finally:
        node.destroy_node()
        rclpy.shutdown()
    what = f"{args.topic}" + (f" with {args.value}" if args.value else "")
    print(f"{heard[0]} of {args.count} messages on {what} within {args.timeout:g} s")
    return 0 if heard[0] >= args.count else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
