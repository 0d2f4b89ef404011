"""CPU load of gnss_node: the vehicle's two receivers, Leica at 1 Hz and ADU5 at 5 Hz.

Each node runs as its own process (the ``gnss_node`` executable with config/gnss_leica.yaml and
config/gnss_adu5.yaml) against an emulated receiver on a pseudo-terminal in this process; CPU
time is read from /proc/<pid>/stat after a warm-up, over ``SECONDS``. Prints numbers, asserts
nothing. Start-up (Python, rclpy imports) is excluded by the warm-up.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import rclpy
from geometry_msgs.msg import TwistWithCovarianceStamped
from sensor_msgs.msg import Imu, NavSatFix

from gnss_driver.emulator import EmulatorConfig, GnssEmulator, constant_velocity
from gnss_driver.profiles import Receiver

REPO = Path(__file__).resolve().parents[1]
WARM_UP_S = 5.0
SECONDS = float(os.environ.get("BENCH_SECONDS", "30"))
TICKS_PER_S = os.sysconf("SC_CLK_TCK")


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of a process [s]."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICKS_PER_S


def main() -> None:
    rclpy.init()
    exe = Path(sys.executable).parent / "gnss_node"
    truth = constant_velocity((10.0, 5.0, 0.0), pitch_deg=1.0, roll_deg=-0.5)
    counts: dict[str, int] = {}
    node = rclpy.create_node("bench_gnss_node")
    for topic, msg_type in (
        ("leica/gnss/fix", NavSatFix),
        ("leica/gnss/vel", TwistWithCovarianceStamped),
        ("adu5/gnss/fix", NavSatFix),
        ("adu5/gnss/attitude", Imu),
    ):
        counts[topic] = 0
        node.create_subscription(
            msg_type, topic, lambda _m, t=topic: counts.__setitem__(t, counts[t] + 1), 100
        )
    leica = GnssEmulator(
        truth, EmulatorConfig(receiver=Receiver.LEICA, leica_extra=("GST", "RMC", "ZDA"))
    )
    adu5 = GnssEmulator(truth, EmulatorConfig(receiver=Receiver.ADU5, adu5_att=True))
    procs = {}
    with leica, adu5:
        for name, device in (("leica", leica), ("adu5", adu5)):
            procs[name] = subprocess.Popen(
                [
                    exe,
                    "--ros-args",
                    "--params-file",
                    str(REPO / "config" / f"gnss_{name}.yaml"),
                    "-p",
                    f"port:={device.path}",
                    "-r",
                    f"__node:={name}",
                    "-r",
                    f"__ns:=/{name}",
                    "--log-level",
                    "warn",
                ],
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
            )
        try:
            end = time.monotonic() + WARM_UP_S
            while time.monotonic() < end:
                rclpy.spin_once(node, timeout_sec=0.1)
            start_cpu = {name: cpu_seconds(p.pid) for name, p in procs.items()}
            start_counts = dict(counts)
            start = time.monotonic()
            while time.monotonic() < start + SECONDS:
                rclpy.spin_once(node, timeout_sec=0.1)
            elapsed = time.monotonic() - start
            used = {name: cpu_seconds(p.pid) - start_cpu[name] for name, p in procs.items()}
        finally:
            for proc in procs.values():
                proc.terminate()
                proc.wait(timeout=10)
    received = {topic: counts[topic] - start_counts[topic] for topic in counts}
    print(f"gnss_node CPU over {elapsed:.0f} s after a {WARM_UP_S:.0f} s warm-up (1 core = 100 %)")
    for name, hz in (("leica", 1.0), ("adu5", 5.0)):
        print(
            f"  {name:>5} ({hz:g} Hz): {100 * used[name] / elapsed:5.2f} % CPU,"
            f" {1e3 * used[name] / (elapsed * hz):5.2f} ms per epoch"
        )
    print(f"  messages received: {received}")
    node.destroy_node()
    rclpy.shutdown()


if __name__ == "__main__":
    main()
