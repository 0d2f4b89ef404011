"""Replay settings (--set, --sweep, --topics) and how the engine is fed (receive order, outages)."""

from __future__ import annotations

from typing import ClassVar

import numpy as np
import pytest

from gnss_ins_common.params import ParameterValueError
from ins_fusion.adapters.messages_in import ImuSample
from ins_fusion.core.filter.records import GnssFixMeasurement, GnssVelocityMeasurement
from ins_fusion.replay import run as replay_run
from ins_fusion.replay.inputs import ImuSeries, ReplayInputs, TopicMap
from ins_fusion.replay.outages import Outage
from ins_fusion.replay.settings import grid, parse_setting, parse_sweep


def test_settings_are_read_as_yaml_and_validated_like_the_node():
    assert parse_setting("use_nhc=false") == ("use_nhc", False)
    assert parse_setting("zupt_sigma=0.05") == ("zupt_sigma", 0.05)
    assert parse_setting("zupt_sigma=1") == ("zupt_sigma", 1.0)  # int widened as the node does
    assert parse_setting("gnss_lever_arm=[0, 0.1, 1.8]") == ("gnss_lever_arm", [0.0, 0.1, 1.8])
    assert parse_setting("map_frame=odom") == ("map_frame", "odom")
    assert parse_setting("calibration_file=") == ("calibration_file", "")


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("no_such_parameter=1", "unknown parameter 'no_such_parameter'"),
        ("zupt_sigma", "not name=value"),
        ("zupt_sigma=-1", r"parameter 'zupt_sigma': -1 is outside \[0.0001, 10.0\]"),
        ("use_nhc=maybe", "parameter 'use_nhc': expected bool"),
        ("gnss_lever_arm=[1, 2]", "needs 3 values"),
        ("zupt_sigma=[1", "cannot read"),
    ],
)
def test_bad_settings_are_refused_with_the_reason(text, message):
    with pytest.raises(ParameterValueError, match=message):
        parse_setting(text)


def test_sweep_values_split_outside_brackets_and_form_a_grid():
    arms = parse_sweep("gnss_lever_arm=[0,0,1.75],[0.1,0,1.75]")
    assert arms == ("gnss_lever_arm", [[0.0, 0.0, 1.75], [0.1, 0.0, 1.75]])
    flags = parse_sweep("use_nhc=true,false")
    assert grid([arms, flags]) == [
        {"gnss_lever_arm": [0.0, 0.0, 1.75], "use_nhc": True},
        {"gnss_lever_arm": [0.0, 0.0, 1.75], "use_nhc": False},
        {"gnss_lever_arm": [0.1, 0.0, 1.75], "use_nhc": True},
        {"gnss_lever_arm": [0.1, 0.0, 1.75], "use_nhc": False},
    ]
    with pytest.raises(ParameterValueError, match="repeats"):
        parse_sweep("use_nhc=true,true")
    with pytest.raises(ParameterValueError, match="swept twice"):
        grid([flags, flags])
    with pytest.raises(ParameterValueError, match="outside"):
        parse_sweep("zupt_sigma=0.01,100")


def test_topic_map():
    topics = TopicMap.parse("imu=/vehicle/imu/data_raw, attitude=adu5/gnss/attitude")
    assert topics == TopicMap(imu="/vehicle/imu/data_raw", attitude="/adu5/gnss/attitude")
    for bad in ("imu", "gyro=/x", "fix="):
        with pytest.raises(ValueError, match="ROLE=TOPIC"):
            TopicMap.parse(bad)
    with pytest.raises(ValueError, match="more than one role"):
        TopicMap.parse("vel=/gnss/fix")


class _RecordingEngine:
    """Stands in for InsEngine: records what it is fed, in order."""

    instances: ClassVar[list[_RecordingEngine]] = []

    def __init__(self, config, calibration=None):
        self.datum = None
        self.fed: list[tuple[str, float]] = []
        self.instances.append(self)

    def add_imu(self, t_s, rate, force):
        self.fed.append(("imu", t_s))

    def add_imu_series(self, t_s, rate, force, ticks, span, rows):
        for k in range(*span):
            self.add_imu(float(t_s[k]), rate[k], force[k])

    def add_gnss_fix(self, fix):
        self.fed.append(("fix", fix.t_s))

    def add_gnss_velocity(self, vel):
        self.fed.append(("vel", vel.t_s))

    def add_attitude(self, att):
        self.fed.append(("attitude", att.t_s))

    def solution_row(self):
        return None

    def status(self):
        return None


def test_engine_is_fed_in_receive_order_without_messages_in_outages(monkeypatch):
    monkeypatch.setattr(replay_run, "InsEngine", _RecordingEngine)
    imu = ImuSeries.from_samples(
        [ImuSample(100.0 + 0.5 * k, (0.0, 0.0, 0.0), (0.0, 0.0, 9.8)) for k in range(8)]
    )

    def fix(t):
        return GnssFixMeasurement(t, 57.0, 10.0, 40.0, np.eye(3))

    def vel(t):
        return GnssVelocityMeasurement(t, np.zeros(3), np.eye(3))

    measurements = [
        (2, "fix", fix(100.4)),  # received after two IMU samples, stamped before the second
        (2, "vel", vel(100.4)),
        (4, "fix", fix(101.5)),  # in the outage 1.5:1 (relative to the first IMU stamp)
        (5, "vel", vel(102.4)),  # in it as well
        (6, "fix", fix(102.5)),  # the outage's end is not in it
        (8, "fix", fix(103.6)),  # after the last IMU sample
    ]
    inputs = ReplayInputs("bag", TopicMap(), imu, measurements, None, 0.0)
    run = replay_run.run_fusion(inputs, {}, [Outage(1.5, 1.0)])
    assert run.dropped == {"fix": 1, "vel": 1, "attitude": 0}
    (engine,) = _RecordingEngine.instances
    assert engine.fed == [
        ("imu", 100.0),
        ("imu", 100.5),
        ("fix", 100.4),
        ("vel", 100.4),
        ("imu", 101.0),
        ("imu", 101.5),
        ("imu", 102.0),
        ("imu", 102.5),
        ("fix", 102.5),
        ("imu", 103.0),
        ("imu", 103.5),
        ("fix", 103.6),
    ]
