"""ins_fusion.bags.columns: the columns of a bag's topics hold exactly the messages, log
times and receive order that bag_io's message-by-message reader gives, for MCAP (read from its
message indexes: several chunks, split files, equal log times across topics, chunk checksums)
and sqlite3."""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag2.storage_mcap import McapReader

from ins_fusion.bags import columns as bag_columns
from ins_fusion.bags.bag_io import BagError, BagReader, BagWriter
from ins_fusion.bags.columns import read_topics
from ins_fusion.bags.typestore import jazzy_typestore

TS = jazzy_typestore()
T = TS.types
T0 = 1_717_236_000_000_000_000
TOPICS = {
    "/imu": "sensor_msgs/msg/Imu",
    "/fix": "sensor_msgs/msg/NavSatFix",
    "/other": "sensor_msgs/msg/Imu",
}


def _imu(t_ns: int, frame: str) -> bytes:
    header = T["std_msgs/msg/Header"](T["builtin_interfaces/msg/Time"](*divmod(t_ns, 10**9)), frame)
    vec = T["geometry_msgs/msg/Vector3"](t_ns % 97 * 1e-3, 0.0, 9.8)
    msg = T["sensor_msgs/msg/Imu"](
        header,
        T["geometry_msgs/msg/Quaternion"](0.0, 0.0, 0.0, 1.0),
        np.zeros(9),
        vec,
        np.zeros(9),
        vec,
        np.zeros(9),
    )
    return bytes(TS.serialize_cdr(msg, "sensor_msgs/msg/Imu"))


def _fix(t_ns: int) -> bytes:
    header = T["std_msgs/msg/Header"](
        T["builtin_interfaces/msg/Time"](*divmod(t_ns, 10**9)), "gnss"
    )
    status = T["sensor_msgs/msg/NavSatStatus"](0, 1)
    msg = T["sensor_msgs/msg/NavSatFix"](
        header, status, 57.0, 10.0, t_ns % 13, np.eye(3).ravel(), 2
    )
    return bytes(TS.serialize_cdr(msg, "sensor_msgs/msg/NavSatFix"))


def _write(path: Path, storage: str, max_file_bytes: int = 0) -> None:
    """5 000 IMU messages at 200 Hz (some with another frame_id, so another length), a fix on
    every 40th sample's log time (a tie with it), and an unread topic."""
    with BagWriter(path, storage=storage, max_file_bytes=max_file_bytes) as writer:
        for topic, msgtype in TOPICS.items():
            writer.add_topic(topic, msgtype)
        for k in range(5000):
            t = T0 + k * 5_000_000
            if k % 40 == 0:
                writer.write("/fix", t, _fix(t))  # written first, received with the sample
            writer.write("/imu", t, _imu(t, "imu_link" if k % 7 else "imu"))
            if k % 100 == 0:
                writer.write("/other", t + 1, _imu(t, "x"))


def _expected(
    reader: BagReader, topics: list[str]
) -> dict[str, tuple[list[int], list[int], list[bytes]]]:
    found: dict[str, tuple[list[int], list[int], list[bytes]]] = {t: ([], [], []) for t in topics}
    for index, msg in enumerate(reader.messages(topics)):
        times, order, payloads = found[msg.topic]
        times.append(msg.log_time_ns)
        order.append(index)
        payloads.append(msg.message)
    return found


@pytest.mark.parametrize(
    ("storage", "max_file_bytes"), [("mcap", 0), ("mcap", 1_200_000), ("sqlite3", 0)]
)
def test_columns_are_the_messages_in_receive_order(tmp_path, storage, max_file_bytes):
    path = tmp_path / "bag"
    _write(path, storage, max_file_bytes)
    topics = ["/imu", "/fix"]
    done: list[int] = []
    with BagReader(path) as reader:
        columns = read_topics(reader, topics, done.append)
        expected = _expected(reader, topics)
    assert done and done[-1] <= 5000 + 125
    for topic in topics:
        times, order, payloads = expected[topic]
        column = columns[topic]
        assert column.msgtype == TOPICS[topic]
        assert column.log_time_ns.tolist() == times
        assert column.order.tolist() == order
        assert list(column.payloads) == payloads
    assert len(columns["/fix"].payloads) == 125


def test_mcap_is_read_from_its_indexes_in_chunks_and_files(tmp_path):
    """The bag of the test above has several chunks per file and several files; the indexed
    reader (not the fallback) reads it."""
    path = tmp_path / "bag"
    _write(path, "mcap", 1_200_000)
    files = sorted(path.glob("*.mcap"))
    assert len(files) >= 2
    parts = bag_columns._indexed_mcap(files, {"/imu", "/fix"}, None)
    assert parts is not None
    assert len({(p.file, p.chunk_offset) for p in parts}) > len(files)


def _with_chunk_checksums(path: Path) -> list[tuple[int, int]]:
    """Write each chunk's CRC-32 of its records into an MCAP file (rosbags writes 0: none;
    ``ros2 bag record`` writes them); returns each chunk's (records offset, size)."""
    data = bytearray(path.read_bytes())
    records = []
    storage = McapReader(path)
    storage.open()
    for chunk in storage.chunks:
        start = chunk.chunk_start_offset + bag_columns._CHUNK_HEADER
        end = start + chunk.uncompressed_size
        crc = zlib.crc32(data[start:end])
        struct.pack_into("<I", data, chunk.chunk_start_offset + bag_columns._CHUNK_CRC_AT, crc)
        records.append((start, chunk.uncompressed_size))
    storage.close()
    path.write_bytes(bytes(data))
    return records


def test_chunk_checksums_are_checked(tmp_path):
    """Chunks with a CRC read as before; a damaged byte in one is a BagError naming the
    checksum, not wrong numbers."""
    path = tmp_path / "bag"
    _write(path, "mcap")
    (file,) = path.glob("*.mcap")
    records = _with_chunk_checksums(file)
    topics = ["/imu", "/fix"]
    with BagReader(path) as reader:
        columns = read_topics(reader, topics)
        expected = _expected(reader, topics)  # rosbags checks the CRCs too
    assert [list(columns[t].payloads) for t in topics] == [expected[t][2] for t in topics]
    data = bytearray(file.read_bytes())
    start, size = records[-1]
    data[start + size // 2] ^= 0xFF
    file.write_bytes(bytes(data))
    with BagReader(path) as reader, pytest.raises(BagError, match="checksum mismatch"):
        read_topics(reader, topics)
