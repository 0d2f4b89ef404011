"""imu400cc_node against the emulated IMU400CC on a pseudo-terminal (real rclpy, real pyserial)."""

from __future__ import annotations

import math
import os
import subprocess

import numpy as np
import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from sensor_msgs.msg import Imu, Temperature
from support.config_checks import assert_file_holds_defaults
from support.pacing import pause
from support.paths import REPO
from support.ros_harness import (
    Collector,
    assert_executable_refuses,
    diagnostic_values,
    node_executable,
    overrides,
    spinning,
    stamp_s,
    wait_for,
)

from gnss_ins_common.params import ParameterValueError
from imu400cc_driver.emulator import (
    EmulatorConfig,
    Imu400ccEmulator,
    SentPacket,
    resting_source,
)
from imu400cc_driver.node import PARAMETERS, Imu400ccNode

pytestmark = pytest.mark.ros

TOPICS = {"imu/data_raw": Imu, "imu/temperature": Temperature, "/diagnostics": DiagnosticArray}


@pytest.fixture(scope="module", autouse=True)
def ros_context():
    rclpy.init()
    yield
    rclpy.shutdown()


def _run(device: Imu400ccEmulator, until, timeout_s: float, **params):
    """Run node + collector until ``until(collector)``; returns (collector, node) after the node
    closed."""
    node = Imu400ccNode(parameter_overrides=overrides(port=device.path, **params))
    collector = Collector(TOPICS)
    try:
        with spinning(node, collector.node):
            assert wait_for(lambda: until(collector), timeout_s), "not enough messages"
    finally:
        node.close()
        node.destroy_node()
        collector.node.destroy_node()
    return collector, node


def _seconds_of_samples(seconds: float, temperatures: int = 0, reports: int = 0):
    """Until the collector holds ``seconds`` of samples at 134 Hz, ``temperatures`` temperature
    messages and ``reports`` diagnostics."""
    return lambda c: (
        c.count("imu/data_raw") >= seconds * 134
        and c.count("imu/temperature") >= temperatures
        and c.count("/diagnostics") >= reports
    )


def test_continuous_stream_values_units_covariance_and_rate():
    config = EmulatorConfig(temperature_c=23.5)
    with Imu400ccEmulator(resting_source(seed=3), config) as dev:
        collector, _ = _run(dev, _seconds_of_samples(3.0, temperatures=2, reports=1), 15.0)
    imu = collector.get("imu/data_raw")
    assert len(imu) > 300
    stamps = np.array([stamp_s(m) for m in imu])
    rate = (len(stamps) - 1) / (stamps[-1] - stamps[0])
    assert rate == pytest.approx(134.0, rel=0.03)
    assert np.all(np.diff(stamps) > 0)
    # Device-clock stamps keep the device's own spacing, free of receive jitter.
    assert np.median(np.diff(stamps)) == pytest.approx(1 / 134, rel=0.01)

    msg = imu[-1]
    assert msg.header.frame_id == "imu_link"
    assert msg.orientation_covariance[0] == -1.0
    gyro_var = [msg.angular_velocity_covariance[i] for i in (0, 4, 8)]
    accel_var = [msg.linear_acceleration_covariance[i] for i in (0, 4, 8)]
    # (7.14) per-sample sigmas at 134 Hz, notes §1.3.
    assert np.sqrt(gyro_var) == pytest.approx([0.0041, 0.0040, 0.0048], rel=1e-3)
    assert np.sqrt(accel_var) == pytest.approx([0.0029, 0.0038, 0.0036], rel=1e-3)
    assert msg.angular_velocity_covariance[1] == 0.0

    force = np.array(
        [[m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z] for m in imu]
    )
    rate_flu = np.array(
        [[m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z] for m in imu]
    )
    # REP-145: a level unit at rest reads about (0, 0, +9.81) m/s^2 in FLU.
    assert force.mean(axis=0) == pytest.approx([0.0, 0.0, 9.80665], abs=0.002)
    assert rate_flu.mean(axis=0) == pytest.approx([0, 0, 0], abs=0.002)
    assert force[:, 2].std() == pytest.approx(0.0036, rel=0.3)

    temps = collector.get("imu/temperature")
    assert 2 <= len(temps) <= 6
    assert temps[-1].temperature == pytest.approx(23.5, abs=0.06)
    assert temps[-1].header.frame_id == "imu_link"

    values = diagnostic_values(collector.get("/diagnostics")[-1])
    assert float(values["rate_hz"]) == pytest.approx(134, rel=0.1)
    assert int(values["bad_checksums"]) == 0
    assert int(values["dropped_packets"]) == 0
    assert float(values["tick_period_us"]) == pytest.approx(0.7929, rel=0.01)
    assert values["serial_number"] == "1040201"


