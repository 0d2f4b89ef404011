"""``gnss_ins redecode`` without ROS: raw topics through a bag and the driver cores again.

A synthetic recording (IMU400CC packets of the protocol's encoder cut into reads, Leica epochs
of the emulator's sentence builders) is decoded again; the result must be what the driver cores
make of the same bytes at the same times, as the nodes feed them (``seconds_of_ns`` of the
stamp they record).
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gnss_driver.driver import GnssDriver
from gnss_driver.emulator import AALBORG_LLH, EmulatorConfig, Truth, leica_sentences
from gnss_driver.messages import epoch_messages
from gnss_driver.parameters import driver_config as gnss_config
from gnss_driver.reader import frame_sentence
from gnss_ins_common.message_fields import seconds_of_ns, set_header, stamp_ns
from gnss_ins_common.serial_reads import ReadBatch
from imu400cc_driver.driver import ImuDriver
from imu400cc_driver.messages import sample_messages
from imu400cc_driver.parameters import driver_config as imu_config
from imu400cc_driver.protocol import RawPacket, encode_packet
from ins_fusion.bags.bag_io import BagReader, BagWriter
from ins_fusion.bags.messages import new_message
from ins_fusion.bags.typestore import jazzy_typestore
from ins_fusion.redecode.decoders import (
    DATA,
    GNSS_CLASSES,
    IMU_TOPICS,
    OPENED,
    STARTED,
    GnssDecoder,
    ImuDecoder,
)
from ins_fusion.redecode.run import RedecodeError, node_parameters, redecode
from ins_fusion.runtime.vehicle_nodes import IMU, LEICA
from ins_fusion.tools.cli import main

CHUNK = "gnss_ins_msgs/msg/SerialChunk"
SENTENCE = "nmea_msgs/msg/Sentence"
START_NS = 1_700_000_000_123_456_789
PERIOD_NS = round(1e9 / 134)
STEP = 9412  # device timer ticks per packet, counting down


def _wire(count: int, first: int = 0) -> tuple[bytes, list[int]]:
    """``count`` packets' bytes and each packet's sample time [ns]."""
    packets = [
        RawPacket((i % 50, -i % 70, 3), (100, -200, 10923), 1514, (41606 - STEP * i) % 65536)
        for i in range(first, first + count)
    ]
    return b"".join(map(encode_packet, packets)), [START_NS + i * PERIOD_NS for i in range(count)]


def _chunks(wire: bytes, cuts: list[int], delay_ns: int = 4_700_000) -> list[tuple[bytes, int]]:
    """The wire read in pieces cut at ``cuts``, each received ``delay_ns`` after its last
    packet's sample time."""
    bounds = [0, *sorted({c for c in cuts if 0 < c < len(wire)}), len(wire)]
    return [
        (wire[a:b], START_NS + ((b - 1) // 18) * PERIOD_NS + delay_ns)
        for a, b in itertools.pairwise(bounds)
    ]


def _serial_chunk(event: int, time_ns: int, data: bytes = b"") -> object:
    msg = new_message(CHUNK)
    msg.event = event
    msg.data = np.frombuffer(data, np.uint8)
    set_header(msg, time_ns, "imu_link")
    return msg


def _cdr(msg: object) -> bytes:
    return bytes(jazzy_typestore().serialize_cdr(msg, msg.__msgtype__))


def _leica_epochs(count: int, bad: int = 3) -> list[tuple[bytes, int]]:
    """One chunk per Leica epoch at 1 Hz (the sentences of ``bad`` with a broken checksum) and
    its receive time [ns]."""
    truth = Truth(*AALBORG_LLH, vel_enu_m_s=(3.0, 4.0, 0.0))
    epochs = []
    for i in range(count):
        utc_s = 1_700_000_000.0 + i
        wire = b"".join(
            frame_sentence(body) for body in leica_sentences(utc_s, truth, EmulatorConfig(), True)
        )
        if i == bad:
            wire = wire.replace(b"*", b"*0", 1)
        epochs.append((wire, stamp_ns(utc_s + 0.25)))
    return epochs


def _imu_live(
    chunks: list[tuple[bytes, int]], params: dict[str, object] | None = None
) -> list[tuple[str, bytes]]:
    """(relative topic, CDR) of what imu400cc_node with ``params`` (default: its installed
    file's) publishes of reads at host times [ns]: the driver fed seconds_of_ns of each
    (imu400cc_driver/node.py ``_on_data``)."""
    params = node_parameters(IMU, None, ()) if params is None else params
    driver = ImuDriver(imu_config(params))
    out: list[tuple[str, bytes]] = []
    for data, received_ns in chunks:
        for sample in driver.feed(data, seconds_of_ns(received_ns)):
            messages = sample_messages(
                sample,
                driver,
                params["frame_id"],
                lambda: new_message("sensor_msgs/msg/Imu"),
                lambda: new_message("sensor_msgs/msg/Temperature"),
            )
            pairs = zip(IMU_TOPICS, messages, strict=True)
            out += [(topic, _cdr(m)) for topic, m in pairs if m is not None]
    return out


def _imu_raw_rows(imu_chunks, events) -> list[tuple[str, int, object]]:
    """/imu/raw as imu400cc_node publishes it: the reads gathered every 0.1 s (RawPublisher),
    an OPENED event after the reads before it; each message logged at its last read."""
    batch = ReadBatch(period_ns=100_000_000, max_reads=64)
    rows: list[tuple[str, int, object]] = []
    last_ns = START_NS

    def publish() -> None:
        if (record := batch.take()) is not None:
            msg = _serial_chunk(DATA, record.read_times_ns[0], record.data)
            msg.read_ends = np.array(record.read_ends, np.uint32)
            msg.read_times_ns = np.array(record.read_times_ns, np.int64)
            rows.append(("/imu/raw", last_ns, msg))

    timeline = sorted(
        [(t, data) for data, t in imu_chunks] + [(t, None) for t in events], key=lambda e: e[0]
    )
    for t, data in timeline:
        if data is None:
            publish()
            rows.append(("/imu/raw", t, _serial_chunk(OPENED, t)))
            continue
        last_ns = t
        if batch.add(data, t):
            publish()
    publish()
    assert len(imu_chunks) < 20 or len(rows) < len(imu_chunks) / 5  # several reads a message
    return rows


def _write_recording(path, imu_chunks, leica_epochs, extra_events=()) -> None:
    """A recording with the raw topics, a stale /imu/data_raw and a topic to copy."""
    with BagWriter(path) as writer:
        writer.add_topic("/imu/raw", CHUNK)
        writer.add_topic("/leica/nmea", SENTENCE)
        writer.add_topic("/leica/port_events", CHUNK)
        stale = new_message("sensor_msgs/msg/Imu")
        writer.write("/imu/data_raw", START_NS, stale)  # replaced by the rebuilt ones
        writer.write("/leica/port_events", START_NS, _serial_chunk(STARTED, START_NS))
        writer.write("/imu/raw", START_NS, _serial_chunk(STARTED, START_NS))
        rows = _imu_raw_rows(imu_chunks, extra_events)
        for wire, t in leica_epochs:
            for line in wire.split(b"\r\n")[:-1]:
                msg = new_message(SENTENCE)
                msg.sentence = line.decode("ascii")
                set_header(msg, t, "gnss_link")
                rows.append(("/leica/nmea", t, msg))
        rows.append(("/rosout_like", START_NS + 5, new_message("std_msgs/msg/String")))
        for topic, t, msg in sorted(rows, key=lambda row: row[1]):
            writer.write(topic, t, msg)


def _topic_cdr(path, topic: str) -> list[bytes]:
    with BagReader(path) as reader:
        return [bytes(m.message) for m in reader.messages([topic])]


def test_serial_chunk_round_trip_through_a_bag(tmp_path):
    sent = [_serial_chunk(DATA, START_NS + i, bytes(range(i, i + 40))) for i in range(3)]
    sent[1].read_ends = np.array([15, 40], np.uint32)
    sent[1].read_times_ns = np.array([START_NS + 1, START_NS + 5], np.int64)
    sent.append(_serial_chunk(OPENED, START_NS + 9))
    with BagWriter(tmp_path / "bag") as writer:
        for msg in sent:
            writer.write("/imu/raw", START_NS, msg)
    with BagReader(tmp_path / "bag") as reader:
        got = [m.message for m in reader.messages(deserialize=True)]
    assert reader.topics["/imu/raw"].msgtype == CHUNK

    def fields(m):
        return (
            m.event,
            bytes(m.data),
            m.header.stamp.nanosec,
            list(m.read_ends),
            list(m.read_times_ns),
        )

    assert [fields(m) for m in got] == [fields(m) for m in sent]
    assert got[0].OPENED == OPENED and got[0].STARTED == STARTED


def test_redecode_is_the_driver_cores_on_the_same_bytes(tmp_path):
    wire, _ = _wire(400)
    second, _ = _wire(200, first=400)
    reopen_ns = START_NS + 400 * PERIOD_NS + 300_000_000
    imu_chunks = _chunks(wire, list(range(7, len(wire), 23)))
    imu_chunks += [  # 0.7 s after the first 400
        (d, t + 400 * PERIOD_NS + 700_000_000)
        for d, t in _chunks(second, list(range(5, len(second), 37)))
    ]
    epochs = _leica_epochs(8)
    _write_recording(tmp_path / "rec", imu_chunks, epochs, [reopen_ns])
    result = redecode(tmp_path / "rec", tmp_path / "out")

    params = node_parameters(IMU, None, ())
    imu = ImuDriver(imu_config(params))
    expected: list[bytes] = []
    reset = False
    for data, t in imu_chunks:
        if t > reopen_ns and not reset:
            imu.reset()
            reset = True
        for sample in imu.feed(data, seconds_of_ns(t)):
            msg = sample_messages(
                sample,
                imu,
                "imu_link",
                lambda: new_message("sensor_msgs/msg/Imu"),
                lambda: new_message("sensor_msgs/msg/Temperature"),
            )[0]
            expected.append(_cdr(msg))
    assert _topic_cdr(tmp_path / "out", "/imu/data_raw") == expected
    assert len(expected) > 550

    gnss_params = node_parameters(LEICA, None, ())
    driver = GnssDriver(gnss_config(gnss_params))
    fixes = []
    for wire_bytes, t in [*epochs, (b"", epochs[-1][1] + 10**9)]:
        outputs = driver.flush_idle(seconds_of_ns(t)) + driver.feed(wire_bytes, seconds_of_ns(t))
        for out in outputs:
            fixes += [
                _cdr(m)
                for topic, m in epoch_messages(out, "gnss_link", "leica", GNSS_CLASSES)
                if topic == "gnss/fix"
            ]
    assert (
        _topic_cdr(tmp_path / "out", "/leica/gnss/fix")
        == fixes[: result.rebuilt["/leica/gnss/fix"]]
    )
    assert len(fixes) >= 6  # one epoch lost to the broken checksum, the last one maybe open
    assert _topic_cdr(tmp_path / "out", "/rosout_like") == _topic_cdr(
        tmp_path / "rec", "/rosout_like"
    )
    assert _topic_cdr(tmp_path / "out", "/imu/raw") == _topic_cdr(tmp_path / "rec", "/imu/raw")
    assert result.recorded == {"/imu/data_raw": 1}


@settings(max_examples=25, deadline=None, derandomize=True)
@given(
    cuts=st.lists(st.integers(1, 18 * 150 - 1), max_size=60),
    delays=st.lists(st.floats(0.0, 0.02), min_size=1, max_size=5),
)
def test_redecode_is_the_live_path_for_any_reads(cuts, delays):
    """Any reads of the same bytes at any times: redecode gives what the node published."""
    wire, _ = _wire(150)
    chunks = [
        (data, stamp_ns(t * 1e-9 + delays[i % len(delays)] + 1e-10 * i))
        for i, (data, t) in enumerate(_chunks(wire, cuts))
    ]
    live = _imu_live(chunks)
    decoder = ImuDecoder(node_parameters(IMU, None, ()))
    redecoded = [
        (topic, _cdr(msg))
        for data, received_ns in [(b"", 0), *chunks]
        for topic, msg in decoder.take(
            _serial_chunk(DATA, received_ns, data) if data else _serial_chunk(STARTED, 0)
        )
    ]
    assert redecoded == live


def test_gnss_lines_one_by_one_are_the_chunks(tmp_path):
    """The nmea topic's lines fed one by one at their chunk's stamp give the epochs the chunks
    gave (the broken sentence rejected both ways)."""
    decoder = GnssDecoder(node_parameters(LEICA, None, ()))
    lines = []
    for wire, t in _leica_epochs(5):
        for line in wire.split(b"\r\n")[:-1]:
            msg = new_message(SENTENCE)
            msg.sentence = line.decode()
            set_header(msg, t, "gnss_link")
            lines += [_cdr(m) for _, m in decoder.line(msg)]
    assert decoder.driver.reader.stats.bad_checksum == 1
    assert len(lines) >= 3 * 3


def test_an_old_bag_is_refused_and_nothing_written(tmp_path, capsys):
    with BagWriter(tmp_path / "old") as writer:
        writer.write("/imu/data_raw", START_NS, new_message("sensor_msgs/msg/Imu"))
    assert main(["redecode", str(tmp_path / "old"), "-o", str(tmp_path / "out")]) == 2
    assert "holds no raw topic" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["old"]


def test_an_existing_output_is_refused(tmp_path, capsys):
    _write_recording(tmp_path / "rec", _chunks(_wire(10)[0], []), [])
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "keep").write_text("mine")
    assert main(["redecode", str(tmp_path / "rec"), "-o", str(tmp_path / "out")]) == 2
    assert "exists already" in capsys.readouterr().err
    assert [p.name for p in (tmp_path / "out").iterdir()] == ["keep"]


def test_bad_parameters_are_refused(tmp_path):
    _write_recording(tmp_path / "rec", _chunks(_wire(10)[0], []), [])
    params = tmp_path / "p.yaml"
    params.write_text("imu400cc_node:\n  ros__parameters:\n    gyro_range_dps: -3.0\n")
    with pytest.raises(RedecodeError, match="gyro_range_dps"):
        redecode(tmp_path / "rec", tmp_path / "out", param_files=[params])
    assert not (tmp_path / "out").exists()


def test_the_right_gyro_range_rebuilds_what_the_wrong_one_recorded(tmp_path):
    """A drive recorded with the wrong IMU parameter file (a gyro range of 200 deg/s instead of
    the unit's 100), redecoded with the right one, gives what the node publishes with the right
    file; with the wrong file, what it published. The rates are exactly half (a power of two:
    no rounding) at the same stamps, nothing else changes."""
    chunks = _chunks(_wire(300)[0], list(range(9, 5400, 31)))
    _write_recording(tmp_path / "rec", chunks, [])
    wrong = tmp_path / "wrong.yaml"
    wrong.write_text("imu400cc_node:\n  ros__parameters:\n    gyro_range_dps: 200.0\n")
    redecode(tmp_path / "rec", tmp_path / "wrong", param_files=[wrong])
    redecode(tmp_path / "rec", tmp_path / "right")
    right_params = node_parameters(IMU, None, ())
    for run, params in (("wrong", {**right_params, "gyro_range_dps": 200.0}), ("right", None)):
        live = [m for topic, m in _imu_live(chunks, params) if topic == "imu/data_raw"]
        assert _topic_cdr(tmp_path / run, "/imu/data_raw") == live, run
    with BagReader(tmp_path / "wrong") as a, BagReader(tmp_path / "right") as b:
        pairs = list(
            zip(
                a.messages(["/imu/data_raw"], deserialize=True),
                b.messages(["/imu/data_raw"], deserialize=True),
                strict=True,
            )
        )
    assert len(pairs) > 250
    for bad, good in pairs:
        a, b = bad.message, good.message
        assert (a.header.stamp.sec, a.header.stamp.nanosec) == (
            b.header.stamp.sec,
            b.header.stamp.nanosec,
        )
        w, v = a.angular_velocity, b.angular_velocity
        assert (w.x, w.y, w.z) == (2 * v.x, 2 * v.y, 2 * v.z)
        f, g = a.linear_acceleration, b.linear_acceleration
        assert (f.x, f.y, f.z) == (g.x, g.y, g.z)
    assert not math.isclose(pairs[10][0].message.angular_velocity.x, 0.0)


@pytest.mark.parametrize(
    ("data", "why"),
    [
        (b"", "not a gnss_ins_msgs/msg/SerialChunk of this release"),  # cut short
        (None, "read ends \\[40\\]... do not cut 20 bytes"),
    ],
)
def test_a_raw_message_that_cannot_be_read_is_named_and_nothing_is_written(tmp_path, data, why):
    """A damaged /imu/raw message (or one of a format this release does not read) stops the
    redecode with its topic and log time, never a traceback or a half-rebuilt bag."""
    msg = _serial_chunk(DATA, START_NS, bytes(20))
    msg.read_ends = np.array([40], np.uint32)
    msg.read_times_ns = np.array([START_NS], np.int64)
    cdr = _cdr(msg)
    with BagWriter(tmp_path / "rec") as writer:
        writer.add_topic("/imu/raw", CHUNK)
        writer.write("/imu/raw", START_NS, cdr[: len(cdr) - 12] if data == b"" else cdr)
    with pytest.raises(RedecodeError, match=f"/imu/raw message logged at {START_NS} ns.*{why}"):
        redecode(tmp_path / "rec", tmp_path / "out")
    assert not (tmp_path / "out").exists()
