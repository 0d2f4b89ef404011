"""The replay's direct CDR decoding agrees with rosbags' deserializer and refuses bad bytes."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from ins_fusion.adapters import cdr_fields
from ins_fusion.adapters.cdr_fields import CdrError
from ins_fusion.bags.bag_io import jazzy_typestore

TS = jazzy_typestore()
T = TS.types
IMU, FIX, TWIST = (
    "sensor_msgs/msg/Imu",
    "sensor_msgs/msg/NavSatFix",
    ("geometry_msgs/msg/TwistWithCovarianceStamped"),
)

floats = st.floats(allow_nan=False, allow_infinity=False, width=64)
vec3s = st.tuples(floats, floats, floats)
headers = st.builds(
    lambda sec, nanosec, frame: T["std_msgs/msg/Header"](
        stamp=T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec), frame_id=frame
    ),
    st.integers(0, 2**31 - 1),
    st.integers(0, 999_999_999),
    st.text(max_size=20),  # every length modulo 8, multi-byte UTF-8 too
)
endians = st.booleans()


def _vector(v: tuple[float, float, float]):
    return T["geometry_msgs/msg/Vector3"](x=v[0], y=v[1], z=v[2])


def _stamp(header) -> float:
    return header.stamp.sec + header.stamp.nanosec * 1e-9


@given(headers, st.tuples(floats, floats, floats, floats), vec3s, vec3s, endians)
def test_imu_fields_match_rosbags(header, quat, rate, force, little):
    msg = T[IMU](
        header=header,
        orientation=T["geometry_msgs/msg/Quaternion"](x=quat[0], y=quat[1], z=quat[2], w=quat[3]),
        orientation_covariance=np.arange(9.0),
        angular_velocity=_vector(rate),
        angular_velocity_covariance=np.full(9, 2.0),
        linear_acceleration=_vector(force),
        linear_acceleration_covariance=np.full(9, 3.0),
    )
    data = bytes(TS.serialize_cdr(msg, IMU, little_endian=little))
    sample = cdr_fields.imu_sample(data)
    assert sample.t_s == _stamp(header)
    assert sample.rate_flu_rad_s == rate
    assert sample.force_flu_m_s2 == force
    assert cdr_fields.orientation(data) == (_stamp(header), quat)


@given(headers, st.integers(-2, 2), st.integers(0, 15), vec3s, endians)
def test_fix_position_matches_rosbags(header, status, service, lla, little):
    msg = T[FIX](
        header=header,
        status=T["sensor_msgs/msg/NavSatStatus"](status=status, service=service),
        latitude=lla[0],
        longitude=lla[1],
        altitude=lla[2],
        position_covariance=np.arange(9.0),
        position_covariance_type=2,
    )
    data = bytes(TS.serialize_cdr(msg, FIX, little_endian=little))
    assert cdr_fields.position(data) == (_stamp(header), lla)


@given(headers, vec3s, vec3s, endians)
def test_twist_linear_matches_rosbags(header, linear, angular, little):
    msg = T[TWIST](
        header=header,
        twist=T["geometry_msgs/msg/TwistWithCovariance"](
            twist=T["geometry_msgs/msg/Twist"](linear=_vector(linear), angular=_vector(angular)),
            covariance=np.arange(36.0),
        ),
    )
    data = bytes(TS.serialize_cdr(msg, TWIST, little_endian=little))
    assert cdr_fields.linear_velocity(data) == (_stamp(header), linear)


def test_bad_bytes_are_refused_with_a_message():
    msg = T[IMU](
        header=T["std_msgs/msg/Header"](
            stamp=T["builtin_interfaces/msg/Time"](sec=1, nanosec=2), frame_id="imu_link"
        ),
        orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        orientation_covariance=np.zeros(9),
        angular_velocity=_vector((0.0, 0.0, 0.0)),
        angular_velocity_covariance=np.zeros(9),
        linear_acceleration=_vector((0.0, 0.0, 9.8)),
        linear_acceleration_covariance=np.zeros(9),
    )
    data = bytes(TS.serialize_cdr(msg, IMU))
    with pytest.raises(CdrError, match="needed"):
        cdr_fields.imu_sample(data[:-8])
    with pytest.raises(CdrError, match="not a CDR message"):
        cdr_fields.imu_sample(b"\x07" + data[1:])
    with pytest.raises(CdrError, match="frame_id length"):
        cdr_fields.imu_sample(data[:12] + b"\xff\xff\xff\x7f" + data[16:])
    with pytest.raises(CdrError, match="NavSatFix"):
        cdr_fields.position(data[:40])  # an Imu is long enough; a cut one is not
