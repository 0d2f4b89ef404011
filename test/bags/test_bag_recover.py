"""Recovery of killed recordings (ins_fusion.bags.salvage, .recover): files cut at any byte, several
topics whose messages reach the file out of log-time order, split files, sqlite3."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from support.bag_messages import T0, cdr, fix, imu, twist

from ins_fusion.bags.bag_io import BagError, BagReader, BagWriter, read_messages
from ins_fusion.bags.recover import recover_bag
from ins_fusion.bags.salvage import salvage
from ins_fusion.tools.cli import main

MS = 10**6
TOPICS = {"/imu": "sensor_msgs/msg/Imu", "/fix": "sensor_msgs/msg/NavSatFix"}
TOPICS["/vel"] = "geometry_msgs/msg/TwistWithCovarianceStamped"


def arrivals(count: int) -> list[tuple[str, int, bytes]]:
    """``count`` IMU messages at 100 Hz with a GNSS fix and velocity every 10th, each of those
    arriving 55 ms after IMU messages stamped later (a receiver's latency): out of order."""
    out: list[tuple[str, int, bytes]] = []
    for k in range(count):
        t = T0 + k * 10 * MS
        out.append(("/imu", t, cdr(imu(t, k))))
        if k % 10 == 5:
            epoch = t - 55 * MS
            out.append(("/fix", epoch, cdr(fix(epoch, k))))
            out.append(("/vel", epoch, cdr(twist(epoch, k))))
    return out


def killed_recording(
    path: Path, storage: str, count: int, flush_every: int, split_s: float
) -> tuple[Path, list[tuple[int, set[tuple[str, int]]]]]:
    """A recording killed after ``count`` IMU messages: writes as the recorder does (flush every
    ``flush_every`` messages), never closed. Returns the unfinished file and, per flush of it, its
    size then and the messages on disk up to then (including the closed files')."""
    writer = BagWriter(path, storage=storage, max_file_duration_s=split_s)
    for topic, msgtype in TOPICS.items():
        writer.add_topic(topic, msgtype)
    written: set[tuple[str, int]] = set()
    on_disk: set[tuple[str, int]] = set()
    flushes: list[tuple[int, set[tuple[str, int]]]] = [(0, set())]
    files = 0
    for n, (topic, t, data) in enumerate(arrivals(count), start=1):
        writer.write(topic, t, data)
        if len(writer.files) > files:  # a split closed every earlier message's file
            files = len(writer.files)
            on_disk = set(written)
            flushes = [(0, set(on_disk))]
        written.add((topic, t))
        if n % flush_every == 0:
            writer.flush()
            assert writer._part is not None and writer._part.storage is not None
            on_disk = set(written)
            flushes.append((Path(writer._part.storage.path).stat().st_size, set(on_disk)))
    assert writer._part is not None and writer._part.storage is not None
    return Path(writer._part.storage.path), flushes


def recovered_keys(bag: Path) -> list[tuple[str, int]]:
    return [(m.topic, m.log_time_ns) for m in read_messages(bag)]


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(cut=st.floats(0.0, 1.0), zeros=st.sampled_from([0, 0, 4096]), count=st.integers(30, 160))
def test_mcap_cut_at_any_byte_keeps_every_flushed_message(tmp_path_factory, cut, zeros, count):
    """A file cut anywhere (and perhaps extended with zeros, as a file system can leave it after
    a power cut): every message of a flush that lies wholly before the cut comes back, in log-time
    order, nothing else; never a traceback; never a partial bag under the output's name."""
    tmp = tmp_path_factory.mktemp("cut")
    last, flushes = killed_recording(tmp / "bag", "mcap", count, flush_every=17, split_s=0.6)
    data = last.read_bytes()
    kept = round(cut * len(data))
    last.write_bytes(data[:kept] + bytes(zeros))
    # The messages of each flush whose records all lie before the cut; the next flush's too
    # when the cut falls only in the index records that follow its chunk.
    before = [messages for size, messages in flushes if size <= kept]
    after = [messages for size, messages in flushes if size > kept]
    expected = before[-1]
    try:
        recovered = recover_bag(tmp / "bag", tmp / "out")
    except BagError as exc:
        assert not expected and "no complete message" in str(exc)
        assert sorted(p.name for p in tmp.iterdir()) == ["bag"]  # no scratch, no output
        return
    got = recovered_keys(tmp / "out")
    assert set(got) == expected or set(got) == after[:1][0]
    assert [t for _, t in got] == sorted(t for _, t in got)
    assert recovered.summary.count == len(got)
    assert sorted(p.name for p in tmp.iterdir()) == ["bag", "out"]


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_split_recording_killed_in_its_second_file(tmp_path: Path, storage: str):
    """Out-of-order topics over a split: every flushed message, one output file per input."""
    last, flushes = killed_recording(tmp_path / "bag", storage, 150, flush_every=20, split_s=1.0)
    assert last.parent.name == "bag_1"
    recovered = recover_bag(tmp_path / "bag", tmp_path / "out")
    assert set(recovered_keys(tmp_path / "out")) == flushes[-1][1]
    assert [f.path.name for f in recovered.files] == ["bag_0." + last.suffix[1:], last.name]
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [
        "metadata.yaml",
        "out_0" + last.suffix,
        "out_1" + last.suffix,
    ]
    with BagReader(tmp_path / "out") as reader:
        assert {t: i.count for t, i in reader.topics.items()} == {
            t: sum(1 for topic, _ in flushes[-1][1] if topic == t) for t in TOPICS
        }


def test_recover_reports_per_topic_and_the_end_lost(tmp_path: Path, capsys):
    killed_recording(tmp_path / "drive", "mcap", 100, flush_every=30, split_s=0.0)
    assert main(["recover", str(tmp_path / "drive")]) == 0
    out = capsys.readouterr().out
    assert "drive_0.mcap: " in out and "bytes at the end dropped" not in out
    assert "/fix" in out and "/vel" in out and "/imu" in out
    assert "lost at most" in out
    assert (tmp_path / "drive_recovered" / "metadata.yaml").exists()
    # Again onto the same output: refused, nothing touched.
    assert main(["recover", str(tmp_path / "drive")]) == 2
    assert "exists already" in capsys.readouterr().err


def test_a_failure_while_writing_leaves_no_bag_under_the_output_name(tmp_path: Path, monkeypatch):
    killed_recording(tmp_path / "bag", "mcap", 60, flush_every=10, split_s=0.0)

    def fail(*_: object) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(BagWriter, "_write_metadata", fail)
    with pytest.raises(OSError, match="No space"):
        recover_bag(tmp_path / "bag", tmp_path / "out")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bag"]


def test_salvage_of_garbage_and_of_nothing(tmp_path: Path):
    for name, data in (("a_0.mcap", b""), ("b_0.mcap", b"\x89MCAP0\r\n" + b"\xff" * 100)):
        found = salvage(tmp_path / name) if (tmp_path / name).write_bytes(data) >= 0 else None
        assert found is not None and not found.messages and found.dropped_bytes == len(data)
        assert found.stopped
    (tmp_path / "c_0.db3").write_bytes(b"not a database at all" * 50)
    assert not salvage(tmp_path / "c_0.db3").messages


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_a_restarted_recorder_continues_the_same_recording(tmp_path: Path, storage: str):
    """Killed in its second file, resumed, killed again before the first split, resumed and
    closed: one bag with every flushed message of each run and every message of the last."""
    bag = tmp_path / "bag"
    _, flushes = killed_recording(bag, storage, 150, flush_every=20, split_s=1.0)
    first_run = flushes[-1][1]
    closed = len(salvage(bag / f"bag_0.{'mcap' if storage == 'mcap' else 'db3'}").messages)
    writer = BagWriter(bag, storage=storage, max_file_duration_s=1.0, resume=True)
    assert [len(s.messages) for s in writer.resumed] == [len(first_run) - closed]
    assert writer.resumed_end_ns == max(t for _, t in first_run)
    later = T0 + 10**10
    for k in range(30):
        writer.write("/imu", later + k * 10 * MS, cdr(imu(later + k * 10 * MS, k)))
    writer.flush()
    second = {("/imu", later + k * 10 * MS) for k in range(30)}
    writer = BagWriter(bag, storage=storage, resume=True)  # the second run killed as it was
    for k in range(5):
        writer.write("/fix", later + 10**9 + k, cdr(fix(later + 10**9 + k, k)))
    writer.close()
    assert not (bag / ".parts").exists()
    assert sorted(p.name for p in bag.iterdir() if p.is_dir()) == []
    got = recovered_keys(bag)
    assert set(got) == first_run | second | {("/fix", later + 10**9 + k) for k in range(5)}
    assert len(got) == len(set(got))
    with BagReader(bag) as reader:  # topics declared again from the salvaged files
        assert set(reader.topics) == set(TOPICS)


def test_resuming_a_closed_recording_and_removing_its_oldest_files(tmp_path: Path):
    bag = tmp_path / "bag"
    with BagWriter(bag, max_file_duration_s=1.0) as writer:
        for k in range(25):
            writer.write("/imu", T0 + k * 10**8, imu(T0 + k * 10**8, k))
    assert len(writer.files) == 3
    writer = BagWriter(bag, max_file_duration_s=1.0, resume=True)
    assert not (bag / "metadata.yaml").exists()  # being written again
    assert writer.remove_oldest_file() is None  # a closed recording's files go together
    for k in range(25, 50):
        writer.write("/imu", T0 + k * 10**8, imu(T0 + k * 10**8, k))
    removed = writer.remove_oldest_file()
    assert removed is None
    writer.close()
    assert len(read_messages_list := list(read_messages(bag))) == 50
    assert read_messages_list[-1].log_time_ns == T0 + 49 * 10**8
    writer = BagWriter(tmp_path / "fresh", max_file_duration_s=1.0)
    for k in range(25):
        writer.write("/imu", T0 + k * 10**8, imu(T0 + k * 10**8, k))
    removed = writer.remove_oldest_file()
    assert removed is not None and removed[0].name == "fresh_0.mcap"
    assert (removed[1], removed[2]) == (T0, T0 + 9 * 10**8)
    writer.close()
    assert [m.log_time_ns for m in read_messages(tmp_path / "fresh")] == [
        T0 + k * 10**8 for k in range(10, 25)
    ]


def test_a_recording_copied_under_another_name_is_recovered(tmp_path: Path):
    """An operator copies the killed recording to a stick as ``drive``: its files keep their
    names (``bag_<n>``)."""
    _, flushes = killed_recording(tmp_path / "bag", "mcap", 150, flush_every=20, split_s=1.0)
    (tmp_path / "bag").rename(tmp_path / "drive")
    recover_bag(tmp_path / "drive", tmp_path / "out")
    assert set(recovered_keys(tmp_path / "out")) == flushes[-1][1]
    (tmp_path / "drive" / "other_0.mcap").write_bytes(b"")
    with pytest.raises(BagError, match="several recordings: bag, other"):
        recover_bag(tmp_path / "drive", tmp_path / "out2")
