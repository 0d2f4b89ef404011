"""The whole correction chain as on the vehicle: the test caster on 127.0.0.1, ntrip_node, the
Leica's gnss_node and the emulated rover (``rtk_from_corrections``) on a pseudo-terminal.

In one process: the rover receives exactly the caster's frames, in order; its fix turns RTK
fixed within 2 s of the first frame and falls back to float, then standalone, when the caster
stops; the rover's own GGA reaches the caster at the configured interval. Under `gnss_ins launch
--ntrip --record`: the password is in no command line, log, bag or status, and the bag holds the
corrections and the rover's sentences."""

from __future__ import annotations

import itertools
import json
import os
import signal
import subprocess
from pathlib import Path

import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from nmea_msgs.msg import Sentence
from rtcm_msgs.msg import Message
from support.paths import FIXTURES
from support.ros_harness import Collector, overrides, spinning, stamp_s, wait_for

from gnss_driver.emulator import EmulatorConfig, GnssEmulator, constant_velocity
from gnss_driver.node import GnssNode
from imu400cc_driver.emulator import Imu400ccEmulator
from ins_fusion.bags.bag_io import BagReader
from ins_fusion.runtime.processes import gnss_ins_command
from ntrip_client.caster_emulator import CasterEmulator
from ntrip_client.gga import gga_quality
from ntrip_client.node import NtripNode

pytestmark = pytest.mark.ros

CAPTURE = FIXTURES / "rtcm" / "pygpsdata-NTRIP-USCL00CHL0.log"
PASSWORD = "Corr3ct-Horse"
USER = "rover"
MOUNTPOINTS = {"AAU00DNK": (57.01, 9.99)}
#: ntrip_node's gga_interval in the chain [s] (its default is 10 s; 2 s keeps the test short).
GGA_INTERVAL_S = 2.0


@pytest.fixture(scope="module", autouse=True)
def ros_context():
    rclpy.init()
    yield
    rclpy.shutdown()


def _ggas(collector: Collector) -> list[tuple[float, int]]:
    """(stamp [s], quality) of the rover's GGA sentences on /leica/nmea, in order."""
    found = []
    for msg in collector.get("/leica/nmea"):
        quality = gga_quality(msg.sentence)
        if quality is not None:
            found.append((stamp_s(msg), quality))
    return found


def test_the_rover_gets_exactly_the_caster_s_frames_and_turns_rtk_fixed(monkeypatch):
    monkeypatch.setenv("NTRIP_PASSWORD", PASSWORD)
    rover_config = EmulatorConfig(rtk_from_corrections=True, float_hold_s=3.0)
    with (
        CasterEmulator(CAPTURE.read_bytes(), MOUNTPOINTS, (USER, PASSWORD)) as caster,
        GnssEmulator(constant_velocity((3.0, 4.0, 0.0)), rover_config) as rover,
    ):
        namespace = ["--ros-args", "-r", "__ns:=/leica"]
        gnss = GnssNode(
            cli_args=namespace,
            parameter_overrides=overrides(port=rover.path, corrections_max_age=3.0),
        )
        client = NtripNode(
            cli_args=namespace,
            parameter_overrides=overrides(
                url=f"http://{USER}@127.0.0.1:{caster.port}/AAU00DNK",
                gga_interval=GGA_INTERVAL_S,
            ),
        )
        collector = Collector(
            {
                "/leica/nmea": Sentence,
                "/leica/rtcm": Message,
                "/leica/to_device/rtcm": Message,
                "/diagnostics": DiagnosticArray,
            }
        )
        try:
            with spinning(gnss, client, collector.node):
                assert wait_for(lambda: any(q == 4 for _, q in _ggas(collector)), 30.0)
                assert wait_for(lambda: len(caster.gga_received) >= 4, 30.0)
                caster.stop()
                sent = b"".join(caster.sent_frames)
                assert wait_for(lambda: rover.rtcm_received == sent, 10.0)
                stopped = max(s for s, _ in _ggas(collector))
                assert wait_for(lambda: _ggas(collector)[-1][1] == 1, 30.0)  # standalone
        finally:
            client.close()
            gnss.close()
            for node in (client, gnss, collector.node):
                node.destroy_node()
    assert len(caster.sent_frames) > 10
    assert rover.rtcm_received == b"".join(caster.sent_frames)  # in order, none lost, no more
    first_frame_s = stamp_s(collector.get("/leica/to_device/rtcm")[0])
    ggas = _ggas(collector)
    first_fixed_s = next(s for s, q in ggas if q == 4)
    assert first_fixed_s - first_frame_s <= 2.0
    assert all(q != 4 for s, q in ggas if s < first_frame_s)  # no fix before corrections
    after = [q for s, q in ggas if s > stopped + 3.0]
    assert 5 in after and after[-1] == 1  # float for a while, then standalone
    # GGA upstream: the rover's own sentences, at the configured interval, never faster (the
    # margin is the caster thread's delay in reading one of two sentences on 127.0.0.1).
    times = [t for t, _ in caster.gga_received]
    assert all(b - a >= GGA_INTERVAL_S - 0.25 for a, b in itertools.pairwise(times))
    assert all(gga_quality(s.strip()) is not None for _, s in caster.gga_received)


