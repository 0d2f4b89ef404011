"""gnss_ins_common.cdr_messages: templates rewritten in place decode, with rclpy's own
deserializer, to the messages filled field by field."""

from __future__ import annotations

import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Imu

from gnss_ins_common.cdr_messages import ImuWriter, SerializedMessage
from gnss_ins_common.message_fields import fill_imu


@pytest.mark.parametrize("frame_id", ["", "imu_link", "vehicle_1/imu400cc_link"])
def test_imu_writer_gives_the_filled_imu(frame_id):
    rng = np.random.default_rng(len(frame_id))
    gyro_variance, accel_variance = rng.uniform(1e-6, 1e-3, 3), rng.uniform(1e-5, 1e-2, 3)
    zero = np.zeros(3)
    template = fill_imu(Imu(), 0, frame_id, zero, zero, gyro_variance, accel_variance)
    writer = ImuWriter(serialize_message(template))
    for time_ns in (1_717_236_000_123_456_789, 12_500_000_000, 999_999_999, 0):
        rate, force = rng.normal(size=3), rng.normal(size=3) * 10.0
        data = writer.write(time_ns, rate, force)
        expected = fill_imu(Imu(), time_ns, frame_id, rate, force, gyro_variance, accel_variance)
        assert deserialize_message(data, Imu) == expected


def test_a_big_endian_template_is_rewritten_big_endian():
    # header.stamp, frame_id "" (length 1: the NUL), padding to 8, then two float64.
    template = b"\x00\x00\x00\x00" + bytes(8) + b"\x00\x00\x00\x01\x00" + bytes(3) + bytes(16)
    message = SerializedMessage(template, 4, 2)
    data = message.write(3_000_000_007, np.array([1.5, -2.0]))
    assert data[4:12] == b"\x00\x00\x00\x03\x00\x00\x00\x07"
    assert np.frombuffer(data[-16:], ">f8").tolist() == [1.5, -2.0]


def test_bytes_that_are_not_cdr_are_refused():
    with pytest.raises(ValueError, match="not a CDR message"):
        SerializedMessage(b"\x07\x07\x00\x00" + bytes(24), 4, 1)
