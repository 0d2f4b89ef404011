"""The vehicle speed measurement (core/measurements/vehicle_speed.py): its Jacobian against
finite differences of the measurement, its noise, and the engine with a real car's CAN speed
(test/fixtures/comma2k19, "/vehicle/speed"): the scale error found, outages held, a locked
wheel's readings gated. Figures: bench/bench_speed_aiding.py and docs/accuracy.md."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
from geometry_msgs.msg import TwistWithCovarianceStamped
from hypothesis import given, settings
from hypothesis import strategies as st
from nav_msgs.msg import Odometry
from support.paths import FIXTURES

from gnss_ins_common.params import load_yaml
from ins_fusion.adapters import messages_in
from ins_fusion.bags.bag_io import BagReader, BagWriter
from ins_fusion.bags.messages import new_message
from ins_fusion.bags.topics import ODOMETRY_TYPE
from ins_fusion.core.engine.engine import InsEngine, VehicleSpeedMeasurement
from ins_fusion.core.filter.eskf import ATT, BG, VEL, StateLayout
from ins_fusion.core.measurements.vehicle_speed import speed_model, speed_variance
from ins_fusion.core.nav.rotation import mat_from_quat, quat_from_euler, skew
from ins_fusion.core.settings.config import NODE_NAME, FusionConfig
from ins_fusion.core.settings.params import PARAMETERS
from ins_fusion.replay.inputs import load_bag
from ins_fusion.replay.outages import Outage
from ins_fusion.replay.pipeline import replay
from ins_fusion.replay.topics import DEFAULT_REFERENCE, TopicMap
from ins_fusion.tools import cli

FIXTURE = FIXTURES / "comma2k19"
SPEED_BAG = FIXTURE / "comma2k19_ex1_seg40_speed"
#: CAN speed / reference speed on this segment (fixture README: least squares, 0.9914).
CAR_SCALE_ERROR_PCT = -0.86
LAYOUT = StateLayout(gyro_scale=True, mounting=True, speed_scale=True)


def _model(
    mat_nb: np.ndarray,
    vel: np.ndarray,
    rate_b: np.ndarray,
    rate_i: np.ndarray,
    arm_b: np.ndarray,
    mounting: tuple[float, float],
    scale: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(z, H, R) of a reading of 0 m/s (σ 0.1 m/s) with mat_bi = I."""
    return speed_model(
        (mat_nb, vel, rate_b, rate_i),
        arm_b,
        np.eye(3),
        (mounting, scale),
        (0.0, 0.01),
        LAYOUT.size,
        LAYOUT.columns,
    )


def _predicted_speed(*args) -> float:
    """h(x): the speed the model predicts (its innovation for a reading of 0, negated)."""
    return -float(_model(*args)[0][0])


