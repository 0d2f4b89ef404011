"""ROS messages of a recording, built and serialized (CDR) for the bag tests."""

from __future__ import annotations

import numpy as np

from ins_fusion.bags.typestore import jazzy_typestore

TS = jazzy_typestore()
T = TS.types
T0 = 1_377_511_200_000_000_000  # 2013-08-26T10:00:00Z


def imu(t_ns: int, k: float, frame: str = "imu_link", cov: float = 1e-4):
    return T["sensor_msgs/msg/Imu"](
        header(t_ns, frame),
        T["geometry_msgs/msg/Quaternion"](0.1, -0.2, 0.3, 0.9),
        np.arange(9, dtype=np.float64) - 1.0,
        vec(k, -k, 0.5 * k),
        np.full(9, cov),
        vec(0.01, -0.02, 9.81 + k),
        np.linspace(0.0, 1.0, 9),
    )


def fix(t_ns: int, k: float):
    status = T["sensor_msgs/msg/NavSatStatus"](1, 1)
    return T["sensor_msgs/msg/NavSatFix"](
        header(t_ns, "gnss_link"), status, 63.4 + k, 10.4 - k, 50.0 + k, np.eye(3).ravel(), 2
    )


def twist(t_ns: int, k: float):
    twist = T["geometry_msgs/msg/Twist"](vec(k, 2 * k, -k), vec(0.0, 0.0, 0.1))
    return T["geometry_msgs/msg/TwistWithCovarianceStamped"](
        header(t_ns, "gnss_link"),
        T["geometry_msgs/msg/TwistWithCovariance"](twist, np.arange(36, dtype=np.float64)),
    )


def cdr(msg) -> bytes:
    return bytes(TS.serialize_cdr(msg, msg.__msgtype__))


def header(t_ns: int, frame: str):
    return T["std_msgs/msg/Header"](T["builtin_interfaces/msg/Time"](*divmod(t_ns, 10**9)), frame)


def vec(x: float, y: float, z: float):
    return T["geometry_msgs/msg/Vector3"](x, y, z)
