"""ins_fusion.bags.bag_io: bags written and read back field for field, splits, summaries."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from support.bag_messages import T0, TS, cdr, fix, imu, twist

from ins_fusion.bags.bag_io import BagError, BagReader, BagSummary, BagWriter, read_messages

#: RIHS01 hash of sensor_msgs/msg/Imu as a Jazzy rclpy graph reports it.
IMU_HASH = "RIHS01_7d9a00ff131080897a5ec7e26e315954b8eae3353c3f995c55faf71574000b5b"

finite = st.floats(allow_nan=False, allow_infinity=False, width=64)


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_objects_and_raw_bytes_read_back_intact(tmp_path: Path, storage: str):
    written = []
    with BagWriter(tmp_path / "bag", storage=storage) as writer:
        writer.add_topic("/imu/raw_cdr", "sensor_msgs/msg/Imu")
        for k in range(50):
            t = T0 + k * 7_462_687  # 134 Hz
            for topic, msg in (("/imu/data_raw", imu(t, k)), ("/imu/raw_cdr", cdr(imu(t, -k)))):
                writer.write(topic, t, msg)
                written.append((topic, t, msg if isinstance(msg, bytes) else cdr(msg)))
            if k % 10 == 0:
                for topic, msg in (("/gnss/fix", fix(t, k)), ("/gnss/vel", twist(t, k))):
                    writer.write(topic, t + 1, msg)
                    written.append((topic, t + 1, cdr(msg)))
    with BagReader(tmp_path / "bag") as reader:
        assert {t: (i.msgtype, i.count) for t, i in reader.topics.items()} == {
            "/imu/data_raw": ("sensor_msgs/msg/Imu", 50),
            "/imu/raw_cdr": ("sensor_msgs/msg/Imu", 50),
            "/gnss/fix": ("sensor_msgs/msg/NavSatFix", 5),
            "/gnss/vel": ("geometry_msgs/msg/TwistWithCovarianceStamped", 5),
        }
        raw = list(reader.messages())
        decoded = list(reader.messages(["/imu/data_raw"], deserialize=True))
    # every byte of every message, at its time, in time order
    assert sorted((t, topic, data) for topic, t, data in written) == [
        (m.log_time_ns, m.topic, m.message) for m in raw
    ]
    assert [m.log_time_ns for m in raw] == sorted(m.log_time_ns for m in raw)
    first = decoded[3].message
    assert first.header.frame_id == "imu_link"
    assert (first.header.stamp.sec, first.header.stamp.nanosec) == divmod(T0 + 3 * 7_462_687, 10**9)
    assert (first.angular_velocity.x, first.angular_velocity.y) == (3.0, -3.0)
    assert first.orientation.w == 0.9
    np.testing.assert_array_equal(first.orientation_covariance, np.arange(9) - 1.0)
    np.testing.assert_array_equal(first.linear_acceleration_covariance, np.linspace(0, 1, 9))


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_jazzy_metadata_definitions_and_hashes(tmp_path: Path, storage: str):
    bag = tmp_path / "bag"
    with BagWriter(bag, storage=storage) as writer:
        writer.write("/imu/data_raw", T0, imu(T0, 1.0))
        writer.write("/gnss/fix", T0 + 5, fix(T0 + 5, 1.0))
    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["version"] == 9
    assert info["storage_identifier"] == storage
    suffix = ".mcap" if storage == "mcap" else ".db3"
    assert info["relative_file_paths"] == [f"bag_0{suffix}"]
    assert sorted(p.name for p in bag.iterdir()) == sorted(["metadata.yaml", f"bag_0{suffix}"])
    assert info["message_count"] == 2
    assert info["starting_time"]["nanoseconds_since_epoch"] == T0
    assert info["duration"]["nanoseconds"] == 5
    hashes = {
        t["topic_metadata"]["name"]: t["topic_metadata"]["type_description_hash"]
        for t in info["topics_with_message_count"]
    }
    assert hashes["/imu/data_raw"] == IMU_HASH
    assert hashes["/gnss/fix"] == TS.hash_rihs01("sensor_msgs/msg/NavSatFix")
    if storage == "sqlite3":
        with sqlite3.connect(bag / "bag_0.db3") as db:
            rows = dict(
                db.execute("SELECT topic_type, encoded_message_definition FROM message_definitions")
            )
        assert "MSG: std_msgs/Header" in rows["sensor_msgs/msg/Imu"]
        assert "float64[9] orientation_covariance" in rows["sensor_msgs/msg/Imu"]
    # the reader checks each stored definition against its hash (AnyReader raises on mismatch)
    with BagReader(bag) as reader:
        assert reader.start_ns == T0 and reader.end_ns == T0 + 5


def test_split_by_duration_names_files_like_ros2_bag(tmp_path: Path):
    bag = tmp_path / "drive"
    with BagWriter(bag, max_file_duration_s=1.0) as writer:
        for k in range(350):  # 3.49 s at 100 Hz
            writer.write("/imu/data_raw", T0 + k * 10_000_000, imu(T0, k))
    assert [f.name for f in writer.files] == [f"drive_{i}.mcap" for i in range(4)]
    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["relative_file_paths"] == [f.name for f in writer.files]
    assert [f["message_count"] for f in info["files"]] == [100, 100, 100, 50]
    assert info["message_count"] == 350
    assert info["topics_with_message_count"][0]["message_count"] == 350
    assert info["duration"]["nanoseconds"] == 349 * 10_000_000
    times = [m.log_time_ns for m in read_messages(bag)]
    assert times == [T0 + k * 10_000_000 for k in range(350)]


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_split_by_size_and_time_order_across_files(tmp_path: Path, storage: str):
    bag = tmp_path / "bag"
    size = len(cdr(imu(T0, 0.0)))
    # two streams whose times interleave across the file boundaries
    times = [T0 + k * 1000 for k in range(0, 60, 2)] + [T0 + k * 1000 for k in range(1, 60, 2)]
    with BagWriter(bag, storage=storage, max_file_bytes=10 * size) as writer:
        for t in times:
            writer.write("/imu/data_raw", t, imu(t, 0.0))
    assert len(writer.files) == 6
    assert all(f.exists() for f in writer.files)
    assert [m.log_time_ns for m in read_messages(bag)] == sorted(times)
    assert writer.summary.count == 60


def test_summary_counts_span_and_largest_gap():
    summary = BagSummary()
    for k in range(100):
        t = T0 + k * 10_000_000 + (500_000_000 if k >= 40 else 0)  # 0.5 s hole after k = 39
        summary.add("/imu/data_raw", "sensor_msgs/msg/Imu", t)
    for k in range(5):
        summary.add("/gnss/fix", "sensor_msgs/msg/NavSatFix", T0 + k * 200_000_000)
    stats = summary.topics["/imu/data_raw"]
    assert (stats.count, stats.first_ns, stats.last_ns) == (100, T0, T0 + 1_490_000_000)
    assert stats.max_gap_ns == 510_000_000
    assert summary.count == 105
    assert (summary.start_ns, summary.end_ns) == (T0, T0 + 1_490_000_000)
    gaps = summary.largest_gaps()
    assert [(g.topic, g.start_ns, g.length_ns) for g in gaps] == [
        ("/imu/data_raw", T0 + 390_000_000, 510_000_000)
    ]
    text = summary.format("bag x")
    assert "/gnss/fix" in text and "0.5100 s at +0.390 s" in text


def test_summary_of_a_loop_opens_no_negative_gap():
    summary = BagSummary()
    for t in (T0, T0 + 10, T0 + 20, T0, T0 + 10):
        summary.add("/a", "std_msgs/msg/String", t)
    assert summary.topics["/a"].count == 5
    assert summary.topics["/a"].max_gap_ns == 10


def test_writer_refuses_existing_bag_undeclared_raw_and_unknown_type(tmp_path: Path):
    (tmp_path / "exists").mkdir()
    with pytest.raises(BagError, match="exists"):
        BagWriter(tmp_path / "exists")
    with pytest.raises(BagError, match="storage"):
        BagWriter(tmp_path / "x", storage="rosbag1")
    with BagWriter(tmp_path / "bag") as writer:
        with pytest.raises(BagError, match="undeclared"):
            writer.write("/raw", T0, b"\x00\x01\x00\x00")
        with pytest.raises(BagError, match="typestore"):
            writer.add_topic("/custom", "my_msgs/msg/Nothing")
        writer.add_topic("/imu", "sensor_msgs/msg/Imu")
        with pytest.raises(BagError, match="declared as"):
            writer.add_topic("/imu", "sensor_msgs/msg/NavSatFix")


def test_bag_is_closed_and_readable_after_an_error(tmp_path: Path):
    with pytest.raises(RuntimeError), BagWriter(tmp_path / "bag") as writer:
        writer.write("/imu/data_raw", T0, imu(T0, 1.0))
        raise RuntimeError("stopped")
    assert [m.log_time_ns for m in read_messages(tmp_path / "bag")] == [T0]


def test_reader_rejects_missing_bag_and_unknown_topic(tmp_path: Path):
    with pytest.raises(BagError, match="no such bag"):
        BagReader(tmp_path / "none")
    with BagWriter(tmp_path / "bag") as writer:
        writer.write("/imu/data_raw", T0, imu(T0, 1.0))
    with BagReader(tmp_path / "bag") as reader, pytest.raises(BagError, match="/nope"):
        list(reader.messages(["/nope"]))


@settings(
    max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    k=finite,
    cov=finite,
    frame=st.text(st.characters(codec="utf-8", exclude_categories=["Cs", "Cc"]), max_size=20),
    t_ns=st.integers(0, 2**31 * 10**9 - 1),  # header.stamp.sec is an int32
)
def test_any_imu_message_round_trips(tmp_path_factory, k: float, cov: float, frame: str, t_ns: int):
    bag = tmp_path_factory.mktemp("prop") / "bag"
    msg = imu(t_ns, k, frame, cov)
    with BagWriter(bag) as writer:
        writer.write("/imu/data_raw", t_ns, msg)
    (back,) = read_messages(bag, deserialize=True)
    assert back.log_time_ns == t_ns
    assert back.message.header.frame_id == frame
    assert back.message.angular_velocity.x == k
    assert back.message.angular_velocity_covariance[4] == cov
    assert cdr(back.message) == cdr(msg)


def unfinished_bag(path: Path, storage: str, flushed: int, total: int) -> Path:
    """A bag left as a killed recorder leaves it: split once, ``flushed`` messages of the
    second file flushed, ``total`` written, never closed. Returns the unfinished file."""
    writer = BagWriter(path, storage=storage, max_file_duration_s=1.0)
    for k in range(total):
        writer.write("/imu", T0 + k * 10**8, imu(T0 + k * 10**8, k))  # files of 10 messages
        if k == 10 + flushed - 1:
            writer.flush()
    assert writer._part is not None and writer._part.storage is not None
    return Path(writer._part.storage.path)


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_unfinished_bag_is_refused_with_advice_and_recovered(tmp_path: Path, storage: str):
    from ins_fusion.bags.recover import recover_bag

    unfinished_bag(tmp_path / "bag", storage, flushed=5, total=18)
    with pytest.raises(BagError, match="gnss_ins recover"):
        BagReader(tmp_path / "bag")
    recovered = recover_bag(tmp_path / "bag", tmp_path / "out")
    assert len(recovered.files) == 2
    with BagReader(tmp_path / "out") as reader:
        got = list(reader.messages(deserialize=True))
    assert [m.log_time_ns for m in got] == [T0 + k * 10**8 for k in range(15)]
    assert got[-1].message.angular_velocity.x == 14
    with pytest.raises(BagError, match="complete"):
        recover_bag(tmp_path / "out", tmp_path / "again")


@pytest.mark.parametrize("size", [0, 8, 9, 12])
def test_mcap_torn_in_its_header_is_a_clean_error(tmp_path: Path, size: int) -> None:
    """An MCAP file that ends in or right after its magic (hypothesis found 8 bytes)."""
    last = unfinished_bag(tmp_path / "bag", "mcap", flushed=4, total=14)
    last.write_bytes(last.read_bytes()[:size])
    with pytest.raises(BagError, match="gnss_ins recover"):
        BagReader(last)


@settings(
    max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(cut=st.floats(0.0, 1.0))
def test_mcap_cut_anywhere_recovers_a_prefix(tmp_path_factory, cut: float):
    from ins_fusion.bags.recover import recover_bag

    tmp = tmp_path_factory.mktemp("cut")
    last = unfinished_bag(tmp / "bag", "mcap", flushed=4, total=14)
    data = last.read_bytes()
    last.write_bytes(data[: round(cut * len(data))])  # a write torn anywhere
    with pytest.raises(BagError, match="gnss_ins recover"):
        BagReader(last)  # the torn file itself: a clean error, not a traceback
    recover_bag(tmp / "bag", tmp / "out")
    times = [m.log_time_ns for m in read_messages(tmp / "out")]
    assert times == [T0 + k * 10**8 for k in range(len(times))]
    assert len(times) in (10, 14)  # the closed file, and the flushed chunk unless torn
