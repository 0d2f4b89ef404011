"""`gnss_ins imu-demo`: imu400cc_node on an emulated IMU400CC, printing what it publishes (the
node and its listener: ins_fusion/tools/ros_imu_demo.py)."""

from __future__ import annotations

import argparse
import math
from typing import Any

import numpy as np


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Demo options."""
    parser.add_argument("--duration", type=float, default=5.0, help="how long to run [s]")
    parser.add_argument(
        "--mode",
        choices=("continuous", "polled"),
        default="continuous",
        help="imu400cc_node's mode parameter",
    )
    parser.add_argument("--every", type=int, default=67, help="print every N-th Imu message")


def run(args: argparse.Namespace) -> int:
    """Start emulator + node + a listener in one process and summarise the published data."""
    from ins_fusion.tools.ros_imu_demo import listen

    imu_msgs, temps, diagnostics = listen(args.duration, args.mode, args.every)
    _summarise(imu_msgs, temps, diagnostics)
    return 0 if imu_msgs else 1


def _summarise(imu_msgs: list[Any], temps: list[float], diagnostics: list[Any]) -> None:
    """Rate, mean specific force, temperature and last diagnostics of what the node published."""
    if not imu_msgs:
        print("no Imu message received")
        return
    stamps = np.array([m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in imu_msgs])
    force = np.array(
        [
            [m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z]
            for m in imu_msgs
        ]
    )
    span = stamps[-1] - stamps[0]
    print(
        f"\n{len(imu_msgs)} Imu messages over {span:.2f} s of stamps: "
        f"{(len(imu_msgs) - 1) / span if span > 0 else math.nan:.1f} Hz"
    )
    print(
        f"mean specific force (FLU) {np.round(force.mean(axis=0), 3)} m/s^2, "
        f"|f| = {np.linalg.norm(force.mean(axis=0)):.3f}"
    )
    if temps:
        print(f"temperature {temps[-1]:.2f} degC ({len(temps)} messages)")
    if diagnostics:
        status = diagnostics[-1].status[0]
        print(f"diagnostics [{status.name}] {status.message}")
        for kv in status.values:
            print(f"  {kv.key:18s} {kv.value}")
