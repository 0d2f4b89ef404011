"""A recorder killed on a live system: three driver processes on emulated devices publish five
topics, ``gnss_ins record`` is SIGKILLed 5 s after it subscribed to all of them (split files:
2 s into its second file), ``gnss_ins recover`` restores the bag. A
collector in the test process is the reference: every message it received up to 1 s before the
kill must be in the recovered bag, none missing before that. MCAP, sqlite3, and split files
killed during the second file."""

from __future__ import annotations

import signal
import subprocess
import threading
import time

import pytest
import rclpy
from geometry_msgs.msg import TwistWithCovarianceStamped
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import Imu, NavSatFix
from support.pacing import pause
from support.ros_harness import Collector, spinning, wait_for

from gnss_driver.emulator import EmulatorConfig, GnssEmulator, constant_velocity
from gnss_driver.profiles import Receiver
from imu400cc_driver.emulator import Imu400ccEmulator
from ins_fusion.bags.bag_io import BagReader
from ins_fusion.runtime.processes import gnss_ins_command
from ins_fusion.runtime.vehicle_nodes import ADU5, IMU, LEICA, command
from ins_fusion.tools.cli import main

pytestmark = pytest.mark.ros

TOPICS = {
    "/imu/data_raw": Imu,
    "/leica/gnss/fix": NavSatFix,
    "/leica/gnss/vel": TwistWithCovarianceStamped,
    "/adu5/gnss/attitude": Imu,
    "/adu5/gnss/fix": NavSatFix,
}
TYPES = {topic: kind for topic, kind in TOPICS.items()}
#: Seconds the recorder records after its subscriptions (split: after its second file began)
#: before its kill.
RECORD_S = 5.0


@pytest.fixture(scope="module")
def live_system(tmp_path_factory):
    """The three devices emulated, their three driver processes, a reference collector."""
    rclpy.init()
    logs = tmp_path_factory.mktemp("logs")
    leica = GnssEmulator(
        constant_velocity((3.0, 4.0, 0.0)), EmulatorConfig(receiver=Receiver.LEICA)
    )
    adu5 = GnssEmulator(constant_velocity((3.0, 4.0, 0.0)), EmulatorConfig(receiver=Receiver.ADU5))
    with Imu400ccEmulator() as imu, leica, adu5:
        nodes = [
            subprocess.Popen(
                command(spec, None, port),
                stdout=(logs / f"{spec.name}.log").open("w"),
                stderr=subprocess.STDOUT,
            )
            for spec, port in ((IMU, imu.path), (LEICA, leica.path), (ADU5, adu5.path))
        ]
        collector = Collector(TOPICS)
        try:
            with spinning(collector.node):
                assert wait_for(lambda: all(collector.count(t) for t in TOPICS), 60.0), {
                    t: collector.count(t) for t in TOPICS
                }
                yield collector
        finally:
            for node in nodes:
                node.send_signal(signal.SIGINT)
            for node in nodes:
                node.wait(timeout=30)
            collector.node.destroy_node()
            rclpy.shutdown()


def stamp_ns(msg: Imu | NavSatFix | TwistWithCovarianceStamped) -> int:
    return msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec


@pytest.mark.parametrize(
    ("storage", "split"),
    [("mcap", []), ("sqlite3", []), ("mcap", ["--max-bag-duration", "12"])],
    ids=["mcap", "sqlite3", "mcap-split"],
)
def test_killed_recorder_loses_at_most_the_last_second(live_system, tmp_path, storage, split):
    collector: Collector = live_system
    bag = tmp_path / "drive"
    recorder = subprocess.Popen(
        gnss_ins_command("record", "-o", str(bag), "--storage", storage, *split, *TOPICS),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    started = time.time()
    lines: list[str] = []

    def read() -> None:
        assert recorder.stderr is not None
        for line in recorder.stderr:
            lines.append(line)

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        subscribed = lambda: all(f"recording {t} " in "".join(lines) for t in TOPICS)  # noqa: E731
        # Discovery on a loaded machine (the clean-clone run's node session beside the others)
        # once took longer than 30 s for the GNSS topics, their nodes alive and publishing.
        assert wait_for(subscribed, 90.0), "".join(lines)
        if split:
            # the second file is written in its own folder until it is closed
            assert wait_for(lambda: (bag / f"{bag.name}_1").exists(), 30.0)
            pause(2.0)  # into the second file
        else:
            pause(RECORD_S)  # the recording before the kill
        recorder.kill()
        killed = time.time()
        recorder.wait(timeout=30)
        reader.join(timeout=30)
    finally:
        if recorder.poll() is None:
            recorder.kill()
    err = "".join(lines)
    assert "recording /adu5/gnss/fix" in err, err
    assert main(["recover", str(bag), "-o", str(tmp_path / "recovered")]) == 0
    with BagReader(tmp_path / "recovered") as reader:
        files = reader.topics and sorted(p.name for p in (tmp_path / "recovered").iterdir())
        recorded: dict[str, set[int]] = {t: set() for t in TOPICS}
        for msg in reader.messages():
            recorded[msg.topic].add(stamp_ns(deserialize_message(msg.message, TYPES[msg.topic])))
    if split:
        assert len([f for f in files if f.endswith(".mcap")]) == 2  # killed in the second file
    lost_at_end = {}
    for topic in TOPICS:
        sent = list(zip(collector.receive_times[topic], collector.get(topic), strict=True))
        # From the recorder's subscription (its first message of the topic) to 1 s before the kill.
        subscribed = min(at for at, msg in sent if stamp_ns(msg) in recorded[topic])
        assert subscribed < started + 10.0
        window = [stamp_ns(msg) for at, msg in sent if subscribed <= at <= killed - 1.0]
        missing = [s for s in window if s not in recorded[topic]]
        assert not missing, (
            f"{topic}: {len(missing)} of {len(window)} missing, at"
            f" {sorted({round((m - window[0]) / 1e9, 1) for m in missing})} s of the window"
        )
        last = max(at for at, msg in sent if stamp_ns(msg) in recorded[topic])
        lost_at_end[topic] = killed - last
        times = collector.receive_times[topic]
        period = (times[-1] - times[0]) / (len(times) - 1)  # a topic's last message may be
        assert lost_at_end[topic] <= 1.0 + period, (topic, lost_at_end[topic])  # that old
    print(storage, split, {t: round(s, 3) for t, s in lost_at_end.items()})