def _process_command_lines() -> str:
    lines = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                lines.append((entry / "cmdline").read_bytes().replace(b"\0", b" ").decode())
            except (OSError, UnicodeDecodeError):
                continue
    return "\n".join(lines)


def test_under_launch_the_password_is_nowhere_and_the_bag_holds_the_corrections(tmp_path):
    env = {**os.environ, "NTRIP_PASSWORD": PASSWORD}
    rover_config = EmulatorConfig(rtk_from_corrections=True)
    logs, bags = tmp_path / "logs", tmp_path / "bags"
    with (
        CasterEmulator(CAPTURE.read_bytes(), MOUNTPOINTS, (USER, PASSWORD)) as caster,
        GnssEmulator(constant_velocity((3.0, 4.0, 0.0)), rover_config) as rover,
        Imu400ccEmulator() as imu,
    ):
        url = f"http://{USER}@127.0.0.1:{caster.port}/AAU00DNK"
        options = ["--imu-port", imu.path, "--leica-port", rover.path, "--no-adu5"]
        launcher = subprocess.Popen(
            gnss_ins_command(
                "launch", *options, "--log-dir", str(logs), "--record", str(bags), "--ntrip", url
            ),
            stdout=subprocess.PIPE,
            text=True,
            env=env,
        )
        try:
            assert wait_for(lambda: rover.rtcm_frames > 20, 90.0)
            status = subprocess.run(
                gnss_ins_command("status", "--json", "--log-dir", str(logs)),
                capture_output=True,
                text=True,
                timeout=60,
            )
            command_lines = _process_command_lines()
        finally:
            launcher.send_signal(signal.SIGINT)
            output = launcher.communicate(timeout=90)[0]
    view = json.loads(status.stdout)
    row = view["processes"]["ntrip_client"]
    assert row["level"] in ("OK", "WARN"), row
    assert "connected" in json.dumps(row)
    assert url in command_lines  # the client runs, with the URL only
    texts = [status.stdout, status.stderr, output, command_lines]
    texts += [p.read_text(errors="replace") for p in logs.rglob("*") if p.is_file()]
    assert not any(PASSWORD in text for text in texts)
    bag_files = [p for p in bags.rglob("*") if p.is_file()]
    assert bag_files and not any(PASSWORD.encode() in p.read_bytes() for p in bag_files)
    (bag,) = [p for p in bags.iterdir() if p.is_dir()]
    with BagReader(bag) as reader:
        rtcm = [m.message for m in reader.messages(["/leica/rtcm"], deserialize=True)]
        nmea = [m.message for m in reader.messages(["/leica/nmea"], deserialize=True)]
    frames = [bytes(m.message) for m in rtcm]
    start = caster.sent_frames.index(frames[0])
    assert frames == caster.sent_frames[start : start + len(frames)]  # whole frames, in order
    assert any(gga_quality(m.sentence) == 4 for m in nmea)
