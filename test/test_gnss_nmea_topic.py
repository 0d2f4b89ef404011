"""gnss_node publishes every line the receiver sends on ``nmea``, rejected ones included, and its
set-up commands on ``to_device/nmea`` (rclpy, pyserial, emulated receivers on pseudo-terminals)."""

from __future__ import annotations

import threading
import time
from collections import Counter

import pytest
import rclpy
from nmea_msgs.msg import Sentence
from ros_harness import Collector, overrides, spinning, stamp_s, wait_for

from gnss_driver.emulator import EmulatorConfig, GnssEmulator
from gnss_driver.node import GnssNode
from gnss_driver.profiles import Adu5Setup, Receiver, adu5_commands
from gnss_driver.reader import nmea_checksum

pytestmark = pytest.mark.ros


@pytest.fixture(scope="module", autouse=True)
def ros_context():
    rclpy.init()
    yield
    rclpy.shutdown()


def _record_writes(device: GnssEmulator) -> list[bytes]:
    """The sentences the emulator's pty accepts from now on, as written (one write each)."""
    sent: list[bytes] = []
    lock = threading.Lock()
    write = device.pty.write

    def recording_write(data: bytes) -> int:
        accepted = write(data)
        with lock:
            sent.append(data[:accepted])
        return accepted

    device.pty.write = recording_write
    return sent


def _checksum_ok(line: str) -> bool:
    body, _, given = line[1:].rpartition("*")
    return int(given, 16) == nmea_checksum(body.encode())


def test_every_line_sent_is_published_in_order_corrupted_ones_included():
    config = EmulatorConfig(leica_extra=("GST", "RMC", "ZDA"))
    with GnssEmulator(config=config) as device:
        sent = _record_writes(device)
        node = GnssNode(
            parameter_overrides=overrides(port=device.path, receiver="leica", baud=device.baud)
        )
        collector = Collector({"nmea": Sentence})
        try:
            with spinning(node, collector.node):
                assert wait_for(lambda: collector.count("nmea") >= 6, 15.0)
                device.corrupt_checksums(4)
                assert wait_for(lambda: collector.count("nmea") >= 24, 15.0)
                device.go_silent(60.0)
                # Once the emulator is silent, the last line sent is the last one published.
                assert wait_for(
                    lambda: collector.get("nmea")[-1].sentence.encode() == sent[-1].rstrip(), 10.0
                )
                stopped = time.time()
                published = collector.get("nmea")
        finally:
            node.close()
            node.destroy_node()
            collector.node.destroy_node()
    lines = [m.sentence for m in published]
    expected = [data.rstrip(b"\r\n").decode() for data in sent[-len(lines) :]]
    assert lines == expected  # every line from the first one read, in order
    assert Counter(line[3:6] for line in lines) == Counter(line[3:6] for line in expected)
    assert sum(not _checksum_ok(line) for line in lines) == 4
    assert all(m.header.frame_id == "gnss_link" for m in published)
    stamps = [stamp_s(m) for m in published]
    assert stamps == sorted(stamps) and stopped - 60.0 < stamps[0] <= stamps[-1] <= stopped


def test_setup_commands_are_published_as_sent():
    config = EmulatorConfig(receiver=Receiver.ADU5)
    with GnssEmulator(config=config) as device:
        node = GnssNode(
            parameter_overrides=overrides(
                port=device.path,
                receiver="adu5",
                baud=device.baud,
                nmea_output=False,
                autostart=False,
            )
        )
        collector = Collector({"to_device/nmea": Sentence, "nmea": Sentence})
        try:
            with spinning(node, collector.node):
                # Configured (the port opened, the receiver set up) once the subscriber is there.
                assert wait_for(lambda: node.count_subscribers("to_device/nmea") == 1, 10.0)
                node.trigger_configure()
                commands = adu5_commands(Adu5Setup())
                assert wait_for(lambda: collector.count("to_device/nmea") == len(commands), 15.0)
                sent = [m.sentence for m in collector.get("to_device/nmea")]
        finally:
            node.close()
            node.destroy_node()
            collector.node.destroy_node()
    assert sent == commands == device.commands
    assert collector.count("nmea") == 0
