"""ntrip_node (real rclpy node) against the test caster on 127.0.0.1: every frame the caster sends
is published on ``rtcm`` in order, the rover's GGA from ``nmea`` goes upstream, the status says
what happens, and the password is found nowhere."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from nmea_msgs.msg import Sentence
from rtcm_msgs.msg import Message
from support.config_checks import assert_file_holds_defaults
from support.paths import FIXTURES
from support.ros_harness import (
    Collector,
    assert_executable_refuses,
    overrides,
    spinning,
    wait_for,
)

from gnss_driver.reader import frame_sentence
from ntrip_client.caster_emulator import CasterEmulator
from ntrip_client.gga import gga_position
from ntrip_client.node import PARAMETERS, NtripNode

pytestmark = pytest.mark.ros

CAPTURE = FIXTURES / "rtcm" / "pygpsdata-NTRIP-USCL00CHL0.log"
PASSWORD = "s3cret-Pass"
USER = "rover"
MOUNTPOINTS = {"AAU00DNK": (57.01, 9.99), "CPH00DNK": (55.68, 12.57)}
GGA = frame_sentence(
    "GPGGA,120000.00,5700.8880000,N,00959.1900000,E,4,12,0.8,10.000,M,40.000,M,1.0,0001"
).decode()


@pytest.fixture(scope="module", autouse=True)
def ros_context():
    rclpy.init()
    yield
    rclpy.shutdown()


@pytest.fixture
def password_file(tmp_path):
    path = tmp_path / "ntrip-password"
    path.write_text(PASSWORD + "\n")
    path.chmod(stat.S_IRUSR | stat.S_IWUSR)
    return path


def _statuses(collector: Collector) -> list:
    return [s for a in collector.get("/diagnostics") for s in a.status if "NTRIP" in s.name]


def _values(status) -> dict[str, str]:
    return {kv.key: kv.value for kv in status.values}


def test_frames_published_in_order_and_gga_sent_upstream(password_file):
    with CasterEmulator(
        CAPTURE.read_bytes(), MOUNTPOINTS, (USER, PASSWORD), rate_bytes_s=3000.0
    ) as caster:
        node = NtripNode(
            parameter_overrides=overrides(
                url=f"http://{USER}@127.0.0.1:{caster.port}/AAU00DNK",
                password_file=str(password_file),
                gga_interval=1.0,
            )
        )
        collector = Collector({"rtcm": Message, "/diagnostics": DiagnosticArray})
        publisher = collector.node.create_publisher(Sentence, "nmea", 10)
        try:
            with spinning(node, collector.node):
                assert wait_for(lambda: collector.count("rtcm") >= 60, 30.0)
                for _ in range(3):  # the rover's sentences, as gnss_node publishes them
                    publisher.publish(Sentence(sentence=GGA.strip()))
                assert wait_for(lambda: len(caster.gga_received) >= 2, 15.0)
                assert wait_for(
                    lambda: any(
                        _values(s).get("rover_solution") == "RTK fixed"
                        for s in _statuses(collector)
                    ),
                    10.0,
                )
                caster.stop()
                sent = len(caster.sent_frames)
                assert wait_for(lambda: collector.count("rtcm") >= sent, 10.0)
        finally:
            node.close()
            node.destroy_node()
            collector.node.destroy_node()
    published = [bytes(m.message) for m in collector.get("rtcm")]
    assert published == caster.sent_frames[: len(published)]
    assert len(published) == sent
    assert all(sentence.strip() == GGA.strip() for _, sentence in caster.gga_received)
    statuses = _statuses(collector)
    assert any(
        s.level == DiagnosticStatus.OK and _values(s)["caster_state"] == "connected"
        for s in statuses
    )
    text = repr(statuses)
    assert PASSWORD not in text


def test_a_wrong_password_is_an_error_with_the_caster_s_reason(tmp_path, monkeypatch):
    monkeypatch.setenv("NTRIP_PASSWORD", "wrong")
    with CasterEmulator(CAPTURE.read_bytes(), MOUNTPOINTS, (USER, PASSWORD)) as caster:
        node = NtripNode(
            parameter_overrides=overrides(url=f"http://{USER}@127.0.0.1:{caster.port}/AAU00DNK")
        )
        collector = Collector({"rtcm": Message, "/diagnostics": DiagnosticArray})
        try:
            with spinning(node, collector.node):
                assert wait_for(
                    lambda: any(s.level == DiagnosticStatus.ERROR for s in _statuses(collector)),
                    15.0,
                )
        finally:
            node.close()
            node.destroy_node()
            collector.node.destroy_node()
    error = next(s for s in _statuses(collector) if s.level == DiagnosticStatus.ERROR)
    assert "401" in error.message
    assert _values(error)["caster_state"] == "refused"
    assert collector.count("rtcm") == 0
    assert "wrong" not in repr(_statuses(collector))


def test_an_unknown_mountpoint_lists_the_caster_s_nearest_first():
    with CasterEmulator(CAPTURE.read_bytes(), MOUNTPOINTS) as caster:
        node = NtripNode(
            parameter_overrides=overrides(
                url=f"http://127.0.0.1:{caster.port}/NOSUCH",
                fixed_position=[55.7, 12.5, 30.0],
            )
        )
        collector = Collector({"/diagnostics": DiagnosticArray})
        try:
            with spinning(node, collector.node):
                assert wait_for(
                    lambda: any("mountpoints" in _values(s) for s in _statuses(collector)), 20.0
                )
        finally:
            node.close()
            node.destroy_node()
            collector.node.destroy_node()
    status = next(s for s in _statuses(collector) if "mountpoints" in _values(s))
    assert status.level == DiagnosticStatus.ERROR
    assert _values(status)["mountpoints"].startswith("CPH00DNK")  # Copenhagen is nearer
    assert "NOSUCH" in status.message


def test_the_fixed_position_goes_upstream_until_the_rover_has_one(password_file):
    """A caster that needs a position before the rover's first fix gets ``fixed_position``;
    once the rover reports one, the rover's own GGA."""
    with CasterEmulator(CAPTURE.read_bytes(), MOUNTPOINTS, (USER, PASSWORD)) as caster:
        node = NtripNode(
            parameter_overrides=overrides(
                url=f"http://{USER}@127.0.0.1:{caster.port}/AAU00DNK",
                password_file=str(password_file),
                gga_interval=1.0,
                fixed_position=[55.7, 12.5, 30.0],
            )
        )
        collector = Collector({"rtcm": Message})
        publisher = collector.node.create_publisher(Sentence, "nmea", 10)
        try:
            with spinning(node, collector.node):
                assert wait_for(lambda: len(caster.gga_received) >= 2, 15.0)
                fixed = list(caster.gga_received)
                rover_gga = Sentence(sentence=GGA.strip())
                assert wait_for(lambda: node.count_subscribers("nmea") >= 1, 10.0)
                publisher.publish(rover_gga)
                assert wait_for(lambda: caster.gga_received[-1][1] == GGA.strip(), 15.0)
        finally:
            node.close()
            node.destroy_node()
            collector.node.destroy_node()
    assert all(gga_position(sentence) == pytest.approx((55.7, 12.5)) for _, sentence in fixed)


def test_a_password_in_the_url_or_a_readable_password_file_is_refused(tmp_path):
    assert_executable_refuses("ntrip_node", "url", "http://rover:pw@127.0.0.1:2101/AAU00DNK")
    readable = tmp_path / "password"
    readable.write_text("pw\n")
    readable.chmod(0o644)
    result = _run_node(f"password_file:={readable}")
    assert result.returncode == 2
    assert "chmod 600" in result.stderr
    assert "pw" not in result.stderr.replace("password", "")


def _run_node(*parameters: str):
    import subprocess
    import sys

    args = [str(Path(sys.executable).parent / "ntrip_node"), "--ros-args"]
    for parameter in parameters:
        args += ["-p", parameter]
    return subprocess.run(
        args, capture_output=True, text=True, timeout=30, env={**os.environ, "NTRIP_PASSWORD": ""}
    )


def test_the_configuration_file_holds_every_default():
    assert_file_holds_defaults("ntrip.yaml", "ntrip_client", PARAMETERS)
