"""`gnss_ins simulate` to a bag: topics, types, frames, stamps and covariances as the drivers
publish them, every field intact after a round trip through the bag, reproducible."""

from __future__ import annotations

import dataclasses
import math
from collections import Counter
from functools import partial
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
from rclpy.serialization import serialize_message
from sensor_msgs.msg import Imu, Temperature
from support.paths import REPO

from gnss_driver.driver import EpochOutput
from gnss_driver.messages import TOPICS as GNSS_TOPICS
from gnss_driver.node import GnssNode
from gnss_driver.profiles import Receiver
from gnss_driver.utc import DateSource, UtcTime
from gnss_ins_common.axes import AxisMap
from imu400cc_driver import node as imu_node
from imu400cc_driver.axes import ImuMeasurement, PacketConverter, measurement_to_packet
from imu400cc_driver.driver import ImuDriver, ImuSample
from imu400cc_driver.messages import SampleWriter
from imu400cc_driver.protocol import Scaling
from ins_fusion.bags import topics as T  # noqa: N812
from ins_fusion.bags.bag_io import BagReader
from ins_fusion.bags.messages import new_message
from ins_fusion.bags.typestore import jazzy_typestore
from ins_fusion.sim.drive import DEFAULT_START_NS, Simulation, SimulationConfig, SkyZoneSpec
from ins_fusion.tools import cli

#: A moving, turning drive (60 km/h, 90° turn) with a scheduled outage and a bridge.
CONFIG = SimulationConfig(
    scenario="aalborg_turn",
    duration_s=16.0,
    outages=((4.0, 3.0),),
    sky_zones=(SkyZoneSpec(11.0, 25.0, 0),),
    seed=7,
)
ARGS = [
    "simulate",
    "--scenario=aalborg_turn",
    "--duration=16",
    "--outage=4:3",
    "--sky-zone=11:25:0",
    "--seed=7",
]
TS = jazzy_typestore()


def _cdr(message: Any) -> bytes:
    return bytes(TS.serialize_cdr(message, message.__msgtype__))


def _from_rclpy(message: Any, msgtype: str) -> Any:
    """An rclpy message as a rosbags one (CDR round trip; drops rclpy's padding bytes)."""
    return TS.deserialize_cdr(serialize_message(message), msgtype)


def _stamp(message: Any) -> int:
    return int(message.header.stamp.sec) * 1_000_000_000 + int(message.header.stamp.nanosec)


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory) -> dict[str, list[Any]]:
    """The bag of CONFIG through the command line, deserialized: topic -> [(log ns, message)]."""
    path = tmp_path_factory.mktemp("sim") / "drive"
    assert cli.main([*ARGS, f"--output={path}"]) == 0
    out: dict[str, list[Any]] = {}
    with BagReader(path) as reader:
        assert {t: info.msgtype for t, info in reader.topics.items()} == T.TOPICS
        for msg in reader.messages(deserialize=True):
            out.setdefault(msg.topic, []).append((msg.log_time_ns, msg.message))
    return out


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_bag_round_trip_keeps_every_field_and_the_same_seed_gives_the_same_bag(
    tmp_path, storage, capsys
):
    path = tmp_path / "drive"
    assert cli.main([*ARGS, f"--output={path}", f"--storage={storage}"]) == 0
    summary = capsys.readouterr().out
    assert "/imu/data_raw" in summary and "largest gaps" in summary
    expected = list(Simulation(CONFIG).stream())
    with BagReader(path) as reader:
        read = list(reader.messages())
    assert len(read) == len(expected)
    for got, want in zip(read, expected, strict=True):
        assert (got.topic, got.log_time_ns) == (want.topic, want.log_ns)
        assert got.message == _cdr(want.message)
    counts = Counter(m.topic for m in read)
    no_fix = sum(
        TS.deserialize_cdr(m.message, "sensor_msgs/msg/NavSatFix").status.status == -1
        for m in read
        if m.topic == T.GNSS_FIX
    )
    assert no_fix > 3  # the outage and the bridge
    assert counts == {
        T.IMU_DATA: 16 * 134,
        T.IMU_TEMPERATURE: 16,
        T.GNSS_FIX: 16,  # NO_FIX ones included, as gnss_node publishes them
        T.GNSS_TIME: 16,
        T.GNSS_VEL: 16 - no_fix,
        T.GNSS_ATTITUDE: counts[T.GNSS_ATTITUDE],
        T.TRUTH_FIX: 16 * 50,
        T.TRUTH_VEL: 16 * 50,
        T.TRUTH_ATTITUDE: 16 * 50,
    }
    assert 5 * (16 - no_fix - 1) <= counts[T.GNSS_ATTITUDE] <= 5 * (16 - 3)


