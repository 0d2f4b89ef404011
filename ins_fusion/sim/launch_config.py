"""What the vehicle's nodes must be told to navigate on the simulated vehicle (no ROS).

The live drive (ins_fusion/sim/live.py) is the survey car of ``scenarios.SURVEY_CAR`` with the
emulated receivers of ``receivers.emulator_config``: ins_fusion_node needs the car's IMU mounting
and lever arms, each gnss_node the receiver's output latency (the time from an epoch to its
first byte, which it takes off the stamp). ``gnss_ins demo`` passes these values to the nodes as
``-p`` arguments; ``gnss_ins emulate --write-config DIR`` writes them into copies of the
installed parameter files, the directory ``gnss_ins launch --config DIR`` reads.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Mapping
from pathlib import Path

from gnss_driver.profiles import Receiver
from gnss_ins_common.paths import config_file
from ins_fusion.runtime.vehicle_nodes import ADU5, FUSION, LEICA, VEHICLE, NodeSpec
from ins_fusion.sim.receivers import emulator_config
from ins_fusion.sim.scenarios import SURVEY_CAR

#: A parameter value as the files and ``-p`` arguments take it.
Value = float | list[float]


def simulated_vehicle_parameters() -> dict[NodeSpec, dict[str, Value]]:
    """The parameters of each node that depend on the simulated vehicle: the IMU's mounting
    [deg] and lever arm [m, base_link FLU] and the antenna's lever arm (ins_fusion_node), each
    receiver's output latency [s] (its gnss_node)."""
    car = SURVEY_CAR
    return {
        FUSION: {
            "imu_mounting_rpy_deg": [math.degrees(a) for a in car.imu.rpy_rad],
            "imu_lever_arm": list(car.imu.lever_arm_flu_m),
            "gnss_lever_arm": list(car.gnss_antenna_flu_m),
        },
        LEICA: {"latency": emulator_config(Receiver.LEICA).output_latency_s},
        ADU5: {"latency": emulator_config(Receiver.ADU5).output_latency_s},
    }


def parameter_arguments(values: Mapping[str, Value]) -> tuple[str, ...]:
    """``values`` as a node's ``--ros-args`` (``-p NAME:=VALUE`` each)."""
    return tuple(arg for name, v in values.items() for arg in ("-p", f"{name}:={json.dumps(v)}"))


def with_values(text: str, values: Mapping[str, Value], source: str) -> str:
    """A parameter file's ``text`` with each of ``values`` replaced on its own line (comments and
    layout kept) and a first comment saying what changed from ``source``. Raises ValueError
    for a name that is not on exactly one line among the node's parameters (nested ones, e.g.
    ``speed: lever_arm``, are never taken for them)."""
    node = re.search(r"^ *ros__parameters:[^\n]*\n( +)\S", text, re.M)
    if node is None:
        raise ValueError(f"{source}: no ros__parameters")
    for name, value in values.items():
        line = re.compile(rf"^({node[1]}{re.escape(name)}:)[^#\n]*?(\s*#.*)?$", re.M)
        if len(line.findall(text)) != 1:
            raise ValueError(f"{source}: {name} is not on exactly one line of its parameters")
        text = line.sub(rf"\g<1> {json.dumps(value)}\g<2>", text)
    changed = ", ".join(f"{name} {json.dumps(v)}" for name, v in values.items()) or "unchanged"
    return f"# gnss_ins emulate: {source} for the simulated vehicle: {changed}\n{text}"


def write_launch_config(directory: Path) -> list[Path]:
    """Copies of the installed parameter files of the vehicle's nodes in ``directory`` (created
    if missing; files of the same names replaced), with the simulated vehicle's values; the
    files written."""
    directory.mkdir(parents=True, exist_ok=True)
    values = simulated_vehicle_parameters()
    written = []
    for spec in VEHICLE:
        source = config_file(spec.config)
        text = with_values(source.read_text(encoding="utf-8"), values.get(spec, {}), source.name)
        path = directory / spec.config
        path.write_text(text, encoding="utf-8")
        written.append(path)
    return written
