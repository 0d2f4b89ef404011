"""core.filter.adaptation: the IMU noise measured from the data, the white GNSS noise measured from
the innovations, and the fading factor of a gate recovery."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ins_fusion.core.filter.adaptation import (
    B_MEAN,
    B_VERSION,
    ImuNoiseMonitor,
    WhiteNoiseMonitor,
    adapt_process_noise,
    fading_factor,
)

RATE_HZ = 100.0


def _feed(monitor: ImuNoiseMonitor, t: np.ndarray, rate: np.ndarray, force: np.ndarray) -> None:
    for k in range(len(t)):
        monitor.push(float(t[k]), tuple(rate[k]), tuple(force[k]))  # type: ignore[arg-type]


def test_white_noise_density_is_measured_through_smooth_motion():
    """Density 0.01 rad/√s and 0.05 m/s/√s (100× a datasheet) on a vehicle turning and braking
    smoothly: measured within 10 %."""
    rng = np.random.default_rng(1)
    t = np.arange(0.0, 60.0, 1.0 / RATE_HZ)
    motion = np.stack([np.sin(0.5 * t), 0.3 * np.cos(0.2 * t), 9.81 + 0.5 * np.sin(t)], axis=1)
    gyro_density, accel_density = np.array([0.01, 0.02, 0.005]), np.array([0.05, 0.03, 0.08])
    rate = 0.2 * motion + rng.normal(size=(*t.shape, 3)) * gyro_density * math.sqrt(RATE_HZ)
    force = motion + rng.normal(size=(*t.shape, 3)) * accel_density * math.sqrt(RATE_HZ)
    monitor = ImuNoiseMonitor(window_s=30.0)
    _feed(monitor, t, rate, force)
    psd = monitor.psd
    assert psd is not None
    assert np.sqrt(psd[0]) == pytest.approx(gyro_density, rel=0.1)
    assert np.sqrt(psd[1]) == pytest.approx(accel_density, rel=0.1)


def test_vibration_far_above_the_block_rate_is_not_counted_as_noise():
    """A 0.5 m/s² engine vibration at 33 Hz mostly averages out over the 0.05 s blocks, as it
    does in the velocity increments (block mean ∝ sinc(f τ) = 0.17): well below its per-sample
    white equivalent 0.5/√100 m/s/√s, which a per-sample variance would report."""
    t = np.arange(0.0, 30.0, 1.0 / RATE_HZ)
    vib = 0.5 * math.sqrt(2.0) * np.sin(2.0 * math.pi * 33.0 * t)
    force = np.stack([vib, vib, 9.81 + vib], axis=1)
    monitor = ImuNoiseMonitor()
    _feed(monitor, t, np.zeros_like(force), force)
    psd = monitor.psd
    assert psd is not None
    assert np.sqrt(psd[1]).max() < 0.5 * 0.5 / math.sqrt(RATE_HZ)


def test_nothing_is_reported_before_enough_blocks_and_a_reset_keeps_the_estimate():
    monitor = ImuNoiseMonitor()
    t = np.arange(0.0, 0.5, 1.0 / RATE_HZ)  # 10 blocks: 8 second differences
    _feed(monitor, t, np.zeros((len(t), 3)), np.zeros((len(t), 3)))
    assert monitor.psd is None
    _feed(monitor, t + 0.5, np.zeros((len(t), 3)), np.zeros((len(t), 3)))
    psd = monitor.psd
    assert psd is not None and not psd[0].any()
    monitor.reset()
    assert monitor.psd is psd


def test_an_adopted_snapshot_is_read_until_the_estimate_changes_again():
    """``adopt`` (what a compiled run saw at a version) gives the same numbers as reading
    ``psd`` then, and ``psd`` keeps it until the block's version moves on."""
    monitor = ImuNoiseMonitor()
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 1.0, 1.0 / RATE_HZ)
    _feed(monitor, t, rng.normal(size=(len(t), 3)), rng.normal(size=(len(t), 3)))
    read = monitor.psd
    assert read is not None
    version, means = monitor.block[B_VERSION], monitor.block[B_MEAN : B_MEAN + 6].copy()
    _feed(monitor, t + 1.0, rng.normal(size=(len(t), 3)), rng.normal(size=(len(t), 3)))
    adopted = monitor.adopt(version, means)
    np.testing.assert_array_equal(np.concatenate(adopted), np.concatenate(read))
    assert not adopted[0].flags.writeable and not adopted[1].flags.writeable
    monitor.block[B_VERSION] = version  # the block still at that version: the snapshot stays
    assert monitor.psd is adopted
    monitor.block[B_VERSION] = version + 1.0
    assert monitor.psd is not adopted


@settings(max_examples=40, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.floats(1e-4, 0.05),
            st.lists(st.floats(-1e3, 1e3), min_size=6, max_size=6),
        ),
        min_size=1,
        max_size=400,
    )
)
def test_the_density_is_finite_and_never_negative_for_any_input(samples):
    monitor = ImuNoiseMonitor()
    t = 0.0
    for dt, values in samples:
        t += dt
        monitor.push(t, (values[0], values[1], values[2]), (values[3], values[4], values[5]))
    psd = monitor.psd
    if psd is not None:
        for part in psd:
            assert np.isfinite(part).all() and (part >= 0.0).all()


