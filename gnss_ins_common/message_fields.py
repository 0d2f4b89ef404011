"""What the gnss_ins nodes publish, field by field, for rclpy and rosbags messages alike (no ROS).

The ``fill_*`` functions set a message's fields by attribute, so the same function fills an rclpy
message (``sensor_msgs.msg.Imu()``) in a node and a rosbags one in ``gnss_ins simulate``: one
definition of each published message. Conventions (ARCHITECTURE.md): stamps in integer ns
on the host clock, REP-103 ENU/FLU, REP-145 for IMU data; a quantity a message does not carry is
marked by -1 as the first element of its covariance (sensor_msgs/Imu) or by ``UNKNOWN_VARIANCE``
on the diagonal (the angular part of a velocity twist, unobserved attitude axes).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

#: Variance standing for "not measured" on a covariance diagonal [unit^2].
UNKNOWN_VARIANCE = 1.0e6
#: Numbers per axis or matrix element: a sequence or a float array.
Values = Sequence[float] | NDArray[np.float64]
_NS_PER_S = 1_000_000_000


def stamp_ns(seconds: float) -> int:
    """A host time [s] as integer ns, rounded as the drivers split stamps (sec = floor, nanosec
    rounded and kept below one second)."""
    sec = math.floor(seconds)
    return sec * _NS_PER_S + min(_NS_PER_S - 1, round((seconds - sec) * 1e9))


def seconds_of_ns(time_ns: int) -> float:
    """The host time [s] a driver core is fed for a stamp of ``time_ns`` [ns]: the nodes feed
    ``seconds_of_ns(stamp_ns(read_time_s))`` and stamp the raw topics with that ``stamp_ns``, so
    ``gnss_ins redecode`` feeds the very same float from a recording (the ROS clock's own
    conversion, ``node_time_s``)."""
    return time_ns * 1e-9


def set_header(msg: Any, time_ns: int, frame_id: str) -> None:
    """header.stamp from ns since the epoch, header.frame_id."""
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(time_ns, _NS_PER_S)
    msg.header.frame_id = frame_id


def fill_imu(
    msg: Any,
    time_ns: int,
    frame_id: str,
    rate_flu_rad_s: Values,
    specific_force_flu_m_s2: Values,
    gyro_variance: Values,
    accel_variance: Values,
) -> Any:
    """sensor_msgs/Imu of imu/data_raw (REP-145): rate [rad/s] and specific force [m/s²] in the
    FLU frame, diagonal covariances per axis [(rad/s)², (m/s²)²], no orientation."""
    set_header(msg, time_ns, frame_id)
    q = msg.orientation
    q.x, q.y, q.z, q.w = 0.0, 0.0, 0.0, 1.0
    msg.orientation_covariance[0] = -1.0
    w, f = msg.angular_velocity, msg.linear_acceleration
    w.x, w.y, w.z = map(float, rate_flu_rad_s)
    f.x, f.y, f.z = map(float, specific_force_flu_m_s2)
    for i in range(3):
        msg.angular_velocity_covariance[4 * i] = gyro_variance[i]
        msg.linear_acceleration_covariance[4 * i] = accel_variance[i]
    return msg


def fill_temperature(msg: Any, time_ns: int, frame_id: str, celsius: float, variance: float) -> Any:
    """sensor_msgs/Temperature [°C] of imu/temperature."""
    set_header(msg, time_ns, frame_id)
    msg.temperature = float(celsius)
    msg.variance = variance
    return msg


def fill_navsatfix(
    msg: Any,
    time_ns: int,
    frame_id: str,
    status: int,
    service: int,
    lat_deg: float,
    lon_deg: float,
    alt_m: float,
    covariance_enu_m2: Values,
    covariance_type: int,
) -> Any:
    """sensor_msgs/NavSatFix: WGS-84 position (altitude above the ellipsoid), row-major ENU
    covariance [m²]."""
    set_header(msg, time_ns, frame_id)
    msg.status.status, msg.status.service = status, service
    msg.latitude, msg.longitude, msg.altitude = lat_deg, lon_deg, alt_m
    msg.position_covariance[:] = covariance_enu_m2
    msg.position_covariance_type = covariance_type
    return msg


def fill_velocity(
    msg: Any,
    time_ns: int,
    frame_id: str,
    vel_enu_m_s: Values,
    covariance_enu: Values,
) -> Any:
    """geometry_msgs/TwistWithCovarianceStamped: ENU velocity [m/s] with its row-major 3x3
    covariance [m²/s²]; the angular part is not measured (UNKNOWN_VARIANCE on its diagonal)."""
    set_header(msg, time_ns, frame_id)
    linear = msg.twist.twist.linear
    linear.x, linear.y, linear.z = map(float, vel_enu_m_s)
    covariance = [0.0] * 36
    for row in range(3):
        for col in range(3):
            covariance[6 * row + col] = covariance_enu[3 * row + col]
        covariance[7 * (row + 3)] = UNKNOWN_VARIANCE
    msg.twist.covariance[:] = covariance
    return msg


def fill_orientation(
    msg: Any,
    time_ns: int,
    frame_id: str,
    quat_enu_flu_xyzw: Values,
    covariance_rpy_rad2: Values,
) -> Any:
    """sensor_msgs/Imu carrying only an orientation (FLU -> ENU quaternion, scalar last) and its
    row-major roll/pitch/yaw covariance [rad²]; rate and acceleration marked absent."""
    set_header(msg, time_ns, frame_id)
    q = msg.orientation
    q.x, q.y, q.z, q.w = map(float, quat_enu_flu_xyzw)
    msg.orientation_covariance[:] = covariance_rpy_rad2
    msg.angular_velocity_covariance[0] = -1.0
    msg.linear_acceleration_covariance[0] = -1.0
    return msg


def fill_time_reference(
    msg: Any, time_ns: int, frame_id: str, time_ref_ns: int, source: str
) -> Any:
    """sensor_msgs/TimeReference: the receiver's UTC (time_ref) at host time header.stamp."""
    set_header(msg, time_ns, frame_id)
    msg.time_ref.sec, msg.time_ref.nanosec = divmod(time_ref_ns, _NS_PER_S)
    msg.source = source
    return msg
