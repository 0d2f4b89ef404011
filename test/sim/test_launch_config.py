"""The parameter files `gnss_ins emulate --write-config` writes for `gnss_ins launch --config`:
the installed files with the simulated vehicle's lever arms and the emulated receivers' output
latency, as the live drive has them, and nothing else changed."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml

from gnss_driver.profiles import Receiver
from gnss_ins_common.paths import config_file
from ins_fusion.runtime.vehicle_nodes import ADU5, FUSION, LEICA, VEHICLE
from ins_fusion.sim.drive import Simulation, SimulationConfig
from ins_fusion.sim.launch_config import (
    parameter_arguments,
    simulated_vehicle_parameters,
    with_values,
    write_launch_config,
)


def _parameters(path: Path) -> dict[str, object]:
    """The node's parameters of a file (its one node entry)."""
    (entry,) = yaml.safe_load(path.read_text()).values()
    parameters: dict[str, object] = entry["ros__parameters"]
    return parameters


@pytest.fixture(scope="module")
def written(tmp_path_factory: pytest.TempPathFactory) -> Path:
    directory = tmp_path_factory.mktemp("emulated") / "config"
    write_launch_config(directory)
    return directory


def test_one_file_per_node_of_the_vehicle_each_changed_only_where_the_vehicle_says(written):
    assert sorted(p.name for p in written.iterdir()) == sorted(s.config for s in VEHICLE)
    values = simulated_vehicle_parameters()
    for spec in VEHICLE:
        expected = {**_parameters(config_file(spec.config)), **values.get(spec, {})}
        assert _parameters(written / spec.config) == expected, spec.config
    # The comments of the installed files are kept.
    text = (written / LEICA.config).read_text()
    assert "latency: 0.02 " in text and "# [s] epoch to first byte, if known" in text


def test_the_files_describe_the_vehicle_and_receivers_the_live_drive_emulates(written):
    simulation = Simulation(SimulationConfig())
    car = simulation.vehicle.setup
    fusion = _parameters(written / FUSION.config)
    assert fusion["imu_lever_arm"] == list(car.imu.lever_arm_flu_m)
    assert fusion["gnss_lever_arm"] == list(car.gnss_antenna_flu_m)
    assert fusion["imu_mounting_rpy_deg"] == [math.degrees(a) for a in car.imu.rpy_rad]
    spec_of = {Receiver.LEICA: LEICA, Receiver.ADU5: ADU5}
    for receiver, _ in simulation.receivers:
        latency = _parameters(written / spec_of[receiver.receiver].config)["latency"]
        assert latency == receiver.config.output_latency_s > 0.0


def test_a_name_not_among_the_node_parameters_is_refused():
    text = config_file(FUSION.config).read_text()
    assert "      use: false" in text  # speed.use: nested, never taken for a node parameter
    with pytest.raises(ValueError, match="use is not on exactly one line"):
        with_values(text, {"use": 1.0}, FUSION.config)
    with pytest.raises(ValueError, match="no ros__parameters"):
        with_values("a: 1\n", {"latency": 1.0}, "broken.yaml")


def test_the_demo_arguments_carry_the_same_values():
    for values in simulated_vehicle_parameters().values():
        arguments = parameter_arguments(values)
        assert arguments[::2] == ("-p",) * len(values)
        parsed = dict(arg.split(":=") for arg in arguments[1::2])
        assert {k: yaml.safe_load(v) for k, v in parsed.items()} == values
