"""References compared in the frame their messages name (ins_fusion.replay.frames, pipeline).

A reference of the IMU (frame_id imu_link, as comma2k19's) is compared with the fused base_link
solution moved by imu_lever_arm and imu_mounting_rpy_deg; base_link references exactly as
before; other frames as base_link, with a note.
"""

from __future__ import annotations

import json
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ins_fusion.adapters.messages_in import ImuSample
from ins_fusion.bags.bag_io import BagReader, BagWriter
from ins_fusion.core.engine.engine import InsSolution
from ins_fusion.core.nav import earth
from ins_fusion.core.nav.rotation import MAT_FLU_FRD, mat_from_rpy_flu
from ins_fusion.core.settings.config import FusionConfig
from ins_fusion.replay import metrics, pipeline
from ins_fusion.replay.frames import comparison_frame, mounting_quat, moved_track
from ins_fusion.replay.inputs import ImuSeries, Reference, ReplayInputs, Series
from ins_fusion.replay.run import FusionRun, SolutionTrack
from ins_fusion.replay.topics import TopicMap
from ins_fusion.sim.drive import SimulationConfig
from ins_fusion.sim.simulated_bag import write_bag
from ins_fusion.tools import cli

DATUM = (57.0, 10.0, 40.0)
T0 = 1000.0
IMU_ARM = (0.8, 0.1, 1.6)  # base_link FLU [m]
MOUNTING_DEG = (0.0, 3.0, 0.0)  # imu_link pitched 3° in base_link
YAW_RATE = 0.2  # rad/s, a steady left turn at 10 m/s


def _base_pose(t):
    """base_link on a circle: ENU position, orientation (FLU in ENU), velocity, rate (FLU)."""
    yaw = 0.3 + YAW_RATE * t
    radius = 10.0 / YAW_RATE
    pos = np.array([radius * np.sin(yaw), -radius * np.cos(yaw), 2.0])
    vel = 10.0 * np.array([np.cos(yaw), np.sin(yaw), 0.0])
    rot = Rotation.from_euler("ZYX", [yaw, 0.02, -0.01])
    return pos, rot, vel, np.array([0.0, 0.0, YAW_RATE])


def _solution(t):
    pos, rot, vel, rate = _base_pose(t)
    return InsSolution(
        t_s=T0 + t,
        lat_deg=0.0,
        lon_deg=0.0,
        height_m=0.0,
        pos_enu_m=pos,
        vel_enu_m_s=vel,
        quat_enu_flu_xyzw=rot.as_quat(),
        rate_flu_rad_s=rate,
        cov_pos_enu_m2=np.eye(3) * 0.01,
        cov_vel_enu=np.eye(3) * 1e-4,
        cov_att_enu_rad2=np.eye(3) * 1e-6,
        gyro_bias_flu_rad_s=np.zeros(3),
        accel_bias_flu_m_s2=np.zeros(3),
        state="navigating",
    )


def _truth(t_s, frame):
    """Reference of base_link, or of imu_link computed independently of frames.py."""
    pos, quat, vel = [], [], []
    r = np.asarray(IMU_ARM)
    mount = Rotation.from_euler("ZYX", MOUNTING_DEG[::-1], degrees=True)  # yaw, pitch, roll
    for t in t_s:
        p, rot, v, w = _base_pose(t)
        if frame == "imu_link":
            p, v, rot = p + rot.apply(r), v + rot.apply(np.cross(w, r)), rot * mount
        pos.append(p)
        quat.append(rot.as_quat())
        vel.append(v)
    lat, lon, h = earth.enu_to_geodetic(np.array(pos), *np.radians(DATUM[:2]), DATUM[2])
    stamps = T0 + np.asarray(t_s)
    return Reference(
        Series(stamps, np.column_stack([np.degrees(lat), np.degrees(lon), h])),
        Series(stamps, np.array(quat)),
        Series(stamps, np.array(vel)),
        frame,
    )