@settings(max_examples=40, deadline=None)
@given(
    rpy=st.tuples(*[st.floats(-0.3, 0.3)] * 2, st.floats(-math.pi, math.pi)),  # NED
    vel=st.tuples(*[st.floats(-20.0, 20.0)] * 2, st.floats(-1.0, 1.0)),
    rate=st.tuples(*[st.floats(-0.5, 0.5)] * 3),
    arm=st.tuples(*[st.floats(-2.0, 2.0)] * 3),
    mounting=st.tuples(*[st.floats(-0.05, 0.05)] * 2),
    scale=st.floats(-0.05, 0.05),
)
def test_jacobian_matches_finite_differences(rpy, vel, rate, arm, mounting, scale):
    """h(x ⊕ δx) - h(x) = H δx for each error state the model touches, to first order."""
    mat_nb = mat_from_quat(*quat_from_euler(*rpy))
    vel, rate_b, arm_b = (np.array(v, dtype=float) for v in (vel, rate, arm))
    rate_i = rate_b.copy()  # mat_bi = I
    args = (mat_nb, vel, rate_b, rate_i, arm_b, mounting, scale)
    _, H, _ = _model(*args)
    h0 = _predicted_speed(*args)
    eps = 1e-6
    for k in range(3):
        e = np.zeros(3)
        e[k] = eps
        dv = _predicted_speed(mat_nb, vel + e, rate_b, rate_i, arm_b, mounting, scale) - h0
        turned = (np.eye(3) + skew(e)) @ mat_nb  # C_true = (I + [ψ×]) C
        dpsi = _predicted_speed(turned, vel, rate_b, rate_i, arm_b, mounting, scale) - h0
        biased = rate_b - e  # dω_b/dδb_g = -R_bi with R_bi = I
        dbg = _predicted_speed(mat_nb, vel, biased, rate_i, arm_b, mounting, scale) - h0
        assert dv == pytest.approx(H[0, VEL + k] * eps, abs=1e-10)
        assert dpsi == pytest.approx(H[0, ATT + k] * eps, abs=1e-10 + 1e-6 * abs(dpsi))
        assert dbg == pytest.approx(H[0, BG + k] * eps, abs=1e-10)
    dk = _predicted_speed(mat_nb, vel, rate_b, rate_i, arm_b, mounting, scale + eps) - h0
    assert dk == pytest.approx(H[0, LAYOUT.ks] * eps, abs=1e-10)
    for j in range(2):
        turned_mounting = (mounting[0] + eps * (j == 0), mounting[1] + eps * (j == 1))
        dmu = _predicted_speed(mat_nb, vel, rate_b, rate_i, arm_b, turned_mounting, scale) - h0
        assert dmu == pytest.approx(H[0, LAYOUT.mt + j] * eps, abs=1e-10)


def test_noise_is_the_message_variance_above_the_configured_least_sigma():
    reading = VehicleSpeedMeasurement(0.0, 10.0, 0.1**2)
    assert speed_variance(reading, 0.05) == pytest.approx(0.01)
    assert speed_variance(dataclasses.replace(reading, variance_m2_s2=1e-6), 0.05) == 0.05**2
    for unknown in (0.0, -1.0, math.nan, math.inf):
        assert speed_variance(dataclasses.replace(reading, variance_m2_s2=unknown), 0.05) == (
            0.05**2
        )


def test_a_straight_drive_at_10_m_s_reads_10_m_s_times_the_scale():
    """Heading east at 10 m/s, level: the forward speed is 10 m/s; a 2 % scale error reads 10.2;
    a wheel 0.8 m left of the IMU in a 0.2 rad/s left turn rolls 0.16 m/s slower."""
    mat_nb = mat_from_quat(*quat_from_euler(0.0, 0.0, math.pi / 2))  # heading east
    east = np.array((0.0, 10.0, 0.0))  # NED
    still = np.zeros(3)
    assert _predicted_speed(mat_nb, east, still, still, still, (0.0, 0.0), 0.02) == (
        pytest.approx(10.2)
    )
    left_turn_frd = np.array((0.0, 0.0, -0.2))  # FRD z down: a left turn is negative
    wheel_left_frd = np.array((0.0, -0.8, 0.0))
    # floats, as the engine passes them (other types would compile the kernel once more)
    still_mounting = (0.0, 0.0)
    speed = _predicted_speed(
        mat_nb, east, left_turn_frd, left_turn_frd, wheel_left_frd, still_mounting, 0.0
    )
    assert speed == pytest.approx(10.0 - 0.16)


def test_both_message_types_give_the_forward_speed_and_its_variance():
    twist = TwistWithCovarianceStamped()
    odometry = Odometry()
    for message in (twist, odometry):
        message.header.stamp.sec, message.header.stamp.nanosec = 12, 500_000_000
        message.twist.twist.linear.x = -1.25  # reversing
        message.twist.covariance[0] = 0.0025
        assert messages_in.speed_measurement(message) == VehicleSpeedMeasurement(
            12.5, -1.25, 0.0025
        )


def test_an_engine_without_speed_use_refuses_a_speed_reading():
    engine = InsEngine(FusionConfig.default())
    with pytest.raises(ValueError, match=r"speed\.use"):
        engine.add_vehicle_speed(VehicleSpeedMeasurement(0.0, 1.0, 0.01))
    assert "vehicle_speed" not in engine.status().measurements


