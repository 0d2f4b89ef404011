"""IMU error model and sensor profiles."""

from __future__ import annotations

import dataclasses
import math

import allantools
import numpy as np
import pytest
from scipy.optimize import least_squares

from ins_fusion.core.nav import units
from ins_fusion.sim.imu_model import (
    IDEAL,
    IMU400CC,
    L3G4200D_LIS331DLH,
    PROFILES,
    STIM300,
    ImuErrorModel,
    TriadErrors,
)
from ins_fusion.sim.noise import allan_variance

G = 9.81


def _static(n: int) -> tuple[np.ndarray, np.ndarray]:
    return np.zeros((n, 3)), np.tile([0.0, 0.0, G], (n, 1))


def test_unit_conversions_match_oslo_notes():
    # Oslo notes "Implications" R1.
    arw = units.deg_sqrt_h(0.15)
    assert arw == pytest.approx(4.363e-5, rel=1e-3)
    assert arw * math.sqrt(500.0) == pytest.approx(9.757e-4, rel=1e-3)
    assert units.m_s_sqrt_h(0.07) * math.sqrt(500.0) == pytest.approx(0.0261, rel=1e-3)
    assert units.deg_h(0.5) == pytest.approx(2.424e-6, rel=1e-3)
    assert units.mg(0.05) == pytest.approx(4.903e-4, rel=1e-3)
    assert units.to_deg_sqrt_h(arw) == pytest.approx(0.15)
    assert units.to_m_s_sqrt_h(units.m_s_sqrt_h(0.07)) == pytest.approx(0.07)


def test_profiles_store_the_reference_densities():
    assert set(PROFILES) == {"imu400cc", "stim300", "l3g4200d_lis331dlh", "ideal"}
    # Oslo notes §4.3-4.4: 0.1014 deg/sqrt(h), 0.0482 m/s/sqrt(h), B = 0.581 deg/h.
    assert units.to_deg_sqrt_h(STIM300.gyro.noise_density[0]) == pytest.approx(0.1014, rel=1e-3)
    assert units.to_m_s_sqrt_h(STIM300.accel.noise_density[0]) == pytest.approx(0.0482, rel=1e-3)
    assert units.to_deg_h(STIM300.gyro.bias_instability[0]) == pytest.approx(0.581, rel=1e-3)
    # Aalborg notes (5.21): RW = 2.98 deg/sqrt(h) from the mean σ 0.248 deg/s; the per-axis σ
    # of (7.14) average 0.2464 deg/s, hence 2.956.
    mean_arw = np.mean([units.to_deg_sqrt_h(n) for n in IMU400CC.gyro.noise_density])
    assert mean_arw == pytest.approx(2.98, abs=0.03)
    # NTNU notes Table 4.4: bench variance at 50 Hz is the per-sample variance.
    per_sample = np.array(L3G4200D_LIS331DLH.gyro.noise_density) * math.sqrt(50.0)
    assert per_sample**2 == pytest.approx([7.02e-6, 5.14e-6, 7.36e-6])


def test_ideal_profile_returns_the_truth():
    rng = np.random.default_rng(0)
    t = np.arange(100) / 134.0
    rate, force = rng.normal(size=(100, 3)), rng.normal(size=(100, 3))
    measured_rate, measured_force = ImuErrorModel(IDEAL, seed=1).apply(t, rate, force)
    assert np.array_equal(measured_rate, rate)
    assert np.array_equal(measured_force, force)


def test_same_seed_same_record_whatever_the_block_size():
    t = np.arange(2000) / 134.0
    rate, force = _static(2000)
    whole = ImuErrorModel(IMU400CC, seed=7).apply(t, rate, force)
    model = ImuErrorModel(IMU400CC, seed=7)
    parts = [model.apply(t[a:b], rate[a:b], force[a:b]) for a, b in ((0, 1), (1, 700), (700, 2000))]
    assert np.array_equal(np.concatenate([p[0] for p in parts]), whole[0])
    assert np.array_equal(np.concatenate([p[1] for p in parts]), whole[1])
    other = ImuErrorModel(IMU400CC, seed=8).apply(t, rate, force)
    assert not np.array_equal(other[0], whole[0])