def _replay(monkeypatch, frame_id, imu_frame="imu_link", track=None):
    """pipeline.replay with the engine run replaced by the synthetic track (``track``: of
    ``_solution`` when None)."""
    if track is None:
        track = SolutionTrack.from_solutions([_solution(t) for t in np.arange(0.0, 10.01, 0.02)])
    parameters = {"imu_lever_arm": list(IMU_ARM), "imu_mounting_rpy_deg": list(MOUNTING_DEG)}
    config = FusionConfig.from_parameters(parameters)
    status = SimpleNamespace(
        state="navigating",
        resets=0,
        last_reset_reason="",
        measurements={},
        adapted={},
        calibration={},
        warnings=(),
    )
    run = FusionRun(track, status, DATUM, {"fix": 0, "vel": 0, "attitude": 0}, 50.0, 0.0, config)
    monkeypatch.setattr(pipeline, "run_fusion", lambda *args, **kwargs: run)
    truth_frame = "imu_link" if frame_id == "imu_link" else "base_link"
    reference = _truth(np.arange(0.5, 9.5, 0.05), truth_frame)
    reference = Reference(reference.position, reference.attitude, reference.velocity, frame_id)
    imu = ImuSeries.from_samples(
        [ImuSample(T0 + t, (0.0, 0.0, 0.0), (0.0, 0.0, 9.8)) for t in (0.0, 10.0)]
    )
    inputs = ReplayInputs("bag", TopicMap(), imu, [], reference, 0.0, imu_frame)
    return pipeline.replay(inputs, parameters, [], "/ground_truth"), track, reference


def test_mounting_follows_the_engine_convention():
    rpy = np.radians([2.0, 3.0, -5.0])
    expected = MAT_FLU_FRD @ mat_from_rpy_flu(rpy) @ MAT_FLU_FRD  # imu FLU -> base FLU
    assert Rotation.from_quat(mounting_quat(rpy)).as_matrix() == pytest.approx(expected, abs=1e-15)


def test_reference_of_the_imu_is_compared_with_the_moved_solution(monkeypatch):
    result, track, reference = _replay(monkeypatch, "imu_link")
    report = result.report
    assert (report["reference_frame"], report["reference_frame_id"]) == ("imu_link", "imu_link")
    position, attitude = report["position_error_m"], report["attitude_error_deg"]
    assert report["evaluated_samples"] == 180
    # Linear interpolation of a 50 m circle at 50 Hz: chord error ≈ (0.2 m)² / (8 · 50 m).
    assert position["horizontal_max"] < 2e-4 and position["vertical_rms"] < 1e-9
    assert max(attitude.values()) < 1e-6
    assert report["velocity_error_m_s"]["horizontal_rms"] < 2e-3
    # Without the move the errors would be the lever arm and the 3° pitch.
    unmoved = metrics.evaluate(track, reference, DATUM, T0, [], 0.5)
    assert metrics.position_stats(unmoved.position)["horizontal_rms"] > 0.8
    assert metrics.attitude_stats(unmoved.attitude)["pitch_rms"] == pytest.approx(3.0, abs=0.01)


def test_reference_of_the_imu_is_compared_with_the_imu_attitude_covariance(monkeypatch):
    # The engine's attitude error is the IMU's; base_link's adds the mounting's: an IMU
    # reference is scored against imu_link's own covariance, a base_link one against base_link's.
    imu_cov = np.diag([4e-6, 9e-6, 16e-6])
    solutions = [
        replace(_solution(t), cov_att_imu_enu_rad2=imu_cov) for t in np.arange(0.0, 10.01, 0.02)
    ]
    track = SolutionTrack.from_solutions(solutions)
    np.testing.assert_array_equal(track.cov_att_imu_enu_rad2[0], imu_cov)
    moved = moved_track(track, IMU_ARM, np.radians(MOUNTING_DEG), track.cov_att_imu_enu_rad2)
    np.testing.assert_array_equal(moved.cov_att_enu_rad2, track.cov_att_imu_enu_rad2)
    # Without its own (a solution of no estimated mounting) a row holds base_link's.
    plain = SolutionTrack.from_solutions([_solution(0.0)])
    np.testing.assert_array_equal(plain.cov_att_imu_enu_rad2, plain.cov_att_enu_rad2)
    result, _, _ = _replay(monkeypatch, "imu_link", track=track)
    assert result.evaluation.attitude is not None
    # Yaw about up as it is; roll and pitch are E and N turned by the heading (their sum stays).
    variances = np.diagonal(result.evaluation.attitude.cov, axis1=1, axis2=2) / np.degrees(1) ** 2
    np.testing.assert_allclose(variances[:, 2], 16e-6, rtol=1e-9)
    np.testing.assert_allclose(variances[:, 0] + variances[:, 1], 13e-6, rtol=1e-9)
    base, _, _ = _replay(monkeypatch, "base_link", track=track)
    np.testing.assert_allclose(base.evaluation.attitude.sigma, np.degrees(1e-3), rtol=1e-9)


