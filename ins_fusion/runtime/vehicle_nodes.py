"""The vehicle's node set: one table for launch/vehicle.launch.py, `gnss_ins launch` and the demo.

Each receiver's gnss_node runs in its own namespace; ins_fusion_node is remapped to read the Leica
rover's position/velocity and the ADU5's attitude. Pure data plus command-line building (no ROS).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from gnss_ins_common.paths import config_file
from ins_fusion.runtime.processes import python_main


@dataclass(frozen=True)
class NodeSpec:
    """One node of the vehicle: its name, module, namespace, parameter file, serial-port role
    (None: no port) and topic remappings."""

    name: str
    module: str
    executable: str
    namespace: str
    config: str
    port_role: str | None
    remaps: tuple[tuple[str, str], ...] = ()


IMU = NodeSpec("imu400cc_node", "imu400cc_driver.node", "imu400cc_node", "", "imu400cc.yaml", "imu")
LEICA = NodeSpec("leica_gnss", "gnss_driver.node", "gnss_node", "leica", "gnss_leica.yaml", "leica")
ADU5 = NodeSpec("adu5_gnss", "gnss_driver.node", "gnss_node", "adu5", "gnss_adu5.yaml", "adu5")
FUSION = NodeSpec(
    "ins_fusion_node",
    "ins_fusion.node",
    "ins_fusion_node",
    "",
    "ins_fusion.yaml",
    None,
    (
        ("gnss/fix", "/leica/gnss/fix"),
        ("gnss/vel", "/leica/gnss/vel"),
        ("gnss/attitude", "/adu5/gnss/attitude"),
    ),
)
VEHICLE = (IMU, LEICA, ADU5, FUSION)
#: The NTRIP client (with ``--ntrip`` / ``ntrip_url:=``), in the rover's namespace: it publishes
#: the corrections on /leica/rtcm, which the rover's gnss_node writes to its port, and reads the
#: rover's GGA from /leica/nmea.
NTRIP = NodeSpec("ntrip_client", "ntrip_client.node", "ntrip_node", "leica", "ntrip.yaml", None)
#: Default serial ports per role.
DEFAULT_PORTS = {"imu": "/dev/ttyUSB0", "leica": "/dev/ttyUSB1", "adu5": "/dev/ttyUSB2"}
#: ROS 2 discovery ranges the daemon offers (``ROS_AUTOMATIC_DISCOVERY_RANGE``), closed first:
#: LOCALHOST keeps every node reachable only from this machine, SUBNET opens them to every host
#: of the vehicle's network with the same ROS_DOMAIN_ID.
DISCOVERY_RANGES = ("LOCALHOST", "SUBNET")


#: Fast DDS profile of the LOCALHOST range without the shared-memory transport (see the file).
FASTDDS_LOCALHOST_PROFILE = "fastdds_localhost.xml"


def discovery_environment(range_: str, environ: Mapping[str, str] = os.environ) -> dict[str, str]:
    """The environment entries that set the nodes' discovery range (one of DISCOVERY_RANGES).

    With Fast DDS (rmw_fastrtps_cpp, the default RMW) the nodes use UDP only, never the
    shared-memory transport: Fast DDS 2.14 opens a peer's shared-memory port holding the
    participant's send mutex, and the port's health check can sleep 333 ms, so each process that
    joined the domain stalled every publication of every node for a third of a second
    (eProsima/Fast-DDS#6535; docs/operation.md). rmw_fastrtps always adds shared memory for
    the LOCALHOST range, so LOCALHOST is the same settings (no multicast, 127.0.0.1 the initial
    peer) from FASTDDS_LOCALHOST_PROFILE under the range SYSTEM_DEFAULT (which rmw_fastrtps
    leaves to the profile); another RMW gets the range itself.
    """
    if range_ not in DISCOVERY_RANGES:
        raise ValueError(f"discovery range {range_!r}: one of {', '.join(DISCOVERY_RANGES)}")
    if environ.get("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp") != "rmw_fastrtps_cpp":
        return {"ROS_AUTOMATIC_DISCOVERY_RANGE": range_}
    if range_ == "SUBNET":
        return {"ROS_AUTOMATIC_DISCOVERY_RANGE": range_, "FASTDDS_BUILTIN_TRANSPORTS": "UDPv4"}
    return {
        "ROS_AUTOMATIC_DISCOVERY_RANGE": "SYSTEM_DEFAULT",
        "FASTRTPS_DEFAULT_PROFILES_FILE": str(config_file(FASTDDS_LOCALHOST_PROFILE)),
    }


def ros_arguments(
    spec: NodeSpec, config_dir: Path | None, port: str | None, extra: tuple[str, ...] = ()
) -> list[str]:
    """``--ros-args`` of a node: parameter file, port, name, namespace, remaps, extra args."""
    config = config_dir / spec.config if config_dir is not None else config_file(spec.config)
    args = ["--ros-args", "--params-file", str(config), "-r", f"__node:={spec.name}"]
    if spec.namespace:
        args += ["-r", f"__ns:=/{spec.namespace}"]
    if port is not None:
        args += ["-p", f"port:={port}"]
    for source, target in spec.remaps:
        args += ["-r", f"{source}:={target}"]
    return [*args, *extra]


def command(
    spec: NodeSpec, config_dir: Path | None, port: str | None, extra: tuple[str, ...] = ()
) -> list[str]:
    """The node's command line with this interpreter (see ``processes.python_main``)."""
    return python_main(spec.module, *ros_arguments(spec, config_dir, port, extra))


def ntrip_parameters(url: str, password_file: Path | None) -> tuple[str, ...]:
    """The NTRIP client's ``--ros-args`` beyond its file: the caster URL (never a password:
    ntrip_client.caster_url refuses one) and the password file's path, if any."""
    file = () if password_file is None else ("-p", f"password_file:={password_file.absolute()}")
    return ("-p", f"url:={url}", *file)
