"""Direct decoding of the few fields gnss_ins needs from serialized (CDR) messages.

rosbags deserializes a message into a full object tree in about 22 µs, and rclpy builds its
Python message (with numpy covariance arrays) in about as long. ins_fusion_node takes 134 IMU
messages per second, and a simulated bag holds 134 IMU and 150 reference messages per second
for `gnss_ins replay`; all they need is the stamp and a few numbers, which sit at fixed offsets
after the variable-length frame_id: one struct unpack (~1 µs). Node and replay thus also read
the IMU through the same code. Messages used in full (GNSS, a few per second) still go through
rosbags / rclpy. test_cdr_fields.py checks the results against rosbags' deserializer.

Layouts (XCDR1: a 4-byte encapsulation header, then the body, aligned relative to its start):
every message starts with std_msgs/Header = stamp (int32 sec, uint32 nanosec) and frame_id
(uint32 length including the NUL, then the characters).
- sensor_msgs/Imu: padding to 8, orientation (4 float64), its covariance (9), angular_velocity
  (3), its covariance (9), linear_acceleration (3), its covariance (9).
- sensor_msgs/NavSatFix: status (int8), padding to 2, service (uint16), padding to 8, latitude,
  longitude, altitude, position_covariance (9 float64), position_covariance_type (uint8).
- geometry_msgs/TwistWithCovarianceStamped: padding to 8, linear (3 float64), angular (3),
  covariance (36).
"""

from __future__ import annotations

import struct

from ins_fusion.adapters.messages_in import ImuSample

_ENCAPSULATION = 4  # 0x00, 0x00 (big-endian) or 0x01 (little-endian), two option bytes
_LITTLE = (struct.Struct("<iiI"), struct.Struct("<3d"), struct.Struct("<4d"))
_BIG = (struct.Struct(">iiI"), struct.Struct(">3d"), struct.Struct(">4d"))
_IMU_RATE = 8 * (4 + 9)  # from the aligned start: after the orientation and its covariance
_IMU_FORCE = _IMU_RATE + 8 * (3 + 9)
_IMU_SIZE = _IMU_FORCE + 8 * (3 + 9)
_FIX_SIZE = 8 * (3 + 9) + 1
_TWIST_SIZE = 8 * (6 + 36)


class CdrError(ValueError):
    """The bytes are not a serialized message of the expected type (message says why)."""


def _align8(offset: int) -> int:
    return (offset + 7) & ~7


def _header(
    data: bytes, msgtype: str
) -> tuple[float, int, tuple[struct.Struct, struct.Struct, struct.Struct]]:
    """Stamp [s], body offset just after frame_id, and the structs of the byte order."""
    if len(data) < _ENCAPSULATION + 12 or data[0] != 0 or data[1] not in (0, 1):
        raise CdrError(f"{msgtype}: not a CDR message ({len(data)} bytes: {data[:4].hex()})")
    structs = _LITTLE if data[1] == 1 else _BIG
    sec, nanosec, length = structs[0].unpack_from(data, _ENCAPSULATION)
    if length == 0 or length > len(data):
        raise CdrError(f"{msgtype}: frame_id length {length} in a {len(data)}-byte message")
    return sec + nanosec * 1e-9, 12 + length, structs


def _check(data: bytes, end: int, msgtype: str) -> None:
    if len(data) < _ENCAPSULATION + end:
        raise CdrError(f"{msgtype}: {len(data)} bytes, {_ENCAPSULATION + end} needed")


def frame_id(data: bytes) -> str:
    """header.frame_id of a serialized (CDR) message that starts with a std_msgs/Header: after
    the 4-byte encapsulation and the stamp, a uint32 length (with the NUL) and the characters;
    "" when the bytes are too short to hold it."""
    if len(data) < 16:
        return ""
    (length,) = struct.unpack_from("<I" if data[1] == 1 else ">I", data, 12)
    return bytes(data[16 : 16 + max(length - 1, 0)]).decode("utf-8", "replace")


def imu_sample(data: bytes) -> ImuSample:
    """Stamp, angular_velocity and linear_acceleration (imu_link FLU) of a sensor_msgs/Imu."""
    t_s, offset, (_, vec3, _) = _header(data, "sensor_msgs/msg/Imu")
    start = _ENCAPSULATION + _align8(offset)
    _check(data, _align8(offset) + _IMU_SIZE, "sensor_msgs/msg/Imu")
    return ImuSample(
        t_s, vec3.unpack_from(data, start + _IMU_RATE), vec3.unpack_from(data, start + _IMU_FORCE)
    )


def orientation(data: bytes) -> tuple[float, tuple[float, ...]]:
    """Stamp and orientation (x, y, z, w) of a sensor_msgs/Imu."""
    t_s, offset, (_, _, vec4) = _header(data, "sensor_msgs/msg/Imu")
    _check(data, _align8(offset) + _IMU_SIZE, "sensor_msgs/msg/Imu")
    return t_s, vec4.unpack_from(data, _ENCAPSULATION + _align8(offset))


def position(data: bytes) -> tuple[float, tuple[float, ...]]:
    """Stamp and (latitude [deg], longitude [deg], altitude [m]) of a sensor_msgs/NavSatFix."""
    t_s, offset, (_, vec3, _) = _header(data, "sensor_msgs/msg/NavSatFix")
    start = _align8(((offset + 1 + 1) & ~1) + 2)  # status int8, service uint16 aligned to 2
    _check(data, start + _FIX_SIZE, "sensor_msgs/msg/NavSatFix")
    return t_s, vec3.unpack_from(data, _ENCAPSULATION + start)


def linear_velocity(data: bytes) -> tuple[float, tuple[float, ...]]:
    """Stamp and twist.twist.linear of a geometry_msgs/TwistWithCovarianceStamped."""
    t_s, offset, (_, vec3, _) = _header(data, "geometry_msgs/msg/TwistWithCovarianceStamped")
    _check(data, _align8(offset) + _TWIST_SIZE, "geometry_msgs/msg/TwistWithCovarianceStamped")
    return t_s, vec3.unpack_from(data, _ENCAPSULATION + _align8(offset))
