"""Band-limited IMU white noise (Aalborg notes §1.3) and the simulated sensor temperature."""

from __future__ import annotations

import dataclasses
import math

import allantools
import numpy as np
import pytest

from ins_fusion.core.nav import units
from ins_fusion.sim.imu_model import IMU400CC, STIM300, ImuErrorModel, TriadErrors
from ins_fusion.sim.noise import BandLimitedNoise, _first_order_recursion

#: Per-axis σ of (7.14), Aalborg notes §1.3 [rad/s], [m/s²], and the report's averages.
GYRO_SIGMA_7_14 = np.array([0.0041, 0.0040, 0.0048])
ACCEL_SIGMA_7_14 = np.array([0.0029, 0.0038, 0.0036])


def _white_only(triad: TriadErrors) -> TriadErrors:
    """The triad's white noise and bandwidth alone (no bias wander, no quantisation)."""
    return TriadErrors(noise_density=triad.noise_density, bandwidth_hz=triad.bandwidth_hz)


WHITE_IMU400CC = dataclasses.replace(
    IMU400CC, gyro=_white_only(IMU400CC.gyro), accel=_white_only(IMU400CC.accel)
)


def _static(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return np.arange(n) / 134.0, np.zeros((n, 3)), np.tile([0.0, 0.0, 9.81], (n, 1))


def test_recursion_matches_the_sample_by_sample_filter():
    rng = np.random.default_rng(0)
    pole = rng.uniform(0.0, 0.99, 3000)
    pole[::97] = 0.0
    drive = rng.normal(size=(3000, 3))
    expected, value = np.empty_like(drive), np.array([1.0, -2.0, 0.5])
    for k in range(3000):
        value = pole[k] * value + drive[k]
        expected[k] = value
    assert _first_order_recursion(pole, drive, np.array([1.0, -2.0, 0.5])) == pytest.approx(
        expected, abs=1e-10
    )


def test_band_limited_noise_keeps_density_and_has_sigma_n_sqrt_b():
    noise = BandLimitedNoise(np.ones(3), 25.0, np.random.default_rng(1))
    dt = np.full(134 * 600, 1.0 / 134.0)
    first = noise.sample(dt[:1000])
    values = np.concatenate([first, noise.sample(dt[1000:])])
    assert values.std(axis=0) == pytest.approx([5.0] * 3, rel=0.03)  # N sqrt(B)
    one_second_means = values.reshape(-1, 134, 3).mean(axis=1)
    assert one_second_means.std(axis=0) == pytest.approx([1.0] * 3, rel=0.1)  # N / sqrt(1 s)
    # Sampled slower than the bandwidth: plain white noise of the same density.
    slow = BandLimitedNoise(np.ones(3), 25.0, np.random.default_rng(2)).sample(np.full(5000, 0.1))
    assert slow.std(axis=0) == pytest.approx([math.sqrt(10.0)] * 3, rel=0.05)


def test_band_limited_imu400cc_per_sample_sigma_is_the_measured_one():
    """Aalborg notes §1.3: σ_ω = 0.248 °/s and σ_f = 0.352 mg per sample (averages of x, y, z),
    against about 0.57 °/s for white noise of the same density at 134 Hz."""
    t, rate, force = _static(134 * 300)
    gyro, accel = ImuErrorModel(WHITE_IMU400CC, seed=3, band_limited=True).apply(t, rate, force)
    gyro_sigma, accel_sigma = gyro.std(axis=0), (accel - accel.mean(axis=0)).std(axis=0)
    assert gyro_sigma == pytest.approx(GYRO_SIGMA_7_14, rel=0.2)
    assert accel_sigma == pytest.approx(ACCEL_SIGMA_7_14, rel=0.2)
    assert math.degrees(gyro_sigma.mean()) == pytest.approx(0.248, rel=0.2)
    assert accel_sigma.mean() / units.mg(1.0) == pytest.approx(0.352, rel=0.2)
    white_gyro, _ = ImuErrorModel(WHITE_IMU400CC, seed=3).apply(t, rate, force)
    assert math.degrees(white_gyro.std(axis=0).mean()) == pytest.approx(0.57, rel=0.05)
    model = ImuErrorModel(IMU400CC, seed=3, band_limited=True)
    assert model.noise_sigma()[0] == pytest.approx(GYRO_SIGMA_7_14)
    assert model.noise_sigma()[1] == pytest.approx(ACCEL_SIGMA_7_14)


def test_band_limited_imu400cc_keeps_arw_and_vrw():
    """Allan deviation at τ = 1 s .. 10 s (above the filter corners) reads the profile's
    density, as for white noise."""
    t, rate, force = _static(134 * 1800)
    model = ImuErrorModel(WHITE_IMU400CC, seed=4, band_limited=True)
    gyro, accel = model.apply(t, rate, force)
    taus = np.array([1.0, 2.0, 5.0, 10.0])
    for measured, triad in ((gyro, IMU400CC.gyro), (accel, IMU400CC.accel)):
        for axis in range(3):
            x = measured[:, axis] - measured[:, axis].mean()
            taus_out, adev, _, _ = allantools.oadev(x, rate=134.0, data_type="freq", taus=taus)
            density = float(np.mean(adev * np.sqrt(taus_out)))
            assert density == pytest.approx(triad.noise_density[axis], rel=0.05)


def test_band_limiting_is_optional_and_profiles_without_bandwidth_stay_white():
    t, rate, force = _static(500)
    plain = ImuErrorModel(IMU400CC, seed=5).apply(t, rate, force)
    limited = ImuErrorModel(IMU400CC, seed=5, band_limited=True).apply(t, rate, force)
    assert not np.array_equal(plain[0], limited[0])
    stim = ImuErrorModel(STIM300, seed=5).apply(t, rate, force)
    stim_limited = ImuErrorModel(STIM300, seed=5, band_limited=True).apply(t, rate, force)
    assert np.array_equal(stim[0], stim_limited[0])
    assert math.isinf(STIM300.gyro.bandwidth_hz)


def test_band_limited_record_does_not_depend_on_the_block_size():
    t, rate, force = _static(3000)
    whole = ImuErrorModel(IMU400CC, seed=6, band_limited=True).apply(t, rate, force)
    model = ImuErrorModel(IMU400CC, seed=6, band_limited=True)
    parts = [
        model.apply(t[a:b], rate[a:b], force[a:b]) for a, b in ((0, 1), (1, 1200), (1200, 3000))
    ]
    # Quantised to device counts: equal up to a rare count at a rounding boundary.
    resolution = IMU400CC.gyro.resolution
    assert np.concatenate([p[0] for p in parts]) == pytest.approx(whole[0], abs=1.01 * resolution)


def test_temperature_is_seeded_near_28_degrees_and_drifts_slowly():
    t = np.arange(0.0, 3600.0, 1.0)
    readings = [ImuErrorModel(IMU400CC, seed=s).temperature_c(t) for s in range(20)]
    assert np.array_equal(ImuErrorModel(IMU400CC, seed=0).temperature_c(t), readings[0])
    assert not np.array_equal(readings[0], readings[1])
    starts = np.array([r[0] for r in readings])
    assert starts.mean() == pytest.approx(28.0, abs=0.7)  # Aalborg notes §7.1.3, Fig. 8-3
    assert 0.2 < starts.std() < 2.5
    for record in readings:
        assert np.abs(np.diff(record)).max() < 0.01  # slow and smooth
        assert np.ptp(record) < 6.0
    settled = np.array([r[-1] for r in readings])
    assert not np.allclose(settled, starts)
    # Its own stream: the sensor errors do not change when the temperature is read.
    n_t, n_rate, n_force = _static(200)
    model = ImuErrorModel(IMU400CC, seed=0)
    model.temperature_c(t)
    assert np.array_equal(
        model.apply(n_t, n_rate, n_force)[0],
        ImuErrorModel(IMU400CC, seed=0).apply(n_t, n_rate, n_force)[0],
    )