def test_same_seed_same_messages_other_seed_other_noise():
    def imu_values(seed: int) -> list[bytes]:
        config = dataclasses.replace(CONFIG, seed=seed, duration_s=3.0, sky_zones=())
        return [_cdr(e.message) for e in Simulation(config).stream() if e.topic == T.IMU_DATA]

    assert imu_values(7) == imu_values(7)
    assert imu_values(7) != imu_values(8)


def test_imu_topics_follow_rep145_and_the_driver_stamps(bag):
    imu = bag[T.IMU_DATA]
    stamps = np.array([_stamp(m) for _, m in imu])
    assert stamps[0] == DEFAULT_START_NS
    assert np.diff(stamps) == pytest.approx(1e9 / 134, abs=1)
    assert all(log - _stamp(m) == 4_687_500 for log, m in imu)  # 18 bytes at 38400 baud
    gyro_var = np.array([0.0041, 0.0040, 0.0048]) ** 2  # (7.14), the node's defaults
    accel_var = np.array([0.0029, 0.0038, 0.0036]) ** 2
    for _, m in imu[:: 134 * 4]:
        assert m.header.frame_id == "imu_link"
        assert m.orientation_covariance[0] == -1.0
        assert m.angular_velocity_covariance.reshape(3, 3) == pytest.approx(np.diag(gyro_var))
        assert m.linear_acceleration_covariance.reshape(3, 3) == pytest.approx(np.diag(accel_var))
    level = np.mean([m.linear_acceleration.z for _, m in imu[:134]])
    assert level == pytest.approx(9.82, abs=0.1)  # REP-145: +g when level (+ a 7 mg bias)
    # Turning right at 9 °/s (Aalborg §3.4): the z gyro of the FLU imu_link reads about -9 °/s.
    turning = np.mean([m.angular_velocity.z for _, m in imu[134 * 5 : 134 * 9]])
    assert math.degrees(turning) == pytest.approx(-9.0, abs=0.3)
    temperature = bag[T.IMU_TEMPERATURE]
    assert [_stamp(m) for _, m in temperature] == list(stamps[133::134])
    counts = [(m.temperature + 1.375 * 44.44) / (5 / 4096 * 44.44) for _, m in temperature]
    assert counts == pytest.approx(np.round(counts), abs=1e-6)  # (D-4) counts
    assert all(abs(m.temperature - 28.0) < 3.0 for _, m in temperature)


