"""The drivers as managed (lifecycle) nodes: the real executables with ``autostart:=false`` on the
emulated devices, driven through their lifecycle_msgs services as a lifecycle manager (or
``ros2 lifecycle set``) drives them. A plain start (autostart) is what every other node test runs.
"""

from __future__ import annotations

import os
import subprocess
from collections.abc import Iterator
from contextlib import contextmanager

import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState, GetState
from rclpy.node import Node
from sensor_msgs.msg import Imu, NavSatFix
from support.ros_harness import Collector, diagnostic_values, node_executable, spinning, wait_for

from gnss_driver.emulator import EmulatorConfig, GnssEmulator, constant_velocity
from gnss_driver.profiles import Receiver
from imu400cc_driver.emulator import Imu400ccEmulator, resting_source

pytestmark = pytest.mark.ros


@pytest.fixture(scope="module", autouse=True)
def ros_context():
    rclpy.init()
    yield
    rclpy.shutdown()


class Manager:
    """The lifecycle services of one node, called as a lifecycle manager calls them."""

    def __init__(self, client_node: Node, node_name: str) -> None:
        self._change = client_node.create_client(ChangeState, f"/{node_name}/change_state")
        self._get = client_node.create_client(GetState, f"/{node_name}/get_state")
        assert self._change.wait_for_service(timeout_sec=20.0), f"{node_name}: no lifecycle"
        assert self._get.wait_for_service(timeout_sec=20.0)

    def state(self) -> str:
        """The node's state; asked again when an answer does not come (a request sent while
        the service's reply path is still being matched by discovery gets no answer)."""
        for _ in range(5):
            future = self._get.call_async(GetState.Request())
            if wait_for(future.done, 3.0):
                return str(future.result().current_state.label)
            self._get.remove_pending_request(future)
        raise AssertionError("get_state never answered")

    def change(self, transition: int) -> bool:
        request = ChangeState.Request()
        request.transition.id = transition
        future = self._change.call_async(request)
        assert wait_for(future.done, 10.0)
        return bool(future.result().success)


@contextmanager
def driver_process(executable: str, *params: str) -> Iterator[subprocess.Popen[bytes]]:
    """The node executable with ``autostart:=false`` and ``params``, stopped with SIGINT."""
    args = [str(node_executable(executable)), "--ros-args", "-p", "autostart:=false"]
    for param in params:
        args += ["-p", param]
    process = subprocess.Popen(args, env=os.environ.copy())
    try:
        yield process
    finally:
        process.send_signal(2)
        try:
            assert process.wait(timeout=15) == 0
        finally:
            if process.poll() is None:
                process.kill()


def _status(collector: Collector, name: str) -> tuple[int, str, dict[str, str]]:
    """Level, message and values of the latest /diagnostics status whose name starts so."""
    for array in reversed(collector.get("/diagnostics")):
        for status in array.status:
            if status.name.startswith(name):
                return (
                    status.level,
                    status.message,
                    diagnostic_values(DiagnosticArray(status=[status])),
                )
    raise AssertionError(f"no /diagnostics of {name}")


def _fresh_status(collector: Collector, name: str) -> tuple[int, str, dict[str, str]]:
    collector.clear()
    assert wait_for(lambda: collector.count("/diagnostics") >= 2, 5.0)
    return _status(collector, name)


def _held_once(collector: Collector, name: str, state: str, held: int) -> int:
    """Wait for a status of ``name`` in ``state`` that has held more than ``held`` inputs while
    inactive (read from the device, not published); returns its count."""
    collector.clear()

    def reported() -> bool:
        if collector.count("/diagnostics") == 0:
            return False
        _, message, values = _status(collector, name)
        return message.startswith(state) and int(values["held_while_inactive"]) > held

    assert wait_for(reported, 10.0), _status(collector, name)
    return int(_status(collector, name)[2]["held_while_inactive"])


