"""Benchmark of ``gnss_ins record``: throughput, loss, latency and CPU at the drivers' rates.

A publisher in this process sends sensor_msgs/Imu at 134 Hz (the IMU400CC rate, reliable depth
200 like imu400cc_node) and sensor_msgs/NavSatFix at 5 Hz for --duration seconds; the recorder
runs as a subprocess (the real CLI) and is stopped with SIGINT. Printed: messages sent and
recorded per topic, lost (= sent − recorded), messages/s, receive latency (bag log time −
header.stamp, the send time), the recorder's CPU % while recording (from /proc) and the bag size.
``--duration 3600`` is the one-hour case. Plain script, no asserts.
"""

from __future__ import annotations

import argparse
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import rclpy
from rclpy.duration import Duration
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu, NavSatFix

from ins_fusion.bags.bag_io import BagReader

REPO = Path(__file__).resolve().parents[1]
TOPICS = {"/bench/imu": (Imu, 134.0), "/bench/fix": (NavSatFix, 5.0)}


def cpu_seconds(pid: int) -> float:
    """utime + stime of a process (Linux /proc)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def publish(
    duration_s: float, rates: dict[str, float], recorder_pid: int
) -> tuple[dict[str, int], float]:
    """Publish every topic at its rate for ``duration_s`` (header.stamp = send time) once the
    recorder subscribed; returns the counts sent and the recorder's CPU fraction meanwhile."""
    node = rclpy.create_node("bench_record_publisher")
    qos = QoSProfile(depth=200, reliability=ReliabilityPolicy.RELIABLE)
    pubs = {t: node.create_publisher(TOPICS[t][0], t, qos) for t in TOPICS}
    deadline = time.monotonic() + 30.0
    while any(p.get_subscription_count() == 0 for p in pubs.values()):
        if time.monotonic() > deadline:
            sys.exit("the recorder did not subscribe within 30 s")
        time.sleep(0.05)
    sent = dict.fromkeys(TOPICS, 0)
    cpu_start, start = cpu_seconds(recorder_pid), time.monotonic()
    due = dict.fromkeys(TOPICS, start)
    while (now := time.monotonic()) < start + duration_s:
        topic = min(due, key=due.__getitem__)
        if due[topic] > now:
            time.sleep(due[topic] - now)
        msg = TOPICS[topic][0]()
        msg.header.stamp = node.get_clock().now().to_msg()
        msg.header.frame_id = "bench"
        pubs[topic].publish(msg)
        sent[topic] += 1
        due[topic] += 1.0 / rates[topic]
    cpu_fraction = (cpu_seconds(recorder_pid) - cpu_start) / (time.monotonic() - start)
    for p in pubs.values():
        p.wait_for_all_acked(Duration(seconds=5.0))
    node.destroy_node()
    return sent, cpu_fraction


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=60.0, help="seconds of publishing")
    parser.add_argument("--storage", choices=["mcap", "sqlite3"], default="mcap")
    args = parser.parse_args()
    os.environ.setdefault("ROS_DOMAIN_ID", str(random.SystemRandom().randint(101, 200)))
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    rates = {t: rate for t, (_, rate) in TOPICS.items()}

    with tempfile.TemporaryDirectory() as tmp:
        bag = Path(tmp) / "bench"
        command = ["record", "-o", str(bag), "--storage", args.storage, *TOPICS]
        recorder = subprocess.Popen(
            [sys.executable, "-m", "ins_fusion.tools.cli", *command],
            cwd=REPO,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        rclpy.init()
        try:
            sent, cpu_fraction = publish(args.duration, rates, recorder.pid)
        finally:
            rclpy.shutdown()
            recorder.send_signal(signal.SIGINT)
            out, err = recorder.communicate(timeout=120)
        if recorder.returncode != 0:
            sys.exit(f"recorder failed ({recorder.returncode}):\n{err}")
        recorded = dict.fromkeys(TOPICS, 0)
        latency_ms: list[float] = []
        with BagReader(bag) as reader:
            for msg in reader.messages(list(TOPICS), deserialize=True):
                recorded[msg.topic] += 1
                stamp = msg.message.header.stamp
                latency_ms.append((msg.log_time_ns - stamp.sec * 10**9 - stamp.nanosec) / 1e6)
        size_mb = sum(f.stat().st_size for f in bag.iterdir()) / 1e6

    print(f"record benchmark: {args.duration:g} s, storage {args.storage}")
    for topic in TOPICS:
        lost = sent[topic] - recorded[topic]
        print(
            f"  {topic:<12} {rates[topic]:6.1f} Hz  sent {sent[topic]:>7}"
            f"  recorded {recorded[topic]:>7}  lost {lost}"
        )
    total = sum(recorded.values())
    lat = np.array(latency_ms)
    print(f"  throughput      {total / args.duration:.1f} messages/s")
    print(
        f"  receive latency p50 {np.percentile(lat, 50):.2f} ms, p99 {np.percentile(lat, 99):.2f}"
        f" ms, max {lat.max():.2f} ms"
    )
    print(f"  recorder CPU    {100 * cpu_fraction:.1f} % of one core while recording")
    print(f"  bag size        {size_mb:.2f} MB ({size_mb * 1e3 / args.duration:.1f} kB/s)")
    print("  recorder says: " + out.strip().splitlines()[-1].strip())


if __name__ == "__main__":
    main()