def test_gnss_topics_follow_gnss_node(bag):
    fixes = bag[T.GNSS_FIX]
    assert [_stamp(m) for _, m in fixes] == [DEFAULT_START_NS + k * 10**9 for k in range(16)]
    assert all(log - _stamp(m) == 53_000_000 for log, m in fixes)  # leica_rtk latency
    for _, m in fixes:
        assert m.header.frame_id == "gnss_link"
        t = m.header.stamp.sec - DEFAULT_START_NS // 10**9
        if 4 <= t < 7:
            assert m.status.status == -1 and math.isnan(m.latitude)
            assert m.position_covariance_type == 0
        elif t < 4:
            assert m.status.status == 2 and m.status.service == 1  # RTK: GBAS fix
            # From the GST σ: the error model's own, 2 / 2 / 3 cm E / N / U for RTK fixed.
            assert m.position_covariance_type == 3 and m.altitude > 0.0
            assert m.position_covariance == pytest.approx(
                [0.0004, 0, 0, 0, 0.0004, 0, 0, 0, 0.0009], abs=1e-12
            )
    by_second = {m.header.stamp.sec % 60: m for _, m in fixes}
    assert by_second[11].status.status == -1  # under the bridge of the sky zone at t = 11 s
    # After it: RTK float (also GBAS_FIX) while re-converging, a wider covariance than fixed.
    assert by_second[15].status.status == 2
    assert by_second[15].position_covariance[0] > 20 * by_second[2].position_covariance[0]
    times = bag[T.GNSS_TIME]
    assert all(_stamp(m) == m.time_ref.sec * 10**9 + m.time_ref.nanosec for _, m in times)
    assert {m.source for _, m in times} == {"leica"}
    for _, m in bag[T.GNSS_VEL]:
        assert m.header.frame_id == "gnss_link"
        assert m.twist.covariance[0] == pytest.approx(0.05**2)
        assert m.twist.covariance[21] == 1e6  # angular part not measured
        assert math.hypot(m.twist.twist.linear.x, m.twist.twist.linear.y) == pytest.approx(
            60 / 3.6, abs=0.3
        )
    attitude = bag[T.GNSS_ATTITUDE]
    assert all(log - _stamp(m) == 50_000_000 for log, m in attitude)
    for _, m in attitude:
        assert m.angular_velocity_covariance[0] == -1.0
        assert m.linear_acceleration_covariance[0] == -1.0
        assert math.sqrt(m.orientation_covariance[8]) == pytest.approx(math.radians(0.07))


def test_truth_topics_are_base_link_exactly(bag):
    vehicle = Simulation(CONFIG).vehicle
    t = np.array([0.02 * k for k in range(0, 800, 97)])
    truth = vehicle.base_link(t)
    fix, vel, att = (bag[topic][::97] for topic in (T.TRUTH_FIX, T.TRUTH_VEL, T.TRUTH_ATTITUDE))
    for i in range(len(t)):
        (log, f), (_, v), (_, a) = fix[i], vel[i], att[i]
        assert log == _stamp(f) == _stamp(v) == _stamp(a) == DEFAULT_START_NS + round(t[i] * 1e9)
        assert {f.header.frame_id, v.header.frame_id, a.header.frame_id} == {"base_link"}
        assert (f.latitude, f.longitude) == pytest.approx(
            (math.degrees(truth.lat_rad[i]), math.degrees(truth.lon_rad[i])), abs=1e-12
        )
        assert f.altitude == pytest.approx(truth.height_m[i], abs=1e-9)
        assert f.position_covariance_type == 3 and not f.position_covariance.any()
        linear = v.twist.twist.linear
        assert [linear.x, linear.y, linear.z] == pytest.approx(truth.vel_enu_m_s[i], abs=1e-12)
        q = a.orientation
        assert [q.x, q.y, q.z, q.w] == pytest.approx(truth.quat_enu_flu[i], abs=1e-12)
        assert not a.orientation_covariance.any() and a.angular_velocity_covariance[0] == -1.0


def _node_stub(cls: type, **attributes: Any) -> tuple[SimpleNamespace, dict[str, list[Any]]]:
    """An object standing in for an active node: the class's publishing methods bound to it, every
    ``*_pub`` publisher collecting its messages."""
    published: dict[str, list[Any]] = {}
    stub = SimpleNamespace(**attributes)
    for name in ("_imu_pub", "_temp_pub"):
        setattr(stub, name, SimpleNamespace(publish=published.setdefault(name, []).append))
    stub._epoch_pubs = {  # gnss_node's publishers by relative topic
        topic: SimpleNamespace(publish=published.setdefault(topic, []).append)
        for topic in GNSS_TOPICS
    }
    for name in dir(cls):
        if name.startswith("_publish"):
            setattr(stub, name, partial(getattr(cls, name), stub))
    clock = SimpleNamespace(now=lambda: SimpleNamespace(nanoseconds=0))
    stub.get_clock = lambda: clock
    stub.publishing = lambda held=1: True  # an active (lifecycle) driver
    return stub, published


