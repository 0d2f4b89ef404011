"""ins_fusion.replay metrics and outages on synthetic solutions with known errors (exact)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from support.solutions import quaternion, solution

from ins_fusion.core.nav import earth
from ins_fusion.replay import metrics
from ins_fusion.replay.inputs import Reference, Series
from ins_fusion.replay.outages import Outage, mask, parse_outage
from ins_fusion.replay.report import smoothed_report, to_json
from ins_fusion.replay.run import SolutionTrack

DATUM = (57.0, 10.0, 40.0)
T0 = 1000.0


def _reference(t_s, pos_enu, quats=None):
    """Reference series at stamps t_s from ENU positions in the map frame at DATUM."""
    pos = np.asarray(pos_enu, dtype=float)
    lat, lon, h = earth.enu_to_geodetic(pos, *np.radians(DATUM[:2]), DATUM[2])
    position = Series(
        np.asarray(t_s, float), np.column_stack([np.degrees(lat), np.degrees(lon), h])
    )
    attitude = None if quats is None else Series(np.asarray(t_s, float), np.asarray(quats))
    return Reference(position, attitude, None)


def evaluation_track(solutions):
    return SolutionTrack.from_solutions(solutions)


def _evaluate(solutions, reference, outages=(), max_gap_s=1.5):
    return metrics.evaluate(evaluation_track(solutions), reference, DATUM, T0, outages, max_gap_s)


def test_position_statistics_of_known_errors():
    truth = np.array([[float(k), 2.0 * k, 0.5 * k] for k in range(5)])
    error = np.array([[0, 0, 0], [3, 4, 1], [0, 5, -1], [6, 8, 2], [1, 0, -0.5]], dtype=float)
    stamps = T0 + np.arange(5.0)
    solutions = [solution(t, p + e) for t, p, e in zip(stamps, truth, error, strict=True)]
    evaluation = _evaluate(solutions, _reference(stamps, truth))
    np.testing.assert_allclose(evaluation.position.error, error, atol=1e-6)
    np.testing.assert_allclose(evaluation.position.t_rel_s, np.arange(5.0))
    stats = metrics.position_stats(evaluation.position)
    # horizontal errors 0, 5, 5, 10, 1; p95 interpolates between the sorted 5 and 10 at 3.8.
    assert stats["horizontal_rms"] == pytest.approx(math.sqrt(151.0 / 5.0), abs=1e-6)
    assert stats["vertical_rms"] == pytest.approx(math.sqrt(6.25 / 5.0), abs=1e-6)
    assert stats["horizontal_p95"] == pytest.approx(9.0, abs=1e-6)
    assert stats["horizontal_max"] == pytest.approx(10.0, abs=1e-6)
    assert stats["horizontal_final"] == pytest.approx(1.0, abs=1e-6)
    assert stats["vertical_final"] == pytest.approx(-0.5, abs=1e-6)


def test_interpolation_is_exact_for_linear_motion_and_a_steady_turn():
    def pose(t):
        return np.array([10.0 * t, 5.0 * t, 0.1 * t]), quaternion(roll=1.0, yaw=30.0 * t)

    solutions = [solution(T0 + t, *pose(t)) for t in (0.0, 1.0, 2.0)]
    t_ref = np.array([0.25, 0.5, 1.0, 1.75])
    truth = [pose(t) for t in t_ref]
    reference = _reference(T0 + t_ref, [p for p, _ in truth], [q for _, q in truth])
    evaluation = _evaluate(solutions, reference)
    assert evaluation.attitude is not None
    np.testing.assert_allclose(evaluation.position.error, 0.0, atol=1e-6)
    np.testing.assert_allclose(evaluation.attitude.error, 0.0, atol=1e-9)
    np.testing.assert_allclose(evaluation.reference_enu_m, [p for p, _ in truth], atol=1e-6)


def test_only_stamps_between_close_aligned_solutions_are_evaluated():
    solutions = [
        solution(T0 + 0.0, [0, 0, 0], state="aligning"),
        solution(T0 + 1.0, [0, 0, 0]),
        solution(T0 + 2.0, [0, 0, 0]),
        solution(T0 + 5.0, [0, 0, 0]),
        solution(T0 + 6.0, [0, 0, 0]),
    ]
    t_ref = np.array([-1.0, 0.5, 1.5, 3.0, 5.5, 7.0])  # before, aligning, ok, gap, ok, after
    evaluation = _evaluate(solutions, _reference(T0 + t_ref, np.zeros((6, 3))))
    np.testing.assert_allclose(evaluation.position.t_rel_s, [1.5, 5.5])


def test_attitude_errors_are_wrapped_roll_pitch_yaw_differences():
    truth = quaternion(roll=0.0, pitch=0.0, yaw=179.5)
    estimate = quaternion(roll=0.5, pitch=-0.25, yaw=-179.5)
    solutions = [solution(T0 + t, [0, 0, 0], estimate) for t in (0.0, 1.0)]
    reference = _reference([T0 + 0.5], [[0, 0, 0]], [truth])
    evaluation = _evaluate(solutions, reference)
    assert evaluation.attitude is not None
    np.testing.assert_allclose(evaluation.attitude.error, [[0.5, -0.25, 1.0]], atol=1e-9)
    stats = metrics.attitude_stats(evaluation.attitude)
    assert stats["yaw_rms"] == pytest.approx(1.0, abs=1e-9)
    assert stats["roll_rms"] == pytest.approx(0.5, abs=1e-9)


def test_rpy_covariance_follows_the_heading():
    # Heading north (ENU yaw 90°): forward = N, left = -E.
    cov = metrics.rpy_covariance(np.diag([1e-4, 4e-4, 9e-4])[None], np.array([90.0]))
    deg2 = math.degrees(1.0) ** 2
    np.testing.assert_allclose(np.diag(cov[0]), np.array([4e-4, 1e-4, 9e-4]) * deg2, rtol=1e-12)


def _errors(error, cov, t=None, in_outage=None):
    n = len(error)
    return metrics.Errors(
        np.arange(float(n)) if t is None else np.asarray(t, float),
        np.asarray(error, float),
        np.asarray(cov, float),
        np.zeros(n, bool) if in_outage is None else np.asarray(in_outage),
    )


def test_nees_and_3sigma_fraction_of_a_constructed_case():
    full = [[2.0, 1.0, 0.0], [1.0, 2.0, 0.0], [0.0, 0.0, 1.0]]
    errors = _errors(
        [[1, 2, 0], [0, 0, 3], [1, 1, 0], [0, 3.01, 0]],
        [np.diag([1.0, 4.0, 1.0]), np.eye(3), full, np.eye(3)],
        in_outage=[True, True, False, False],
    )
    # 1 + 1; 9 (on the 3σ bound: inside); (1, 1) [[2, 1], [1, 2]]^-1 (1, 1) = 2/3; 3.01².
    expected = [2.0, 9.0, 2.0 / 3.0, 3.01**2]
    np.testing.assert_allclose(metrics.nees(errors), expected, rtol=1e-12)
    np.testing.assert_array_equal(metrics.within_3sigma(errors), [True, True, True, False])
    stats = metrics.consistency_stats(errors)
    assert stats["mean"] == pytest.approx(np.mean(expected), rel=1e-12)
    assert stats["within_3sigma_fraction"] == 0.75
    assert stats["axis_within_3sigma_fraction"] == [1.0, 0.75, 1.0]
    inside = metrics.consistency_stats(errors, errors.in_outage)
    assert inside == {
        "mean": pytest.approx(5.5),
        "within_3sigma_fraction": 1.0,
        "axis_within_3sigma_fraction": [1.0, 1.0, 1.0],
        "samples": 2,
    }
    empty = metrics.consistency_stats(errors, np.zeros(4, bool))
    assert empty == {
        "mean": None,
        "within_3sigma_fraction": None,
        "axis_within_3sigma_fraction": [None, None, None],
        "samples": 0,
    }


def test_attitude_nees_is_that_of_the_small_rotation_about_the_enu_axes():
    # Level truth heading 30° (ENU yaw); the estimate turned by δθ about the ENU axes (R_est =
    # exp([δθ×]) R_true, as the engine injects its attitude error) with the attitude covariance
    # P about the ENU axes: the NEES is δθᵀ P⁻¹ δθ (to first order in δθ: rtol 1e-3 at 1e-4 rad).
    truth = Rotation.from_quat(quaternion(yaw=30.0))
    P = np.array([[1.0, 0.3, 0.1], [0.3, 2.0, -0.2], [0.1, -0.2, 0.5]]) * 1e-8
    turns = np.array([[1.0, -2.0, 0.5], [0.0, 0.0, 4.0], [0.0, 0.0, 0.0]]) * 1e-4
    stamps = T0 + np.arange(3.0)
    solutions = [
        solution(t, [0, 0, 0], (Rotation.from_rotvec(d) * truth).as_quat(), cov_att=P)
        for t, d in zip(stamps, turns, strict=True)
    ]
    reference = _reference(stamps, np.zeros((3, 3)), [truth.as_quat()] * 3)
    evaluation = _evaluate(solutions, reference, outages=[Outage(0.5, 2.0)])
    assert evaluation.attitude is not None
    closed_form = np.einsum("ij,jk,ik->i", turns, np.linalg.inv(P), turns)
    np.testing.assert_allclose(metrics.nees(evaluation.attitude), closed_form, rtol=1e-3)
    # The second stamp's yaw error is 4e-4 rad against σ_yaw = sqrt(0.5e-8) = 0.71e-4: outside.
    nees = smoothed_report(evaluation_track(solutions), 0.0, evaluation, [Outage(0.5, 2.0)], None)[
        "nees"
    ]
    assert nees["dof"] == 3 and nees["attitude_samples"] == 3
    assert nees["attitude_mean"] == pytest.approx(closed_form.mean(), rel=1e-3)
    assert nees["yaw_within_3sigma_fraction"] == pytest.approx(2.0 / 3.0)
    assert nees["attitude_within_3sigma_fraction"] == pytest.approx(2.0 / 3.0)
    assert nees["in_outage"]["attitude_mean"] == pytest.approx(closed_form[1:].mean(), rel=1e-3)
    assert nees["in_outage"]["yaw_within_3sigma_fraction"] == 0.5
    assert nees["out_of_outage"]["attitude_mean"] == pytest.approx(closed_form[0], rel=1e-3)
    assert nees["out_of_outage"]["yaw_within_3sigma_fraction"] == 1.0


def test_without_an_attitude_reference_the_attitude_nees_is_none():
    stamps = T0 + np.arange(3.0)
    solutions = [solution(t, [0, 0, 0]) for t in stamps]
    evaluation = _evaluate(solutions, _reference(stamps, np.zeros((3, 3))))
    nees = smoothed_report(evaluation_track(solutions), 0.0, evaluation, [], None)["nees"]
    assert nees["samples"] == 3 and nees["position_mean"] is not None
    assert nees["attitude_mean"] is None and nees["yaw_within_3sigma_fraction"] is None
    assert nees["attitude_samples"] == 0


def test_outage_statistics_take_the_stamps_inside_the_window():
    t = np.arange(11.0)
    error = np.column_stack([t, np.zeros(11), -t / 10.0])
    cov = np.array([np.diag([k, 2.0 * k, 1.0]) for k in t])
    errors = _errors(error, cov, t)
    stats = metrics.outage_stats(errors, Outage(2.0, 3.0))  # stamps 2, 3, 4; not 5
    assert stats == {
        "start_s": 2.0,
        "duration_s": 3.0,
        "horizontal_error_end_m": 4.0,
        "horizontal_sigma_end_m": pytest.approx(math.sqrt(12.0)),
        "horizontal_error_max_m": 4.0,
        "vertical_error_max_m": pytest.approx(0.4),
    }
    assert metrics.outage_stats(errors, Outage(9.5, 5.0))["horizontal_error_end_m"] == 10.0
    beyond = metrics.outage_stats(errors, Outage(20.0, 1.0))
    assert beyond["horizontal_error_end_m"] is None and beyond["vertical_error_max_m"] is None


def test_outage_windows_include_their_start_and_exclude_their_end():
    outages = [Outage(2.0, 3.0), Outage(10.0, 0.5)]
    t = np.array([1.999, 2.0, 4.999, 5.0, 10.0, 10.25, 10.5])
    np.testing.assert_array_equal(mask(t, outages), [0, 1, 1, 0, 1, 1, 0])


def test_parse_outage():
    assert parse_outage("50:20") == Outage(50.0, 20.0)
    assert parse_outage("0.5:1e1") == Outage(0.5, 10.0)
    for bad, reason in [
        ("50", "START:DURATION"),
        ("50:20:1", "START:DURATION"),
        ("a:20", "numbers"),
        ("-1:20", "START"),
        ("5:0", "DURATION"),
        ("5:nan", "DURATION"),
    ]:
        with pytest.raises(ValueError, match=reason):
            parse_outage(bad)


def test_report_json_is_strict():
    text = to_json({"a": math.nan, "b": [np.float64(1.5), math.inf], "c": {"d": np.int64(2)}})
    assert json.loads(text) == {"a": None, "b": [1.5, None], "c": {"d": 2}}
    assert "NaN" not in text and "Infinity" not in text
