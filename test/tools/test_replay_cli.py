"""`gnss_ins replay` end to end on a small simulated bag, and its refusals of bad input.

The bag: 90 s of the figure-eight scenario (10 s standstill, one lap of two 40 m circles at
10 m/s, braking), imu400cc IMU, Leica RTK at 1 Hz, ADU5 at 5 Hz, truth at 50 Hz. Accuracy bounds
are generous (bench/bench_replay.py measures them precisely).
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from support.sim_bags import FIGURE_EIGHT_90_S, shared_bag

from gnss_ins_common.params import validate_all
from ins_fusion.bags.bag_io import BagReader, BagWriter
from ins_fusion.core.filter.records import GnssFixMeasurement
from ins_fusion.core.settings.config import FusionConfig
from ins_fusion.core.settings.params import PARAMETERS
from ins_fusion.replay.inputs import load_bag
from ins_fusion.replay.outages import Outage, mask
from ins_fusion.replay.pipeline import replay
from ins_fusion.replay.plot import measured, plot_replay, settled_from
from ins_fusion.tools import cli

DURATION_S = FIGURE_EIGHT_90_S.duration_s
OUTAGE = (40.0, 10.0)


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    return shared_bag(tmp_path_factory, "figure_eight_90_s", FIGURE_EIGHT_90_S)


def _replay(capsys, *argv):
    """(exit status, stdout, stderr) of ``gnss_ins replay ARGV``."""
    try:
        code = cli.main(["replay", *map(str, argv)])
    except SystemExit as exc:  # argparse refusals
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def replayed(bag, tmp_path_factory):
    out = tmp_path_factory.mktemp("replay_out")
    paths = {"report": out / "r.json", "plot": out / "p.png", "output": out / "fused"}
    argv = [
        "replay",
        str(bag),
        "--outage",
        f"{OUTAGE[0]:g}:{OUTAGE[1]:g}",
        *(item for key, path in paths.items() for item in (f"--{key}", str(path))),
    ]
    code = cli.main(argv)
    return code, paths, json.loads(paths["report"].read_text())


def test_replay_writes_report_plot_and_fused_bag(replayed):
    code, paths, report = replayed
    assert code == 0
    for key in (
        "imu_samples",
        "duration_s",
        "wall_time_s",
        "realtime_factor",
        "position_error_m",
        "attitude_error_deg",
        "outages",
        "nees",
        "measurements",
    ):
        assert key in report, key
    assert set(report["position_error_m"]) >= {
        "horizontal_rms",
        "vertical_rms",
        "horizontal_p95",
        "horizontal_max",
    }
    assert set(report["attitude_error_deg"]) >= {"roll_rms", "pitch_rms", "yaw_rms"}
    assert set(report["nees"]) >= {"position_mean", "position_within_3sigma_fraction"}
    for part in ("in_outage", "out_of_outage"):
        assert report["nees"][part]["samples"] > 0
    assert report["topics"] == {
        "imu": "/imu/data_raw",
        "fix": "/gnss/fix",
        "vel": "/gnss/vel",
        "attitude": "/gnss/attitude",
    }
    assert report["imu_samples"] == 134 * DURATION_S
    assert report["duration_s"] == pytest.approx(DURATION_S, abs=0.01)
    assert report["realtime_factor"] == pytest.approx(report["duration_s"] / report["wall_time_s"])
    (outage,) = report["outages"]
    assert set(outage) >= {
        "start_s",
        "duration_s",
        "horizontal_error_end_m",
        "horizontal_error_max_m",
        "vertical_error_max_m",
    }
    assert (outage["start_s"], outage["duration_s"]) == OUTAGE
    # 10 s of the 1 Hz Leica fix and velocity and of the 5 Hz ADU5 attitude.
    assert report["dropped_messages"] == {"fix": 10, "vel": 10, "attitude": 50}
    assert report["measurements"]["gnss_position"]["used"] > 40
    assert set(report["measurements"]["gnss_position"]) >= {"used", "rejected"}
    assert paths["plot"].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_replay_accuracy_within_generous_bounds(replayed):
    _, _, report = replayed
    assert report["aligned_at_s"] < 30.0
    assert report["position_error_m"]["horizontal_rms"] < 1.0
    assert report["position_error_m"]["vertical_rms"] < 0.5
    assert report["attitude_error_deg"]["yaw_rms"] < 0.5
    assert report["outages"][0]["horizontal_error_end_m"] < 3.0
    assert 0.5 < report["nees"]["position_mean"] < 10.0
    assert report["nees"]["position_within_3sigma_fraction"] > 0.8


def test_fused_bag_holds_odometry_and_fix_of_base_link(replayed):
    _, paths, report = replayed
    with BagReader(paths["output"]) as reader:
        assert {t: i.msgtype for t, i in reader.topics.items()} == {
            "/ins/odometry": "nav_msgs/msg/Odometry",
            "/ins/fix": "sensor_msgs/msg/NavSatFix",
        }
        assert reader.topics["/ins/odometry"].count == reader.topics["/ins/fix"].count
        odometry = [m.message for m in reader.messages(["/ins/odometry"], deserialize=True)]
        fix = next(reader.messages(["/ins/fix"], deserialize=True)).message
    stamps = np.array([o.header.stamp.sec + o.header.stamp.nanosec * 1e-9 for o in odometry])
    assert len(stamps) > 50 * (DURATION_S - 30.0)
    assert np.median(np.diff(stamps)) == pytest.approx(0.02, abs=0.004)  # output_rate 50 Hz
    odometry = odometry[-1]
    assert (odometry.header.frame_id, odometry.child_frame_id) == ("map", "base_link")
    assert odometry.pose.covariance[0] > 0.0 and odometry.twist.covariance[0] > 0.0
    assert fix.header.frame_id == "base_link"
    assert fix.latitude == pytest.approx(report["datum"][0], abs=1e-3)  # within ~100 m


def test_sweep_ranks_settings_and_applies_overrides(bag, tmp_path, capsys):
    params = tmp_path / "params.yaml"
    params.write_text("ins_fusion_node:\n  ros__parameters:\n    use_zaru: false\n")
    report_path = tmp_path / "sweep.json"
    code, out, _ = _replay(
        capsys,
        bag,
        "--params",
        params,
        "--set",
        "zupt_sigma=0.03",
        "--sweep",
        "use_attitude=true,false",
        "--rank-by",
        "yaw_rms",
        "--outage",
        "40:10",
        "--report",
        report_path,
    )
    assert code == 0
    assert "ranked by yaw_rms" in out
    sweep = json.loads(report_path.read_text())
    assert sweep["rank_by"] == "yaw_rms"
    runs = sweep["runs"]
    assert sorted(run["setting"]["use_attitude"] for run in runs) == [False, True]
    scores = [run["score"] for run in runs]
    assert scores == sorted(scores)
    for run in runs:
        report = run["report"]
        assert scores[runs.index(run)] == report["attitude_error_deg"]["yaw_rms"]
        use_attitude = run["setting"]["use_attitude"]
        assert report["parameters"] == {
            "use_zaru": False,
            "zupt_sigma": 0.03,
            **({} if use_attitude else {"use_attitude": False}),
        }
        assert report["measurements"]["zaru"]["used"] == 0
        assert (report["measurements"]["attitude"]["used"] > 0) == use_attitude


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--topics", "imu=/imu/other"], "no IMU messages on /imu/other"),
        (
            ["--topics", "imu=/gnss/time_reference"],
            "'imu' topic /gnss/time_reference is sensor_msgs/msg/TimeReference, expected"
            " sensor_msgs/msg/Imu",
        ),
        (["--topics", "imu=/gnss/fix"], "topic /gnss/fix is given for more than one role"),
        (
            ["--topics", "fix=/leica/gnss/fix,attitude=/adu5/gnss/attitude"],
            "--topics names fix=/leica/gnss/fix, attitude=/adu5/gnss/attitude, not in the bag",
        ),
        (["--reference", "/truth"], "no reference topic /truth/fix"),
        (["--reference", "/gnss"], "reference topic(s) /gnss/attitude, /gnss/fix, /gnss/vel are"),
        (["--outage", "500:10"], "starts after the IMU data ends"),
        (["--set", "no_such=1"], "unknown parameter 'no_such'"),
        (["--set", "zupt_sigma=-1"], "parameter 'zupt_sigma': -1 is outside"),
        (["--set", "use_nhc=1"], "parameter 'use_nhc': expected bool"),
        (["--outage", "50"], "START:DURATION"),
        (["--outage=-5:20"], "START must be"),
        (["--topics", "imu"], "ROLE=TOPIC"),
        (["--sweep", "use_nhc=true,false", "--plot", "x.png"], "not with --sweep"),
        (["--rank-by", "yaw_rms"], "--rank-by ranks the runs of a --sweep"),
        (["--sweep", "use_nhc=true,false", "--sweep", "use_nhc=false"], "swept twice"),
        (["--set", "calibration_file=/no/such.yaml"], "cannot read calibration file"),
        (["--free-inertial", "500"], "--free-inertial 500 is after the IMU data end"),
        (["--free-inertial", "30", "--outage", "40:5"], "not with --outage or --sweep"),
        (["--free-inertial", "-1"], "START must be a finite number >= 0"),
    ],
)
def test_bad_input_is_refused_with_exit_status_2(bag, capsys, argv, message):
    code, _, err = _replay(capsys, bag, *argv)
    assert code == 2
    assert message in err


def test_free_inertial_withholds_gnss_and_reports_the_drift(bag, tmp_path, capsys):
    """--free-inertial 30: no GNSS message from 30 s on is used, no pseudo-measurement at all,
    and the drift against the withheld fixes 5...180 s later is printed and reported (the bag
    ends 60 s after START: the later times are not bracketed by a fix)."""
    report = tmp_path / "free.json"
    code, out, err = _replay(capsys, bag, "--free-inertial", "30", "--report", report)
    assert code == 0, err
    assert "free-inertial from 30 s (GNSS withheld, no ZUPT/ZARU/NHC)" in out
    data = json.loads(report.read_text())
    section = data["free_inertial"]
    assert section["elapsed_s"] == [5, 10, 15, 20, 30, 40, 50, 60, 120, 180]
    horizontal = section["horizontal_m"]
    assert all(v is not None for v in horizontal[:7]) and horizontal[-2:] == [None, None]
    assert horizontal[0] < horizontal[6]  # the unaided INS drifts
    assert data["dropped_messages"]["fix"] == int(DURATION_S) - 30
    for kind in ("zupt", "zaru", "nhc"):
        assert data["measurements"][kind]["used"] == 0
    assert data["parameters"] == {"use_zupt": False, "use_zaru": False, "use_nhc": False}


def test_missing_or_unreadable_bag_is_refused(tmp_path, capsys):
    code, _, err = _replay(capsys, tmp_path / "nothing")
    assert (code, "no such bag" in err) == (2, True)
    garbage = tmp_path / "garbage.mcap"
    garbage.write_text("not a bag")
    code, _, err = _replay(capsys, garbage)
    assert (code, f"cannot read bag {garbage}" in err) == (2, True)
    empty_dir = tmp_path / "empty"
    empty_dir.mkdir()
    code, _, err = _replay(capsys, empty_dir)
    assert (code, "metadata.yaml" in err) == (2, True)


def test_bad_parameter_file_and_existing_output_are_refused(bag, tmp_path, capsys):
    params = tmp_path / "params.yaml"
    params.write_text("ins_fusion_node:\n  ros__parameters:\n    nhc_sigma: 0.0\n")
    code, _, err = _replay(capsys, bag, "--params", params)
    assert (code, "parameter 'nhc_sigma'" in err) == (2, True)
    code, _, err = _replay(capsys, bag, "--params", tmp_path / "missing.yaml")
    assert (code, "cannot read parameter file" in err) == (2, True)
    code, _, err = _replay(capsys, bag, "--output", tmp_path)
    assert (code, "exists already" in err) == (2, True)
    foreign = tmp_path / "foreign.yaml"
    foreign.write_text("gnss_node:\n  ros__parameters:\n    baud: 9600\n")
    code, _, err = _replay(capsys, bag, "--params", foreign)
    assert code == 2
    assert "has no section for ins_fusion_node (top keys: gnss_node)" in err


def test_outputs_not_written_are_named_with_the_reason(bag, tmp_path, capsys):
    """Without the IMU's first 60 s and GNSS there is no alignment: no plot, no fused bag."""
    plot, fused = tmp_path / "p.png", tmp_path / "fused"
    short = tmp_path / "imu_only"
    with BagReader(bag) as reader, BagWriter(short) as writer:
        writer.add_topic("/imu/data_raw", reader.topics["/imu/data_raw"].msgtype)
        for msg in reader.messages(["/imu/data_raw"]):
            if msg.log_time_ns < reader.start_ns + 3_000_000_000:
                writer.write(msg.topic, msg.log_time_ns, msg.message)
    code, _, err = _replay(capsys, short, "--plot", plot, "--output", fused)
    assert code == 1
    assert f"plot {plot} not written: there is no fused solution" in err
    assert f"fused bag {fused} not written: there is no fused solution" in err
    assert not plot.exists() and not fused.exists()