def test_imu_messages_are_what_imu400cc_node_publishes():
    """imu400cc_node's own publishing code (with its default parameters) on the packets the
    emulator makes of the simulated samples gives the simulated messages."""
    defaults = {p.name: p.default for p in imu_node.PARAMETERS}
    driver = ImuDriver(imu_node.driver_config(defaults))
    writer = SampleWriter(driver, defaults["frame_id"], Imu, Temperature, serialize_message)
    stub, published = _node_stub(imu_node.Imu400ccNode, _driver=driver, _writer=writer)
    config = dataclasses.replace(CONFIG, duration_s=1.0, sky_zones=())
    events = Simulation(config).imu_events(0.0, 1.0)
    axes = AxisMap.from_spec(defaults["axis_map"])
    scaling = Scaling(defaults["gyro_range_dps"], defaults["accel_range_g"])
    convert = PacketConverter(scaling, axes, defaults["accel_sign"], defaults["gravity"])
    for event in events:
        m = event.message
        stamp_s = _stamp(m) / 1e9
        if event.topic == T.IMU_TEMPERATURE:
            still = ImuMeasurement(np.zeros(3), np.zeros(3), m.temperature, 0)
            stub._publish(ImuSample(stamp_s, still, with_temperature=True))
            node_msg = TS.deserialize_cdr(published["_temp_pub"][-1], "sensor_msgs/msg/Temperature")
        else:
            w, f = m.angular_velocity, m.linear_acceleration
            packet = measurement_to_packet(
                [w.x, w.y, w.z], [f.x, f.y, f.z], 28.0, 0, scaling, axes, defaults["accel_sign"]
            )
            measured = convert(packet)
            stub._publish(ImuSample(stamp_s, measured, with_temperature=False))
            node_msg = TS.deserialize_cdr(published["_imu_pub"][-1], "sensor_msgs/msg/Imu")
            # Same device counts: equal to rounding; the node's covariances come from densities
            # rounded to 1e-9.
            for ours, theirs in ((w, node_msg.angular_velocity), (f, node_msg.linear_acceleration)):
                assert [theirs.x, theirs.y, theirs.z] == pytest.approx([ours.x, ours.y, ours.z])
            node_msg.angular_velocity, node_msg.linear_acceleration = w, f
            for name in ("angular_velocity_covariance", "linear_acceleration_covariance"):
                assert getattr(node_msg, name) == pytest.approx(getattr(m, name), rel=1e-5)
                setattr(node_msg, name, getattr(m, name))
        assert abs(_stamp(node_msg) - _stamp(m)) <= 1000  # the node stamps from float seconds
        node_msg.header.stamp = m.header.stamp
        assert _cdr(node_msg) == _cdr(m)


def test_gnss_messages_are_what_gnss_node_publishes():
    """gnss_node's own publishing code on the driver core's reading of the receivers' sentences
    gives the simulated messages (the ADU5 contributes its attitude only)."""
    config = dataclasses.replace(CONFIG, duration_s=6.0, sky_zones=())
    events = Simulation(config).gnss_events(0.0, 6.0)
    simulation = Simulation(config)
    node_messages: list[tuple[str, Any]] = []
    for receiver, model in simulation.receivers:
        stub, published = _node_stub(
            GnssNode,
            _frame_id="gnss_link",
            _receiver=receiver.receiver,
            _latencies=[],
            _last_fix_type="none",
            _last_date_source="none",
        )
        for epoch in model.epochs(0.0, 6.0):
            utc_s = config.start_ns / 1e9 + epoch.t_s
            solution = receiver.solve(utc_s, epoch)
            utc = UtcTime(utc_s, DateSource.RECEIVER)
            stub._publish(
                [EpochOutput(utc_s, utc_s, utc, solution.fix, solution.velocity, solution.attitude)]
            )
        wanted = (
            [("gnss/attitude", T.GNSS_ATTITUDE)]
            if receiver.receiver is Receiver.ADU5
            else [
                ("gnss/fix", T.GNSS_FIX),
                ("gnss/vel", T.GNSS_VEL),
                ("gnss/time_reference", T.GNSS_TIME),
            ]
        )
        for publisher, topic in wanted:
            node_messages += [
                (topic, _from_rclpy(m, T.TOPICS[topic])) for m in published.get(publisher, [])
            ]
    assert len(node_messages) == len(events)
    ours = {(e.topic, round(_stamp(e.message), -6)): e.message for e in events}
    for topic, theirs in node_messages:
        mine = ours[(topic, round(_stamp(theirs), -6))]
        assert abs(_stamp(theirs) - _stamp(mine)) <= 1000  # the node stamps from float seconds
        theirs.header.stamp = mine.header.stamp
        if topic == T.GNSS_TIME:
            ns = (theirs.time_ref.sec - mine.time_ref.sec) * 10**9
            assert abs(ns + theirs.time_ref.nanosec - mine.time_ref.nanosec) <= 1000
            theirs.time_ref = mine.time_ref
        assert _cdr(theirs) == _cdr(mine)
    assert len(events) == 6 + 4 + 6 + 5 * 4  # fixes, velocities, times, attitudes; outage at 4 s


