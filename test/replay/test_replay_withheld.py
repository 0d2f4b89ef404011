"""Outages scored against the GNSS fixes they withheld (ins_fusion.replay.withheld).

Hand-computed antenna, lever-arm covariance and NEES on synthetic solutions; then
`gnss_ins replay` on a 50 s simulated figure-eight (10 s standstill, then 10 m/s; Leica RTK at
1 Hz, ADU5) with and without its /ground_truth topics.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from support.solutions import solution as metrics_solution

from ins_fusion.bags.bag_io import BagReader, BagWriter
from ins_fusion.core.filter.records import GnssFixMeasurement
from ins_fusion.core.nav import earth
from ins_fusion.replay.frames import lever_arm_covariance, moved_track
from ins_fusion.replay.outages import Outage
from ins_fusion.replay.ranking import RANK_METRICS
from ins_fusion.replay.run import SolutionTrack
from ins_fusion.replay.withheld import evaluate_withheld, withheld_stats
from ins_fusion.sim.drive import SimulationConfig
from ins_fusion.sim.simulated_bag import write_bag
from ins_fusion.tools import cli

DATUM = (57.0, 10.0, 40.0)
T0 = 1000.0
YAW_90 = Rotation.from_euler("ZYX", [90.0, 0.0, 0.0], degrees=True).as_quat()
LEVER_ARM = (0.5, 0.2, 1.5)  # base_link FLU [m]
FIX_COV = np.diag([0.01, 0.01, 0.04])


def _solution(t, cov_att):
    """A base_link solution at (10, 20, 1) m ENU facing east (test_replay_metrics' builder)."""
    return metrics_solution(
        t, (10.0, 20.0, 1.0), quat=YAW_90, cov_pos=np.diag([0.04, 0.04, 0.09]), cov_att=cov_att
    )


def _fix(t, enu, valid=True):
    lat, lon, h = earth.enu_to_geodetic(np.asarray(enu, float), *np.radians(DATUM[:2]), DATUM[2])
    return GnssFixMeasurement(
        t, math.degrees(float(lat)), math.degrees(float(lon)), float(h), FIX_COV, valid
    )


def test_antenna_is_base_link_plus_rotated_lever_arm_with_its_attitude_covariance():
    """Heading north (yaw 90°): forward 0.5 -> north, left 0.2 -> west, up 1.5 -> up."""
    cov_att = np.diag([0.0, 0.0, 1e-4])  # yaw only: ψ × a = ψ (-a_N, a_E, 0)
    track = SolutionTrack.from_solutions([_solution(T0 + 10.0, cov_att)])
    antenna = moved_track(track, LEVER_ARM)
    assert antenna.pos_enu_m[0] == pytest.approx([9.8, 20.5, 2.5], abs=1e-12)
    # a = (-0.2, 0.5, 1.5): displacement ψ (-0.5, -0.2, 0) -> σψ² [[0.25, 0.1], [0.1, 0.04]]
    expected = np.diag([0.04, 0.04, 0.09])
    expected[:2, :2] += 1e-4 * np.array([[0.25, 0.1], [0.1, 0.04]])
    assert antenna.cov_pos_enu_m2[0] == pytest.approx(expected, abs=1e-15)
    assert lever_arm_covariance(np.eye(3)[None], np.array([[1.0, 0.0, 0.0]]))[0] == pytest.approx(
        np.diag([0.0, 1.0, 1.0])
    )
    # The orientation and velocity of a point without rotation or rate are base_link's.
    assert antenna.quat_enu_flu_xyzw[0] == pytest.approx(YAW_90)
    assert antenna.vel_enu_m_s[0] == pytest.approx(np.zeros(3))


def test_withheld_fix_errors_and_nees_by_hand():
    cov_att = np.zeros((3, 3))  # P_filter = P_pos, S = diag(0.05, 0.05, 0.13)
    track = SolutionTrack.from_solutions(
        [_solution(T0 + t, cov_att) for t in np.arange(9.0, 16.0, 0.5)]
    )
    antenna = np.array([9.8, 20.5, 2.5])
    fixes = [
        _fix(T0 + 10.2, antenna - [-0.3, 0.4, -0.2]),  # e = (-0.3, 0.4, -0.2): inside 3σ
        _fix(T0 + 11.0, antenna, valid=False),  # withheld, not compared
        _fix(T0 + 12.7, antenna - [1.0, 0.0, 0.0]),  # e = (1, 0, 0): 1 > 3 sqrt(0.05)
        _fix(T0 + 30.0, antenna),  # after the track: not compared
    ]
    evaluation = evaluate_withheld(track, fixes, DATUM, T0, LEVER_ARM, max_gap_s=1.0)
    assert evaluation.errors.error == pytest.approx(
        np.array([[-0.3, 0.4, -0.2], [1.0, 0.0, 0.0]]), abs=1e-6
    )
    stats = withheld_stats(evaluation, Outage(10.0, 5.0))
    nees_1 = 0.09 / 0.05 + 0.16 / 0.05 + 0.04 / 0.13
    assert stats["withheld_fixes"] == 3 and stats["evaluated_fixes"] == 2
    assert stats["horizontal_error_end_m"] == pytest.approx(1.0, abs=1e-6)
    assert stats["horizontal_error_max_m"] == pytest.approx(1.0, abs=1e-6)
    assert stats["vertical_error_max_m"] == pytest.approx(0.2, abs=1e-6)
    assert stats["horizontal_sigma_end_m"] == pytest.approx(math.sqrt(0.08))
    assert stats["nees"] == {
        "dof": 3,
        "mean": pytest.approx((nees_1 + 1.0 / 0.05) / 2.0, rel=1e-5),
        "within_3sigma_fraction": 0.5,
        "samples": 2,
    }
    late = withheld_stats(evaluation, Outage(20.0, 15.0))
    assert (late["withheld_fixes"], late["evaluated_fixes"]) == (1, 0)
    assert late["horizontal_error_end_m"] is None and late["nees"]["mean"] is None


def test_rank_by_withheld_drift_needs_no_reference():
    report = {
        "outages": [{"horizontal_error_end_m": None, "horizontal_error_max_m": None}],
        "withheld_fixes": [
            {"horizontal_error_end_m": 2.0, "horizontal_error_max_m": 2.5},
            {"horizontal_error_end_m": 3.0, "horizontal_error_max_m": 3.5},
        ],
    }
    assert RANK_METRICS["withheld_end_max"][0](report) == 3.0
    assert RANK_METRICS["withheld_max"][0](report) == 3.5
    assert RANK_METRICS["outage_end_max"][0](report) is None
    assert RANK_METRICS["withheld_end_max"][0]({"withheld_fixes": []}) is None


# --------------------------------------------------------------------------------------------
# gnss_ins replay end to end
# --------------------------------------------------------------------------------------------

OUTAGE = "25:10"


@pytest.fixture(scope="module")
def bags(tmp_path_factory):
    """(with reference, sensors only) of one 50 s simulated drive."""
    root = tmp_path_factory.mktemp("withheld")
    full, sensors = root / "full", root / "sensors"
    write_bag(SimulationConfig(scenario="figure_eight", duration_s=50.0, seed=5), full)
    topics = ["/imu/data_raw", "/gnss/fix", "/gnss/vel", "/gnss/attitude"]
    with BagReader(full) as reader, BagWriter(sensors) as writer:
        for topic in topics:
            writer.add_topic(topic, reader.topics[topic].msgtype)
        for msg in reader.messages(topics):
            writer.write(msg.topic, msg.log_time_ns, msg.message)
    return full, sensors


def _replay(capsys, tmp_path, bag, *argv):
    path = tmp_path / f"{bag.name}.json"
    code = cli.main(["replay", str(bag), "--report", str(path), *map(str, argv)])
    out, err = capsys.readouterr()
    assert code == 0, err
    return json.loads(path.read_text()), out, err


def test_bag_without_reference_is_scored_against_the_withheld_fixes(bags, tmp_path, capsys):
    _, sensors = bags
    report, out, err = _replay(capsys, tmp_path, sensors, "--outage", OUTAGE)
    assert report["reference"] is None and report["outages"][0]["horizontal_error_end_m"] is None
    (row,) = report["withheld_fixes"]
    assert (row["start_s"], row["duration_s"]) == (25.0, 10.0)
    assert row["withheld_fixes"] == report["dropped_messages"]["fix"] >= 9
    assert row["evaluated_fixes"] == row["withheld_fixes"]
    for key in ("horizontal_error_end_m", "horizontal_sigma_end_m", "horizontal_error_max_m"):
        assert math.isfinite(row[key]), key
    assert 0.0 <= row["horizontal_error_end_m"] <= row["horizontal_error_max_m"] < 5.0
    assert row["nees"]["samples"] == row["evaluated_fixes"]
    assert 0.0 < row["nees"]["mean"] < 50.0
    assert "withheld GNSS fixes" in err
    assert "accuracy not evaluated (withheld fixes below)" in out
    assert "withheld fixes (fused antenna - fix" in out


def test_withheld_drift_agrees_with_the_reference(bags, tmp_path, capsys):
    """With a reference both are reported; RTK fixes (cm) and base_link vs antenna (a lever
    arm rotated by a small attitude error) differ little."""
    full, _ = bags
    report, out, _ = _replay(capsys, tmp_path, full, "--outage", OUTAGE)
    (reference,), (withheld,) = report["outages"], report["withheld_fixes"]
    assert withheld["evaluated_fixes"] == report["dropped_messages"]["fix"]
    for key in ("horizontal_error_end_m", "horizontal_error_max_m"):
        assert withheld[key] == pytest.approx(reference[key], abs=0.2), key
    assert "outage  start s" in out and "withheld fixes" in out


def test_sweep_ranks_by_withheld_drift_without_reference(bags, tmp_path, capsys):
    _, sensors = bags
    path = tmp_path / "sweep.json"
    argv = ["replay", str(sensors), "--outage", OUTAGE, "--report", str(path)]
    argv += ["--sweep", "use_nhc=true,false", "--rank-by", "withheld_end_max", "--workers", "1"]
    assert cli.main(argv) == 0
    out, _ = capsys.readouterr()
    assert "ranked by withheld_end_max" in out
    runs = json.loads(path.read_text())["runs"]
    scores = [run["score"] for run in runs]
    assert len(scores) == 2 and all(s is not None for s in scores) and scores == sorted(scores)
    assert scores == [r["report"]["withheld_fixes"][0]["horizontal_error_end_m"] for r in runs]
