"""`gnss_ins redecode` of a `gnss_ins launch --record` recording on the emulated devices (rclpy,
pyserial, pseudo-terminals): the rebuilt topics are the recorded ones, field for field.

The comparison of a device starts at the first (re)open of its port that the recording saw
while it was recording that device's raw topics: the IMU's replug (``imu/raw`` event OPENED,
the driver reset) and each receiver's restart after its kill -9 (``port_events`` STARTED, a new
driver). Before that the nodes had decoded bytes the recorder was not yet subscribed to (it
starts beside them), so the live drivers' state (device clock, epochs, clock envelope) held
what the recording lacks; messages stamped before it are left out. The raw topics are latched
(a restarted node's first reads reach the recorder when it matches the new publisher), its
outputs are not: what a restarted receiver published before the recorder matched its output
topic was never recorded (redecode rebuilds it), so a topic's comparison starts at its first
message recorded after the open. It ends at the last stamp both have: the launch's SIGINT
stops the recorder and the nodes in no fixed order.
"""

from __future__ import annotations

import os
import signal
import subprocess

import pytest
import rclpy
from ros_harness import wait_for
from test_launch import launched, node_pids

from ins_fusion.bags.bag_io import BagReader, jazzy_typestore
from ins_fusion.redecode.decoders import header_ns
from ins_fusion.runtime.processes import gnss_ins_command

pytestmark = pytest.mark.ros

#: Extra seconds of steady recording before and after the faults (the issue's 10-minute run:
#: GNSS_INS_REDECODE_STEADY_S=280); the suite's run has none.
STEADY_S = float(os.environ.get("GNSS_INS_REDECODE_STEADY_S", "0"))

#: Compared topic -> the raw topic whose events start its comparison.
COMPARED = {
    "/imu/data_raw": "/imu/raw",
    "/leica/gnss/fix": "/leica/port_events",
    "/leica/gnss/vel": "/leica/port_events",
    "/adu5/gnss/attitude": "/adu5/port_events",
}


@pytest.fixture(scope="module", autouse=True)
def ros_context():
    rclpy.init()
    yield
    rclpy.shutdown()


def _grows(collector, topic: str, by: int, timeout_s: float) -> bool:
    target = collector.count(topic) + by
    return wait_for(lambda: collector.count(topic) >= target, timeout_s)


def _kill_and_wait(launcher_pid: int, name: str) -> None:
    before = node_pids(launcher_pid)[name]
    os.kill(before, signal.SIGKILL)
    assert wait_for(lambda: node_pids(launcher_pid).get(name, before) != before, 10.0), name


def _first_live_open(reader: BagReader, raw: str) -> int:
    """Stamp [ns] of the first (re)open on ``raw`` after the device's first recorded data."""
    data = "/imu/raw" if raw == "/imu/raw" else raw.replace("port_events", "nmea")
    messages = [m.message for m in reader.messages([data], deserialize=True)]
    start = next(header_ns(m) for m in messages if getattr(m, "event", 0) == 0)
    events = reader.messages([raw], deserialize=True)
    return next(
        header_ns(m.message) for m in events if m.message.event and header_ns(m.message) > start
    )


def _stamped(path, topic: str) -> list[tuple[int, bytes]]:
    """(stamp, CDR) of each message, serialized again by rosbags: field for field, without the
    padding bytes rclpy leaves as they were."""
    store = jazzy_typestore()
    with BagReader(path) as reader:
        messages = [reader.deserialize(m.message, m.msgtype) for m in reader.messages([topic])]
    return [(header_ns(m), bytes(store.serialize_cdr(m, m.__msgtype__))) for m in messages]


def test_a_recording_redecoded_gives_what_the_nodes_published(tmp_path):
    bags = tmp_path / "bags"
    with launched(tmp_path, "--record", str(bags)) as (launcher, collector, output, imu):
        log = tmp_path / "recorder.log"
        assert wait_for(lambda: log.exists() and "recording /imu/raw" in log.read_text(), 60.0)
        assert wait_for(lambda: "recording /adu5/port_events" in log.read_text(), 30.0)
        assert _grows(collector, "imu/data_raw", int(134 * (5 + STEADY_S)), 30.0 + 2 * STEADY_S)
        imu.unplug()
        assert _grows(collector, "leica/gnss/fix", 3, 30.0)  # ~3 s without the IMU
        imu.plug()
        assert _grows(collector, "imu/data_raw", 134 * 5, 30.0)
        for name in ("leica_gnss", "adu5_gnss"):
            _kill_and_wait(launcher.pid, name)
        assert _grows(collector, "leica/gnss/fix", int(10 + STEADY_S), 60.0 + 2 * STEADY_S)
        assert _grows(collector, "adu5/gnss/attitude", 10, 60.0)
    assert launcher.returncode == 0, output[0]
    (bag,) = bags.iterdir()
    out = tmp_path / "redecoded"
    done = subprocess.run(
        gnss_ins_command("redecode", str(bag), "-o", str(out)),
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    with BagReader(bag) as reader:
        starts = {raw: _first_live_open(reader, raw) for raw in set(COMPARED.values())}
    for topic, raw in COMPARED.items():
        recorded, rebuilt = _stamped(bag, topic), _stamped(out, topic)
        end = min(recorded[-1][0], rebuilt[-1][0])
        theirs = [(t, m) for t, m in recorded if starts[raw] < t <= end]
        start = theirs[0][0]  # the output topic matched by the recorder again
        mine = [(t, m) for t, m in rebuilt if start <= t <= end]
        print(f"{topic}: {len(theirs)} compared of {len(recorded)} recorded")
        assert len(theirs) > (100 if topic == "/imu/data_raw" else 5), topic
        differing = sorted({t for t, _ in mine} ^ {t for t, _ in theirs})[:5]
        assert mine == theirs, (topic, starts[raw], len(mine), len(theirs), differing)
    replay = subprocess.run(
        gnss_ins_command(
            "replay",
            str(out),
            "--topics",
            "fix=/leica/gnss/fix,vel=/leica/gnss/vel,attitude=/adu5/gnss/attitude",
        ),
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert replay.returncode == 0, replay.stderr[-2000:]
