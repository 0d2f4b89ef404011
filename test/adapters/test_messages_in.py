"""ins_fusion.adapters.messages_in: the node's and the replay's one reading of the input messages.

Messages are built with the drivers' own fill functions (bags.messages, rosbags message objects)
and as plain attribute objects holding array.array fields the way rclpy messages do.
"""

from __future__ import annotations

import array
import math
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from gnss_ins_common.message_fields import fill_imu, fill_navsatfix, fill_orientation, fill_velocity
from gnss_ins_common.navsat import HEIGHT_UNKNOWN_VARIANCE_M2
from ins_fusion.adapters import cdr_fields, messages_in
from ins_fusion.bags.messages import new_message
from ins_fusion.bags.topics import FIX_TYPE, IMU_TYPE, VELOCITY_TYPE
from ins_fusion.bags.typestore import jazzy_typestore

T_NS = 1_717_236_000_123_456_789
T_S = 1_717_236_000 + 0.123456789
COV3 = [0.01, 0.001, 0.0, 0.001, 0.02, 0.0, 0.0, 0.0, 0.09]


def _fix(status=2, cov_type=2, alt=41.5, cov=COV3):
    msg = new_message(FIX_TYPE)
    return fill_navsatfix(msg, T_NS, "gnss_link", status, 1, 57.01, 9.98, alt, cov, cov_type)


def test_imu_sample_reads_stamp_rate_and_specific_force():
    """The IMU as its driver fills it, read from the bytes as the node and a replay read it."""
    msg = fill_imu(
        new_message(IMU_TYPE),
        T_NS,
        "imu_link",
        [0.01, -0.02, 0.03],
        [0.1, 0.2, 9.81],
        [1e-6] * 3,
        [1e-4] * 3,
    )
    sample = cdr_fields.imu_sample(bytes(jazzy_typestore().serialize_cdr(msg, IMU_TYPE)))
    assert sample.t_s == pytest.approx(T_S, abs=1e-9)
    assert sample.rate_flu_rad_s == (0.01, -0.02, 0.03)
    assert sample.force_flu_m_s2 == (0.1, 0.2, 9.81)


def test_valid_fix_carries_position_and_enu_covariance():
    fix = messages_in.fix_measurement(_fix())
    assert fix.valid
    assert (fix.lat_deg, fix.lon_deg, fix.height_m) == (57.01, 9.98, 41.5)
    assert fix.t_s == pytest.approx(T_S, abs=1e-9)
    np.testing.assert_array_equal(fix.cov_enu_m2, np.reshape(COV3, (3, 3)))


@pytest.mark.parametrize(
    ("alt", "vertical"),
    [(math.nan, 0.09), (41.5, HEIGHT_UNKNOWN_VARIANCE_M2), (41.5, math.inf), (math.nan, math.nan)],
)
def test_a_2d_fix_is_valid_with_its_height_marked_unknown(alt, vertical):
    cov = [0.01, 0.001, 0.5, 0.001, 0.02, 0.5, 0.5, 0.5, vertical]
    fix = messages_in.fix_measurement(_fix(0, 1, alt, cov))
    assert fix.valid and not fix.height_known and math.isnan(fix.height_m)
    assert (fix.lat_deg, fix.lon_deg) == (57.01, 9.98)
    expected = np.diag([0.0, 0.0, HEIGHT_UNKNOWN_VARIANCE_M2])
    expected[:2, :2] = [[0.01, 0.001], [0.001, 0.02]]
    np.testing.assert_array_equal(fix.cov_enu_m2, expected)  # no vertical correlation left
    assert messages_in.fix_measurement(_fix()).height_known


@pytest.mark.parametrize(
    ("status", "cov_type", "alt", "cov"),
    [
        (-1, 2, 41.5, COV3),  # NO_FIX
        (-2, 2, 41.5, COV3),  # STATUS_UNKNOWN
        (0, 0, 41.5, COV3),  # covariance type UNKNOWN: cannot be weighted
        (0, 1, math.nan, [math.nan, 0, 0, 0, 1.0, 0, 0, 0, 1.0]),  # 2-D, horizontal unusable
        (0, 2, 41.5, [math.nan] * 9),
        (0, 2, 41.5, [0.0] * 9),
        (0, 2, 41.5, [-1.0, 0, 0, 0, -1.0, 0, 0, 0, -4.0]),
        (0, 2, 41.5, [1.0, 0, 0, 0, 1.0, 0, 0, 0, 0.0]),
        (0, 3, 41.5, [1.0, 2.0, 0, 2.0, 1.0, 0, 0, 0, 1.0]),  # eigenvalue -1
        (0, 2, 41.5, [1.0, 0, 0, 0, math.inf, 0, 0, 0, 1.0]),
    ],
    ids=[
        "no_fix",
        "status_unknown",
        "covariance_unknown",
        "nan_altitude",
        "nan_covariance",
        "zero_covariance",
        "negative_covariance",
        "zero_vertical_variance",
        "indefinite_covariance",
        "infinite_variance",
    ],
)
def test_fix_without_usable_position_is_invalid(status, cov_type, alt, cov):
    assert not messages_in.fix_measurement(_fix(status, cov_type, alt, cov)).valid


@settings(max_examples=300, deadline=None)
@given(
    arrays(np.float64, (3, 3), elements=st.floats(-10.0, 10.0)),
    st.floats(-3.0, 3.0),
)
def test_positive_definite_agrees_with_the_eigenvalues(m, shift):
    """The closed-form check (leading principal minors) says what the smallest eigenvalue
    says, for symmetric matrices not within rounding of singular."""
    cov = m @ m.T + shift * np.eye(3)
    smallest = np.linalg.eigvalsh(cov).min()
    assume(abs(smallest) > 1e-6 * max(1.0, float(np.abs(cov).max())))
    asymmetric = cov + np.triu(np.ones((3, 3)), 1)
    assert messages_in.positive_definite(cov) == (smallest > 0.0)
    assert not messages_in.positive_definite(asymmetric)
    # Many at once: each as on its own.
    many = np.stack([cov, asymmetric, np.full((3, 3), np.nan), cov])
    expected = [smallest > 0.0, False, False, smallest > 0.0]
    assert messages_in.positive_definite(many).tolist() == expected


