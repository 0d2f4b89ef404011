"""imu400cc_node under CPU contention: packets sent, received, lost, and the node's own
dropped-packet count. Prints numbers, asserts nothing.

The node runs as its real executable reading the emulated IMU400CC on a pseudo-terminal, while
``--load`` busy Python processes compete for the cores (load 4-6 on a 2-core machine with
``--load 4``). Lost = packets the emulator wrote minus Imu messages received, split into those
the node never framed (its ``packets`` count) and those the starved listener missed; the node's
``dropped_packets`` (from device-timer gaps) must not exceed what the node missed.

    .venv/bin/python bench/bench_imu_contention.py [--seconds 30] [--load 4]
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu

from imu400cc_driver.emulator import Imu400ccEmulator


def _busy(stop: multiprocessing.synchronize.Event) -> None:
    while not stop.is_set():
        sum(range(10_000))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=30.0)
    parser.add_argument("--load", type=int, default=4, help="busy processes")
    parser.add_argument("--warmup", type=float, default=3.0)
    args = parser.parse_args()
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    os.environ.setdefault("ROS_DOMAIN_ID", str(40 + os.getpid() % 50))

    rclpy.init()
    listener = rclpy.create_node("bench_imu_contention")
    counts = {"imu": 0}
    last_diag: dict[str, str] = {}
    lock = threading.Lock()
    # The window opens at the first diagnostics status after the load starts: the node's
    # counters, the emulator's and the listener's, taken together.
    armed = threading.Event()
    start: list[tuple[dict[str, str], int, int]] = []
    device = Imu400ccEmulator()

    def on_imu(_msg: Imu) -> None:
        with lock:
            counts["imu"] += 1

    def on_diag(msg: DiagnosticArray) -> None:
        with lock:
            last_diag.update({kv.key: kv.value for kv in msg.status[0].values})
            if armed.is_set() and not start:
                start.append((dict(last_diag), device.packets_sent, counts["imu"]))

    qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
    listener.create_subscription(Imu, "imu/data_raw", on_imu, qos)
    listener.create_subscription(DiagnosticArray, "/diagnostics", on_diag, 10)
    executor = SingleThreadedExecutor()
    executor.add_node(listener)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()

    stop = multiprocessing.Event()
    hogs = [multiprocessing.Process(target=_busy, args=(stop,)) for _ in range(args.load)]
    exe = Path(sys.executable).parent / "imu400cc_node"
    with device:
        # stall_timeout: the silence that ends the run is no reason to reconnect.
        node = subprocess.Popen(
            [exe, "--ros-args", "-p", f"port:={device.path}", "-p", "stall_timeout:=10.0"]
        )
        time.sleep(args.warmup)
        for hog in hogs:
            hog.start()
        armed.set()
        while not start:
            time.sleep(0.01)
        diag0, sent0, received0 = start[0]
        time.sleep(args.seconds)
        load = os.getloadavg()[0]
        stop.set()
        for hog in hogs:
            hog.join()
        device.go_silent(60.0)  # end of the measured stream
        sent = device.packets_sent - sent0
        time.sleep(2.0)  # the last messages and one more diagnostics status
        with lock:
            received = counts["imu"] - received0
            diag = dict(last_diag)
        node.terminate()
        node.wait(timeout=10)
        overflow = device.pty.overflow_bytes
    executor.shutdown()
    spinner.join(timeout=5.0)
    listener.destroy_node()
    rclpy.shutdown()

    def grew(key: str) -> int:
        return int(diag.get(key, 0)) - int(diag0.get(key, 0))

    print(f"imu400cc_node, {args.seconds:.0f} s with {args.load} busy processes")
    print(f"  load average (1 min) {load:.1f} on {os.cpu_count()} cores")
    framed = grew("packets")
    print(
        f"  packets sent {sent}, framed by the node {framed}, received {received}, lost"
        f" {sent - received} (by the node {sent - framed}, by the listener {framed - received})"
    )
    print(
        f"  node counts: dropped_packets {grew('dropped_packets'):+d}, timer_gaps"
        f" {grew('timer_gaps'):+d}, wraps_taken_back {grew('wraps_taken_back'):+d},"
        f" bad_checksums {grew('bad_checksums'):+d}, clock_resets {grew('clock_resets'):+d},"
        f" reconnects {grew('reconnects'):+d}"
    )
    print(f"  bytes the pty could not take (emulator side): {overflow}")


if __name__ == "__main__":
    main()