def _sensors_only(bag, path, seconds):
    """The first ``seconds`` of the bag's sensor topics (no reference) at ``path``."""
    topics = ["/imu/data_raw", "/gnss/fix", "/gnss/vel", "/gnss/attitude"]
    with BagReader(bag) as reader, BagWriter(path) as writer:
        for topic in topics:
            writer.add_topic(topic, reader.topics[topic].msgtype)
        end_ns = reader.start_ns + round(seconds * 1e9)
        for msg in reader.messages(topics):
            if msg.log_time_ns < end_ns:
                writer.write(msg.topic, msg.log_time_ns, msg.message)
    return path


def test_bag_without_reference_is_replayed_without_accuracy(bag, tmp_path, capsys):
    """The first 40 s of the sensor topics only: speed, states and counters, accuracy null."""
    sensors = _sensors_only(bag, tmp_path / "sensors", 40.0)
    report_path, plot_path = tmp_path / "r.json", tmp_path / "p.png"
    code, out, err = _replay(capsys, sensors, "--report", report_path, "--plot", plot_path)
    assert code == 0
    assert "no reference (/ground_truth/fix) in the bag" in err
    assert "accuracy not evaluated" in out
    report = json.loads(report_path.read_text())
    assert report["reference"] is None and report["evaluated_samples"] == 0
    assert set(report["position_error_m"].values()) == {None}
    assert report["nees"]["position_mean"] is None
    assert report["measurements"]["gnss_position"]["used"] > 10
    assert plot_path.read_bytes()[:4] == b"\x89PNG"