@pytest.fixture(scope="module")
def can_inputs():
    return load_bag(SPEED_BAG, TopicMap(), DEFAULT_REFERENCE, reference_required=True)


def _without_speed(inputs):
    return dataclasses.replace(
        inputs, measurements=[m for m in inputs.measurements if m[1] != "speed"]
    )


def test_the_cars_scale_error_is_found_and_15_s_outages_drift_several_times_less(can_inputs):
    """The CAN speed reads 0.86 % low against the reference (fixture README); the filter with
    the phone's parameters (its mounting measured) finds it inside its 3σ. With the defaults (as
    replay gives them) the 15 s outages' largest errors shrink at least 3x, inside 3σ
    (bench/bench_speed_aiding.py)."""
    outages = (Outage(5.0, 15.0), Outage(25.0, 15.0), Outage(43.0, 15.0))
    reports = {
        aided: replay(inputs, {}, outages, DEFAULT_REFERENCE).report
        for aided, inputs in (("no", _without_speed(can_inputs)), ("yes", can_inputs))
    }
    phone = load_yaml(FIXTURE / "ins_fusion_phone.yaml", NODE_NAME, PARAMETERS)
    cal = replay(can_inputs, phone, (), DEFAULT_REFERENCE).report["self_calibration"]
    assert (
        abs(cal["speed_scale_error_pct"] - CAR_SCALE_ERROR_PCT)
        < 3.0 * cal["speed_scale_sigma_pct"] + 0.05
    )
    assert "speed_scale_error_pct" not in reports["no"]["self_calibration"]

    def worst(report):
        return max(o["horizontal_error_max_m"] for o in report["outages"])

    assert worst(reports["no"]) > 3.0 * worst(reports["yes"])
    for outage in reports["yes"]["outages"]:
        assert outage["horizontal_error_end_m"] < 3.0 * outage["horizontal_sigma_end_m"]
    assert reports["yes"]["nees"]["position_within_3sigma_fraction"] >= 0.95


def test_a_locked_wheel_is_gated_not_followed(can_inputs):
    """Half a second of readings at 0 m/s (a locked wheel, a skid) while the car drives at
    ~15 m/s inside a GNSS outage: every one is rejected, and the trajectory stays where the
    clean run puts it."""
    outages = (Outage(25.0, 15.0),)
    t0 = can_inputs.t0_s
    locked = [
        (k, role, dataclasses.replace(m, speed_m_s=0.0))
        if role == "speed" and 30.0 <= m.t_s - t0 < 30.5
        else (k, role, m)
        for k, role, m in can_inputs.measurements
    ]
    spoilt = sum(a != b for a, b in zip(locked, can_inputs.measurements, strict=True))
    assert spoilt > 30
    clean = replay(can_inputs, {}, outages, DEFAULT_REFERENCE).report
    skid = replay(
        dataclasses.replace(can_inputs, measurements=locked), {}, outages, DEFAULT_REFERENCE
    ).report
    gated = skid["measurements"]["vehicle_speed"]["gated"]
    assert gated >= clean["measurements"]["vehicle_speed"]["gated"] + spoilt
    end = (
        clean["outages"][0]["horizontal_error_end_m"],
        skid["outages"][0]["horizontal_error_end_m"],
    )
    assert abs(end[1] - end[0]) < 0.2


def test_replay_uses_the_bags_speed_and_says_so_in_its_report(tmp_path, capsys):
    report_path = tmp_path / "report.json"
    code = cli.main(["replay", str(SPEED_BAG), "--report", str(report_path)])
    out, err = capsys.readouterr()
    assert code == 0, err
    report = json.loads(report_path.read_text())
    counters = report["measurements"]["vehicle_speed"]
    # Most are used; the others fall in moments where the phone's vibrating accelerometer,
    # low-passed over 0.1 s, reads more than speed.max_accel (counted rejected, not gated).
    assert counters["used"] > 0.85 * 4974 and counters["gated"] < 0.02 * 4974
    assert "vehicle_speed" in out and "vehicle speed scale error" in out


