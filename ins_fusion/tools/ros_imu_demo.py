"""The rclpy half of ``gnss_ins imu-demo`` (ins_fusion/tools/imu_demo.py): imu400cc_node on an
emulated IMU400CC and a listener, in one process."""

from __future__ import annotations

import time
from typing import Any

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from sensor_msgs.msg import Imu, Temperature

from imu400cc_driver.emulator import Imu400ccEmulator
from imu400cc_driver.node import Imu400ccNode


def listen(duration_s: float, mode: str, every: int) -> tuple[list[Any], list[float], list[Any]]:
    """Run the emulator, the node (``mode`` continuous/polled) and a listener for
    ``duration_s`` [s], printing every ``every``-th Imu message; returns the Imu messages, the
    temperatures [°C] and the DiagnosticArray messages received."""
    rclpy.init()
    imu_msgs: list[Any] = []
    temps: list[float] = []
    diagnostics: list[Any] = []
    with Imu400ccEmulator() as device:
        node = Imu400ccNode(
            parameter_overrides=[
                Parameter("port", value=device.path),
                Parameter("mode", value=mode),
            ]
        )
        listener = rclpy.create_node("imu_demo_listener")

        def on_imu(msg: Imu) -> None:
            imu_msgs.append(msg)
            if len(imu_msgs) % every == 1:
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
        end = time.monotonic() + duration_s
        while time.monotonic() < end:
            executor.spin_once(timeout_sec=0.1)
        node.close()
        executor.shutdown()
        node.destroy_node()
        listener.destroy_node()
    rclpy.shutdown()
    return imu_msgs, temps, diagnostics
