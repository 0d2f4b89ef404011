"""``gnss_ins record`` and ``gnss_ins play`` through real rclpy nodes.

A publisher in the test process sends a known sequence, the recorder (a subprocess) writes it,
is stopped by a signal, and the bag is compared byte for byte; then the player (a subprocess)
publishes the bag to a collector and a use_sim_time node in the test process.
"""

from __future__ import annotations

import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import rclpy
import yaml
from rclpy.duration import Duration
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from rclpy.serialization import deserialize_message, serialize_message
from rosbags.interfaces import QosReliability
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu, NavSatFix
from support.pacing import pause
from support.paths import REPO
from support.ros_harness import Collector, spinning, wait_for

from ins_fusion.bags.bag_io import BagReader, BagWriter
from ins_fusion.tools.cli import main

pytestmark = pytest.mark.ros

N_IMU, N_FIX, N_SENSOR = 200, 20, 10
PLAYED = ["/test/imu", "/test/fix"]


@pytest.fixture(scope="module", autouse=True)
def ros_context():
    rclpy.init()
    yield
    rclpy.shutdown()


#: Runs one sub-command module the way ``gnss_ins`` does, without importing every other one.
SUBCOMMAND = """
import argparse, importlib, sys
module = importlib.import_module("ins_fusion.tools." + sys.argv[1])
parser = argparse.ArgumentParser()
module.add_arguments(parser)
sys.exit(module.run(parser.parse_args(sys.argv[2:])))
"""


