"""Launch the gnss_ins vehicle on a machine with a full ROS 2 Jazzy install.

    ros2 launch gnss_ins vehicle.launch.py imu_port:=/dev/ttyUSB0 \
        leica_port:=/dev/ttyUSB1 adu5_port:=/dev/ttyUSB2 [record_dir:=/data/bags] \
        [ntrip_url:=http://USER@HOST:2101/MOUNTPOINT ntrip_password_file:=/etc/gnss_ins/ntrip]

The nodes, namespaces and remappings come from ins_fusion.runtime.vehicle_nodes (the same table as
`gnss_ins launch` and the demo); parameters from the installed config/*.yaml, the port arguments
override them. Each GNSS receiver runs in its own namespace (``leica/gnss/fix``,
``adu5/gnss/attitude``); ins_fusion_node reads those. Every node is respawned 1 s after it ends
(``respawn:=false``: not). A non-empty ``record_dir`` also starts `gnss_ins record` into
``record_dir/vehicle_<UTC start time>`` (ins_fusion.runtime.recorder), respawned the same way
and continuing the same recording (``--resume``). A non-empty ``ntrip_url`` also starts the NTRIP
client that brings the Leica rover its corrections (docs/ntrip.md); its password comes from
``ntrip_password_file`` or the environment variable NTRIP_PASSWORD, never an argument. ROS
discovery is closed to this machine (``discovery:=LOCALHOST``) unless ``discovery:=SUBNET``
opens it.
"""

from pathlib import Path

from launch import LaunchContext, LaunchDescription
from launch.actions import DeclareLaunchArgument, ExecuteProcess, OpaqueFunction
from launch.conditions import evaluate_condition_expression
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from gnss_ins_common.paths import config_file
from ins_fusion.runtime.health import STATUS_PROCESS, status_command
from ins_fusion.runtime.recorder import (
    DEFAULT_SPLIT_S,
    RECORDER,
    STORAGES,
    TOPICS_FILE,
    Recording,
    read_topics,
    recording_name,
)
from ins_fusion.runtime.vehicle_nodes import (
    DEFAULT_PORTS,
    DISCOVERY_RANGES,
    NTRIP,
    VEHICLE,
    NodeSpec,
    discovery_environment,
)

#: Seconds between the end of a process and its respawn.
RESPAWN_DELAY_S = 1.0


def generate_launch_description() -> LaunchDescription:
    """The IMU400CC, Leica, ADU5 and fusion nodes with their configuration files, and the
    recorder when ``record_dir`` is given."""
    arguments = [
        *(
            DeclareLaunchArgument(f"{role}_port", default_value=port)
            for role, port in DEFAULT_PORTS.items()
        ),
        DeclareLaunchArgument(
            "respawn", default_value="true", description="start a process again when it ends"
        ),
        DeclareLaunchArgument(
            "record_dir", default_value="", description="record into DIR/vehicle_<UTC time>"
        ),
        DeclareLaunchArgument(
            "record_split", default_value=str(DEFAULT_SPLIT_S), description="seconds per file"
        ),
        DeclareLaunchArgument(
            "record_topics",
            default_value=str(config_file(TOPICS_FILE)),
            description="YAML file with the list 'topics:' to record",
        ),
        DeclareLaunchArgument("record_storage", default_value=STORAGES[0], choices=list(STORAGES)),
        DeclareLaunchArgument(
            "ntrip_url",
            default_value="",
            description="NTRIP caster http[s]://USER@HOST:PORT/MOUNTPOINT (no password)",
        ),
        DeclareLaunchArgument(
            "ntrip_password_file",
            default_value="",
            description="file with the caster's password (mode 0600); empty: $NTRIP_PASSWORD",
        ),
        DeclareLaunchArgument(
            "discovery",
            default_value=DISCOVERY_RANGES[0],
            choices=list(DISCOVERY_RANGES),
            description="ROS 2 discovery range: LOCALHOST (this machine only) or SUBNET",
        ),
    ]
    return LaunchDescription([*arguments, OpaqueFunction(function=_processes)])


def _processes(context: LaunchContext) -> list[ExecuteProcess]:
    """The nodes and the recorder, with the launch arguments' values."""

    def value(name: str) -> str:
        return LaunchConfiguration(name).perform(context)

    respawn = evaluate_condition_expression(context, [LaunchConfiguration("respawn")])
    env = discovery_environment(value("discovery"))

    def node(spec: NodeSpec, parameters: dict[str, str]) -> Node:
        return Node(
            package="gnss_ins",
            executable=spec.executable,
            name=spec.name,
            namespace=spec.namespace,
            parameters=[str(config_file(spec.config)), *([parameters] if parameters else [])],
            remappings=list(spec.remaps),
            output="screen",
            respawn=respawn,
            respawn_delay=RESPAWN_DELAY_S,
            additional_env=env,
        )

    processes: list[ExecuteProcess] = [
        node(spec, {"port": value(f"{spec.port_role}_port")} if spec.port_role else {})
        for spec in VEHICLE
    ]
    if value("ntrip_url"):
        parameters = {"url": value("ntrip_url")}
        if value("ntrip_password_file"):
            parameters["password_file"] = value("ntrip_password_file")
        processes.append(node(NTRIP, parameters))
    processes.append(  # the system's health on /gnss_ins/status
        ExecuteProcess(
            cmd=status_command(None),
            name=STATUS_PROCESS,
            output="screen",
            respawn=respawn,
            respawn_delay=RESPAWN_DELAY_S,
            additional_env=env,
        )
    )
    if value("record_dir"):
        recording = Recording(
            Path(value("record_dir")) / recording_name(),
            tuple(read_topics(Path(value("record_topics")))),
            float(value("record_split")),
            value("record_storage"),
        )
        recording.output.parent.mkdir(parents=True, exist_ok=True)
        processes.append(
            ExecuteProcess(
                cmd=recording.command(),
                name=RECORDER,
                output="screen",
                respawn=respawn,
                respawn_delay=RESPAWN_DELAY_S,
                additional_env=env,
            )
        )
    return processes
