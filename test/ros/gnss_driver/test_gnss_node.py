"""gnss_node against the emulated Leica rover and ADU5 on pseudo-terminals (rclpy, pyserial)."""

from __future__ import annotations

import math
import os
import subprocess
import threading
import time
from typing import Any

import numpy as np
import pymap3d
import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import TwistWithCovarianceStamped
from scipy.spatial.transform import Rotation
from sensor_msgs.msg import Imu, NavSatFix, NavSatStatus, TimeReference
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

from gnss_driver.emulator import EmulatorConfig, GnssEmulator, Truth, constant_velocity
from gnss_driver.node import PARAMETERS, GnssNode
from gnss_driver.profiles import CAR_OFFSETS_DEG, Adu5Setup, Receiver, adu5_commands
from gnss_ins_common.params import ParameterValueError

pytestmark = pytest.mark.ros

TOPICS = {
    "gnss/fix": NavSatFix,
    "gnss/vel": TwistWithCovarianceStamped,
    "gnss/attitude": Imu,
    "gnss/time_reference": TimeReference,
    "/diagnostics": DiagnosticArray,
}
#: Emulator output delay, told to the node as its ``latency`` parameter [s].
LATENCY = 0.02
VELOCITY = (3.0, 4.0, 0.0)  # ENU [m/s]: heading atan2(3, 4) = 36.87 deg


@pytest.fixture(scope="module", autouse=True)
def ros_context():
    rclpy.init()
    yield
    rclpy.shutdown()


