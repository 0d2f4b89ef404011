"""Launch the gnss_ins drivers on a machine with a full ROS 2 Jazzy install.

    ros2 launch gnss_ins vehicle.launch.py imu_port:=/dev/ttyUSB0 \
        leica_port:=/dev/ttyUSB1 adu5_port:=/dev/ttyUSB2

Parameters come from the installed config/*.yaml; the port arguments override them. Each GNSS
receiver runs in its own namespace (``leica/gnss/fix``, ``adu5/gnss/attitude``, ...).
"""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def generate_launch_description() -> LaunchDescription:
    """IMU400CC, Leica RTK rover and ADU5 driver nodes with their configuration files."""
    config = os.path.join(get_package_share_directory("gnss_ins"), "config")
    ports = {name: LaunchConfiguration(f"{name}_port") for name in ("imu", "leica", "adu5")}
    defaults = {"imu": "/dev/ttyUSB0", "leica": "/dev/ttyUSB1", "adu5": "/dev/ttyUSB2"}
    drivers = [
        ("imu400cc_node", "imu400cc_node", "", "imu400cc.yaml", "imu"),
        ("gnss_node", "leica_gnss", "leica", "gnss_leica.yaml", "leica"),
        ("gnss_node", "adu5_gnss", "adu5", "gnss_adu5.yaml", "adu5"),
    ]
    return LaunchDescription(
        [
            *(
                DeclareLaunchArgument(f"{name}_port", default_value=default)
                for name, default in defaults.items()
            ),
            *(
                Node(
                    package="gnss_ins",
                    executable=executable,
                    name=node_name,
                    namespace=namespace,
                    parameters=[os.path.join(config, yaml_file), {"port": ports[port]}],
                    output="screen",
                )
                for executable, node_name, namespace, yaml_file, port in drivers
            ),
        ]
    )