@pytest.mark.parametrize("how", ["--set", "--params"])
def test_speed_use_false_leaves_the_bags_speed_out_and_says_so(how, tmp_path, capsys):
    """A user's ``speed.use: false`` (``--set`` or a parameter file) wins over the bag's speed:
    the replay is the one of the same drive without its speed topic (the fixture it was made
    from), and says what it left out."""
    if how == "--set":
        declined = ["--set", "speed.use=false"]
    else:
        params = tmp_path / "params.yaml"
        params.write_text("ins_fusion_node:\n  ros__parameters:\n    speed:\n      use: false\n")
        declined = ["--params", str(params)]
    reports = []
    for bag, options in ((SPEED_BAG, declined), (FIXTURE / "comma2k19_ex1_seg40", [])):
        report_path = tmp_path / "report.json"
        assert cli.main(["replay", str(bag), "--report", str(report_path), *options]) == 0
        reports.append(json.loads(report_path.read_text()))
        report_path.unlink()
    _, err = capsys.readouterr()
    source = "--set" if how == "--set" else str(tmp_path / "params.yaml")
    assert f"note: speed.use false ({source}): the bag's 4974 vehicle speed readings" in err
    assert "vehicle_speed" not in reports[0]["measurements"]
    for key in ("measurements", "position_error_m", "nees"):
        assert reports[0][key] == reports[1][key], key


def test_speed_use_is_not_swept(capsys):
    """Sweeping speed.use would compare nothing: a bag's speed is used unless declined."""
    assert cli.main(["replay", str(SPEED_BAG), "--sweep", "speed.use=true,false"]) == 2
    assert "speed.use is not swept" in capsys.readouterr().err


def test_wheel_odometry_in_a_bag_is_the_same_speed_under_topics_speed(tmp_path, capsys):
    """The fixture's speed rewritten as nav_msgs/Odometry on another topic and named with
    ``--topics speed=``: the replay reads the same readings (through rosbags) and gives the same
    report as from the TwistWithCovarianceStamped."""
    bag = tmp_path / "odometry"
    with BagReader(SPEED_BAG) as reader, BagWriter(bag) as writer:
        for message in reader.messages(deserialize=True):
            if message.topic != "/vehicle/speed":
                writer.add_topic(message.topic, reader.topics[message.topic].msgtype)
                writer.write(message.topic, message.log_time_ns, message.message)
                continue
            odometry = new_message(ODOMETRY_TYPE)
            odometry.header = message.message.header
            odometry.child_frame_id = "base_link"
            odometry.twist = message.message.twist
            writer.write("/wheels/odometry", message.log_time_ns, odometry)
    reports = []
    for path, topics in ((SPEED_BAG, []), (bag, ["--topics", "speed=/wheels/odometry"])):
        report_path = tmp_path / f"{path.name}.json"
        assert cli.main(["replay", str(path), "--report", str(report_path), *topics]) == 0
        reports.append(json.loads(report_path.read_text()))
    capsys.readouterr()
    assert reports[1]["topics"]["speed"] == "/wheels/odometry"
    for key in ("measurements", "self_calibration", "position_error_m", "nees"):
        assert reports[1][key] == reports[0][key], key


def test_the_speed_time_offset_is_taken_off_every_speed_stamp(can_inputs):
    """speed.time_offset -0.036 s (the fixture's CAN speed leads the reference by 36 ms) gives
    the same run as the readings stamped 36 ms later."""
    outages = (Outage(25.0, 15.0),)
    later = [
        (k, role, dataclasses.replace(m, t_s=m.t_s + 0.036) if role == "speed" else m)
        for k, role, m in can_inputs.measurements
    ]
    shifted = replay(
        dataclasses.replace(can_inputs, measurements=later), {}, outages, DEFAULT_REFERENCE
    )
    offset = replay(can_inputs, {"speed.time_offset": -0.036}, outages, DEFAULT_REFERENCE)
    assert np.array_equal(shifted.run.track.rows, offset.run.track.rows)