def test_stamps_are_sample_times_not_read_times():
    sent: list[SentPacket] = []
    with Imu400ccEmulator(on_packet=sent.append) as dev:
        collector, _ = _run(dev, _seconds_of_samples(4.0), 15.0)
    imu = collector.get("imu/data_raw")
    stamps = np.array([stamp_s(m) for m in imu])
    # The i-th message is the i-th streamed packet: the set-up's 'G' answer is not published.
    sample_times = np.array([p.sample_wall_s for p in sent[1 : 1 + len(stamps)]])
    writes = np.array([p.written_wall_s for p in sent[1 : 1 + len(stamps)]])
    # The emulator writes a packet once its 18 bytes have been on the wire (a loaded machine
    # only makes it later): the driver must take that transmission time off, not the read time.
    assert np.median(writes - sample_times) >= 18 * 10 / 38400 - 1e-4
    error = (stamps - sample_times)[len(stamps) // 2 :]  # after the clock fit settled
    # The fit cannot see a transfer latency below the smallest one it observed: on a loaded
    # 2-core machine the pseudo-terminal alone adds 0.5-0.8 ms (a read-time stamp would be
    # 4.7 ms late, the packet's time on the wire).
    assert np.median(np.abs(error)) < 1.0e-3
    assert np.percentile(np.abs(error), 95) < 2e-3


def test_polled_mode_follows_poll_rate():
    with Imu400ccEmulator() as dev:
        until = lambda c: c.count("imu/data_raw") >= 50  # noqa: E731
        collector, _ = _run(dev, until, 15.0, mode="polled", poll_rate=20.0)
        assert dev.commands["G"] >= 50
        assert dev.commands["C"] == 0
    stamps = np.array([stamp_s(m) for m in collector.get("imu/data_raw")])
    assert np.all(np.diff(stamps) > 0)
    assert (len(stamps) - 1) / (stamps[-1] - stamps[0]) == pytest.approx(20.0, rel=0.15)


def test_fault_run_garbage_corruption_drops_and_a_vanishing_port():
    with Imu400ccEmulator(resting_source(seed=1)) as dev:
        node = Imu400ccNode(parameter_overrides=overrides(port=dev.path, stall_timeout=0.5))
        collector = Collector(TOPICS)
        try:
            with spinning(node, collector.node):
                assert wait_for(lambda: collector.count("imu/data_raw") > 100, 5.0)
                dev.send_garbage(bytes([0xFF, 0x00, 0x13, 0xFF, 0xFF, 0x42] * 10))
                dev.corrupt_packets(5)
                pause(0.3)  # one fault at a time
                dev.drop_packets(3)
                pause(0.3)
                dev.drop_packets(20)  # longer than one timer wrap (~7 packets)
                pause(0.5)
                before_unplug = collector.count("imu/data_raw")
                dev.unplug()
                pause(1.0)  # unplugged for a second: at most the samples in flight arrive
                assert collector.count("imu/data_raw") - before_unplug < 10
                dev.plug()
                assert wait_for(
                    lambda: collector.count("imu/data_raw") > before_unplug + 150, 10.0
                ), "no data after the port came back"
                starts = dev.commands["C"]
                dev.go_silent(1.5)  # a stalled stream: the node must reopen and re-issue 'C'
                assert wait_for(lambda: dev.commands["C"] > starts, 10.0)
                after_stall = collector.count("imu/data_raw")
                assert wait_for(lambda: collector.count("imu/data_raw") > after_stall + 100, 10)
                reports = collector.count("/diagnostics")  # one more after the last sample
                assert wait_for(lambda: collector.count("/diagnostics") > reports, 5.0)
        finally:
            node.close()
            node.destroy_node()
            collector.node.destroy_node()
        assert dev.commands["C"] >= 3  # start-up, after the re-plug, after the stall
    values = diagnostic_values(collector.get("/diagnostics")[-1])
    assert int(values["bad_checksums"]) >= 5
    assert int(values["skipped_bytes"]) >= 60
    assert int(values["dropped_packets"]) >= 23
    assert int(values["reconnects"]) >= 2
    assert int(values["stalls"]) >= 1
    stamps = [stamp_s(m) for m in collector.get("imu/data_raw")]
    assert np.all(np.diff(stamps) > 0)
    forces = [m.linear_acceleration.z for m in collector.get("imu/data_raw")]
    assert all(abs(f - 9.80665) < 0.1 for f in forces), "a corrupted packet was published"


def test_power_cycle_on_a_noisy_line_reconnects_on_no_valid_packet():
    """After a power-cycle the unit is silent in polled mode, but line noise keeps bytes coming:
    only a "no valid packet" time-out restarts the stream."""
    with Imu400ccEmulator(resting_source(seed=2)) as dev:
        node = Imu400ccNode(parameter_overrides=overrides(port=dev.path, packet_timeout=0.5))
        collector = Collector(TOPICS)
        try:
            with spinning(node, collector.node):
                assert wait_for(lambda: collector.count("imu/data_raw") > 100, 5.0)
                dev.line_noise(400.0, seed=5)
                dev.power_cycle()
                assert wait_for(lambda: not dev.streaming, 2.0)
                cycled = collector.count("imu/data_raw")
                # Noise only for packet_timeout (0.5 s), then one reconnect (~1 s of set-up):
                # the generous wait is for a loaded machine, not a bound on the recovery time.
                assert wait_for(lambda: collector.count("imu/data_raw") > cycled + 134, 20.0), (
                    "no data after the power-cycle on a noisy line"
                )
                assert dev.commands["C"] >= 2
                assert wait_for(lambda: len(collector.get("/diagnostics")) > 0, 3.0)

                def recovered() -> bool:
                    values = diagnostic_values(collector.get("/diagnostics")[-1])
                    # last_error is cleared once the unit answered its set-up again.
                    return int(values["invalid_stalls"]) >= 1 and values["last_error"] == ""

                assert wait_for(recovered, 5.0), "the stall is not counted or not cleared"
        finally:
            node.close()
            node.destroy_node()
            collector.node.destroy_node()
    assert node.link_stats.invalid_stalls >= 1  # kept after the link stopped


@pytest.mark.parametrize(
    ("name", "value", "fragment"),
    [
        ("mode", "fast", "not one of"),
        ("poll_rate", 500.0, "poll_rate"),
        ("axis_map", ["x", "x", "z"], "axis_map"),
        ("gyro_noise_density", [0.1, 0.1], "needs 3 values"),
        ("accel_sign", 0.5, "accel_sign"),
    ],
)
def test_bad_parameters_are_rejected_with_a_clear_message(name, value, fragment):
    with pytest.raises(ParameterValueError, match=fragment):
        Imu400ccNode(parameter_overrides=overrides(port="/nonexistent", **{name: value}))


def test_executable_runs_against_the_emulator_and_refuses_bad_parameters():
    assert_executable_refuses("imu400cc_node", "mode", "fast")
    exe = node_executable("imu400cc_node")
    with Imu400ccEmulator() as dev:
        collector = Collector({"imu/data_raw": Imu})
        proc = subprocess.Popen(
            [
                exe,
                "--ros-args",
                "--params-file",
                str(REPO / "config" / "imu400cc.yaml"),
                "-p",
                f"port:={dev.path}",
            ],
            env=os.environ.copy(),
        )
        try:
            with spinning(collector.node):
                assert wait_for(lambda: collector.count("imu/data_raw") > 134, 20.0)
        finally:
            proc.terminate()
            assert proc.wait(timeout=10) == 0
            collector.node.destroy_node()
        # 'P' stops the stream at start-up and again at shutdown (notes §11.1 item 2).
        assert wait_for(lambda: dev.commands["P"] >= 2, 2.0)


def test_config_file_matches_the_declared_defaults():
    values = assert_file_holds_defaults("imu400cc.yaml", "imu400cc_node", PARAMETERS)
    assert math.isclose(values["gravity"], 9.80665)