def test_imu_driver_follows_its_lifecycle():
    topics = {"imu/data_raw": Imu, "/diagnostics": DiagnosticArray}
    with (
        Imu400ccEmulator(resting_source(seed=2)) as device,
        driver_process("imu400cc_node", f"port:={device.path}", "diagnostics_period:=0.2"),
    ):
        collector = Collector(topics, name="lifecycle_imu_collector")
        with spinning(collector.node):
            manager = Manager(collector.node, "imu400cc_node")
            assert manager.state() == "unconfigured"
            level, message, _ = _fresh_status(collector, "imu400cc_node")
            assert message.startswith("unconfigured") and level == DiagnosticStatus.WARN
            assert sum(device.commands.values()) == 0  # the port was not opened

            assert manager.change(Transition.TRANSITION_CONFIGURE)
            assert manager.state() == "inactive"
            assert wait_for(lambda: device.commands["C"] == 1, 10.0)  # set up and streaming
            held = _held_once(collector, "imu400cc_node", "inactive", 100)  # read, not published
            assert collector.count("imu/data_raw") == 0

            assert manager.change(Transition.TRANSITION_ACTIVATE)
            assert manager.state() == "active"
            assert wait_for(lambda: collector.count("imu/data_raw") >= 134, 5.0)
            level, message, _ = _fresh_status(collector, "imu400cc_node")
            assert (level, message) == (DiagnosticStatus.OK, "streaming")

            assert manager.change(Transition.TRANSITION_DEACTIVATE)
            # Reported inactive (the samples in flight before it have arrived), then a second
            # of samples (134) read while inactive: none of them published.
            held = _held_once(collector, "imu400cc_node", "inactive", held)
            collector.clear()
            _held_once(collector, "imu400cc_node", "inactive", held + 134)
            assert collector.count("imu/data_raw") == 0

            stops = device.commands["P"]
            assert manager.change(Transition.TRANSITION_CLEANUP)
            assert manager.state() == "unconfigured"
            assert device.commands["P"] == stops + 1  # the stream stopped before closing
            assert not device.streaming

            # configure again: the port is opened and set up anew, and the data flows.
            assert manager.change(Transition.TRANSITION_CONFIGURE)
            assert manager.change(Transition.TRANSITION_ACTIVATE)
            collector.clear()
            assert wait_for(lambda: collector.count("imu/data_raw") >= 134, 10.0)
            assert device.commands["C"] == 2
            collector.node.destroy_node()


def test_gnss_driver_follows_its_lifecycle():
    topics = {"gnss/fix": NavSatFix, "/diagnostics": DiagnosticArray}
    config = EmulatorConfig(receiver=Receiver.LEICA)
    with (
        GnssEmulator(constant_velocity((3.0, 4.0, 0.0)), config) as device,
        driver_process(
            "gnss_node", f"port:={device.path}", "receiver:=leica", "diagnostics_period:=0.2"
        ),
    ):
        collector = Collector(topics, name="lifecycle_gnss_collector")
        with spinning(collector.node):
            manager = Manager(collector.node, "gnss_node")
            assert manager.state() == "unconfigured"
            _, message, values = _fresh_status(collector, "gnss_node")
            assert message.startswith("unconfigured") and values["held_while_inactive"] == "0"
            assert manager.change(Transition.TRANSITION_CONFIGURE)
            # the port opened on configure: epochs read, none published
            held = _held_once(collector, "gnss_node", "inactive", 0)
            assert collector.count("gnss/fix") == 0

            assert manager.change(Transition.TRANSITION_ACTIVATE)
            assert wait_for(lambda: collector.count("gnss/fix") >= 2, 6.0)  # 1 Hz
            assert manager.change(Transition.TRANSITION_DEACTIVATE)
            # Reported inactive (a fix in flight before it has arrived), then two epochs (1 Hz)
            # read while inactive: neither published.
            held = _held_once(collector, "gnss_node", "inactive", held)
            collector.clear()
            _held_once(collector, "gnss_node", "inactive", held + 1)
            assert collector.count("gnss/fix") == 0
            assert manager.change(Transition.TRANSITION_CLEANUP)
            assert manager.state() == "unconfigured"
            _, message, _ = _fresh_status(collector, "gnss_node")
            assert message.startswith("unconfigured")
            collector.node.destroy_node()
