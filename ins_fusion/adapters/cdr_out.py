"""ins_fusion_node's outputs written straight into serialized (CDR) messages (no ROS import).

rclpy converts a Python message to its C twin field by field before it serializes it (~20 µs for
an Odometry and its two 36-element covariances, most of a publish). The node therefore
serializes one message per output once, with its frame ids set, and for each output overwrites
in place the stamp and the fixed-size run of float64 at the end of the message, where every
number it publishes sits (``gnss_ins_common.cdr_messages``):

- nav_msgs/Odometry: position, orientation, pose covariance, linear and angular velocity, twist
  covariance (85 float64, ``core.output.output_numbers``);
- sensor_msgs/NavSatFix: status (int8 just after frame_id), then latitude, longitude, altitude
  and the covariance (12 float64) before position_covariance_type (uint8, the last byte);
- sensor_msgs/Imu of ins/imu: orientation, its covariance, angular_velocity, its covariance,
  linear_acceleration, its covariance (37 float64; no acceleration: covariance[0] = -1);
- tf2_msgs/TFMessage with one transform: translation and rotation (7 float64); its stamp comes
  after the sequence length.

Layouts as in ``cdr_fields``. The messages decode to what ``solution_out.fill_odometry`` /
``fill_fused_fix`` and ``message_fields.fill_orientation`` fill (test_cdr_out.py).
"""

from __future__ import annotations

import struct
from typing import NamedTuple

import numpy as np

from gnss_ins_common.cdr_messages import CDR_HEADER, IMU_DOUBLES, SerializedMessage, write_each
from gnss_ins_common.message_fields import stamp_ns
from gnss_ins_common.navsat import NavSatStatus
from gnss_ins_common.types import FloatArray
from ins_fusion.core.output.output_numbers import (
    FIX,
    IMU,
    NUMBERS,
    ODOMETRY,
    TRANSFORM,
    output_numbers,
)
from ins_fusion.core.output.solution import STATE, STATES, T

_ODOMETRY_DOUBLES = 3 + 4 + 36 + 3 + 3 + 36
_FIX_DOUBLES = 3 + 9
_TF_DOUBLES = 3 + 4


class Outputs(NamedTuple):
    """One output's serialized messages."""

    odometry: bytes
    fix: bytes
    imu: bytes
    transform: bytes


class OutputWriter:
    """Serialized ins/odometry, ins/fix, ins/imu and /tf of a solution row, from one template
    each (serialized by the node with the frame ids and constant fields set:
    ``status.service`` and ``position_covariance_type`` of the fix)."""

    def __init__(
        self,
        odometry: bytes,
        fix: bytes,
        imu: bytes,
        transform: bytes,
        rate_variance_rad2_s2: float,
    ) -> None:
        """Templates of each message; ``rate_variance_rad2_s2``: variance of each rate axis."""
        self._odometry = SerializedMessage(odometry, CDR_HEADER, _ODOMETRY_DOUBLES)
        self._fix = SerializedMessage(fix, CDR_HEADER, _FIX_DOUBLES, trailing=1)
        self._imu = SerializedMessage(imu, CDR_HEADER, IMU_DOUBLES)
        self._transform = SerializedMessage(transform, CDR_HEADER + 4, _TF_DOUBLES)
        # status.status: the int8 right after frame_id (stamp, then its length and characters)
        (length,) = struct.unpack_from("<I" if fix[1] == 1 else ">I", fix, CDR_HEADER + 8)
        self._fix_status_at = CDR_HEADER + 12 + length
        self._rate_variance = rate_variance_rad2_s2
        self._numbers = np.empty(NUMBERS)

    def write(self, row: FloatArray) -> Outputs | None:
        """The four messages of a solution row (core.output.solution), stamped at its IMU stamp;
        None if the row is not publishable (a non-finite number or covariance not PSD)."""
        numbers = self._numbers
        if not output_numbers(row, self._rate_variance, numbers):
            return None
        time_ns = stamp_ns(float(row[T]))
        aligning = STATES[int(row[STATE])] == "aligning"
        self._fix.buffer[self._fix_status_at] = (
            NavSatStatus.NO_FIX if aligning else NavSatStatus.FIX
        ) & 0xFF
        return Outputs(
            *write_each(
                time_ns,
                (
                    (self._odometry, numbers[ODOMETRY]),
                    (self._fix, numbers[FIX]),
                    (self._imu, numbers[IMU]),
                    (self._transform, numbers[TRANSFORM]),
                ),
            )
        )
