"""gnss_node writes the RTCM 3 corrections of the ``rtcm`` topic to an emulated Leica rover whose
solution follows them (rclpy, pyserial, a pseudo-terminal)."""

from __future__ import annotations

import random
import time
from collections.abc import Callable

import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rtcm_msgs.msg import Message
from support.pacing import pause
from support.paths import FIXTURES
from support.ros_harness import Collector, diagnostic_values, overrides, spinning, wait_for

from gnss_driver.emulator import EmulatorConfig, GnssEmulator
from gnss_driver.node import GnssNode
from gnss_ins_common.rtcm import make_frame, split_frames

pytestmark = pytest.mark.ros

CAPTURE = FIXTURES / "rtcm" / "pygpsdata-NTRIP-USCL00CHL0.log"
#: The capture's 35 frames (RTCM 1001..1230 of a real NTRIP caster's stream).
FRAMES, _ = split_frames(CAPTURE.read_bytes())
TOPICS = {"/diagnostics": DiagnosticArray, "to_device/rtcm": Message}
GARBAGE = b"ICY 200 OK\r\n\x00\x01 noise"


@pytest.fixture(scope="module", autouse=True)
def ros_context():
    rclpy.init()
    yield
    rclpy.shutdown()


class Base:
    """A plain rclpy node publishing rtcm_msgs/Message on ``rtcm`` (an NTRIP client stand-in)."""

    def __init__(self) -> None:
        self.node = rclpy.create_node("test_rtcm_base")
        qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        self.publisher = self.node.create_publisher(Message, "rtcm", qos)

    def send(self, data: bytes) -> None:
        self.publisher.publish(Message(message=data))


def _status(collector: Collector) -> dict[str, str]:
    reports = collector.get("/diagnostics")
    return diagnostic_values(reports[-1]) if reports else {}


def _fix_type_is(collector: Collector, name: str) -> Callable[[], bool]:
    return lambda: _status(collector).get("last_fix_type") == name


def _random_frames(count: int, seed: int) -> list[bytes]:
    rng = random.Random(seed)
    return [
        make_frame(bytes((0x3E, 0xD0)) + rng.randbytes(rng.randrange(20, 200)))
        for _ in range(count)
    ]


def _node(device: GnssEmulator) -> GnssNode:
    return GnssNode(
        parameter_overrides=overrides(
            port=device.path, receiver="leica", baud=device.baud, diagnostics_period=0.2
        )
    )


def test_valid_frames_reach_the_rover_whole_and_in_order_and_its_fix_follows():
    config = EmulatorConfig(rtk_from_corrections=True, rtk_hold_s=2.0, float_hold_s=3.0)
    # Whole frames, 1-3 a message, garbage around some, one frame with a broken CRC and one
    # split over two messages: only the whole valid frames may reach the rover.
    broken = bytearray(FRAMES[5])
    broken[10] ^= 0xFF
    split = FRAMES[9]
    messages = [
        FRAMES[0],
        GARBAGE + FRAMES[1] + FRAMES[2],
        FRAMES[3] + GARBAGE,
        FRAMES[4] + bytes(broken) + FRAMES[6],
        FRAMES[7] + FRAMES[8] + split[:20],
        split[20:] + FRAMES[10],
        *(b"".join(FRAMES[i : i + 3]) for i in range(11, len(FRAMES), 3)),
    ]
    valid = [f for i, f in enumerate(FRAMES) if i not in (5, 9)]
    invalid_bytes = 2 * len(GARBAGE) + len(broken) + len(split)
    with GnssEmulator(config=config) as device:
        node, base, collector = _node(device), Base(), Collector(TOPICS)
        try:
            with spinning(node, base.node, collector.node):
                assert wait_for(_fix_type_is(collector, "SPS"), 15.0), _status(collector)
                assert wait_for(lambda: base.publisher.get_subscription_count() == 1, 10.0)
                for message in messages:
                    base.send(message)
                assert wait_for(lambda: device.rtcm_frames == len(valid), 10.0)
                # A stream keeps the rover fixed; without it, float, then standalone.
                deadline, streamed = time.monotonic() + 15.0, 0
                while not _fix_type_is(collector, "RTK_FIXED")() and time.monotonic() < deadline:
                    base.send(FRAMES[0])
                    valid.append(FRAMES[0])
                    streamed += 1
                    pause(0.5)  # the stream's pace
                assert _fix_type_is(collector, "RTK_FIXED")(), _status(collector)
                assert wait_for(lambda: device.rtcm_frames == len(valid), 10.0)
                assert wait_for(_fix_type_is(collector, "RTK_FLOAT"), 10.0), _status(collector)
                assert wait_for(_fix_type_is(collector, "SPS"), 10.0), _status(collector)
                status = _status(collector)
                written = b"".join(bytes(m.message) for m in collector.get("to_device/rtcm"))
        finally:
            node.close()
            node.destroy_node()
            base.node.destroy_node()
            collector.node.destroy_node()
        assert device.rtcm_received == b"".join(valid)
    assert written == b"".join(valid)
    assert int(status["rtcm_messages"]) == len(messages) + streamed
    assert int(status["rtcm_frames_written"]) == len(valid)
    assert int(status["rtcm_bytes_written"]) == len(b"".join(valid))
    assert int(status["rtcm_invalid_bytes"]) == invalid_bytes
    assert int(status["rtcm_crc_failures"]) >= 1
    assert status["rtcm_dropped_stale"] == status["rtcm_write_failures"] == "0"
    assert float(status["rtcm_age_s"]) > 0.0
    assert "1001:" in status["rtcm_message_numbers"]


def test_frames_received_while_the_port_is_lost_are_never_written():
    before, during, after = (_random_frames(5, seed) for seed in (1, 2, 3))
    config = EmulatorConfig(rtk_from_corrections=True)
    with GnssEmulator(config=config) as device:
        node, base, collector = _node(device), Base(), Collector(TOPICS)
        try:
            with spinning(node, base.node, collector.node):
                assert wait_for(lambda: node.port_open, 15.0)
                assert wait_for(lambda: base.publisher.get_subscription_count() == 1, 10.0)
                base.send(b"".join(before))
                assert wait_for(lambda: device.rtcm_frames == len(before), 10.0)
                device.unplug()
                assert wait_for(lambda: not node.port_open, 15.0)
                base.send(b"".join(during))

                # Received, then dropped while the port is lost (a frame the writer had taken
                # just before is refused by the link: a write failure).
                def dropped() -> int:
                    status = _status(collector)
                    return sum(
                        int(status.get(k, 0)) for k in ("rtcm_dropped_stale", "rtcm_write_failures")
                    )

                assert wait_for(lambda: dropped() == len(during), 10.0), _status(collector)
                device.plug()
                assert wait_for(lambda: node.port_open, 20.0)
                base.send(b"".join(after))
                assert wait_for(lambda: device.rtcm_frames == len(before) + len(after), 10.0)
        finally:
            node.close()
            node.destroy_node()
            base.node.destroy_node()
            collector.node.destroy_node()
        assert device.rtcm_received == b"".join(before + after)


def test_without_corrections_input_there_is_no_rtcm_subscription():
    node = GnssNode(parameter_overrides=overrides(port="/nonexistent/tty", corrections_input=False))
    try:
        assert node.get_subscriptions_info_by_topic("/rtcm") == []
    finally:
        node.close()
        node.destroy_node()