class Recorder:
    """The emulator's epochs: UTC -> truth."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.truth: dict[float, Truth] = {}

    def __call__(self, utc_s: float, truth: Truth) -> None:
        with self.lock:
            self.truth[round(utc_s, 2)] = truth

    def at(self, utc_s: float) -> Truth:
        with self.lock:
            return self.truth[round(utc_s, 2)]


def _node(device: GnssEmulator, receiver: Receiver, **params) -> GnssNode:
    return GnssNode(
        parameter_overrides=overrides(
            port=device.path, receiver=receiver.value, baud=device.baud, latency=LATENCY, **params
        )
    )


def _run(device: GnssEmulator, receiver: Receiver, until, timeout_s: float, **params):
    node = _node(device, receiver, **params)
    collector = Collector(TOPICS)
    try:
        with spinning(node, collector.node):
            assert wait_for(lambda: until(collector), timeout_s), "not enough messages"
            assert collector.more("/diagnostics", 1, 5.0)  # a report after the last epoch
    finally:
        node.close()
        node.destroy_node()
        collector.node.destroy_node()
    return collector


def _each_fix_has_its_utc(collector: Collector) -> bool:
    """Every fix (with a position) received has its time reference (published after it)."""
    utc_of = _utc_by_stamp(collector)
    fixes = collector.get("gnss/fix")
    return all(
        round(stamp_s(f), 6) in utc_of
        for f in fixes
        if f.status.status != NavSatStatus.STATUS_NO_FIX
    )


def _utc_by_stamp(collector: Collector) -> dict[float, float]:
    return {
        round(stamp_s(m), 6): m.time_ref.sec + m.time_ref.nanosec * 1e-9
        for m in collector.get("gnss/time_reference")
    }


def _published_by(
    collector: Collector, sent: list[tuple[float, float]], opened: float, end: float
) -> bool:
    """Whether the receiver wrote past ``end`` and every epoch it wrote from ``opened`` + 0.2 s
    to ``end`` (host times) has been published as an attitude."""
    written = list(sent)
    if not written or written[-1][1] < end:
        return False
    expected = {round(utc, 2) for utc, at in written if opened + 0.2 < at < end}
    utc_of = _utc_by_stamp(collector)
    stamps = (round(stamp_s(m), 6) for m in collector.get("gnss/attitude"))
    return expected <= {round(utc_of[s], 2) for s in stamps if s in utc_of}


def _timed(messages: list[Any], utc_of: dict[float, float]) -> list[Any]:
    """The messages whose epoch's time reference was collected: all but possibly the newest,
    whose time reference may still have been on its way when the collection stopped."""
    timed = [m for m in messages if round(stamp_s(m), 6) in utc_of]
    assert timed == messages[: len(timed)] and len(timed) >= len(messages) - 1
    return timed


def test_leica_fix_velocity_covariance_and_stamps():
    recorder = Recorder()
    config = EmulatorConfig(receiver=Receiver.LEICA, output_latency_s=LATENCY)
    with GnssEmulator(constant_velocity(VELOCITY), config, on_epoch=recorder) as dev:
        collector = _run(
            dev,
            Receiver.LEICA,
            lambda c: c.count("gnss/fix") >= 4 and c.count("/diagnostics") >= 3,
            12.0,
        )
    fixes, utc_of = collector.get("gnss/fix"), _utc_by_stamp(collector)
    assert collector.get("gnss/attitude") == []
    for fix in _timed(fixes, utc_of):
        utc = utc_of[round(stamp_s(fix), 6)]
        # Stamp = the epoch's UTC on the host clock (the emulator runs on the host clock).
        assert abs(stamp_s(fix) - utc) < 0.02
        truth = recorder.at(utc)
        east, north, up = pymap3d.geodetic2enu(
            fix.latitude, fix.longitude, fix.altitude, truth.lat_deg, truth.lon_deg, truth.alt_m
        )
        assert math.hypot(east, north) < 0.001 and abs(up) < 0.002  # 7-decimal minutes, mm
        assert fix.header.frame_id == "gnss_link"
        assert fix.status.status == NavSatStatus.STATUS_GBAS_FIX  # RTK fixed
        assert fix.status.service == NavSatStatus.SERVICE_GPS
        # LLQ CQ 0.05 m = 2 cm + 3 cm: sigma_h 0.02 -> 0.0002 per axis; sigma_v 0.03.
        assert fix.position_covariance_type == NavSatFix.COVARIANCE_TYPE_DIAGONAL_KNOWN
        assert list(fix.position_covariance) == pytest.approx(
            [0.0002, 0, 0, 0, 0.0002, 0, 0, 0, 0.0009]
        )
    assert np.all(np.diff([stamp_s(f) for f in fixes]) == pytest.approx(1.0, abs=0.02))

    vel = collector.get("gnss/vel")[-1]
    v = vel.twist.twist.linear
    assert (v.x, v.y, v.z) == pytest.approx(VELOCITY, abs=0.01)
    cov = np.array(vel.twist.covariance).reshape(6, 6)
    assert np.diag(cov) == pytest.approx([0.0025, 0.0025, 1e6, 1e6, 1e6, 1e6])

    values = diagnostic_values(collector.get("/diagnostics")[-1])
    assert collector.get("/diagnostics")[-1].status[0].level == b"\x00"
    assert values["last_fix_type"] == "RTK_FIXED"
    assert values["date_source"] == "receiver"
    assert int(values["bad_checksum"]) == int(values["late_sentences"]) == 0
    # Host minus UTC: the emulator's 20 ms output delay (plus the smallest receive delay).
    assert float(values["clock_offset_ms"]) == pytest.approx(20.0, abs=10.0)
    # After two epochs ended by the idle time-out (their same content is then confirmed) each
    # is published as soon as its LLQ is in, ~0.21 s after its UTC (~190 bytes at 9600 baud),
    # not 0.5 s idle or 1 s later.
    received = collector.receive_times["gnss/fix"]
    assert all(t - stamp_s(f) < 0.6 for f, t in zip(fixes[2:], received[2:], strict=True))
    assert float(values["latency_ms"]) > 190


@pytest.mark.parametrize("offsets_in_receiver", [True, False])
def test_adu5_setup_commands_and_vehicle_attitude(offsets_in_receiver):
    recorder = Recorder()
    truth_source = constant_velocity(VELOCITY, pitch_deg=2.0, roll_deg=-1.0)
    # The antenna frame really is mounted with the calibrated offsets of the report's car.
    config = EmulatorConfig(
        receiver=Receiver.ADU5, output_latency_s=LATENCY, mount_offsets_deg=CAR_OFFSETS_DEG
    )
    with GnssEmulator(truth_source, config, on_epoch=recorder) as dev:
        collector = _run(
            dev,
            Receiver.ADU5,
            lambda c: c.count("gnss/attitude") >= 10 and c.count("/diagnostics") >= 1,
            10.0,
            adu5_offsets_in_receiver=offsets_in_receiver,
        )
        commands = dev.commands
        removed_by_receiver = dev.offsets_deg
    offsets = CAR_OFFSETS_DEG if offsets_in_receiver else (0.0, 0.0, 0.0)
    assert commands == adu5_commands(Adu5Setup(offsets_deg=offsets))
    assert removed_by_receiver == offsets

    utc_of = _utc_by_stamp(collector)
    for msg in _timed(collector.get("gnss/attitude")[2:], utc_of):
        truth = recorder.at(utc_of[round(stamp_s(msg), 6)])
        assert abs(stamp_s(msg) - utc_of[round(stamp_s(msg), 6)]) < 0.02
        q = msg.orientation
        got = Rotation.from_quat([q.x, q.y, q.z, q.w])
        # Vehicle FLU in ENU: yaw = 90 - heading; ADU5 pitch +2 (nose up) is ROS pitch -2
        # (about y = left); ADU5 roll -1 (left side down) is ROS roll -1 (about x = forward).
        want = Rotation.from_euler("ZYX", [90.0 - truth.heading_deg, -2.0, -1.0], degrees=True)
        assert (got * want.inv()).magnitude() < math.radians(0.02)  # PAT's 0.01 deg digits
        assert msg.angular_velocity_covariance[0] == msg.linear_acceleration_covariance[0] == -1
        expected = [math.radians(s) ** 2 for s in (0.24, 0.14, 0.07)]
        assert np.diag(np.reshape(msg.orientation_covariance, (3, 3))) == pytest.approx(expected)
        assert msg.header.frame_id == "gnss_link"

    values = diagnostic_values(collector.get("/diagnostics")[-1])
    assert values["setup"] == "7 ACK"
    assert values["date_source"] == "host"
    assert float(values["rate_hz"]) == pytest.approx(5.0, rel=0.3)


def test_adu5_that_never_answers_loses_no_epoch_to_the_setup():
    recorder = Recorder()
    sent: list[tuple[float, float]] = []  # (UTC, host time written)
    config = EmulatorConfig(receiver=Receiver.ADU5, answer_commands=False)

    def on_epoch(utc_s: float, truth: Truth) -> None:
        recorder(utc_s, truth)
        sent.append((utc_s, time.time()))

    with GnssEmulator(constant_velocity(VELOCITY), config, on_epoch=on_epoch) as dev:
        node = _node(dev, Receiver.ADU5)
        collector = Collector(TOPICS)
        try:
            with spinning(node, collector.node):
                assert wait_for(lambda: dev.commands, 10.0)
                opened = time.time()  # the port opened before the first command came
                # 7 commands x 0.5 s without an answer, then 1 s more: until every epoch
                # the receiver wrote by then is published.
                assert wait_for(lambda: len(dev.commands) == 7, 6.0)
                end = time.time() + 1.0
                wait_for(lambda: _published_by(collector, sent, opened, end), 10.0)
        finally:
            node.close()
            node.destroy_node()
            collector.node.destroy_node()
    expected = {round(utc, 2) for utc, written in sent if opened + 0.2 < written < end}
    assert len(expected) >= 15  # the set-up takes 3.5 s at 5 Hz
    published = set(_utc_by_stamp(collector).values())
    published = {round(u, 2) for u in published}
    assert expected <= published, sorted(expected - published)
    attitudes = {round(stamp_s(m), 6) for m in collector.get("gnss/attitude")}
    utc_of = _utc_by_stamp(collector)
    assert expected <= {round(utc_of[s], 2) for s in attitudes}
    values = diagnostic_values(collector.get("/diagnostics")[-1])
    assert values["setup"] == "7 no answer"


def test_use_gnss_time_stamps_fixes_with_the_sentences_utc():
    recorder = Recorder()
    # The host clock is the UTC source here; the receiver's output delay is 60 ms.
    config = EmulatorConfig(receiver=Receiver.LEICA, output_latency_s=0.06)
    with GnssEmulator(constant_velocity(VELOCITY), config, on_epoch=recorder) as dev:
        collector = _run(
            dev,
            Receiver.LEICA,
            lambda c: c.count("gnss/fix") >= 4 and c.count("/diagnostics") >= 3,
            12.0,
            use_gnss_time=True,
            gnss_time_offset_warn=0.03,
        )
    with recorder.lock:
        sent = set(recorder.truth)
    fixes = collector.get("gnss/fix")
    for fix in fixes:
        utc = round(stamp_s(fix), 2)
        assert utc in sent and abs(stamp_s(fix) - utc) < 1e-3  # the sentence's UTC, < 1 ms
    # TimeReference keeps the envelope mapping as without use_gnss_time: the UTC on the host
    # clock (60 ms output delay) minus the ``latency`` parameter (LATENCY).
    for ref in collector.get("gnss/time_reference")[3:]:
        utc = ref.time_ref.sec + ref.time_ref.nanosec * 1e-9
        assert stamp_s(ref) - utc == pytest.approx(0.06 - LATENCY, abs=0.015)
    last = collector.get("/diagnostics")[-1]
    values = diagnostic_values(last)
    assert values["time_mode"] == "gnss"
    assert float(values["clock_offset_ms"]) == pytest.approx(60.0, abs=15.0)
    assert last.status[0].level == b"\x01" and "host - UTC" in last.status[0].message


def test_custom_setup_commands_and_a_rejected_one():
    config = EmulatorConfig(receiver=Receiver.ADU5)
    commands = ["$PASHS,ELM,10", "$PASHS,XYZ,1", "$PASHS,NME,PAT,A,ON"]
    with GnssEmulator(constant_velocity(VELOCITY), config) as dev:
        collector = _run(
            dev,
            Receiver.ADU5,
            lambda c: c.count("gnss/fix") >= 5 and c.count("/diagnostics") >= 1,
            10.0,
            setup_commands=commands,
        )
        assert dev.commands == commands  # the list replaces the defaults
    status = collector.get("/diagnostics")[-1].status[0]
    values = diagnostic_values(collector.get("/diagnostics")[-1])
    assert values["setup"] == "2 ACK, 1 NAK"
    assert status.level == b"\x01" and "rejected 1 set-up command" in status.message


def test_adu5_fault_run():
    recorder = Recorder()
    config = EmulatorConfig(receiver=Receiver.ADU5, output_latency_s=LATENCY)
    with GnssEmulator(constant_velocity(VELOCITY), config, on_epoch=recorder) as dev:
        node = _node(dev, Receiver.ADU5, stall_timeout=0.6)
        collector = Collector(TOPICS)
        try:
            with spinning(node, collector.node):
                assert wait_for(lambda: collector.count("gnss/attitude") >= 5, 10.0)

                def received(epochs: int) -> None:
                    """Wait until the node published ``epochs`` more fixes: the emulator's
                    pending faults (one epoch each, 5 damaged sentences within two) are spent."""
                    count = collector.count("gnss/fix")
                    assert wait_for(lambda: collector.count("gnss/fix") >= count + epochs, 10.0)

                dev.corrupt_checksums(3)
                dev.cut_lines(2)
                dev.send_garbage(b"\x00\xff\xfe\x13garbage\r\n")
                received(4)
                dev.reset_attitude(3)
                received(4)
                dev.degrade_attitude(2)
                received(3)
                dev.lose_fix(3)
                received(4)
                dev.jump(2, north_m=50.0)
                received(3)
                before = collector.count("gnss/fix")
                dev.unplug()
                pause(1.0)  # unplugged for a second: at most the fix in flight arrives
                assert collector.count("gnss/fix") - before <= 1
                dev.plug()
                assert wait_for(lambda: collector.count("gnss/fix") > before + 5, 10.0)
                setups = dev.commands.count("$PASHS,ELM,15")
                dev.go_silent(1.0)  # a stalled stream: reopen, set up again
                assert wait_for(lambda: dev.commands.count("$PASHS,ELM,15") > setups, 5.0)
                after = collector.count("gnss/fix")
                assert wait_for(lambda: collector.count("gnss/fix") > after + 5, 10.0)
                reports = collector.count("/diagnostics")  # one more after the last fix
                assert wait_for(lambda: collector.count("/diagnostics") > reports, 5.0)
                dev.go_silent(60.0)  # no more epochs: the time reference of the last fix
                assert wait_for(lambda: _each_fix_has_its_utc(collector), 5.0)
        finally:
            node.close()
            node.destroy_node()
            collector.node.destroy_node()
    statuses = [d.status[0] for d in collector.get("/diagnostics")]
    assert any(s.level == b"\x01" and s.message.startswith("attitude:") for s in statuses)
    assert any(s.level == b"\x02" and s.message.startswith("port closed") for s in statuses)
    values = diagnostic_values(collector.get("/diagnostics")[-1])
    assert int(values["bad_checksum"]) >= 3
    assert int(values["truncated"]) >= 2
    assert int(values["garbage"]) >= 1
    assert int(values["attitude_resets"]) >= 3 + 3  # the reset flags and the epochs without fix
    assert int(values["attitude_degraded"]) >= 2
    assert int(values["reconnects"]) >= 2
    assert int(values["stalls"]) >= 1

    fixes = collector.get("gnss/fix")
    no_fix = [f for f in fixes if f.status.status == NavSatStatus.STATUS_NO_FIX]
    assert len(no_fix) >= 3
    assert all(math.isnan(f.latitude) and math.isnan(f.altitude) for f in no_fix)
    assert all(f.position_covariance_type == NavSatFix.COVARIANCE_TYPE_UNKNOWN for f in no_fix)
    # The outlier is passed on as the receiver reported it (gating is the fusion's job).
    # A fix already on its way when the receiver went silent can arrive after the wait above,
    # without the time reference its epoch never completed: only the newest (``_timed``).
    utc_of = _utc_by_stamp(collector)
    offsets = []
    with_position = [f for f in fixes if f.status.status != NavSatStatus.STATUS_NO_FIX]
    for fix in _timed(with_position, utc_of):
        truth = recorder.at(utc_of[round(stamp_s(fix), 6)])
        _, north, _ = pymap3d.geodetic2enu(
            fix.latitude, fix.longitude, truth.alt_m, truth.lat_deg, truth.lon_deg, truth.alt_m
        )
        offsets.append(north)
    assert sum(abs(n - 50.0) < 0.5 for n in offsets) == 2
    assert sum(abs(n) < 0.5 for n in offsets) == len(offsets) - 2
    # Degraded attitude: sigmas x 2.4 (MRMS 12 mm vs 5 mm) on two messages.
    yaw_var = [m.orientation_covariance[8] for m in collector.get("gnss/attitude")]
    assert sum(v == pytest.approx(math.radians(0.07 * 2.4) ** 2) for v in yaw_var) == 2
    stamps = [stamp_s(m) for m in collector.get("gnss/attitude")]
    assert np.all(np.diff(stamps) > 0)


@pytest.mark.parametrize(
    ("name", "value", "fragment"),
    [
        ("receiver", "garmin", "not one of"),
        ("setup_commands", ["$PASHS,ELM,15\r\n$PASHS,RST"], "setup_commands"),
        ("adu5_vectors", [0.0, 1.0], "9 values"),
        ("attitude_sigma_rpy", [0.1, 0.1], "3 values"),
        ("adu5_port", "C", "not one of"),
        ("llq_projection", "EPSG:4326", "not a projected CRS"),
        ("llq_projection", "EPSG:0", "unknown coordinate reference system"),
    ],
)
def test_bad_parameters_are_rejected_with_a_clear_message(name, value, fragment):
    with pytest.raises(ParameterValueError, match=fragment):
        GnssNode(parameter_overrides=overrides(port="/nonexistent", **{name: value}))


def test_executable_with_the_adu5_config_and_a_renamed_node():
    assert_executable_refuses("gnss_node", "receiver", "garmin")
    exe = node_executable("gnss_node")
    config = EmulatorConfig(receiver=Receiver.ADU5)
    with GnssEmulator(constant_velocity(VELOCITY), config) as dev:
        collector = Collector({"adu5/gnss/attitude": Imu})
        proc = subprocess.Popen(
            [
                exe,
                "--ros-args",
                "--params-file",
                str(REPO / "config" / "gnss_adu5.yaml"),
                "-p",
                f"port:={dev.path}",
                "-r",
                "__node:=adu5",
                "-r",
                "__ns:=/adu5",
            ],
            env=os.environ.copy(),
        )
        try:
            with spinning(collector.node):
                assert wait_for(lambda: collector.count("adu5/gnss/attitude") >= 5, 20.0)
        finally:
            proc.terminate()
            assert proc.wait(timeout=10) == 0
            collector.node.destroy_node()
        assert dev.commands[:1] == ["$PASHS,ELM,15"]
    assert collector.get("adu5/gnss/attitude")[-1].header.frame_id == "adu5_link"


#: Values that legitimately differ from the declared defaults, per profile file.
PROFILE_VALUES = {
    "gnss_leica.yaml": {"port": "/dev/ttyUSB1"},
    "gnss_adu5.yaml": {
        "corrections_input": False,
        "port": "/dev/ttyUSB2",
        "baud": 115200,
        "receiver": "adu5",
        "frame_id": "adu5_link",
        "stall_timeout": 1.0,
        "epoch_idle_timeout": 0.1,
    },
    "gnss_generic.yaml": {"receiver": "generic", "velocity_sigma": 0.2},
}


@pytest.mark.parametrize("name", sorted(PROFILE_VALUES))
def test_config_files_match_the_declared_parameters(name):
    assert_file_holds_defaults(name, "gnss_node", PARAMETERS, PROFILE_VALUES[name])