def test_plot_without_reference_shows_the_measurements_against_the_fused_solution(bag, tmp_path):
    """Without a reference the plot's panels get the fixes (an outage's withheld ones too) and
    the attitudes minus the fused solution: the withheld fixes show the drift."""
    inputs = load_bag(_sensors_only(bag, tmp_path / "sensors", DURATION_S))
    parameters = validate_all(PARAMETERS, {})
    outage = Outage(*OUTAGE)
    result = replay(inputs, parameters, [outage], None)
    assert result.evaluation is None and result.run.datum is not None
    arm = FusionConfig.from_parameters(parameters).gnss_lever_arm_flu_m
    data = measured(result.run.track, inputs.measurements, result.run.datum, arm, inputs.t0_s)
    track_s = result.run.track.t_s[[0, -1]]
    fixes = [m.t_s for _, _, m in inputs.measurements if isinstance(m, GnssFixMeasurement)]
    assert len(data.fix_t_s) == sum(track_s[0] <= t <= track_s[1] for t in fixes) > 60
    horizontal = np.hypot(data.fix_minus_fused_m[:, 0], data.fix_minus_fused_m[:, 1])
    inside = mask(data.fix_t_s, [outage])
    aided = ~inside & (data.fix_t_s > 15.0)
    assert inside.sum() >= 8 and np.median(horizontal[aided]) < 0.1
    assert horizontal[inside][-1] > 5 * np.median(horizontal[aided])  # the drift is visible
    assert len(data.att_t_s) > 100 and np.median(np.abs(data.att_minus_fused_deg)) < 1.0
    plot = tmp_path / "p.png"
    plot_replay(plot, result.compared_track, inputs.t0_s, None, [outage], "t", None, data)
    assert plot.read_bytes()[:4] == b"\x89PNG"


