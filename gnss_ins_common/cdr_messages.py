"""Serialized (CDR) messages rewritten in place from a template (no ROS import).

rclpy converts a Python message to its C twin field by field before it serializes it, and
building the Python message costs as much again (~18 µs for a sensor_msgs/Imu with its three
9-element covariances); a publisher also takes the serialized bytes. A node that publishes a
message type often therefore serializes one message once, its frame id (the only
variable-length field) and constant fields set, and for each message overwrites in place the
stamp and the float64 that change, which sit at fixed offsets from the end.

Layouts (XCDR1): a 4-byte encapsulation header whose second byte is 1 for little-endian, 0 for
big-endian, then the body, aligned relative to its start. Every message here starts with
std_msgs/Header: stamp (int32 sec, uint32 nanosec), frame_id (uint32 length including the NUL,
then the characters). sensor_msgs/Imu ends with 37 float64: orientation (4), its covariance (9),
angular_velocity (3), its covariance (9), linear_acceleration (3), its covariance (9);
sensor_msgs/Temperature with temperature and variance.
"""

from __future__ import annotations

import struct
from collections.abc import Iterable

import numpy as np
from numpy.typing import ArrayLike

#: Bytes of the encapsulation header before the body; header.stamp starts right after it.
CDR_HEADER = 4
#: float64 at the end of a sensor_msgs/Imu, and angular_velocity and linear_acceleration among
#: them.
IMU_DOUBLES = 4 + 9 + 3 + 9 + 3 + 9
IMU_RATE = slice(13, 16)
IMU_FORCE = slice(25, 28)
_NS_PER_S = 1_000_000_000


class SerializedMessage:
    """A serialized message whose stamp and last ``doubles`` float64 (followed by ``trailing``
    bytes) are rewritten for each message; ``stamp_at``: offset of header.stamp [bytes]."""

    def __init__(self, template: bytes, stamp_at: int, doubles: int, trailing: int = 0) -> None:
        """Take a copy of ``template`` (a serialized message of the type, frame ids set)."""
        if len(template) < CDR_HEADER or template[1] not in (0, 1):
            raise ValueError(f"not a CDR message: {bytes(template[:4]).hex()}")
        order = "<" if template[1] == 1 else ">"
        self.buffer = bytearray(template)
        self._stamp = struct.Struct(order + "iI")
        self._stamp_at = stamp_at
        start = len(template) - trailing - 8 * doubles
        #: The last ``doubles`` float64 of the message, a view of ``buffer``.
        self.values = np.frombuffer(self.buffer, np.dtype(order + "f8"), doubles, start)

    def stamp(self, time_ns: int) -> None:
        """Set header.stamp to ``time_ns`` [ns since the epoch]."""
        self._stamp.pack_into(self.buffer, self._stamp_at, *divmod(time_ns, _NS_PER_S))

    def write(self, time_ns: int, values: ArrayLike) -> bytes:
        """The message stamped ``time_ns`` [ns since the epoch] with ``values`` at its end."""
        self.stamp(time_ns)
        self.values[:] = values
        return bytes(self.buffer)


def write_each(time_ns: int, filled: Iterable[tuple[SerializedMessage, ArrayLike]]) -> list[bytes]:
    """Each (message, values) of ``filled`` written at ``time_ns`` [ns since the epoch]
    (``SerializedMessage.write``): the messages of one output."""
    return [message.write(time_ns, values) for message, values in filled]


class ImuWriter:
    """sensor_msgs/Imu messages of one template (frame id, orientation and the covariances
    set) with the stamp, angular velocity and linear acceleration of each sample."""

    def __init__(self, template: bytes) -> None:
        """``template``: a serialized sensor_msgs/Imu."""
        self._message = SerializedMessage(template, CDR_HEADER, IMU_DOUBLES)
        values = self._message.values
        self._rate, self._force = values[IMU_RATE], values[IMU_FORCE]

    def write(self, time_ns: int, rate_rad_s: ArrayLike, accel_m_s2: ArrayLike) -> bytes:
        """The message stamped ``time_ns`` [ns since the epoch] with angular velocity
        ``rate_rad_s`` [rad/s] and linear acceleration ``accel_m_s2`` [m/s²] (3 each, in the
        template's frame)."""
        self._message.stamp(time_ns)
        self._rate[:] = rate_rad_s
        self._force[:] = accel_m_s2
        return bytes(self._message.buffer)
