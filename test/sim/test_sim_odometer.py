"""Odometer error model (ins_fusion/sim/odometer_model.py): scale error, pulse-count
quantisation, slip only under hard braking, seeded noise; the wheel's truth on the vehicle."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ins_fusion.sim.odometer_model import DMI, IDEAL, OdometerModel, OdometerProfile
from ins_fusion.sim.scenarios import SCENARIOS, SURVEY_CAR
from ins_fusion.sim.vehicle import VehicleSetup, VehicleTruth

#: A speed with a known integral: 10 + 3 sin(t/2) m/s, its acceleration at most 1.5 m/s².
OMEGA = 0.5


def _wavy(t):
    return 10.0 + 3.0 * np.sin(OMEGA * t), 3.0 * OMEGA * np.cos(OMEGA * t)


def _wavy_mean(a, b):
    """Exact mean of the wavy speed over [a, b]."""
    return 10.0 + 3.0 * (np.cos(OMEGA * a) - np.cos(OMEGA * b)) / (OMEGA * (b - a))


def _braking(decel):
    """From 30 m/s, decelerating at a constant ``decel`` [m/s²]."""
    return lambda t: (30.0 - decel * t, np.full_like(t, -decel))


def _times(profile: OdometerProfile, seconds: float) -> np.ndarray:
    return np.arange(1, round(seconds * profile.rate_hz) + 1) / profile.rate_hz


@settings(max_examples=30, deadline=None)
@given(scale=st.floats(-0.05, 0.05), rate=st.sampled_from([1.0, 10.0, 20.0, 50.0]))
def test_without_quantisation_noise_or_slip_it_reads_the_scaled_mean_speed(scale, rate):
    profile = dataclasses.replace(IDEAL, scale_error=scale, rate_hz=rate)
    out = OdometerModel(profile, _wavy, seed=1).measure(_times(profile, 12.0))
    expected = _wavy_mean(out.period_start_s, out.t_s)
    np.testing.assert_allclose(out.true_mean_speed_m_s, expected, rtol=1e-12)
    np.testing.assert_allclose(out.speed_m_s, (1.0 + scale) * expected, rtol=1e-12)


@settings(max_examples=30, deadline=None)
@given(
    pulses_per_m=st.floats(1.0, 2000.0),
    rate=st.sampled_from([5.0, 20.0, 50.0]),
    scale=st.floats(-0.03, 0.03),
)
def test_a_pulse_counter_reads_whole_steps_and_keeps_the_distance_to_one_pulse(
    pulses_per_m, rate, scale
):
    profile = dataclasses.replace(
        DMI, pulses_per_m=pulses_per_m, rate_hz=rate, scale_error=scale, noise_sigma_m_s=0.0
    )
    assert profile.step_m_s == pytest.approx(rate / pulses_per_m)
    out = OdometerModel(profile, _wavy, seed=2).measure(_times(profile, 10.0))
    pulses = out.speed_m_s / profile.step_m_s
    np.testing.assert_allclose(pulses, np.round(pulses), atol=1e-6)
    scaled = (1.0 + scale) * out.true_mean_speed_m_s
    assert np.all(np.abs(out.speed_m_s - scaled) < profile.step_m_s * (1 + 1e-9))
    # The errors of the outputs do not add up: the counted distance is within one pulse.
    counted_m = np.sum(out.speed_m_s) / rate
    assert abs(counted_m - np.sum(scaled) / rate) <= 1.0 / pulses_per_m + 1e-9
    # The stated σ holds the quantisation (variance step²/6) when the steps are small.
    if profile.step_m_s < 0.05 and len(error := out.speed_m_s - scaled) >= 100:
        assert np.std(error) == pytest.approx(profile.reported_sigma_m_s, rel=0.35)


@settings(max_examples=40, deadline=None)
@given(decel=st.floats(0.0, 8.0), threshold=st.floats(0.5, 6.0))
def test_slip_only_while_braking_harder_than_the_threshold(decel, threshold):
    profile = dataclasses.replace(
        IDEAL, slip_threshold_m_s2=threshold, slip_per_m_s2=DMI.slip_per_m_s2
    )
    out = OdometerModel(profile, _braking(decel), seed=3).measure(_times(profile, 3.0))
    slip = DMI.slip_per_m_s2 * max(decel - threshold, 0.0)
    np.testing.assert_allclose(out.speed_m_s, (1.0 - slip) * out.true_mean_speed_m_s, rtol=1e-12)
    if decel <= threshold:
        np.testing.assert_array_equal(out.speed_m_s, out.true_mean_speed_m_s)
    # Accelerating as hard never slips.
    ahead = OdometerModel(profile, lambda t: (5.0 + decel * t, np.full_like(t, decel)), seed=3)
    rising = ahead.measure(_times(profile, 3.0))
    np.testing.assert_array_equal(rising.speed_m_s, rising.true_mean_speed_m_s)


def test_slip_saturates_at_a_locked_wheel_and_a_negative_gain_over_reads():
    locked = dataclasses.replace(IDEAL, slip_threshold_m_s2=1.0, slip_per_m_s2=1.0)
    assert np.all(
        OdometerModel(locked, _braking(5.0), 0).measure(_times(locked, 2.0)).speed_m_s == 0
    )
    over = dataclasses.replace(IDEAL, slip_threshold_m_s2=1.0, slip_per_m_s2=-0.1)
    out = OdometerModel(over, _braking(3.0), 0).measure(_times(over, 2.0))
    np.testing.assert_allclose(out.speed_m_s, 1.2 * out.true_mean_speed_m_s, rtol=1e-12)


def test_same_seed_same_outputs_whatever_the_split_other_seed_other_noise():
    times = _times(DMI, 30.0)
    whole = OdometerModel(DMI, _wavy, seed=5).measure(times)
    split = OdometerModel(DMI, _wavy, seed=5)
    parts = [split.measure(part) for part in np.array_split(times, [1, 7, 300, 301])]
    np.testing.assert_array_equal(np.concatenate([p.speed_m_s for p in parts]), whole.speed_m_s)
    other = OdometerModel(DMI, _wavy, seed=6).measure(times)
    assert not np.array_equal(other.speed_m_s, whole.speed_m_s)
    noisy = dataclasses.replace(DMI, pulses_per_m=0.0, noise_sigma_m_s=0.2)
    out = OdometerModel(noisy, _wavy, seed=7).measure(_times(noisy, 600.0))
    error = out.speed_m_s - (1.0 + DMI.scale_error) * out.true_mean_speed_m_s
    assert np.std(error) == pytest.approx(0.2, rel=0.05)
    assert abs(np.mean(error)) < 0.01


def test_times_must_increase_and_profiles_are_checked():
    model = OdometerModel(DMI, _wavy, seed=0)
    model.measure(np.array([0.05, 0.1]))
    with pytest.raises(ValueError, match="increase"):
        model.measure(np.array([0.1]))
    assert len(model.measure(np.array([])).speed_m_s) == 0
    for bad in (
        {"rate_hz": 0.0},
        {"scale_error": -1.0},
        {"pulses_per_m": -1.0},
        {"noise_sigma_m_s": math.nan},
    ):
        with pytest.raises(ValueError, match="odometer dmi"):
            dataclasses.replace(DMI, **bad)


def test_the_wheel_reads_base_link_speed_plus_the_turn_at_its_lever_arm():
    """At base_link (rear-axle centre) the forward speed is the path speed; on the left rear
    hub the wheel turns slower in a left turn and faster in a right turn by ω_z × 0.8 m."""
    trajectory = SCENARIOS["test_pattern"](240.0)
    t = np.linspace(60.0, 239.0, 400)
    speed, accel = trajectory.path_speed(t)
    at_axle = VehicleTruth(trajectory, VehicleSetup()).odometer(t)
    np.testing.assert_allclose(at_axle[0], speed, atol=1e-9)
    np.testing.assert_array_equal(at_axle[1], accel)
    hub = VehicleTruth(trajectory, SURVEY_CAR).odometer(t)[0]
    truth = trajectory.frame_truth(t)
    yaw_rate = truth.rate_flu_rad_s[:, 2]  # ω_ib: earth rate (~6e-5 rad/s) aside, the turn
    pitch_rate = truth.rate_flu_rad_s[:, 1]
    lever = SURVEY_CAR.odometer_flu_m
    np.testing.assert_allclose(hub, speed - yaw_rate * lever[1] + pitch_rate * lever[2], atol=1e-4)
    assert np.max(np.abs(hub - speed)) > 0.2  # the turns of the test pattern show