def test_message_helpers_fill_rclpy_messages_alike():
    from sensor_msgs.msg import Imu

    from gnss_ins_common.message_fields import fill_imu, stamp_ns

    args = (
        1_717_236_000_123_456_789,
        "imu_link",
        [0.1, 0.2, 0.3],
        [0.0, 0.0, 9.8],
        [1, 2, 3],
        [4, 5, 6],
    )
    rclpy_msg = fill_imu(Imu(), *args)
    assert _cdr(_from_rclpy(rclpy_msg, "sensor_msgs/msg/Imu")) == _cdr(
        fill_imu(new_message("sensor_msgs/msg/Imu"), *args)
    )
    assert stamp_ns(1.9999999999) == 1_999_999_999  # kept within the second, as the nodes do
    assert stamp_ns(12.5) == 12_500_000_000


def test_command_line_errors(tmp_path, capsys):
    assert cli.main(["simulate", "--duration=1"]) == 2
    assert "either --output" in capsys.readouterr().err
    (tmp_path / "taken").mkdir()
    assert cli.main(["simulate", "--duration=1", f"--output={tmp_path / 'taken'}"]) == 2
    assert "exists" in capsys.readouterr().err
    assert cli.main([*ARGS, "--duration=5", f"--output={tmp_path / 'short'}"]) == 2
    assert "sky zone at 11 s: outside the 5 s drive" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        cli.main(["simulate", "--outage=5", "--output=x"])


def test_imu_and_gnss_rates_replace_the_profiles(tmp_path, capsys):
    """--imu-rate / --gnss-rate: the IMU and the position receiver at the rates asked for (the
    ADU5 keeps its own), stamps on the new grid; refused in live mode."""
    path = tmp_path / "rates"
    args = ["simulate", "--duration=6", "--imu-rate=200", "--gnss-rate=2", f"--output={path}"]
    assert cli.main(args) == 0
    assert "imu at 200 Hz, gnss at 2 Hz" in capsys.readouterr().out
    with BagReader(path) as reader:
        stamps: dict[str, list[int]] = {}
        for msg in reader.messages([T.IMU_DATA, T.GNSS_FIX, T.GNSS_ATTITUDE], deserialize=True):
            stamps.setdefault(msg.topic, []).append(_stamp(msg.message))
    for topic, period_ns in ((T.IMU_DATA, 5_000_000), (T.GNSS_FIX, 500_000_000)):
        assert np.all(np.diff(stamps[topic]) == period_ns), topic
    assert len(stamps[T.IMU_DATA]) == 6 * 200
    assert np.all(np.diff(stamps[T.GNSS_ATTITUDE]) == 200_000_000)  # the ADU5's own 5 Hz
    assert cli.main(["simulate", "--live", "--imu-rate=200"]) == 2
    assert "for bags" in capsys.readouterr().err


def test_the_option_table_of_simulator_md_gives_the_parser_defaults() -> None:
    """docs/simulator.md's `| --option | `default` |` rows say what `simulate --help` does."""
    import argparse
    import re

    from ins_fusion.tools import simulate

    parser = argparse.ArgumentParser()
    simulate.add_arguments(parser)
    defaults = {a.option_strings[-1]: a.default for a in parser._actions if a.option_strings}
    page = (REPO / "docs" / "simulator.md").read_text()
    rows = re.findall(r"^\| `(--[a-z0-9-]+)` \| `([^`|]+)` \|", page, re.M)
    assert len(rows) >= 4, rows
    for option, default in rows:
        assert str(defaults[option]) == default, option