def test_velocity_takes_linear_block_and_keeps_unknown_vertical():
    cov = [0.0025, 0.0, 0.0, 0.0, 0.0025, 0.0, 0.0, 0.0, 1e6]
    msg = fill_velocity(new_message(VELOCITY_TYPE), T_NS, "gnss_link", [3, 4, 0], cov)
    vel = messages_in.velocity_measurement(msg)
    np.testing.assert_array_equal(vel.vel_enu_m_s, [3.0, 4.0, 0.0])
    np.testing.assert_array_equal(vel.cov_enu_m2_s2, np.reshape(cov, (3, 3)))
    assert vel.t_s == pytest.approx(T_S, abs=1e-9)


def test_attitude_reads_orientation_and_rpy_covariance():
    quat = [0.0, 0.0, math.sqrt(0.5), math.sqrt(0.5)]
    cov = [1.7e-5, 0, 0, 0, 6e-6, 0, 0, 0, 1.5e-6]
    msg = fill_orientation(new_message(IMU_TYPE), T_NS, "gnss_link", quat, cov)
    att = messages_in.attitude_measurement(msg)
    np.testing.assert_array_equal(att.quat_enu_flu_xyzw, quat)
    np.testing.assert_array_equal(att.cov_rpy_rad2, np.reshape(cov, (3, 3)))


def test_imu_message_without_orientation_measures_no_angle():
    zeros = [0.0] * 3
    msg = fill_imu(new_message(IMU_TYPE), T_NS, "imu_link", *[zeros] * 4)
    att = messages_in.attitude_measurement(msg)
    assert np.isinf(np.diag(att.cov_rpy_rad2)).all()


def _stamped(**fields):
    stamp = SimpleNamespace(sec=1_717_236_000, nanosec=500_000_000)
    return SimpleNamespace(header=SimpleNamespace(stamp=stamp, frame_id="x"), **fields)


def test_rclpy_style_fields_are_read_the_same():
    """rclpy keeps fixed-size float arrays as numpy arrays or array.array; both work."""
    vec = SimpleNamespace
    fix = _stamped(
        status=SimpleNamespace(status=0, service=1),
        latitude=1.0,
        longitude=2.0,
        altitude=3.0,
        position_covariance=array.array("d", COV3),
        position_covariance_type=3,
    )
    twist = _stamped(
        twist=SimpleNamespace(
            twist=SimpleNamespace(linear=vec(x=1.0, y=2.0, z=3.0), angular=vec(x=0, y=0, z=0)),
            covariance=array.array("d", range(36)),
        )
    )
    measured = messages_in.fix_measurement(fix)
    assert measured.valid and measured.t_s == 1_717_236_000.5
    np.testing.assert_array_equal(measured.cov_enu_m2, np.reshape(COV3, (3, 3)))
    vel = messages_in.velocity_measurement(twist)
    np.testing.assert_array_equal(vel.cov_enu_m2_s2, [[0, 1, 2], [6, 7, 8], [12, 13, 14]])


def test_held_imu_feeds_the_engine_as_add_imu_does_sample_by_sample(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """HeldImu (the node's way in: the replay's add_imu_series, its compiled runs) gives the
    same solution rows and counters as add_imu per sample, holding up to a few samples between
    outputs and taking them before each measurement."""
    from ins_fusion.core.engine import sample_runs
    from ins_fusion.core.engine.engine import FusionConfig, InsEngine
    from ins_fusion.core.engine.warm_up import synthetic_drive

    runs = []
    take_run = sample_runs.take_run
    monkeypatch.setattr(sample_runs, "take_run", lambda *args: runs.append(1) or take_run(*args))

    (t_s, rate, force, ticks), measurements = synthetic_drive()
    config = FusionConfig.from_parameters({"alignment.duration": 1.0})
    held_engine, plain_engine = InsEngine(config), InsEngine(config)
    held = messages_in.HeldImu(3)
    rows: dict[str, list[np.ndarray]] = {"held": [], "plain": []}
    pending = list(measurements)
    for k in range(len(t_s)):
        while pending and pending[0][0] <= k:
            measurement = pending.pop(0)[1]
            held.take(held_engine)
            for engine in (held_engine, plain_engine):
                if isinstance(measurement, messages_in.GnssFixMeasurement):
                    engine.add_gnss_fix(measurement)
                elif isinstance(measurement, messages_in.GnssVelocityMeasurement):
                    engine.add_gnss_velocity(measurement)
                elif isinstance(measurement, messages_in.AttitudeMeasurement):
                    engine.add_attitude(measurement)
        sample = messages_in.ImuSample(float(t_s[k]), tuple(rate[k]), tuple(force[k]))
        held.hold(sample)
        plain_engine.add_imu(*sample)
        if ticks[k] or held.full:
            held.take(held_engine)
        if ticks[k]:
            for name, engine in (("held", held_engine), ("plain", plain_engine)):
                row = engine.solution_row()
                if row is not None:
                    rows[name].append(row)
    held.take(held_engine)
    assert held.count == 0 and len(rows["plain"]) > 200 and len(runs) > 100
    np.testing.assert_array_equal(np.array(rows["held"]), np.array(rows["plain"]))
    assert repr(held_engine.status()) == repr(plain_engine.status())