def gnss_ins(command: str, *args: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-c", SUBCOMMAND, command, *args],
        cwd=REPO,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def finish(process: subprocess.Popen[str], timeout_s: float = 60.0) -> str:
    out, err = process.communicate(timeout=timeout_s)
    assert process.returncode == 0, err
    return out


def imu(k: int) -> Imu:
    msg = Imu()
    msg.header.stamp.sec, msg.header.stamp.nanosec = 1_700_000_000 + k // 134, k % 134 * 7_462_686
    msg.header.frame_id = "imu_link"
    msg.angular_velocity.x, msg.angular_velocity.z = 0.001 * k, -0.5
    msg.linear_acceleration.z = 9.81 + 1e-4 * k
    msg.orientation_covariance[0] = -1.0
    msg.angular_velocity_covariance[4] = 1e-6 * k
    return msg


def fix(k: int) -> NavSatFix:
    msg = NavSatFix()
    msg.header.frame_id = "gnss_link"
    msg.latitude, msg.longitude, msg.altitude = 63.4 + 1e-6 * k, 10.4, 50.0 + k
    msg.position_covariance[8] = 4.0
    return msg


def publish_sequence(node) -> tuple[dict[str, list], int, int]:
    """Publish the known sequence once the recorder subscribed; returns the sent messages per
    topic and the wall-clock window (ns) that holds every receive time."""
    reliable = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
    pubs = {
        "/test/imu": node.create_publisher(Imu, "/test/imu", reliable),
        "/test/fix": node.create_publisher(NavSatFix, "/test/fix", reliable),
        "/test/sensor": node.create_publisher(Imu, "/test/sensor", qos_profile_sensor_data),
    }
    assert wait_for(lambda: all(p.get_subscription_count() for p in pubs.values()), 30.0)
    sent: dict[str, list] = {topic: [] for topic in pubs}
    window_start = time.time_ns()
    for k in range(N_IMU):
        for topic, msg, every in (
            ("/test/imu", imu(k), 1),
            ("/test/fix", fix(k), N_IMU // N_FIX),
            ("/test/sensor", imu(-k), N_IMU // N_SENSOR),
        ):
            if k % every == 0:
                pubs[topic].publish(msg)
                sent[topic].append(msg)
        pause(0.002)  # >= 0.4 s of publishing in all
    for topic in PLAYED:
        assert pubs[topic].wait_for_all_acked(Duration(seconds=20))  # acks ride on heartbeats
    return sent, window_start, time.time_ns()


def play_back_and_compare(bag: Path, sent: dict[str, list]) -> None:
    with BagReader(bag) as reader:
        played = list(reader.messages(PLAYED))
        bag_start_ns = reader.start_ns  # play starts here: --all records other topics earlier
    first_ns, last_ns = played[0].log_time_ns, played[-1].log_time_ns
    collector = Collector({"/test/imu": Imu, "/test/fix": NavSatFix, "/clock": Clock})
    follower = rclpy.create_node(
        "sim_time_follower", parameter_overrides=[Parameter("use_sim_time", value=True)]
    )
    try:
        with spinning(collector.node, follower):
            player = gnss_ins(
                "play", str(bag), "--topics", *PLAYED, "--clock", "50", "--rate", "2",
                "--wait-for-subscribers",
            )  # fmt: skip
            out = finish(player)
            assert wait_for(lambda: [collector.count(t) for t in PLAYED] == [N_IMU, N_FIX], 10.0), [
                collector.count(t) for t in PLAYED
            ]
            assert wait_for(lambda: follower.get_clock().now().nanoseconds == last_ns, 10.0)
        for topic in PLAYED:
            assert collector.get(topic) == sent[topic]
        clock_ns = [c.clock.sec * 10**9 + c.clock.nanosec for c in collector.get("/clock")]
        assert len(clock_ns) >= 2
        assert clock_ns == sorted(clock_ns)
        assert bag_start_ns <= clock_ns[0] <= first_ns and clock_ns[-1] == last_ns
        assert f"/test/imu  sensor_msgs/msg/Imu  {N_IMU:>8}" in out.replace("        ", "  ")
    finally:
        collector.node.destroy_node()
        follower.destroy_node()


@pytest.mark.parametrize(
    ("storage", "signum", "options"),
    [
        ("mcap", signal.SIGINT, ["/test/imu", "test/fix", "/test/sensor"]),
        ("sqlite3", signal.SIGTERM, ["--all", "--max-bag-duration", "0.3"]),
    ],
)
def test_record_stop_and_play_back(tmp_path: Path, storage: str, signum: int, options: list[str]):
    bag = tmp_path / "bag"
    recorder = gnss_ins("record", "-o", str(bag), "--storage", storage, *options)
    node = rclpy.create_node("test_publisher")  # created after the recorder: it waits for it
    try:
        sent, window_start, window_end = publish_sequence(node)
        recorder.send_signal(signum)
        out = finish(recorder)
        type_hash = str(node.get_publishers_info_by_topic("/test/imu")[0].topic_type_hash)
    finally:
        if recorder.poll() is None:
            recorder.kill()
        node.destroy_node()

    assert "lost in transport once subscribed (reported by the middleware): none" in out
    assert re.search(r"topics subscribed [\d.-]+ s after the start: messages published", out)
    with BagReader(bag) as reader:
        topics = reader.topics
        recorded = {t: list(reader.messages([t])) for t in ("/test/imu", "/test/fix")}
        sensor = list(reader.messages(["/test/sensor"]))
    # every message with every field (the wire bytes may carry CDR end padding)
    for topic, cls in (("/test/imu", Imu), ("/test/fix", NavSatFix)):
        assert [deserialize_message(m.message, cls) for m in recorded[topic]] == sent[topic]
        times = [m.log_time_ns for m in recorded[topic]]
        assert times == sorted(times)
        assert window_start <= times[0] and times[-1] <= window_end
    assert 1 <= len(sensor) <= N_SENSOR
    assert all(deserialize_message(m.message, Imu) in sent["/test/sensor"] for m in sensor)
    assert topics["/test/fix"].qos[0].reliability == QosReliability.RELIABLE
    assert topics["/test/sensor"].qos[0].reliability == QosReliability.BEST_EFFORT
    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    hashes = {
        t["topic_metadata"]["name"]: t["topic_metadata"]["type_description_hash"]
        for t in info["topics_with_message_count"]
    }
    assert hashes["/test/imu"] == type_hash  # what the rclpy graph reports for the type
    assert info["storage_identifier"] == storage
    if "--all" in options:
        assert len(info["relative_file_paths"]) >= 2  # >= 0.4 s recorded, split every 0.3 s
    else:
        assert sorted(topics) == ["/test/fix", "/test/imu", "/test/sensor"]
    play_back_and_compare(bag, sent)


def test_play_loops_until_interrupted(tmp_path: Path):
    bag = tmp_path / "tiny"
    with BagWriter(bag, storage="sqlite3") as writer:
        writer.add_topic("/test/imu", "sensor_msgs/msg/Imu")
        for k in range(10):
            writer.write("/test/imu", 10**18 + k * 10_000_000, serialize_message(imu(k)))
    collector = Collector({"/test/imu": Imu}, name="loop_collector")
    try:
        with spinning(collector.node):
            player = gnss_ins("play", str(bag), "--loop", "--wait-for-subscribers")
            looped = wait_for(lambda: collector.count("/test/imu") >= 30, 30.0)
            player.send_signal(signal.SIGINT)
            out = finish(player)
        assert looped
        assert collector.get("/test/imu")[:30] == [imu(k % 10) for k in range(30)]
        assert "pass(es)" in out
    finally:
        collector.node.destroy_node()


def test_play_interrupted_before_any_subscriber_says_nothing_was_published(tmp_path: Path):
    bag = tmp_path / "unheard"
    with BagWriter(bag, storage="mcap") as writer:
        writer.add_topic("/test/unheard", "sensor_msgs/msg/Imu")
        writer.write("/test/unheard", 10**18, serialize_message(imu(0)))
    player = gnss_ins("play", str(bag), "--loop", "--wait-for-subscribers")
    assert player.stderr is not None
    assert "waiting for subscribers" in player.stderr.readline()
    player.send_signal(signal.SIGINT)
    out = finish(player)
    assert "interrupted while waiting for subscribers, nothing published" in out
    assert "pass(es)" not in out


def test_refusals(tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    assert main(["record", "-o", str(tmp_path / "bag")]) == 2
    assert "name topics" in capsys.readouterr().err
    assert main(["play", str(tmp_path / "none")]) == 2
    assert "no such bag" in capsys.readouterr().err
    assert not (tmp_path / "bag").exists()


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_killed_record_is_recovered_up_to_the_last_second(tmp_path: Path, storage: str):
    bag = tmp_path / "bag"
    recorder = gnss_ins("record", "-o", str(bag), "--storage", storage, "/test/live")
    node = rclpy.create_node("live_publisher")
    reliable = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
    publisher = node.create_publisher(Imu, "/test/live", reliable)
    try:
        assert wait_for(lambda: publisher.get_subscription_count() > 0, 30.0)
        sent_ns = []
        for k in range(300):  # 3 s at 100 Hz, each message stamped with its publication time
            msg = imu(k)
            sent_ns.append(time.time_ns())
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(sent_ns[-1], 10**9)
            publisher.publish(msg)
            pause(0.01)  # 100 Hz
        recorder.kill()
        killed_ns = time.time_ns()
        recorder.communicate(timeout=30)
    finally:
        if recorder.poll() is None:
            recorder.kill()
        node.destroy_node()
    assert not (bag / "metadata.yaml").exists()
    assert main(["recover", str(bag)]) == 0
    with BagReader(tmp_path / "bag_recovered") as reader:
        headers = [deserialize_message(m.message, Imu).header for m in reader.messages()]
    stamps = [h.stamp.sec * 10**9 + h.stamp.nanosec for h in headers]
    assert stamps == sent_ns[: len(stamps)]  # in order, none missing
    print(f"{storage}: {(killed_ns - stamps[-1]) / 1e9:.3f} s before the kill lost")
    assert len(stamps) >= sum(t <= killed_ns - 10**9 for t in sent_ns)  # all but the last 1 s


def test_a_topic_is_silent_after_its_messages_stop_and_before_its_first_only_much_later(
    tmp_path: Path,
):
    """--silence-warning 0.5: a topic whose messages stopped is called silent within ~1 s; one
    that has a publisher but no message yet (the fusion's outputs while it aligns, a receiver
    sent no set-up commands) is never silent, its log says "no message yet" once after
    12 x 0.5 s; one that carried a burst of messages (set-up commands written) is never silent."""
    from diagnostic_msgs.msg import DiagnosticArray
    from rcl_interfaces.msg import Log
    from std_msgs.msg import String

    node = rclpy.create_node("test_silences")
    collector = Collector({"/diagnostics": DiagnosticArray, "/rosout": Log})

    def no_message_yet_at() -> list[float]:
        return [
            at
            for at, log in zip(
                collector.receive_times["/rosout"], collector.get("/rosout"), strict=True
            )
            if log.msg.startswith("/test/quiet: no message yet") and log.level == Log.INFO
        ]

    stops = node.create_publisher(String, "/test/stops", 10)
    node.create_publisher(String, "/test/quiet", 10)  # never publishes
    burst = node.create_publisher(String, "/test/burst", 10)

    def silent_since(start: float) -> list[tuple[float, str]]:
        return [
            (at, status.message)
            for at, array in zip(
                collector.receive_times["/diagnostics"], collector.get("/diagnostics"), strict=True
            )
            for status in array.status
            if at >= start and status.name.startswith("gnss_ins_record")
            and status.message.startswith("silent")
        ]  # fmt: skip

    recorder = gnss_ins(
        "record", "-o", str(tmp_path / "bag"), "--silence-warning", "0.5", "/test/stops",
        "/test/quiet", "/test/burst", "/test/nobody",
    )  # fmt: skip
    try:
        with spinning(collector.node):
            assert wait_for(lambda: stops.get_subscription_count() > 0, 20.0)
            assert wait_for(lambda: burst.get_subscription_count() > 0, 20.0)

            def statuses() -> list[tuple[bytes, str]]:
                return [
                    (s.level, s.message)
                    for array in collector.get("/diagnostics")
                    for s in array.status
                    if s.name.startswith("gnss_ins_record")
                ]

            # A requested topic nobody publishes (corrections without a caster) is no fault.
            assert wait_for(
                lambda: (b"\x00", "recording; no publisher yet: /test/nobody") in statuses(), 10.0
            )
            start = time.time()
            for _ in range(5):
                burst.publish(String(data="set-up"))
            for _ in range(30):  # 1.5 s at 20 Hz: a stream
                stops.publish(String(data="x"))
                pause(0.05)  # 20 Hz
            stopped = time.time()
            assert wait_for(lambda: silent_since(stopped), 5.0)
            _, message = silent_since(stopped)[0]
            assert message == "silent: /test/stops"
            assert wait_for(no_message_yet_at, 15.0)
            reports = collector.count("/diagnostics")
            assert wait_for(lambda: collector.count("/diagnostics") > reports + 1, 5.0)
            assert not any("quiet" in m for _, m in silent_since(start))
        recorder.send_signal(signal.SIGINT)
        _out, err = recorder.communicate(timeout=60)
    finally:
        if recorder.poll() is None:
            recorder.kill()
        node.destroy_node()
        collector.node.destroy_node()
    # Called silent after the 0.5 s it was given, within a second; "no message yet" only
    # after 12 x 0.5 s since the subscription (the recorder's own reckoning in its log).
    silent = re.search(r"/test/stops silent for ([\d.]+) s although it has a publisher", err)
    assert silent and 0.5 <= float(silent.group(1)) < 2.0, err
    waited = re.search(r"/test/quiet: no message yet, (\d+) s after its subscription", err)
    assert waited and int(waited.group(1)) >= 12 * 0.5, err
    assert err.count("/test/quiet: no message yet") == 1 and "/test/quiet silent for" not in err
    assert "/test/burst silent" not in err and "/test/burst: no message" not in err
    assert not any("burst" in m or "nobody" in m for _, m in silent_since(start))
