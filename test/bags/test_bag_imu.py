"""ins_fusion.bags.imu: the IMU record of a bag, written and read back through real MCAP bags."""

from __future__ import annotations

import numpy as np
import pytest

from gnss_ins_common.message_fields import fill_imu, stamp_ns
from ins_fusion.bags.bag_io import BagError, BagReader, BagWriter
from ins_fusion.bags.imu import ImuRecord, read_imu, write_imu_bag
from ins_fusion.bags.messages import new_message
from ins_fusion.bags.topics import IMU_DATA, IMU_TYPE
from ins_fusion.bags.typestore import jazzy_typestore

T0_S = 1_717_236_000.123456789


def _record(n: int = 50) -> ImuRecord:
    rng = np.random.default_rng(1)
    t = T0_S + np.arange(n) / 134.0
    return ImuRecord(
        t, rng.normal(size=(n, 3)), rng.normal(size=(n, 3)), t[::10] + 0.001, 20.0 + t[::10] - T0_S
    )


def test_written_record_reads_back_on_both_time_bases(tmp_path):
    record = _record()
    write_imu_bag(tmp_path / "lab", record)
    back = read_imu(tmp_path / "lab")
    assert back.name == "lab" and back.start_ns == 0
    stamps = np.array([stamp_ns(t) for t in record.t_s])
    np.testing.assert_array_equal(back.t_s, stamps // 10**9 + (stamps % 10**9) * 1e-9)
    np.testing.assert_allclose(back.t_s, record.t_s, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(back.rate_flu_rad_s, record.rate_flu_rad_s)
    np.testing.assert_array_equal(back.force_flu_m_s2, record.force_flu_m_s2)
    np.testing.assert_array_equal(back.temperature_c, record.temperature_c)
    relative = read_imu(tmp_path / "lab", relative=True)
    assert relative.start_ns == stamps[0] and relative.t_s[0] == 0.0
    np.testing.assert_array_equal(relative.t_s, (stamps - stamps[0]) / 1e9)
    np.testing.assert_allclose(
        relative.temperature_t_s, back.temperature_t_s - back.t_s[0], rtol=0, atol=1e-6
    )
    assert read_imu(tmp_path / "lab", temperature_topic=None).temperature_t_s.shape == (0,)


def test_written_imu_messages_are_the_bytes_rosbags_serializes(tmp_path):
    """The writer's numpy encoding: every message as rosbags serializes fill_imu's message,
    logged its delay after its stamp (one stamp on the last nanosecond of a second)."""
    record = _record()
    stamps = np.array([stamp_ns(t) for t in record.t_s])
    stamps[0] = 1_717_235_999_999_999_999
    write_imu_bag(tmp_path / "lab", record, stamps_ns=stamps, delay_ns=4_690_000)
    with BagReader(tmp_path / "lab") as reader:
        written = list(reader.messages([IMU_DATA]))
    typestore, zero = jazzy_typestore(), (0.0,) * 3
    assert [m.log_time_ns for m in written] == [int(s) + 4_690_000 for s in stamps]
    for message, stamp, rate, force in zip(
        written, stamps.tolist(), record.rate_flu_rad_s, record.force_flu_m_s2, strict=True
    ):
        expected = fill_imu(new_message(IMU_TYPE), stamp, "imu_link", rate, force, zero, zero)
        assert bytes(message.message) == bytes(typestore.serialize_cdr(expected, IMU_TYPE))


def test_samples_come_in_stamp_order_without_repeats(tmp_path):
    """Logged out of order, one stamp twice: sorted, the first of the two kept."""
    stamps = [3, 1, 2, 2]
    with BagWriter(tmp_path / "shuffled") as writer:
        for k, stamp in enumerate(stamps):
            msg = fill_imu(
                new_message(IMU_TYPE), stamp, "imu_link", (k, 0, 0), (0, 0, 9.8), (0,) * 3, (0,) * 3
            )
            writer.write(IMU_DATA, 100 + k, msg)
    record = read_imu(tmp_path / "shuffled", relative=True)
    assert record.start_ns == 1
    np.testing.assert_array_equal(record.t_s, [0.0, 1e-9, 2e-9])
    np.testing.assert_array_equal(record.rate_flu_rad_s[:, 0], [1.0, 2.0, 0.0])


def test_bad_bags_are_refused_with_the_reason(tmp_path):
    write_imu_bag(tmp_path / "lab", _record())
    with pytest.raises(BagError, match=r"no topic /imu/raw \(Imu topics: /imu/data_raw\)"):
        read_imu(tmp_path / "lab", "/imu/raw")
    with pytest.raises(BagError, match="is sensor_msgs/msg/Temperature, not sensor_msgs/msg/Imu"):
        read_imu(tmp_path / "lab", "/imu/temperature")
    with BagWriter(tmp_path / "unset") as writer:
        for k in range(3):
            msg = fill_imu(
                new_message(IMU_TYPE), 0, "imu_link", (0,) * 3, (0,) * 3, (0,) * 3, (0,) * 3
            )
            writer.write(IMU_DATA, k, msg)
    with pytest.raises(BagError, match=r"3 message\(s\) \(1 distinct stamp\(s\): are the header"):
        read_imu(tmp_path / "unset")
    with pytest.raises(BagError, match="no such bag"):
        read_imu(tmp_path / "nothing")
