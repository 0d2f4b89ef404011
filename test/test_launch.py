"""`gnss_ins launch` and the shared vehicle node table (also used by launch/vehicle.launch.py)."""

from __future__ import annotations

import ast
import signal
import subprocess
from pathlib import Path

import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from ros_harness import Collector, spinning, wait_for
from sensor_msgs.msg import Imu, NavSatFix

from gnss_driver.emulator import EmulatorConfig, GnssEmulator, constant_velocity
from gnss_driver.profiles import Receiver
from imu400cc_driver.emulator import Imu400ccEmulator
from ins_fusion.runtime.processes import gnss_ins_command
from ins_fusion.runtime.vehicle_nodes import FUSION, VEHICLE, ros_arguments

pytestmark = pytest.mark.ros
REPO = Path(__file__).resolve().parents[1]
NODE_NAMES = {"imu400cc_node", "leica_gnss", "adu5_gnss", "ins_fusion_node"}


@pytest.fixture(scope="module", autouse=True)
def ros_context():
    rclpy.init()
    yield
    rclpy.shutdown()


def test_node_table_wires_the_fusion_node_to_the_receivers_namespaces():
    namespaces = {spec.name: spec.namespace for spec in VEHICLE}
    assert namespaces == {
        "imu400cc_node": "",
        "leica_gnss": "leica",
        "adu5_gnss": "adu5",
        "ins_fusion_node": "",
    }
    args = ros_arguments(FUSION, None, None)
    assert "gnss/fix:=/leica/gnss/fix" in args
    assert "gnss/attitude:=/adu5/gnss/attitude" in args
    assert (REPO / "config" / "ins_fusion.yaml").samefile(args[args.index("--params-file") + 1])


def test_ros_launch_file_uses_the_shared_table():
    source = (REPO / "launch" / "vehicle.launch.py").read_text()
    tree = ast.parse(source)
    imported = {
        alias.name
        for node in ast.walk(tree)
        if isinstance(node, ast.ImportFrom) and node.module == "ins_fusion.runtime.vehicle_nodes"
        for alias in node.names
    }
    assert {"VEHICLE", "DEFAULT_PORTS"} <= imported
    assert "generate_launch_description" in source


def test_launch_starts_every_node_on_emulated_hardware_and_stops_cleanly(tmp_path):
    leica = GnssEmulator(
        constant_velocity((3.0, 4.0, 0.0)), EmulatorConfig(receiver=Receiver.LEICA)
    )
    adu5 = GnssEmulator(constant_velocity((3.0, 4.0, 0.0)), EmulatorConfig(receiver=Receiver.ADU5))
    topics = {
        "imu/data_raw": Imu,
        "leica/gnss/fix": NavSatFix,
        "adu5/gnss/attitude": Imu,
        "/diagnostics": DiagnosticArray,
    }
    with Imu400ccEmulator() as imu, leica, adu5:
        collector = Collector(topics)
        launcher = subprocess.Popen(
            gnss_ins_command(
                "launch",
                "--imu-port",
                imu.path,
                "--leica-port",
                leica.path,
                "--adu5-port",
                adu5.path,
                "--log-dir",
                str(tmp_path),
            ),
            stdout=subprocess.PIPE,
            text=True,
        )
        try:
            with spinning(collector.node):
                assert wait_for(lambda: all(collector.count(t) > 2 for t in topics), 30.0), {
                    t: collector.count(t) for t in topics
                }
                # Every node reports on /diagnostics (the fusion node starts slowest).
                assert wait_for(lambda: _reporters(collector) >= NODE_NAMES, 30.0), _reporters(
                    collector
                )
        finally:
            launcher.send_signal(signal.SIGINT)
            output, _ = launcher.communicate(timeout=30)
            collector.node.destroy_node()
    assert launcher.returncode == 0, output
    for spec in VEHICLE:
        assert f"started {spec.name}" in output
        assert (tmp_path / f"{spec.name}.log").exists()


def _reporters(collector: Collector) -> set[str]:
    """Node names in the /diagnostics statuses received so far."""
    return {
        status.name.split(":")[0]
        for array in collector.get("/diagnostics")
        for status in array.status
    }


def test_launch_refuses_a_missing_config_directory(tmp_path):
    result = subprocess.run(
        gnss_ins_command("launch", "--config", str(tmp_path / "nope")),
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 2
    assert "not a directory" in result.stdout
