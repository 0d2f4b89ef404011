"""The replay's direct CDR decoding agrees with rosbags' deserializer and refuses bad bytes."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from ins_fusion.adapters import cdr_fields, messages_in
from ins_fusion.adapters.cdr_fields import CdrError
from ins_fusion.bags.typestore import jazzy_typestore

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


quats = st.tuples(floats, floats, floats, floats)


def _imu_bytes(header, quat, rate, force, little) -> bytes:
    msg = T[IMU](
        header=header,
        orientation=T["geometry_msgs/msg/Quaternion"](x=quat[0], y=quat[1], z=quat[2], w=quat[3]),
        orientation_covariance=np.arange(9.0),
        angular_velocity=_vector(rate),
        angular_velocity_covariance=np.full(9, 2.0),
        linear_acceleration=_vector(force),
        linear_acceleration_covariance=np.full(9, 3.0),
    )
    return bytes(TS.serialize_cdr(msg, IMU, little_endian=little))


def _fix_bytes(header, status, service, lla, little) -> bytes:
    msg = T[FIX](
        header=header,
        status=T["sensor_msgs/msg/NavSatStatus"](status=status, service=service),
        latitude=lla[0],
        longitude=lla[1],
        altitude=lla[2],
        position_covariance=np.arange(9.0),
        position_covariance_type=2,
    )
    return bytes(TS.serialize_cdr(msg, FIX, little_endian=little))


def _twist_bytes(header, linear, angular, little) -> bytes:
    msg = T[TWIST](
        header=header,
        twist=T["geometry_msgs/msg/TwistWithCovariance"](
            twist=T["geometry_msgs/msg/Twist"](linear=_vector(linear), angular=_vector(angular)),
            covariance=np.arange(36.0),
        ),
    )
    return bytes(TS.serialize_cdr(msg, TWIST, little_endian=little))


@given(headers, quats, vec3s, vec3s, endians)
def test_imu_fields_match_rosbags(header, quat, rate, force, little):
    data = _imu_bytes(header, quat, rate, force, little)
    sample = cdr_fields.imu_sample(data)
    assert sample.t_s == _stamp(header)
    assert sample.rate_flu_rad_s == rate
    assert sample.force_flu_m_s2 == force
    assert cdr_fields.orientation(data) == (_stamp(header), quat)


@given(headers, st.integers(-2, 2), st.integers(0, 15), vec3s, endians)
def test_fix_position_matches_rosbags(header, status, service, lla, little):
    data = _fix_bytes(header, status, service, lla, little)
    assert cdr_fields.position(data) == (_stamp(header), lla)


@given(headers, vec3s, vec3s, endians)
def test_twist_linear_matches_rosbags(header, linear, angular, little):
    data = _twist_bytes(header, linear, angular, little)
    assert cdr_fields.linear_velocity(data) == (_stamp(header), linear)


def _bits(values) -> bytes:
    return np.asarray(values, dtype=np.float64).tobytes()


def _topic(messages, repeat: int) -> list[bytes]:
    """Mixed layouts (frame_id lengths, byte orders), then a run of the first message's layout
    (the whole-topic path)."""
    return [*messages, *messages[:1] * repeat]


@given(st.lists(st.tuples(headers, quats, vec3s, vec3s, endians), max_size=5), st.integers(0, 30))
def test_whole_imu_topics_decode_as_each_message(messages, repeat):
    payloads = _topic([_imu_bytes(*m) for m in messages], repeat)
    t_s, stamp_ns, rate, force = cdr_fields.imu_columns(payloads)
    samples = [cdr_fields.imu_sample(d) for d in payloads]
    assert _bits(t_s) == _bits([s.t_s for s in samples])  # the same values to the bit
    headers = [m[0].stamp for m in messages] + [messages[0][0].stamp] * repeat if messages else []
    assert stamp_ns.tolist() == [h.sec * 1_000_000_000 + h.nanosec for h in headers]
    assert _bits(rate) == _bits([s.rate_flu_rad_s for s in samples])
    assert _bits(force) == _bits([s.force_flu_m_s2 for s in samples])
    t_s, quat = cdr_fields.orientations(payloads)
    assert _bits(quat) == _bits([cdr_fields.orientation(d)[1] for d in payloads])
    assert rate.shape == force.shape == (len(payloads), 3) and quat.shape == (len(payloads), 4)


def test_blocks_of_a_topic_split_its_layouts_as_a_whole_topic_does(monkeypatch):
    """Decoded a few messages at a time (cdr_fields._BLOCK), a topic whose layouts (frame_id
    lengths, byte orders) and lengths alternate decodes as each message."""
    monkeypatch.setattr(cdr_fields, "_BLOCK", 3)
    frames = ["imu", "imu_link", "a", "imu"]
    payloads = []
    for k in range(23):
        header = T["std_msgs/msg/Header"](
            stamp=T["builtin_interfaces/msg/Time"](sec=k, nanosec=7 * k), frame_id=frames[k % 4]
        )
        vec = (0.1 * k, -0.2 * k, 9.8)
        payloads.append(_imu_bytes(header, (0.0, 0.0, 0.0, 1.0), vec, vec, k % 3 != 0))
    t_s, _, rate, _ = cdr_fields.imu_columns(payloads)
    samples = [cdr_fields.imu_sample(d) for d in payloads]
    assert _bits(t_s) == _bits([s.t_s for s in samples])
    assert _bits(rate) == _bits([s.rate_flu_rad_s for s in samples])


@given(
    st.lists(st.tuples(headers, vec3s, vec3s, endians), max_size=5),
    st.integers(0, 30),
    st.integers(-2, 2),
)
def test_whole_fix_and_twist_topics_decode_as_each_message(messages, repeat, status):
    fixes = _topic([_fix_bytes(h, status, 1, v, little) for h, v, _, little in messages], repeat)
    t_s, lla = cdr_fields.positions(fixes)
    assert _bits(t_s) == _bits([cdr_fields.position(d)[0] for d in fixes])
    assert _bits(lla) == _bits([cdr_fields.position(d)[1] for d in fixes])
    twists = _topic([_twist_bytes(*m) for m in messages], repeat)
    t_s, linear = cdr_fields.linear_velocities(twists)
    assert _bits(t_s) == _bits([cdr_fields.linear_velocity(d)[0] for d in twists])
    assert _bits(linear) == _bits([cdr_fields.linear_velocity(d)[1] for d in twists])
    assert lla.shape == linear.shape == (len(fixes), 3)


covariances = st.lists(
    st.floats(width=64) | st.sampled_from([0.0, -1.0, float("nan")]), min_size=36, max_size=36
)


@given(
    st.lists(
        st.tuples(headers, st.integers(-128, 127), vec3s, covariances, st.integers(0, 3), endians),
        max_size=5,
    ),
    st.integers(0, 30),
)
def test_whole_gnss_topics_give_the_measurements_of_each_message(messages, repeat):
    """fix_columns / twist_columns with messages_in.*_from_fields: the measurements that
    rosbags' message objects give through messages_in.fix_measurement / velocity_measurement
    (status, covariance type, every covariance element, to the bit)."""
    fixes, twists = [], []
    for header, status, lla, cov, cov_type, little in messages:
        fix = T[FIX](
            header=header,
            status=T["sensor_msgs/msg/NavSatStatus"](status=status, service=1),
            latitude=lla[0],
            longitude=lla[1],
            altitude=lla[2],
            position_covariance=np.array(cov[:9]),
            position_covariance_type=cov_type,
        )
        fixes.append(bytes(TS.serialize_cdr(fix, FIX, little_endian=little)))
        twist = T[TWIST](
            header=header,
            twist=T["geometry_msgs/msg/TwistWithCovariance"](
                twist=T["geometry_msgs/msg/Twist"](linear=_vector(lla), angular=_vector(lla)),
                covariance=np.array(cov),
            ),
        )
        twists.append(bytes(TS.serialize_cdr(twist, TWIST, little_endian=little)))
    fixes, twists = _topic(fixes, repeat), _topic(twists, repeat)
    columns = cdr_fields.fix_columns(fixes)
    measurements = messages_in.fixes_from_fields(
        columns.t_s,
        columns.lla,
        columns.status,
        columns.covariance_type,
        columns.covariance.reshape(-1, 3, 3),
    )
    for data, got in zip(fixes, measurements, strict=True):
        expected = messages_in.fix_measurement(TS.deserialize_cdr(data, FIX))
        assert (got.t_s, got.valid) == (expected.t_s, expected.valid)
        assert _bits((got.lat_deg, got.lon_deg, got.height_m)) == _bits(
            (expected.lat_deg, expected.lon_deg, expected.height_m)
        )
        assert _bits(got.cov_enu_m2) == _bits(expected.cov_enu_m2)
    columns_v = cdr_fields.twist_columns(twists)
    for i, data in enumerate(twists):
        expected_v = messages_in.velocity_measurement(TS.deserialize_cdr(data, TWIST))
        got_v = messages_in.velocity_from_fields(
            float(columns_v.t_s[i]),
            tuple(columns_v.linear[i].tolist()),
            columns_v.covariance[i].reshape(6, 6),
        )
        assert got_v.t_s == expected_v.t_s
        assert _bits(got_v.vel_enu_m_s) == _bits(expected_v.vel_enu_m_s)
        assert _bits(got_v.cov_enu_m2_s2) == _bits(expected_v.cov_enu_m2_s2)


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
    good = [data] * 3
    with pytest.raises(CdrError, match="needed"):
        cdr_fields.imu_columns([*good, data[:-8]])  # the odd one out in its own group
    with pytest.raises(CdrError, match="needed"):
        cdr_fields.imu_columns([data[:-8]] * 3)
    with pytest.raises(CdrError, match="not a CDR message"):
        cdr_fields.imu_columns([*good, b"\x07" + data[1:]])
    with pytest.raises(CdrError, match="frame_id length"):
        cdr_fields.imu_columns([data[:12] + b"\xff\xff\xff\x7f" + data[16:]] * 2)
    with pytest.raises(CdrError, match="not a CDR message"):
        cdr_fields.imu_columns([b"\x00\x01"] * 4)  # too short for a header
