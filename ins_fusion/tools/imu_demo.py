"""`gnss_ins imu-demo`: imu400cc_node on an emulated IMU400CC, printing what it publishes."""

from __future__ import annotations

import argparse
import math
import time

import numpy as np


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Demo options."""
    parser.add_argument("--duration", type=float, default=5.0, help="how long to run [s]")
    parser.add_argument("--mode", choices=("continuous", "polled"), default="continuous")
    parser.add_argument("--every", type=int, default=67, help="print every N-th Imu message")


def run(args: argparse.Namespace) -> int:
    """Start emulator + node + a listener in one process and summarise the published data."""
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter
    from sensor_msgs.msg import Imu, Temperature

    from imu400cc_driver.emulator import Imu400ccEmulator
    from imu400cc_driver.node import Imu400ccNode

    rclpy.init()
    imu_msgs: list[Imu] = []
    temps: list[float] = []
    diagnostics: list[DiagnosticArray] = []
    with Imu400ccEmulator() as device:
        node = Imu400ccNode(
            parameter_overrides=[
                Parameter("port", value=device.path),
                Parameter("mode", value=args.mode),
            ]
        )
        listener = rclpy.create_node("imu_demo_listener")

        def on_imu(msg: Imu) -> None:
            imu_msgs.append(msg)
            if len(imu_msgs) % args.every == 1:
                a, w = msg.linear_acceleration, msg.angular_velocity
                print(
                    f"imu/data_raw  t={msg.header.stamp.sec}.{msg.header.stamp.nanosec:09d} "
                    f"frame={msg.header.frame_id}  f=({a.x:+.3f}, {a.y:+.3f}, {a.z:+.3f}) m/s^2  "
                    f"w=({w.x:+.4f}, {w.y:+.4f}, {w.z:+.4f}) rad/s",
                    flush=True,
                )

        listener.create_subscription(Imu, "imu/data_raw", on_imu, 500)
        listener.create_subscription(
            Temperature, "imu/temperature", lambda m: temps.append(m.temperature), 10
        )
        listener.create_subscription(DiagnosticArray, "/diagnostics", diagnostics.append, 10)
        executor = SingleThreadedExecutor()  # the multi-threaded one starves the reader
        executor.add_node(node)
        executor.add_node(listener)
        end = time.monotonic() + args.duration
        while time.monotonic() < end:
            executor.spin_once(timeout_sec=0.1)
        node.close()
        executor.shutdown()
        node.destroy_node()
        listener.destroy_node()
    rclpy.shutdown()
    _summarise(imu_msgs, temps, diagnostics)
    return 0 if imu_msgs else 1


def _summarise(imu_msgs: list, temps: list[float], diagnostics: list) -> None:
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