@pytest.mark.parametrize("gain", [0.0, 0.5, 0.95])
def test_white_gnss_noise_is_measured_whatever_the_filter_gain(gain):
    """A 5 m white receiver reporting σ 10 m (share 0.25) and a drifting state error whose
    growth the filter knows, fixes weighted by a gain from 0 (all rejected) to 0.95 (followed):
    the measured white share is the receiver's, ±15 %."""
    rng = np.random.default_rng(2)
    monitor = WhiteNoiseMonitor(window_epochs=200.0)
    state_error, drift = np.zeros(3), 1.0  # INS drift per epoch [m]
    reported = np.full(3, 100.0)
    for k in range(2000):
        state_error = state_error + rng.normal(size=3) * drift
        innovation = rng.normal(size=3) * 5.0 - state_error
        correction = gain * innovation
        state_error = state_error + correction
        predicted, updated = np.full(3, 30.0 + drift**2), np.full(3, 30.0)
        monitor = monitor.pushed(
            0.2 * k, innovation, innovation - correction, predicted, updated, reported
        )
    share = monitor.share
    assert share is not None
    assert share == pytest.approx(np.full(3, 0.25), rel=0.15)


def _pushed(monitor: WhiteNoiseMonitor, t: float, z: np.ndarray) -> WhiteNoiseMonitor:
    zero, one = np.zeros(3), np.ones(3)
    return monitor.pushed(t, z, z, zero, zero, one)


def test_white_gnss_noise_ignores_fixes_across_an_outage_and_outliers_are_clipped():
    monitor = WhiteNoiseMonitor()
    rng = np.random.default_rng(3)
    for k in range(100):
        monitor = _pushed(monitor, float(k), rng.normal(size=3) * 0.1)
    before = monitor.share  # E[(Δz)²] / (1 + 1) = 0.01
    assert before is not None and before == pytest.approx(np.full(3, 0.01), rel=0.5)
    jumped = _pushed(monitor, 200.0, np.full(3, 30.0))  # after a 100 s outage
    assert np.array_equal(jumped.share, before)
    outlier = _pushed(monitor, 100.0, np.full(3, 30.0))  # 30 m in one epoch
    assert (outlier.share <= before * (1.0 + 9.0 / 30.0) + 1e-12).all()
    assert _pushed(monitor.restarted(), 100.0, np.ones(3)).share is not None


def test_fading_factor_makes_a_rejected_innovation_typical():
    # Scalar: z² / (λ a + r) = target  =>  λ = (z²/target - r) / a.
    z, a, r = np.array([3.0]), np.array([[0.1]]), np.array([[0.05]])
    lam = fading_factor(z, a, r, 1.0)
    assert lam == pytest.approx((9.0 - 0.05) / 0.1, rel=1e-6)
    assert fading_factor(np.array([0.1]), a, r, 1.0) == 1.0
    # The innovation lies where H P Hᵀ has no variance: no factor helps.
    z2 = np.array([0.0, 5.0])
    assert fading_factor(z2, np.diag([1.0, 0.0]), np.eye(2) * 1e-4, 2.0) == math.inf


def test_process_noise_grows_while_the_innovations_are_too_large_and_returns_after():
    """NIS/dof of 4 (a covariance half the size it should be in σ) raises the factor on the
    IMU process noise; typical innovations (1) bring it back to the user's model, never below;
    a single outlier moves it little (clipped)."""
    mean, scale = 1.0, 1.0
    for _ in range(200):
        mean, scale = adapt_process_noise(mean, scale, 4.0)
    assert mean == pytest.approx(4.0, rel=0.01) and scale > 10.0
    high = scale
    for _ in range(2000):
        mean, scale = adapt_process_noise(mean, scale, 0.5)
    assert scale == 1.0 and mean == pytest.approx(0.5, rel=0.01)
    mean, scale = adapt_process_noise(1.0, 1.0, 1e6)
    assert mean == pytest.approx(1.2) and scale < 1.01
    assert high <= 100.0


@pytest.mark.parametrize("accepted", [True, False])
def test_a_fix_update_pushes_its_residual_and_variance_after_the_update(accepted):
    """WhiteNoiseMonitor.pushed_fix (compiled) is ``pushed`` with the residual z - H δx (z when
    rejected) and diag(H P Hᵀ) after the update, over a run of fixes."""
    rng = np.random.default_rng(4)
    by_fix, by_arrays = WhiteNoiseMonitor(), WhiteNoiseMonitor()
    for k in range(30):
        H = rng.normal(size=(3, 8))
        root = rng.normal(size=(8, 8))
        P = root @ root.T
        z, dx = rng.normal(size=3), rng.normal(size=8)
        predicted, reported = rng.uniform(1.0, 2.0, 3), rng.uniform(0.5, 1.0, 3)
        by_fix = by_fix.pushed_fix(0.2 * k, z, H, dx if accepted else None, P, predicted, reported)
        residual = z - H @ dx if accepted else z
        by_arrays = by_arrays.pushed(
            0.2 * k, z, residual, predicted, np.diagonal(H @ P @ H.T), reported
        )
    assert by_fix.ready and by_arrays.ready
    np.testing.assert_allclose(by_fix.values, by_arrays.values, rtol=1e-12)