def test_the_plot_is_scaled_to_the_navigation_not_the_alignment(bag, tmp_path):
    """The alignment's σ spike (degrees) is drawn, clipped; the attitude panels' scale is that of
    the navigation after it (tenths of a degree), errors and ±3σ inside."""
    inputs = load_bag(bag)
    result = replay(inputs, validate_all(PARAMETERS, {}), [], "/ground_truth")
    assert result.evaluation is not None and result.evaluation.attitude is not None
    attitude = result.evaluation.attitude
    figure = plot_replay(
        tmp_path / "p.png", result.compared_track, inputs.t0_s, result.evaluation, [], "t"
    )
    settled = attitude.t_rel_s >= settled_from(attitude.t_rel_s, attitude.sigma)
    assert 0.9 * len(settled) < settled.sum() < len(settled)  # a short transient left out
    for axis, panel in enumerate(figure.axes[4:7]):  # track, E, N, U, roll, pitch, yaw
        low, high = panel.get_ylim()
        bound = 3.0 * attitude.sigma[:, axis]
        if axis > 0:  # the pitch and yaw spikes, clipped
            assert bound.max() > 2.0 * high
        shown = np.concatenate([bound[settled], -bound[settled], attitude.error[settled, axis]])
        assert low <= shown.min() and shown.max() <= high < 1.2 * shown.max()


def test_a_refused_run_names_the_outputs_it_did_not_write(bag, tmp_path, capsys):
    report, plot = tmp_path / "r.json", tmp_path / "p.png"
    topics = "imu=/imu/data_raw,fix=/leica/gnss/fix"
    code, _, err = _replay(capsys, bag, "--topics", topics, "--report", report, "--plot", plot)
    assert code == 2 and "fix=/leica/gnss/fix, not in the bag" in err
    assert f"report {report} not written because of the error" in err
    assert f"plot {plot} not written because of the error" in err
    assert not report.exists() and not plot.exists()
