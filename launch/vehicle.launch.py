"""Launch the gnss_ins drivers on a machine with a full ROS 2 Jazzy install.

    ros2 launch gnss_ins vehicle.launch.py imu_port:=/dev/ttyUSB0

Parameters come from the installed config/*.yaml; the port arguments override them.
"""

import os

from ament_index_python.packages import get_package_share_directory
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from launch import LaunchDescription


def generate_launch_description() -> LaunchDescription:
    """IMU400CC driver node with its configuration."""
    config = os.path.join(get_package_share_directory("gnss_ins"), "config")
    imu_port = LaunchConfiguration("imu_port")
    return LaunchDescription(
        [
            DeclareLaunchArgument("imu_port", default_value="/dev/ttyUSB0"),
            Node(
                package="gnss_ins",
                executable="imu400cc_node",
                name="imu400cc_node",
                parameters=[os.path.join(config, "imu400cc.yaml"), {"port": imu_port}],
                output="screen",
            ),
        ]
    )