def test_deterministic_errors_follow_the_observation_equation():
    gyro = TriadErrors(
        bias=(0.01, -0.02, 0.03),
        scale_pos=(0.01, 0.02, 0.03),
        scale_neg=(-0.01, -0.02, -0.03),
        misalignment_rad=((0.0, 1e-3, -2e-3), (3e-3, 0.0, 0.0), (0.0, 0.0, 0.0)),
    )
    g_sens = ((0.0, 0.0, 1e-3), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    profile = dataclasses.replace(IDEAL, gyro=gyro, gyro_g_sensitivity=g_sens)
    rate = np.array([[0.5, -0.5, 0.2], [-0.5, 0.5, -0.2]])
    force = np.array([[0.0, 0.0, G], [0.0, 0.0, G]])
    measured, _ = ImuErrorModel(profile, seed=0).apply(np.array([0.0, 0.01]), rate, force)
    expected_first = [
        0.5 * 1.01 + 1e-3 * -0.5 - 2e-3 * 0.2 + 0.01 + 1e-3 * G,
        -0.5 * 0.98 + 3e-3 * 0.5 - 0.02,
        0.2 * 1.03 + 0.03,
    ]
    assert measured[0] == pytest.approx(expected_first, abs=1e-15)
    assert measured[1, 0] == pytest.approx(-0.5 * 0.99 + 1e-3 * 0.5 + 2e-3 * 0.2 + 0.01 + 1e-3 * G)


def test_imu400cc_accelerometer_scale_depends_on_the_input_size():
    """Aalborg report §9.1.1: the scale by input size. The x accelerometer's scale error is
    +0.0652 % at +0.2 g and +0.0172 % at -0.2 g (S1 mod, Fig. 5-33) but -0.2953 % at ±1 g (S2,
    Fig. 5-35); z: -0.0202 % at +0.2 g, -0.0002 % at 1 g."""
    accel = dataclasses.replace(
        IDEAL.accel,
        **{
            k: getattr(IMU400CC.accel, k)
            for k in ("scale_pos", "scale_neg", "scale_large_pos", "scale_large_neg", "large_input")
        },
    )
    profile = dataclasses.replace(IDEAL, accel=accel)
    inputs_g = np.array([1.0, -1.0, 0.2, -0.2])
    force = np.zeros((4, 3))
    force[:, 0] = force[:, 2] = inputs_g * G
    _, measured = ImuErrorModel(profile, seed=0).apply(np.arange(4) * 0.01, np.zeros((4, 3)), force)
    scale_percent = (measured[:, [0, 2]] / force[:, [0, 2]] - 1.0) * 100.0
    # imu_link x reads minus device x (axis map x, accelerometer sign -1): a FLU input of +0.2 g
    # is a device input of -0.2 g and takes the device's negative-input value, and vice versa;
    # imu_link z reads device z (map -z, sign -1).
    assert scale_percent[:, 0] == pytest.approx([-0.2953, -0.2953, 0.0172, 0.0652], abs=1e-12)
    assert scale_percent[:, 1] == pytest.approx([-0.0002, -0.0002, -0.0202, 0.0846], abs=1e-12)


def test_quantisation_and_saturation_of_the_imu400cc():
    t = np.arange(3) / 134.0
    rate = np.array([[0.0, 0.0, math.radians(400.0)]] * 3)
    force = np.array([[0.0, 0.0, 5 * G]] * 3)
    measured_rate, measured_force = ImuErrorModel(IMU400CC, seed=0).apply(t, rate, force)
    assert measured_rate[:, 2] == pytest.approx(math.radians(150.0))
    assert measured_force[:, 2] == pytest.approx(units.mg(3000.0))
    counts = measured_rate / IMU400CC.gyro.resolution
    assert counts == pytest.approx(np.round(counts), abs=1e-6)


def test_ntnu_gyro_wraps_sign_above_32_deg_s():
    # NTNU notes §11: above about 0.6 rad/s the gyros report the opposite sign.
    t = np.arange(2) / 50.0
    rate = np.array([[0.0, 0.0, 0.5], [0.0, 0.0, 0.7]])
    measured, _ = ImuErrorModel(L3G4200D_LIS331DLH, seed=0).apply(t, rate, _static(2)[1])
    assert measured[0, 2] == pytest.approx(0.5, abs=0.02)
    assert measured[1, 2] == pytest.approx(0.7 - 2 * math.radians(32.768), abs=0.02)
    assert measured[1, 2] < 0.0


def _fit_allan(
    x: np.ndarray, rate_hz: float, taus: np.ndarray, time_constant_s: float
) -> tuple[float, float]:
    """(white density, Gauss-Markov sigma) fitted to the overlapping Allan deviation of x, with
    the correlation time given; residuals in log variance weighted by sqrt(cluster count)."""
    taus_out, adev, _, _ = allantools.oadev(x - x.mean(), rate=rate_hz, data_type="freq", taus=taus)
    weight = np.sqrt(len(x) / rate_hz / taus_out)

    def residual(p: np.ndarray) -> np.ndarray:
        model = allan_variance(taus_out, math.exp(p[0]), math.exp(p[1]), time_constant_s)
        return weight * (np.log(model) - np.log(adev**2))

    start = np.log([adev[0] * math.sqrt(taus_out[0]), adev.max()])
    n, b = np.exp(least_squares(residual, start).x)
    return float(n), float(b)


def test_allan_deviation_recovers_imu400cc_white_noise():
    # One hour at the native 134 Hz: the ARW/VRW read-off region (0.1 s to 10 s).
    rate_hz, n = 134.0, 134 * 3600
    gyro, accel = ImuErrorModel(IMU400CC, seed=11).apply(np.arange(n) / rate_hz, *_static(n))
    taus = np.logspace(-1, 1, 12)
    for measured, triad in ((gyro, IMU400CC.gyro), (accel, IMU400CC.accel)):
        for axis in range(3):
            density, _ = _fit_allan(measured[:, axis], rate_hz, taus, 300.0)
            assert density == pytest.approx(triad.noise_density[axis], rel=0.05)


def test_allan_deviation_recovers_imu400cc_bias_instability():
    """A long static record (about 500 correlation times) to see the Gauss-Markov bias under the
    white noise. Sampled at 10 Hz: the profile is defined by densities, so the statistics at
    τ >= 1 s do not depend on the output rate, and 1.5 million samples keep the test fast."""
    rate_hz, n = 10.0, 1_500_000
    gyro, accel = ImuErrorModel(IMU400CC, seed=5).apply(np.arange(n) / rate_hz, *_static(n))
    taus = np.logspace(0, math.log10(n / rate_hz / 20), 25)
    checks = [(gyro[:, 2], IMU400CC.gyro, 2)] + [(accel[:, i], IMU400CC.accel, i) for i in range(3)]
    for measured, triad, axis in checks:
        density, sigma = _fit_allan(measured, rate_hz, taus, triad.bias_correlation_time_s[axis])
        assert density == pytest.approx(triad.noise_density[axis], rel=0.10)
        assert sigma == pytest.approx(triad.bias_instability[axis], rel=0.10)
