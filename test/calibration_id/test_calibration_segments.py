"""Static/steady segment detection, given windows and their checks, the σ of segment means."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ins_fusion.bags.imu import ImuRecord
from ins_fusion.calibration_id import procedures
from ins_fusion.calibration_id.model import Site
from ins_fusion.calibration_id.segments import (
    DetectorSettings,
    Kind,
    SegmentError,
    detect,
    from_window,
    means,
    static_only,
)
from ins_fusion.sim.imu_model import IMU400CC

SITE = Site.at(57.0)
SETTINGS = DetectorSettings()


@pytest.fixture(scope="module")
def six():
    """Six 30-s positions joined by 5-s turns (position k held from 35 k to 35 k + 30 s)."""
    record, _ = procedures.simulate(procedures.six_position(30.0, 5.0), IMU400CC, SITE, 11)
    return record


def test_detects_each_position_inside_its_hold(six):
    segments = detect(six, 0, SETTINGS)
    assert len(segments) == 6
    for k, s in enumerate(segments):
        start, end = s.t_start_s - six.t_s[0], s.t_end_s - six.t_s[0]
        hold_start, hold_end = 35.0 * k, 35.0 * k + 30.0
        assert s.kind is Kind.STATIC
        assert hold_start <= start < hold_start + 3.0, (k, start)  # trim 1 s + half window
        assert hold_end - 3.0 < end <= hold_end, (k, end)
        assert s.where.startswith("bag 1, ")


def test_short_holds_are_not_segments(six):
    segments = detect(six, 0, DetectorSettings(min_duration_s=40.0))
    assert segments == []


def test_rotation_at_constant_rate_is_a_rotation_segment():
    steps = procedures.turn_table(2.0 * math.pi, math.radians(10.0), 15.0)[:3]
    record, _ = procedures.simulate(steps, IMU400CC, SITE, 12)
    kinds = [s.kind for s in detect(record, 0, SETTINGS)]
    assert kinds == [Kind.STATIC, Kind.ROTATION, Kind.STATIC]


def test_given_window_inside_a_hold(six):
    segment = from_window(six, 0, 40.0, 60.0, SETTINGS)
    assert segment.kind is Kind.STATIC
    assert segment.duration_s == pytest.approx(20.0, abs=0.02)
    assert segment.means.force_m_s2[2] < -9.5  # the second position: -z up


def test_moving_data_given_as_static_is_refused(six):
    with pytest.raises(SegmentError, match="not static or steady"):
        from_window(six, 0, 20.0, 45.0, SETTINGS)  # the first turn is at 30-35 s


def test_too_short_and_outside_windows_are_refused(six):
    with pytest.raises(SegmentError, match="shorter than the minimum 10 s"):
        from_window(six, 0, 40.0, 45.0, SETTINGS)
    with pytest.raises(SegmentError, match="no samples"):
        from_window(six, 0, 500.0, 520.0, SETTINGS)


def test_static_only_names_a_rotating_segment():
    steps = procedures.turn_table(2.0 * math.pi, math.radians(10.0), 15.0)[:3]
    record, _ = procedures.simulate(steps, IMU400CC, SITE, 12)
    with pytest.raises(SegmentError, match="rotates at 10"):
        static_only(detect(record, 0, SETTINGS), "six-position")


def test_sigma_of_the_mean_matches_white_and_coloured_noise():
    """Batch means: white noise gives σ/√n; noise correlated over 10 samples (a moving
    average) gives a σ of the mean √10 times larger at the same per-sample σ. Each σ comes
    from 30 blocks (±13 %); the mean over six axes (force and rate) is checked."""
    rng = np.random.default_rng(0)
    n, rate = 100_000, 100.0
    t = np.arange(n) / rate
    white = rng.standard_normal((n, 6))
    kernel = np.ones(10) / math.sqrt(10.0)
    coloured = np.stack([np.convolve(white[:, i], kernel, "same") for i in range(6)], axis=1)
    for noise, expected in ((white, 1.0 / math.sqrt(n)), (coloured, math.sqrt(10.0 / n))):
        record = ImuRecord(t, noise[:, 3:], noise[:, :3], name="noise")
        m = means(record, 0, n)
        sigma = np.concatenate((m.force_sigma_m_s2, m.rate_sigma_rad_s))
        assert np.mean(sigma) == pytest.approx(expected, rel=0.2)
