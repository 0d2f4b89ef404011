"""Launch the gnss_ins vehicle on a machine with a full ROS 2 Jazzy install.

    ros2 launch gnss_ins vehicle.launch.py imu_port:=/dev/ttyUSB0 \
        leica_port:=/dev/ttyUSB1 adu5_port:=/dev/ttyUSB2

The nodes, namespaces and remappings come from ins_fusion.runtime.vehicle_nodes (the same table as
`gnss_ins launch` and the demo); parameters from the installed config/*.yaml, the port arguments
override them. Each GNSS receiver runs in its own namespace (``leica/gnss/fix``,
``adu5/gnss/attitude``); ins_fusion_node reads those.
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from gnss_ins_common.paths import config_file
from ins_fusion.runtime.vehicle_nodes import DEFAULT_PORTS, VEHICLE


def generate_launch_description() -> LaunchDescription:
    """The IMU400CC, Leica, ADU5 and fusion nodes with their configuration files."""
    arguments = [
        DeclareLaunchArgument(f"{role}_port", default_value=port)
        for role, port in DEFAULT_PORTS.items()
    ]

    def port(role: str | None) -> list[dict[str, LaunchConfiguration]]:
        return [{"port": LaunchConfiguration(f"{role}_port")}] if role else []

    nodes = [
        Node(
            package="gnss_ins",
            executable=spec.executable,
            name=spec.name,
            namespace=spec.namespace,
            parameters=[
                str(config_file(spec.config)),
                *(
                    [{"port": LaunchConfiguration(f"{spec.port_role}_port")}]
                    if spec.port_role
                    else []
                ),
            ],
            remappings=list(spec.remaps),
            output="screen",
        )
        for spec in VEHICLE
    ]
    return LaunchDescription([*arguments, *nodes])
