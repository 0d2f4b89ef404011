"""imu400cc_node end to end: latency and CPU at 134 Hz. Prints numbers, asserts nothing.

The node runs as its real executable in its own process (as in deployment) and reads the
emulated IMU400CC on a pseudo-terminal; this process hosts the emulator and a subscriber.
Latency = subscriber receive time - the time the emulator wrote the packet's last byte, matched
through the message stamp to the emulator's true sample time (4.6875 ms of wire time before the
scheduled write); the stamp error is measured against that true sample time too.
CPU = the node process's user + system time over the measurement, in percent of one core, and
per thread (/proc/PID/task: "main" spins the executor, the serial link's thread is named after
the executable, Fast DDS's threads after their task), with the load average beside it (the
machine is shared).

    .venv/bin/python bench/bench_imu_node.py [--packets 10000] [--raw-output false] [--tree DIR]

``--raw-output false`` runs the node without its imu/raw topic (parameter ``raw_output``), so the
two runs give the raw topic's cost; no subscriber listens to imu/raw either way. ``--tree DIR``
runs the node from another source tree (an A/B in one session: ``git worktree add DIR COMMIT``).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu

from gnss_ins_common.rates import IMU400CC_RATE_HZ
from imu400cc_driver.emulator import Imu400ccEmulator, SentPacket


def process_cpu_s(pid: int) -> float:
    """user + system CPU seconds of a process, from /proc."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def thread_cpu_s(pid: int) -> dict[str, float]:
    """user + system CPU seconds of each thread of a process, by name (threads of one name
    summed; Fast DDS names its threads, the Python ones are named after the executable, but the
    main thread, which spins the executor, is "main")."""
    tick = os.sysconf("SC_CLK_TCK")
    threads: dict[str, float] = {}
    for task in Path(f"/proc/{pid}/task").iterdir():
        try:
            name = "main" if task.name == str(pid) else (task / "comm").read_text().strip()
            fields = (task / "stat").read_text().rsplit(")", 1)[1].split()
        except FileNotFoundError:  # ended meanwhile
            continue
        threads[name] = threads.get(name, 0.0) + (int(fields[11]) + int(fields[12])) / tick
    return threads


def print_cpu(
    cpu_s: float,
    threads: tuple[dict[str, float], dict[str, float]],
    wall_s: float,
    load: tuple[float, float, float],
    digits: int,
) -> None:
    """The node's CPU over ``wall_s`` [s] (``cpu_s`` seconds of it) with the ``load`` average
    taken at its end, then each thread's share from its ``thread_cpu_s`` before and after (those
    of 0.05 % or more)."""
    print(
        f"  node CPU: {100 * cpu_s / wall_s:.{digits}f} % of one core "
        f"(load average {load[0]:.1f} / {load[1]:.1f} / {load[2]:.1f})"
    )
    before, after = threads
    for name in sorted(after, key=lambda n: before.get(n, 0.0) - after[n]):
        share = 100 * (after[name] - before.get(name, 0.0)) / wall_s
        if share >= 0.05:
            print(f"    thread {name}: {share:.{digits}f} %")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--packets", type=int, default=10_000)
    parser.add_argument(
        "--raw-output", choices=("true", "false"), default="true", help="the node's raw_output"
    )
    parser.add_argument("--warmup", type=float, default=3.0, help="seconds before measuring")
    parser.add_argument("--tree", type=Path, help="run the node from this source tree")
    args = parser.parse_args()
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    os.environ.setdefault("ROS_DOMAIN_ID", str(40 + os.getpid() % 50))

    sent: list[SentPacket] = []
    received: list[tuple[float, float]] = []  # (stamp, receive wall time)
    lock = threading.Lock()
    rclpy.init()
    listener = rclpy.create_node("bench_imu_listener")

    def on_imu(msg: Imu) -> None:
        now = time.time()
        with lock:
            received.append((msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9, now))

    qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
    listener.create_subscription(Imu, "imu/data_raw", on_imu, qos)
    executor = SingleThreadedExecutor()
    executor.add_node(listener)
    spin = threading.Thread(target=executor.spin, daemon=True)
    spin.start()

    exe = Path(sys.executable).parent / "imu400cc_node"
    node_env = dict(os.environ)
    if args.tree:
        node_env["PYTHONPATH"] = str(args.tree.resolve())
    with Imu400ccEmulator(on_packet=sent.append) as device:
        node = subprocess.Popen(
            [
                exe,
                "--ros-args",
                "-p",
                f"port:={device.path}",
                "-p",
                f"raw_output:={args.raw_output}",
            ],
            env=node_env,
        )
        time.sleep(args.warmup)
        with lock:
            received.clear()
        first = len(sent)
        cpu0, wall0 = process_cpu_s(node.pid), time.monotonic()
        threads0 = thread_cpu_s(node.pid)
        duration = args.packets / IMU400CC_RATE_HZ
        time.sleep(duration)
        cpu1, wall1 = process_cpu_s(node.pid), time.monotonic()
        threads1 = thread_cpu_s(node.pid)
        load = os.getloadavg()
        written = len(sent) - first
        time.sleep(0.5)  # let the last messages arrive
        node.terminate()
        node.wait(timeout=10)
    executor.shutdown()
    listener.destroy_node()
    rclpy.shutdown()

    measured = sent[max(first - 10, 0) :]
    write_times = np.array([p.written_wall_s for p in measured])
    samples = np.array([p.sample_wall_s for p in measured])
    with lock:
        pairs = np.array(received)
    stamps, arrivals = pairs[:, 0], pairs[:, 1]
    index = np.clip(np.searchsorted(samples, stamps), 1, len(samples) - 1)
    nearest = np.where(
        np.abs(samples[index] - stamps) < np.abs(samples[index - 1] - stamps), index, index - 1
    )
    stamp_error = stamps - samples[nearest]
    matched = np.abs(stamp_error) < 0.5 / IMU400CC_RATE_HZ
    latency_ms = (arrivals[matched] - write_times[nearest[matched]]) * 1e3
    print(f"imu400cc_node at {IMU400CC_RATE_HZ:.0f} Hz, {wall1 - wall0:.1f} s measured")
    print(
        f"  messages received {len(stamps)}, matched to packets {int(matched.sum())}, "
        f"packets written {written}"
    )
    print(
        "  latency (last byte written -> Imu received) [ms]: "
        f"p50 {np.percentile(latency_ms, 50):.3f}  p99 {np.percentile(latency_ms, 99):.3f}  "
        f"max {latency_ms.max():.3f}"
    )
    print(
        "  stamp - true sample time [ms]: "
        f"p50 {np.percentile(stamp_error[matched], 50) * 1e3:+.3f}  "
        f"p99 |err| {np.percentile(np.abs(stamp_error[matched]), 99) * 1e3:.3f}"
    )
    print_cpu(cpu1 - cpu0, (threads0, threads1), wall1 - wall0, load, 2)


if __name__ == "__main__":
    main()
