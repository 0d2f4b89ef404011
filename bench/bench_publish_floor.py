"""The floor of a Python ROS 2 process at the IMU's rate on this machine: CPU of a process that
wakes 134 times a second and does nothing, publishes an empty sensor_msgs/Imu (reliable, as
imu/data_raw) without a subscriber, and with one and two subscribers in other processes. The
middleware runs as ``gnss_ins launch`` runs it (discovery_environment("LOCALHOST"): UDP only).
What a driver node costs beyond these numbers is its own work. Prints numbers, asserts nothing.

    .venv/bin/python bench/bench_publish_floor.py [--seconds 20]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys

from ins_fusion.runtime.vehicle_nodes import discovery_environment

RATE_HZ = 134.0
TOPIC = "/bench_floor/imu"

#: One process: ``publisher MODE SUBSCRIBERS SECONDS`` or ``subscriber SECONDS``.
CHILD = r"""
import sys, time
import rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu
role, *rest = sys.argv[1:]
rclpy.init()
node = rclpy.create_node("bench_floor_" + role)
qos = QoSProfile(depth=200, reliability=ReliabilityPolicy.RELIABLE)
if role == "subscriber":
    from rclpy.experimental import EventsExecutor
    from rclpy.task import Future
    node.create_subscription(Imu, "TOPIC", lambda m: None, qos, raw=True)
    executor = EventsExecutor()
    executor.add_node(node)
    end = time.monotonic() + float(rest[0])
    try:
        while time.monotonic() < end:
            executor.spin_until_future_complete(Future(), timeout_sec=0.1)
    except Exception:  # SIGTERM at the end: rclpy's handler shuts the context down
        pass
    sys.exit(0)
mode, subscribers, seconds = rest[0], int(rest[1]), float(rest[2])
publisher = node.create_publisher(Imu, "TOPIC", qos)
deadline = time.monotonic() + 20.0
while publisher.get_subscription_count() < subscribers and time.monotonic() < deadline:
    time.sleep(0.05)
time.sleep(1.0)
msg, period = Imu(), 1.0 / RATE
cpu0, wall0 = time.process_time(), time.monotonic()
due = wall0
while time.monotonic() - wall0 < seconds:
    if mode == "publish":
        publisher.publish(msg)
    due += period
    time.sleep(max(0.0, due - time.monotonic()))
cpu = (time.process_time() - cpu0) / (time.monotonic() - wall0) * 100.0
print(f"{cpu:.2f} {publisher.get_subscription_count()}")
""".replace("TOPIC", TOPIC).replace("RATE", repr(RATE_HZ))


def run_case(mode: str, subscribers: int, seconds: float, env: dict[str, str]) -> str:
    """CPU % of the publisher process, with ``subscribers`` subscriber processes beside it."""
    listeners = [
        subprocess.Popen([sys.executable, "-c", CHILD, "subscriber", str(seconds + 25.0)], env=env)
        for _ in range(subscribers)
    ]
    try:
        out = subprocess.run(
            [sys.executable, "-c", CHILD, "publisher", mode, str(subscribers), str(seconds)],
            env=env,
            capture_output=True,
            text=True,
            timeout=seconds + 60.0,
            check=True,
        ).stdout.split()
    finally:
        for listener in listeners:
            listener.terminate()
            listener.wait(timeout=30)
    cpu, matched = out
    return f"{float(cpu):5.2f} % ({matched} matched)"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=20.0, help="measured seconds per case")
    args = parser.parse_args()
    env = {
        **os.environ,
        **discovery_environment("LOCALHOST"),
        "ROS_DOMAIN_ID": str(150 + os.getpid() % 50),
    }
    print(f"a Python process at {RATE_HZ:g} Hz, % of one core ({args.seconds:g} s each):")
    for label, mode, subscribers in (
        ("wakes only", "sleep", 0),
        ("publishes an Imu, no subscriber", "publish", 0),
        ("publishes an Imu, 1 subscriber", "publish", 1),
        ("publishes an Imu, 2 subscribers", "publish", 2),
    ):
        print(f"  {label:<34} {run_case(mode, subscribers, args.seconds, env)}")
    print(f"  load average {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
