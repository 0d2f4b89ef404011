"""Topic names, frames and message types of the nodes as bags hold them (absolute names, the
nodes' relative names in the root namespace; ARCHITECTURE.md "Nodes and interfaces").

One place for what ``gnss_ins simulate``, ``import-qfree``, ``replay``, ``allan``, ``calibrate``
and the demo read and write. Plain constants: the command lines import them without loading
rosbags or the engine.

| topic | type | frame |
|---|---|---|
| /imu/data_raw | sensor_msgs/Imu (REP-145) | imu_link |
| /imu/temperature | sensor_msgs/Temperature | imu_link |
| /gnss/fix | sensor_msgs/NavSatFix | gnss_link |
| /gnss/vel | geometry_msgs/TwistWithCovarianceStamped (ENU) | gnss_link |
| /gnss/attitude | sensor_msgs/Imu (orientation only) | gnss_link |
| /gnss/time_reference | sensor_msgs/TimeReference | gnss_link |
| /vehicle/speed | geometry_msgs/TwistWithCovarianceStamped (linear.x = forward speed) | base_link |
| /ground_truth/fix, /vel, /attitude | as /gnss/* (a reference: the simulator's truth) | base_link |
| /ins/odometry, /ins/fix | Odometry, NavSatFix (ins_fusion_node's output) | map, base_link |
"""

from __future__ import annotations

#: ROS message types, as rosbags names them.
IMU_TYPE = "sensor_msgs/msg/Imu"
TEMPERATURE_TYPE = "sensor_msgs/msg/Temperature"
FIX_TYPE = "sensor_msgs/msg/NavSatFix"
VELOCITY_TYPE = "geometry_msgs/msg/TwistWithCovarianceStamped"
ATTITUDE_TYPE = IMU_TYPE
TIME_REFERENCE_TYPE = "sensor_msgs/msg/TimeReference"
ODOMETRY_TYPE = "nav_msgs/msg/Odometry"

IMU_DATA, IMU_TEMPERATURE = "/imu/data_raw", "/imu/temperature"
GNSS_FIX, GNSS_VEL, GNSS_ATTITUDE = "/gnss/fix", "/gnss/vel", "/gnss/attitude"
GNSS_TIME = "/gnss/time_reference"
#: Prefix of the reference topics PREFIX/fix, PREFIX/vel, PREFIX/attitude.
TRUTH_PREFIX = "/ground_truth"
TRUTH_FIX, TRUTH_VEL, TRUTH_ATTITUDE = (
    f"{TRUTH_PREFIX}/fix",
    f"{TRUTH_PREFIX}/vel",
    f"{TRUTH_PREFIX}/attitude",
)
INS_ODOMETRY, INS_FIX = "/ins/odometry", "/ins/fix"
#: The vehicle's forward speed (odometer, CAN): VELOCITY_TYPE, twist.linear.x [m/s].
VEHICLE_SPEED = "/vehicle/speed"
IMU_FRAME, GNSS_FRAME, TRUTH_FRAME = "imu_link", "gnss_link", "base_link"
SPEED_FRAME = "base_link"

#: The sensor and truth topics a simulation may write and their types, in the order they are
#: declared in a bag.
TOPICS: dict[str, str] = {
    IMU_DATA: IMU_TYPE,
    IMU_TEMPERATURE: TEMPERATURE_TYPE,
    GNSS_FIX: FIX_TYPE,
    GNSS_VEL: VELOCITY_TYPE,
    GNSS_TIME: TIME_REFERENCE_TYPE,
    GNSS_ATTITUDE: ATTITUDE_TYPE,
    TRUTH_FIX: FIX_TYPE,
    TRUTH_VEL: VELOCITY_TYPE,
    TRUTH_ATTITUDE: ATTITUDE_TYPE,
}
