"""The gnss_node executable survives a live fuzz on a pty and publishes only sound messages.

20 000 fuzzed valid-checksum sentences (gnss_driver.fuzz, seeded), with a valid epoch after
every 50, are written to a pty the real node reads; then valid epochs follow. The process must
still run, the valid epochs must come out, and every fix it published must have a finite,
positive covariance.
"""

from __future__ import annotations

import math
import os
import subprocess

import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from sensor_msgs.msg import NavSatFix, NavSatStatus
from support.pacing import pause
from support.ros_harness import (
    Collector,
    diagnostic_values,
    node_executable,
    spinning,
    wait_for,
)
from support.waiting import wait_until_steady

from gnss_driver.fuzz import TEMPLATES, FuzzSource
from gnss_driver.reader import frame_sentence
from gnss_ins_common.pty_device import PtyDevice

pytestmark = pytest.mark.ros

FUZZED = 20_000
VALID_EVERY = 50


@pytest.fixture(scope="module", autouse=True)
def ros_context():
    rclpy.init()
    yield
    rclpy.shutdown()


def valid_epoch(second: int) -> bytes:
    """The templates at 12:35:19 + ``second`` s (UTC and GPS time of week)."""
    minutes, seconds = divmod(35 * 60 + 19 + second, 60)
    hhmmss = f"{12 + minutes // 60:02d}{minutes % 60:02d}{seconds:02d}.00"
    return b"".join(
        frame_sentence(t.replace("123519.00", hhmmss).replace("218137.0", f"{218137 + second}.0"))
        for t in TEMPLATES
    )


def write_whole(device: PtyDevice, data: bytes) -> None:
    """Write every byte, as fast as the node reads them: the pty takes what fits in its buffer
    (the rest would be dropped), the remainder once the node has read some."""
    while data := data[device.write(data) :]:
        pause(0.002)  # the node reads meanwhile


def test_gnss_node_survives_a_live_fuzz():
    source = FuzzSource(seed=2024)
    collector = Collector({"gnss/fix": NavSatFix, "/diagnostics": DiagnosticArray})
    with PtyDevice() as device:
        proc = subprocess.Popen(
            [
                node_executable("gnss_node"),
                "--ros-args",
                "-p",
                f"port:={device.path}",
                "-p",
                "receiver:=generic",
                "-p",
                "baud:=115200",
                "-p",
                "diagnostics_period:=0.2",
            ],
            env=os.environ.copy(),
        )
        try:
            with spinning(collector.node):
                # The node runs and has opened the port: a diagnostics report says so.
                def port_open() -> bool:
                    reports = collector.get("/diagnostics")
                    return bool(reports) and not reports[-1].status[0].message.startswith("port")

                assert wait_for(port_open, 60.0)
                stream, second = [], 0
                for written in range(1, FUZZED + 1):
                    stream.append(source.sentence())
                    if written % VALID_EVERY == 0:
                        second += 1
                        stream.append(valid_epoch(second))
                write_whole(device, b"".join(stream))
                # Until the node has read and published the last of it: no new fix for 0.5 s.
                fuzz_fixes = wait_until_steady(lambda: collector.count("gnss/fix"), 0.5, 30.0)
                for _ in range(5):
                    second += 1
                    device.write(valid_epoch(second))
                    pause(0.2)  # one epoch at a time
                assert wait_for(lambda: collector.count("gnss/fix") >= fuzz_fixes + 4, 5.0)
                assert wait_for(lambda: collector.count("/diagnostics") >= 3, 3.0)
                assert proc.poll() is None, "gnss_node exited"
        finally:
            proc.terminate()
            code = proc.wait(timeout=10)
            collector.node.destroy_node()
    assert code == 0
    fixes = collector.get("gnss/fix")
    assert fuzz_fixes > FUZZED // VALID_EVERY // 2  # most valid epochs came through the fuzz
    for fix in fixes:
        if fix.status.status != NavSatStatus.STATUS_NO_FIX:
            cov = fix.position_covariance
            assert all(math.isfinite(c) for c in cov) and min(cov[0], cov[4], cov[8]) > 0.0
    assert fixes[-1].status.status == NavSatStatus.STATUS_FIX
    values = diagnostic_values(collector.get("/diagnostics")[-1])
    assert int(values["internal_errors"]) == 0
    assert int(values["bad_fields"]) > 1000
