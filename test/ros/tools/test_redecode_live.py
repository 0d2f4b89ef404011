"""`gnss_ins redecode` of a `gnss_ins launch --record` recording on the emulated devices (rclpy,
pyserial, pseudo-terminals): the rebuilt topics are the recorded ones, field for field.

The raw topics are latched (2 000 IMU reads, 500 lines): the recorder, started beside the nodes,
gets each device's reads from the node's start (its STARTED event) on, so the comparison covers
the whole recording except the seconds around the faults:
- the IMU unplugged and plugged back (the driver reset at the OPENED event): 1 s before the
  unplug to 1 s after the reopen (the node's stall detection and the reopen take place there);
- each receiver's kill -9 and restart: 1 s before the kill to 5 s after the new node's STARTED
  event. The killed node may have read lines it published on ``nmea`` but not yet the epoch
  they closed; the new node publishes outputs before the recorder matches its output topics
  (those are never recorded; redecode rebuilds them).
A topic's comparison ends at the last stamp both have: the launch's SIGINT stops the recorder and
the nodes in no fixed order.
"""

from __future__ import annotations

import os
import signal
import subprocess
import time

import pytest
import rclpy
from support.launching import launched, node_pids
from support.ros_harness import wait_for

from ins_fusion.bags.bag_io import BagReader
from ins_fusion.bags.typestore import jazzy_typestore
from ins_fusion.redecode.decoders import OPENED, STARTED, header_ns
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


def _kill_and_wait(launcher_pid: int, name: str) -> float:
    """Kill the node; the wall time [s] of the kill once launch has restarted it."""
    before = node_pids(launcher_pid)[name]
    killed_s = time.time()
    os.kill(before, signal.SIGKILL)
    assert wait_for(lambda: node_pids(launcher_pid).get(name, before) != before, 10.0), name
    return killed_s


def _events(reader: BagReader, raw: str) -> list[tuple[int, int]]:
    """(stamp [ns], event) of the opens recorded on ``raw`` (data reads left out)."""
    messages = reader.messages([raw], deserialize=True)
    return [(header_ns(m.message), m.message.event) for m in messages if m.message.event]


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
        unplugged_s = time.time()
        imu.unplug()
        assert _grows(collector, "leica/gnss/fix", 3, 30.0)  # ~3 s without the IMU
        imu.plug()
        assert _grows(collector, "imu/data_raw", 134 * 5, 30.0)
        killed_s = {
            name: _kill_and_wait(launcher.pid, name) for name in ("leica_gnss", "adu5_gnss")
        }
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
        events = {raw: _events(reader, raw) for raw in set(COMPARED.values())}
    # Nanosecond windows left out of each device's comparison (module docstring).
    second = 1_000_000_000
    reopen = next(t for t, event in events["/imu/raw"] if event == OPENED)
    skipped = {"/imu/raw": [(int((unplugged_s - 1.0) * second), reopen + second)]}
    for raw, name in (("/leica/port_events", "leica_gnss"), ("/adu5/port_events", "adu5_gnss")):
        kill = int((killed_s[name] - 1.0) * second)
        restart = next(t for t, event in events[raw] if event == STARTED and t > kill)
        skipped[raw] = [(kill, restart + 5 * second)]
    for raw, found in events.items():
        assert found[0][1] == STARTED, (raw, found)  # recorded from the node's start
    for topic, raw in COMPARED.items():
        recorded, rebuilt = _stamped(bag, topic), _stamped(out, topic)
        start, end = events[raw][0][0], min(recorded[-1][0], rebuilt[-1][0])

        def compared(messages, raw=raw, start=start, end=end):
            return [
                (t, m)
                for t, m in messages
                if start <= t <= end and not any(a <= t <= b for a, b in skipped[raw])
            ]

        theirs, mine = compared(recorded), compared(rebuilt)
        first = theirs[0][0]  # the recorder's first message of the topic
        mine = [(t, m) for t, m in mine if t >= first]
        print(f"{topic}: {len(theirs)} compared of {len(recorded)} recorded")
        assert first - start < 30 * second, topic  # the recording's start is compared
        assert len(theirs) > (100 if topic == "/imu/data_raw" else 5), topic
        differing = sorted({t for t, _ in mine} ^ {t for t, _ in theirs})[:5]
        assert mine == theirs, (topic, len(mine), len(theirs), differing)
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