def test_moved_track_adds_the_attitude_covariance_through_the_lever_arm():
    level = replace(_solution(0.0), quat_enu_flu_xyzw=Rotation.from_euler("Z", 0.7).as_quat())
    track = SolutionTrack.from_solutions([level])
    moved = moved_track(track, (0.0, 0.0, 2.0))  # straight up: tilts move it, heading does not
    extra = moved.cov_pos_enu_m2[0] - track.cov_pos_enu_m2[0]
    assert extra == pytest.approx(np.diag([4e-6, 4e-6, 0.0]), abs=1e-9)


def test_base_link_reference_is_evaluated_exactly_as_before(monkeypatch):
    result, track, reference = _replay(monkeypatch, "base_link")
    before = metrics.evaluate(track, reference, DATUM, 0.0, [], 0.5)
    assert result.compared_track is result.run.track
    assert result.report["reference_frame"] == "base_link"
    assert np.array_equal(result.evaluation.position.error, before.position.error)
    assert np.array_equal(result.evaluation.position.cov, before.position.cov)
    assert np.array_equal(result.evaluation.attitude.error, before.attitude.error)
    assert np.array_equal(result.evaluation.velocity.error, before.velocity.error)


@pytest.mark.parametrize("frame_id", ["", "gps_antenna"])
def test_other_frames_are_compared_as_base_link(monkeypatch, frame_id):
    result, track, reference = _replay(monkeypatch, frame_id)
    before = metrics.evaluate(track, reference, DATUM, 0.0, [], 0.5)
    assert np.array_equal(result.evaluation.position.error, before.position.error)
    report = result.report
    assert (report["reference_frame"], report["reference_frame_id"]) == ("base_link", frame_id)


def test_comparison_frame():
    assert comparison_frame("imu_link", "base_link", "") == "imu_link"
    assert comparison_frame("imu", "base_link", "imu") == "imu"
    assert comparison_frame("base_link", "base_link", "imu_link") == "base_link"
    assert comparison_frame("vehicle", "vehicle", "imu_link") == "vehicle"
    assert comparison_frame("", "base_link", "imu_link") is None
    assert comparison_frame("gnss_link", "base_link", "imu_link") is None


# --------------------------------------------------------------------------------------------
# gnss_ins replay: the frame_id read from the bag
# --------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    path = tmp_path_factory.mktemp("frames") / "eight"
    write_bag(SimulationConfig(scenario="figure_eight", duration_s=30.0, seed=4), path)
    return path


def _relabelled(bag, path, frame_id):
    """The bag with the /ground_truth/* messages' header.frame_id set to ``frame_id``."""
    with BagReader(bag) as reader, BagWriter(path) as writer:
        for topic, info in reader.topics.items():
            writer.add_topic(topic, info.msgtype)
        raw = [t for t in reader.topics if not t.startswith("/ground_truth/")]
        for msg in reader.messages(list(reader.topics), deserialize=True, raw_topics=raw):
            if msg.topic not in raw:
                msg.message.header.frame_id = frame_id
            writer.write(msg.topic, msg.log_time_ns, msg.message)
    return path


def _run(capsys, bag, report):
    assert cli.main(["replay", str(bag), "--report", str(report)]) == 0
    _, err = capsys.readouterr()
    return json.loads(report.read_text()), err


def test_frame_id_of_the_bag_chooses_the_comparison(bag, tmp_path, capsys):
    """The simulator's truth is of base_link: labelled imu_link it is compared with the solution
    moved by the default imu_lever_arm (0.8, 0, 1.6), so the errors become that lever arm."""
    base, err = _run(capsys, bag, tmp_path / "base.json")
    assert (base["reference_frame"], base["reference_frame_id"]) == ("base_link", "base_link")
    assert "note" not in err
    imu, err = _run(capsys, _relabelled(bag, tmp_path / "imu", "imu_link"), tmp_path / "imu.json")
    assert (imu["reference_frame"], imu["reference_frame_id"]) == ("imu_link", "imu_link")
    assert "moved there by imu_lever_arm" in err
    assert imu["position_error_m"]["horizontal_rms"] == pytest.approx(0.8, abs=0.2)
    assert imu["position_error_m"]["vertical_rms"] == pytest.approx(1.6, abs=0.1)
    other, err = _run(capsys, _relabelled(bag, tmp_path / "gps", "gps"), tmp_path / "gps.json")
    assert (other["reference_frame"], other["reference_frame_id"]) == ("base_link", "gps")
    assert "frame_id 'gps' is neither base_link nor the IMU's" in err
    assert other["position_error_m"] == base["position_error_m"]
