"""Problems reach the console: ins_fusion_node logs at WARN what its diagnostics show, and
`gnss_ins launch` reports a port that does not exist and its nodes' warnings (real processes)."""

from __future__ import annotations

import dataclasses
import signal
import subprocess
import threading

import pytest
import rclpy
from sensor_msgs.msg import Imu
from support.pacing import pause
from support.ros_harness import node_executable, wait_for

from ins_fusion.adapters.status_log import INFO, WARN, StatusLog
from ins_fusion.core.engine.engine import InsEngine
from ins_fusion.core.settings.config import FusionConfig
from ins_fusion.runtime.processes import gnss_ins_command

pytestmark = pytest.mark.ros


class _Lines:
    """Every line a process writes to one of its pipes, read on a thread."""

    def __init__(self, pipe) -> None:
        self.lines: list[str] = []
        threading.Thread(target=lambda: self.lines.extend(pipe), daemon=True).start()

    def has(self, *fragments: str) -> bool:
        return any(all(f in line for f in fragments) for line in list(self.lines))


def test_status_log_reports_changes_once_per_interval():
    status = InsEngine(FusionConfig.default()).status()
    log = StatusLog(interval_s=10.0, gap_rate_hz=0.5)
    assert log.update(status, 0.0) == [(INFO, "state aligning")]
    reset = dataclasses.replace(status, resets=1, last_reset_reason="IMU gap of 2.000 s")
    assert log.update(reset, 1.0) == [(WARN, "1 filter reset(s); last: IMU gap of 2.000 s")]
    again = dataclasses.replace(reset, resets=3)
    assert log.update(again, 5.0) == []  # within the interval: held back, then summed
    assert log.update(again, 11.5) == [(WARN, "2 filter reset(s); last: IMU gap of 2.000 s")]
    degraded = dataclasses.replace(again, state="degraded", imu_gaps=4)
    assert log.update(degraded, 12.0) == [(WARN, "state degraded (was aligning)")]  # 4 < 5
    many = dataclasses.replace(degraded, imu_gaps=40, imu_out_of_order=2)
    assert log.update(many, 13.0) == [
        (WARN, "2 IMU sample(s) with a stamp before the previous one"),
        (WARN, "40 IMU gap(s) (lost or implausible samples, bridged)"),
    ]
    warned = dataclasses.replace(many, warnings=("unit levelled upside down",))
    assert log.update(warned, 13.5) == [(WARN, "unit levelled upside down")]
    assert log.update(warned, 30.0) == []  # each engine warning once


@pytest.mark.ros
def test_fusion_node_logs_a_reset_with_its_reason_at_warn():
    node = subprocess.Popen(
        [node_executable("ins_fusion_node"), "--ros-args", "-p", "diagnostics_period:=0.2"],
        stderr=subprocess.PIPE,
        text=True,
    )
    stderr = _Lines(node.stderr)
    rclpy.init()
    feeder = rclpy.create_node("imu_feeder")
    publisher = feeder.create_publisher(Imu, "imu/data_raw", 200)
    try:
        assert wait_for(lambda: publisher.get_subscription_count() > 0, 60.0)
        t = 1000.0
        for i in range(400):  # 3 s at 134 Hz, a 2 s hole after the first 200 samples
            t += 2.0 if i == 200 else 1.0 / 134.0
            msg = Imu()
            msg.header.stamp.sec, msg.header.stamp.nanosec = int(t), int(t % 1.0 * 1e9)
            msg.linear_acceleration.z = 9.81
            publisher.publish(msg)
            pause(0.002)  # the samples' pace
        assert wait_for(lambda: stderr.has("[WARN]", "filter reset", "IMU gap of 2.0"), 60.0), (
            "".join(stderr.lines)
        )
    finally:
        feeder.destroy_node()
        rclpy.shutdown()
        node.send_signal(signal.SIGINT)
        node.wait(timeout=30)
    assert stderr.has("[INFO]", "state aligning")


@pytest.mark.ros
def test_launch_reports_a_missing_port_and_the_node_warnings(tmp_path):
    missing = str(tmp_path / "no_such_tty")
    launcher = subprocess.Popen(
        gnss_ins_command(
            "launch",
            "--imu-port",
            missing,
            "--leica-port",
            missing + "1",
            "--no-adu5",
            "--log-dir",
            str(tmp_path / "logs"),
        ),
        stdout=subprocess.PIPE,
        text=True,
    )
    stdout = _Lines(launcher.stdout)
    try:
        assert wait_for(lambda: stdout.has(f"warning: {missing} does not exist"), 60.0)
        # The driver's own warning about the port, forwarded from its log.
        assert wait_for(lambda: stdout.has("imu400cc_node: [WARN]", missing), 90.0), stdout.lines
    finally:
        launcher.send_signal(signal.SIGINT)
        launcher.wait(timeout=60)
