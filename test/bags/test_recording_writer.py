"""ins_fusion.bags.recording: log-time order, bounded flushes, the disk guard (a fake statvfs;
the live recorder on a real full file system is in test_record_disk.py)."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st
from support.bag_messages import T0, cdr, imu

from ins_fusion.bags.bag_io import BagReader, BagWriter, read_messages
from ins_fusion.bags.recording import FreeSpace, MinFree, RecordingWriter

MS = 10**6
GIB = 2**30


class FakeDisk:
    """A file system whose free space the test sets; deleting a file frees its size."""

    def __init__(self, free: int, total: int = 100 * GIB) -> None:
        self.free, self.total = free, total

    def __call__(self, _: Path) -> FreeSpace:
        return FreeSpace(self.free, self.total)


def recording(tmp_path: Path, disk: FakeDisk, policy: str = "stop", split_s: float = 0.0):
    writer = BagWriter(tmp_path / "bag", max_file_duration_s=split_s)
    writer.add_topic("/imu", "sensor_msgs/msg/Imu")
    log: list[tuple[str, str]] = []
    rec = RecordingWriter(
        writer,
        lambda level, text: log.append((level, text)),
        hold_s=0.2,
        flush_period_s=0.4,
        min_free=MinFree.parse("1G"),
        policy=policy,
        statvfs=disk,
    )
    return rec, log


def test_messages_are_written_in_log_time_order_after_the_hold(tmp_path: Path):
    rec, _ = recording(tmp_path, FakeDisk(50 * GIB))
    arrival = [0, 30, 10, 50, 20, 400, 40]  # ms; 40 arrives after 400 was written: late
    for k, ms in enumerate(arrival[:5]):
        rec.receive("/imu", T0 + ms * MS, cdr(imu(T0 + ms * MS, k)))
    rec.service(now_ns=T0 + 100 * MS, monotonic=0.0)
    assert rec.writer.summary.count == 0  # all still held
    rec.service(now_ns=T0 + 240 * MS, monotonic=0.1)
    assert rec.writer.summary.count == 4  # 0, 10, 20, 30: held 0.2 s by 240 ms
    rec.receive("/imu", T0 + 400 * MS, cdr(imu(T0 + 400 * MS, 5)))
    rec.service(now_ns=T0 + 700 * MS, monotonic=0.2)
    rec.receive("/imu", T0 + 40 * MS, cdr(imu(T0 + 40 * MS, 6)))
    rec.close()
    assert rec.late == 1
    times = [(m.log_time_ns - T0) // MS for m in read_messages(tmp_path / "bag")]
    assert times == [0, 10, 20, 30, 40, 50, 400]


def test_service_asks_to_be_called_when_the_next_message_or_flush_is_due(tmp_path: Path):
    rec, _ = recording(tmp_path, FakeDisk(50 * GIB))
    assert rec.service(now_ns=T0, monotonic=0.0) == pytest.approx(1.0)  # the next disk check
    rec.receive("/imu", T0, cdr(imu(T0, 0)))
    assert rec.service(now_ns=T0 + 50 * MS, monotonic=0.05) == pytest.approx(0.15)
    rec.service(now_ns=T0 + 200 * MS, monotonic=0.2)
    assert rec.service(now_ns=T0 + 210 * MS, monotonic=0.21) == pytest.approx(0.39)
    rec.close()


def test_the_guard_warns_at_twice_the_limit_then_stops_with_a_complete_bag(tmp_path: Path):
    disk = FakeDisk(3 * GIB)
    rec, log = recording(tmp_path, disk)
    for k in range(10):
        rec.receive("/imu", T0 + k * 10 * MS, cdr(imu(T0 + k * 10 * MS, k)))
    rec.service(now_ns=T0 + GIB, monotonic=0.0)
    assert log == []
    disk.free = GIB + GIB // 2
    rec.service(now_ns=T0 + GIB, monotonic=1.0)
    assert [level for level, _ in log] == ["warn"] and "disk space low" in log[0][1]
    rec.receive("/imu", T0 + 2 * GIB, cdr(imu(T0 + 2 * GIB, 99)))
    disk.free = GIB - 1
    rec.service(now_ns=T0 + 2 * GIB, monotonic=2.0)
    assert rec.stopped is not None and "below the limit" in rec.stopped
    assert log[-1][0] == "error"
    with BagReader(tmp_path / "bag") as reader:  # complete: no recover needed
        assert reader.topics["/imu"].count == 11


def test_rotation_deletes_the_oldest_files_of_the_recording_and_says_which(tmp_path: Path):
    disk = FakeDisk(50 * GIB)
    rec, log = recording(tmp_path, disk, policy="rotate", split_s=1.0)
    for k in range(45):  # 4 closed files and an open one
        t = T0 + k * 100 * MS
        rec.receive("/imu", t, cdr(imu(t, k)))
        rec.service(now_ns=t + 300 * MS, monotonic=k * 0.1)
    assert [f.name for f in rec.writer.files] == [f"bag_{i}.mcap" for i in range(4)]

    def freed(_: Path) -> FreeSpace:  # each deletion frees 0.6 GiB
        return FreeSpace(GIB // 2 + 6 * GIB // 10 * len(rec.deleted), 100 * GIB)

    rec.statvfs = freed
    rec.service(now_ns=T0 + 10**10, monotonic=100.0)
    assert rec.stopped is None
    # The open file closed at the limit; deleted until twice the limit (2 GiB) was free.
    assert [p.name for p in rec.deleted] == ["bag_0.mcap", "bag_1.mcap", "bag_2.mcap"]
    assert sum("deleted the oldest file bag_" in text for _, text in log) == 3
    rec.close()
    with BagReader(tmp_path / "bag") as reader:
        assert reader.topics["/imu"].count == 15  # bag_3 and bag_4


@given(st.integers(0, 10**15), st.sampled_from(["", "K", "M", "G", "KiB", "MB", "g"]))
def test_min_free_sizes_parse(value: int, unit: str):
    scale = {"": 1, "K": 2**10, "M": 2**20, "G": 2**30}[unit[:1].upper()]
    assert MinFree.parse(f"{value}{unit}").limit(10**18) == value * scale


def test_min_free_percent_and_both_and_refusals():
    assert MinFree.parse("5%").limit(1000) == 50
    assert MinFree.parse("1G,5%").limit(4 * GIB) == round(0.05 * 4 * GIB)
    assert MinFree.parse("1G,5%").limit(100 * GIB) == GIB
    for bad in ("", "x", "5%%", "120%", "1G,2G", "-1G", "nan", "inf"):
        with pytest.raises(ValueError):
            MinFree.parse(bad)
