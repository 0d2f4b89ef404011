"""Direct decoding of the few fields gnss_ins needs from serialized (CDR) messages.

rosbags deserializes a message into a full object tree in about 22 µs, and rclpy builds its
Python message (with numpy covariance arrays) in about as long. ins_fusion_node takes 134 IMU
messages per second, and a simulated bag holds 134 IMU and 150 reference messages per second
for `gnss_ins replay`; all they need is the stamp and a few numbers, which sit at fixed offsets
after the variable-length frame_id: one struct unpack (~1 µs). Node and replay thus also read
the IMU through the same code. The node takes GNSS messages (a few per second) through rclpy.
test_cdr_fields.py checks the results against rosbags' deserializer.

The replay decodes whole topics at once (``imu_columns``, ``orientations``, ``positions``,
``linear_velocities``, and the GNSS fix and velocity inputs: ``fix_columns``,
``twist_columns``): messages of one length, byte order and frame_id length share one layout,
so numpy reads each field of all of them from one array of their bytes (~0.5 µs a message
instead of ~4; rosbags' full deserialization of a NavSatFix ~60 µs), with the same values to
the bit.

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
from collections.abc import Callable, Iterator, Sequence
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from gnss_ins_common.types import FloatArray, IntArray
from ins_fusion.adapters.messages_in import ImuSample
from ins_fusion.adapters.payloads import Payloads

_ENCAPSULATION = 4  # 0x00, 0x00 (big-endian) or 0x01 (little-endian), two option bytes
_LITTLE = (struct.Struct("<iiI"), struct.Struct("<3d"), struct.Struct("<4d"))
_BIG = (struct.Struct(">iiI"), struct.Struct(">3d"), struct.Struct(">4d"))
_IMU_RATE = 8 * (4 + 9)  # from the aligned start: after the orientation and its covariance
_IMU_FORCE = _IMU_RATE + 8 * (3 + 9)
_IMU_SIZE = _IMU_FORCE + 8 * (3 + 9)
_FIX_SIZE = 8 * (3 + 9) + 1
_FIX_COVARIANCE = 8 * 3  # position_covariance after latitude, longitude, altitude
_FIX_COVARIANCE_TYPE = _FIX_COVARIANCE + 8 * 9
_TWIST_SIZE = 8 * (6 + 36)
_TWIST_COVARIANCE = 8 * 6  # after linear and angular


class CdrError(ValueError):
    """The bytes are not a serialized message of the expected type (message says why)."""


def _align8(offset: int) -> int:
    return (offset + 7) & ~7


_Structs = tuple[struct.Struct, struct.Struct, struct.Struct]


class _Layout(NamedTuple):
    """A message type's fixed-size body after the header: where it starts (from the offset just
    after frame_id, relative to the end of the encapsulation) and its size [bytes]."""

    msgtype: str
    start: Callable[[int], int]
    size: int


_IMU = _Layout("sensor_msgs/msg/Imu", _align8, _IMU_SIZE)
# status int8, service uint16 aligned to 2, then the float64 fields aligned to 8
_FIX = _Layout("sensor_msgs/msg/NavSatFix", lambda o: _align8(((o + 1 + 1) & ~1) + 2), _FIX_SIZE)
_TWIST = _Layout("geometry_msgs/msg/TwistWithCovarianceStamped", _align8, _TWIST_SIZE)


def _header(data: bytes, msgtype: str) -> tuple[float, int, _Structs]:
    """Stamp [s], body offset just after frame_id, and the structs of the byte order."""
    if len(data) < _ENCAPSULATION + 12 or data[0] != 0 or data[1] not in (0, 1):
        raise CdrError(f"{msgtype}: not a CDR message ({len(data)} bytes: {data[:4].hex()})")
    structs = _LITTLE if data[1] == 1 else _BIG
    sec, nanosec, length = structs[0].unpack_from(data, _ENCAPSULATION)
    if length == 0 or length > len(data):
        raise CdrError(f"{msgtype}: frame_id length {length} in a {len(data)}-byte message")
    return sec + nanosec * 1e-9, 12 + length, structs


def _body(data: bytes, layout: _Layout) -> tuple[float, int, _Structs]:
    """Stamp [s], offset of the fixed-size body in ``data`` and the structs of the byte order;
    CdrError when the bytes are too short for the type."""
    t_s, offset, structs = _header(data, layout.msgtype)
    start = layout.start(offset)
    if len(data) < _ENCAPSULATION + start + layout.size:
        raise CdrError(
            f"{layout.msgtype}: {len(data)} bytes, {_ENCAPSULATION + start + layout.size} needed"
        )
    return t_s, _ENCAPSULATION + start, structs


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
    t_s, at, (_, vec3, _) = _body(data, _IMU)
    return ImuSample(
        t_s, vec3.unpack_from(data, at + _IMU_RATE), vec3.unpack_from(data, at + _IMU_FORCE)
    )


def orientation(data: bytes) -> tuple[float, tuple[float, ...]]:
    """Stamp and orientation (x, y, z, w) of a sensor_msgs/Imu."""
    t_s, at, (_, _, vec4) = _body(data, _IMU)
    return t_s, vec4.unpack_from(data, at)


def position(data: bytes) -> tuple[float, tuple[float, ...]]:
    """Stamp and (latitude [deg], longitude [deg], altitude [m]) of a sensor_msgs/NavSatFix."""
    t_s, at, (_, vec3, _) = _body(data, _FIX)
    return t_s, vec3.unpack_from(data, at)


def linear_velocity(data: bytes) -> tuple[float, tuple[float, ...]]:
    """Stamp and twist.twist.linear of a geometry_msgs/TwistWithCovarianceStamped."""
    t_s, at, (_, vec3, _) = _body(data, _TWIST)
    return t_s, vec3.unpack_from(data, at)


# --------------------------------------------------------------------------------------------
# Whole topics at once
# --------------------------------------------------------------------------------------------


class _Stamped(NamedTuple):
    """Stamps of many messages: seconds as the single-message decoders give them (n,) and
    integer nanoseconds (n,), and per field asked for its float64 values (n, count)."""

    t_s: FloatArray
    stamp_ns: IntArray
    values: list[FloatArray]


def _columns(
    payloads: Sequence[bytes], layout: _Layout, fields: Sequence[tuple[int, int]]
) -> _Stamped:
    """The stamps and, per (offset from the body, count) of ``fields``, the values of many
    messages of one type; CdrError as for one message."""
    n = len(payloads)
    t_s = np.empty(n)
    stamp_ns = np.empty(n, dtype=np.int64)
    values = [np.empty((n, count)) for _, count in fields]
    for rows, raw in _groups(Payloads.of(payloads)):
        first = raw[0].tobytes()
        _, at, _ = _body(first, layout)  # the checks hold for the whole group
        order = "<" if first[1] == 1 else ">"
        sec = _read(raw, _ENCAPSULATION, np.dtype(order + "i4"), 1)[:, 0]
        nanosec = _read(raw, _ENCAPSULATION + 4, np.dtype(order + "u4"), 1)[:, 0]
        t_s[rows] = sec.astype(np.float64) + nanosec.astype(np.float64) * 1e-9
        stamp_ns[rows] = sec.astype(np.int64) * 1_000_000_000 + nanosec.astype(np.int64)
        for out, (offset, count) in zip(values, fields, strict=True):
            out[rows] = _read(raw, at + offset, np.dtype(order + "f8"), count)
    return _Stamped(t_s, stamp_ns, values)


#: Bytes that fix a message's layout: the encapsulation and the frame_id length.
_LAYOUT_BYTES = [0, 1, 12, 13, 14, 15]


#: Messages copied out at a time: their bytes stay in the cache, the copy's memory is reused.
_BLOCK = 4096


def _groups(payloads: Payloads) -> Iterator[tuple[IntArray, NDArray[np.uint8]]]:
    """Messages of one layout (the same length, encapsulation and frame_id length), at most
    ``_BLOCK`` at a time: their indices and their bytes (m, length)."""
    lengths = payloads.lengths
    distinct, first = np.unique(lengths, return_index=True)
    for size in distinct[np.argsort(first)].tolist():  # the usual topic: one length
        same_length = np.flatnonzero(lengths == size)
        for start in range(0, len(same_length), _BLOCK):
            rows = same_length[start : start + _BLOCK]
            raw = payloads.rows(rows, size)  # each message copied once
            if size <= max(_LAYOUT_BYTES):  # too short to hold a header: each on its own
                yield from ((rows[i : i + 1], raw[i : i + 1]) for i in range(len(rows)))
                continue
            keys = raw[:, _LAYOUT_BYTES]
            if np.all(keys == keys[0]):
                yield rows, raw
                continue
            _, group_of = np.unique(keys, axis=0, return_inverse=True)
            group_of = group_of.ravel()
            by_group = np.argsort(group_of, kind="stable")
            cuts = np.flatnonzero(np.diff(group_of[by_group])) + 1
            parts = sorted(np.split(by_group, cuts), key=lambda part: int(part[0]))
            yield from ((rows[part], raw[part]) for part in parts)


def _read(raw: NDArray[np.uint8], start: int, dtype: np.dtype[Any], count: int) -> NDArray[Any]:
    """``count`` values of ``dtype`` at byte ``start`` of each row of ``raw`` (n, count)."""
    return np.ascontiguousarray(raw[:, start : start + dtype.itemsize * count]).view(dtype)


class ImuColumns(NamedTuple):
    """Many sensor_msgs/Imu: stamps [s] (n,) (as ``imu_sample``) and [ns since the epoch]
    (n,), angular_velocity [rad/s] and linear_acceleration [m/s²] (n, 3)."""

    t_s: FloatArray
    stamp_ns: IntArray
    rate: FloatArray
    force: FloatArray


def imu_columns(payloads: Sequence[bytes]) -> ImuColumns:
    """``imu_sample`` of many sensor_msgs/Imu, with the stamps in integer nanoseconds too."""
    t_s, stamp_ns, (rate, force) = _columns(payloads, _IMU, ((_IMU_RATE, 3), (_IMU_FORCE, 3)))
    return ImuColumns(t_s, stamp_ns, rate, force)


def orientations(payloads: Sequence[bytes]) -> tuple[FloatArray, FloatArray]:
    """Stamps [s] (n,) and orientations (n, 4) (x, y, z, w) of many sensor_msgs/Imu."""
    t_s, _, (quat,) = _columns(payloads, _IMU, ((0, 4),))
    return t_s, quat


def positions(payloads: Sequence[bytes]) -> tuple[FloatArray, FloatArray]:
    """Stamps [s] (n,) and (latitude [deg], longitude [deg], altitude [m]) (n, 3) of many
    sensor_msgs/NavSatFix."""
    t_s, _, (lla,) = _columns(payloads, _FIX, ((0, 3),))
    return t_s, lla


def linear_velocities(payloads: Sequence[bytes]) -> tuple[FloatArray, FloatArray]:
    """Stamps [s] (n,) and twist.twist.linear (n, 3) of many TwistWithCovarianceStamped."""
    t_s, _, (linear,) = _columns(payloads, _TWIST, ((0, 3),))
    return t_s, linear


class FixColumns(NamedTuple):
    """Many sensor_msgs/NavSatFix: stamps [s] (n,) (as ``position``), status.status (n,),
    (latitude [deg], longitude [deg], altitude [m]) (n, 3), position_covariance (n, 9)
    row-major ENU [m²] and position_covariance_type (n,)."""

    t_s: FloatArray
    status: list[int]
    lla: FloatArray
    covariance: FloatArray
    covariance_type: list[int]


def fix_columns(payloads: Sequence[bytes]) -> FixColumns:
    """What the fusion reads of many sensor_msgs/NavSatFix (the status and covariance type,
    one byte each, message by message; the numbers as columns)."""
    t_s, _, (lla, cov) = _columns(payloads, _FIX, ((0, 3), (_FIX_COVARIANCE, 9)))
    status, cov_type = [], []
    for data in payloads:
        _, after_frame, _ = _header(data, _FIX.msgtype)
        byte = data[_ENCAPSULATION + after_frame]
        status.append(byte - 256 if byte > 127 else byte)  # int8
        cov_type.append(data[_ENCAPSULATION + _FIX.start(after_frame) + _FIX_COVARIANCE_TYPE])
    return FixColumns(t_s, status, lla, cov, cov_type)


class TwistColumns(NamedTuple):
    """Many TwistWithCovarianceStamped: stamps [s] (n,), twist.twist.linear (n, 3) and
    twist.covariance (n, 36) row-major."""

    t_s: FloatArray
    linear: FloatArray
    covariance: FloatArray


def twist_columns(payloads: Sequence[bytes]) -> TwistColumns:
    """What the fusion reads of many geometry_msgs/TwistWithCovarianceStamped."""
    t_s, _, (linear, cov) = _columns(payloads, _TWIST, ((0, 3), (_TWIST_COVARIANCE, 36)))
    return TwistColumns(t_s, linear, cov)
