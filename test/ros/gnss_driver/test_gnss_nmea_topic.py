"""gnss_node publishes every line the receiver sends on ``nmea``, rejected ones included, and its
set-up commands on ``to_device/nmea`` (rclpy, pyserial, emulated receivers on pseudo-terminals)."""

from __future__ import annotations

import threading
import time
from collections import Counter

import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from nmea_msgs.msg import Sentence
from support.ros_harness import Collector, diagnostic_values, overrides, spinning, stamp_s, wait_for

from gnss_driver.emulator import EmulatorConfig, GnssEmulator
from gnss_driver.node import GnssNode
from gnss_driver.profiles import Adu5Setup, Receiver, adu5_commands
from gnss_driver.reader import frame_sentence

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


#: Lines the receiver sends while otherwise silent, each rejected by the node for its reason.
ODD_LINES = {
    "unknown_sentence": [frame_sentence("GPXYZ,1,2,3"), frame_sentence("PXYZA,7,ok")],
    "missing_checksum": [b"$GPZDA,123519.00,07,12,2026,00,00\r\n"],
}
#: The counters per reason the test injects lines for.
REJECTED = ("bad_checksum", "truncated", "unknown_sentence", "missing_checksum")


def _rejected(collector: Collector) -> dict[str, int]:
    """The node's rejected-input counters of its latest /diagnostics status."""
    reports = collector.get("/diagnostics")
    values = diagnostic_values(reports[-1]) if reports else {}
    return {kind: int(values.get(kind, -1)) for kind in REJECTED}


@pytest.mark.parametrize("receiver", [Receiver.LEICA, Receiver.ADU5])
def test_every_line_sent_is_published_in_order_rejected_ones_included(receiver):
    """Every line the receiver sends is on ``nmea`` in order: 4 with a broken checksum, 2 cut
    off by the next sentence, 2 of unknown types and 1 without a checksum among them, which
    the node's /diagnostics count per reason."""
    extra = ("GST", "RMC", "ZDA") if receiver is Receiver.LEICA else ()
    config = EmulatorConfig(receiver=receiver, leica_extra=extra)
    with GnssEmulator(config=config) as device:
        sent = _record_writes(device)
        node = GnssNode(
            parameter_overrides=overrides(
                port=device.path,
                receiver=receiver.value,
                baud=device.baud,
                diagnostics_period=0.2,
            )
        )
        collector = Collector({"nmea": Sentence, "/diagnostics": DiagnosticArray})
        try:
            with spinning(node, collector.node):
                assert wait_for(lambda: collector.count("nmea") >= 6, 15.0)
                device.corrupt_checksums(4)  # the next 4 sentences, then 2 cut in half
                device.cut_lines(2)
                assert wait_for(lambda: collector.count("nmea") >= 30, 15.0)
                device.go_silent(60.0)
                # Once the emulator is silent, the last line sent is the last one published.
                assert wait_for(
                    lambda: collector.get("nmea")[-1].sentence.encode() == sent[-1].rstrip(), 10.0
                )
                for line in (line for lines in ODD_LINES.values() for line in lines):
                    device.send_garbage(line)
                assert wait_for(
                    lambda: collector.get("nmea")[-1].sentence.encode() == sent[-1].rstrip(), 10.0
                )
                stopped = time.time()
                injected = {"bad_checksum": 4, "truncated": 2}
                injected |= {kind: len(lines) for kind, lines in ODD_LINES.items()}
                assert wait_for(lambda: _rejected(collector) == injected, 10.0), _rejected(
                    collector
                )
                published = collector.get("nmea")
        finally:
            node.close()
            node.destroy_node()
            collector.node.destroy_node()
    lines = [m.sentence for m in published]
    expected = [data.rstrip(b"\r\n").decode() for data in sent[-len(lines) :]]
    assert lines == expected  # every line from the first one read, in order
    assert Counter(line[3:6] for line in lines) == Counter(line[3:6] for line in expected)
    assert sum("*" not in line for line in lines) == 2 + 1  # the cut ones, the one without
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
