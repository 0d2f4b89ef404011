"""core.measurements.gnss_noise: the correlated GNSS error states follow the measured
white/correlated split."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from ins_fusion.core.filter.adaptation import W_COUNT, W_MEAN
from ins_fusion.core.filter.eskf import POS, ErrorStateFilter, StateLayout
from ins_fusion.core.filter.records import GnssFixMeasurement
from ins_fusion.core.filter.state import FilterState
from ins_fusion.core.measurements.gnss_noise import (
    NOISE_KEPT,
    NOISE_MOVED,
    NOISE_RESTART,
    GnssNoise,
)
from ins_fusion.core.nav.rotation import quat_from_euler
from ins_fusion.core.nav.strapdown import NavState
from ins_fusion.core.settings.config import FusionConfig


def test_an_error_state_less_certain_than_its_new_process_shrinks_with_its_estimate():
    """The split moved towards white: an axis whose error-state variance (4 m²) exceeds the new
    stationary variance (1 m²) shrinks to it, estimate and correlations by the same factor
    (1/2); axes still below theirs keep estimate and covariance; P stays positive
    semi-definite."""
    config = FusionConfig.default()
    layout = StateLayout(gnss_error=True)
    gp = layout.gp
    assert gp is not None
    kf = ErrorStateFilter(layout, config.imu_noise, config.gnss_correlation_time_s)
    rng = np.random.default_rng(6)
    root = rng.standard_normal((layout.size, layout.size)) * 0.1
    P = root @ root.T
    P[gp : gp + 3, gp : gp + 3] += np.eye(3) * 4.0
    P[POS : POS + 3, gp : gp + 3] = P[gp : gp + 3, POS : POS + 3] = -np.eye(3) * 1.5
    P = P + np.eye(layout.size) * 3.0
    kf.P = before = P
    nav = NavState(
        math.radians(57.0), math.radians(10.0), 40.0, np.zeros(3), quat_from_euler(0, 0, 0)
    )
    s = FilterState(0.0, nav, (0.0, 0.0, 0.0), True)
    s.gnss_error = (1.0, 1.0, 1.0)
    variance = np.diagonal(before)[gp : gp + 3]
    GnssNoise.set_correlated_variance(s, kf, np.array([variance[0] / 4.0, 10.0, 20.0]))
    assert kf.P[gp, gp] == pytest.approx(variance[0] / 4.0)
    assert kf.P[gp, POS] == pytest.approx(0.5 * before[gp, POS])
    assert s.gnss_error == pytest.approx((0.5, 1.0, 1.0))
    assert np.array_equal(kf.P[gp + 1 :, gp + 1 :], before[gp + 1 :, gp + 1 :])
    assert np.linalg.eigvalsh(kf.P).min() > 0.0
    assert s.gnss_variance == (variance[0] / 4.0, 10.0, 20.0)
    unchanged = kf.P
    GnssNoise.set_correlated_variance(s, kf, np.array([10.0, 10.0, 20.0]))
    assert kf.P is unchanged


def _state() -> FilterState:
    nav = NavState(
        math.radians(57.0), math.radians(10.0), 40.0, np.zeros(3), quat_from_euler(0, 0, 0)
    )
    return FilterState(0.0, nav, (0.0, 0.0, 0.0), True)


def _fix(cov_enu: np.ndarray) -> GnssFixMeasurement:
    return GnssFixMeasurement(1.0, 57.0, 10.0, 40.0, cov_enu)


@settings(max_examples=200, deadline=None)
@given(
    arrays(np.float64, (3, 3), elements=st.floats(-1.0, 1.0)),
    st.floats(1e-4, 100.0),
    st.one_of(st.none(), arrays(np.float64, 3, elements=st.floats(0.01, 300.0))),
    st.booleans(),
)
def test_the_split_is_the_documented_formula(root, scale, share, correlated_states):
    """position_noise's white covariance and correlated variance are the docstring's formula
    (written out here with numpy): white per NED axis = min(variance, max(floor σ², fraction ×
    variance)) (all of it without correlated states), raised to the measured share × variance
    and capped at 100 × variance; the covariance scaled by √(white / variance) per axis, so its
    correlations are kept; the rest is the correlated variance."""
    config = FusionConfig.default()
    noise = GnssNoise(config, StateLayout(gnss_error=correlated_states))
    cov_enu = (root @ root.T + np.eye(3) * 1e-3) * scale
    s = _state()
    if share is not None:  # measured: the monitor's running mean after enough epochs
        s.gnss_white.values[W_MEAN : W_MEAN + 3] = share
        s.gnss_white.values[W_COUNT] = 10.0
        assert s.gnss_white.share is not None
    white, correlated, reported, _ = noise.position_noise(s, _fix(cov_enu))
    swap = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])  # ENU <-> NED
    total = swap @ cov_enu @ swap.T * config.gnss_position_noise_scale**2
    variance = np.diagonal(total)
    floor = np.square(swap @ config.gnss_white_sigma_enu_m)
    expected = np.minimum(variance, np.maximum(floor, config.gnss_white_fraction * variance))
    if not correlated_states:
        expected = variance
    if share is not None:
        expected = np.minimum(np.maximum(expected, share * variance), 100.0 * variance)
    factor = np.sqrt(expected / variance)
    np.testing.assert_allclose(reported, variance, rtol=1e-15)
    np.testing.assert_allclose(np.diagonal(white), expected, rtol=1e-12)
    np.testing.assert_allclose(white, total * np.outer(factor, factor), rtol=1e-12, atol=1e-300)
    np.testing.assert_allclose(
        correlated, np.maximum(variance - expected, 0.0), atol=1e-12 * variance.max()
    )


def test_the_correlated_states_restart_when_the_reported_variance_jumps():
    """The first fix and a fix whose reported variance changed by more than 1.5 times on an
    axis (another fix type) restart the correlated error states; an unchanged fix keeps them
    while its split is unchanged and asks for the new variance when the split moved; without
    correlated states nothing is asked."""
    config = FusionConfig.default()
    noise = GnssNoise(config, StateLayout(gnss_error=True))
    s = _state()
    cov = np.diag([0.02, 0.03, 0.05]) ** 2
    _, correlated, reported, action = noise.position_noise(s, _fix(cov))
    assert action == NOISE_RESTART  # nothing reported before
    s.gnss_reported = tuple(reported.tolist())
    s.gnss_variance = tuple(correlated.tolist())
    assert noise.position_noise(s, _fix(cov))[3] == NOISE_KEPT
    s.gnss_variance = (0.0, 0.0, 0.0)
    assert noise.position_noise(s, _fix(cov))[3] == NOISE_MOVED
    for factor, expected in ((1.4, NOISE_MOVED), (1.6, NOISE_RESTART), (1 / 1.6, NOISE_RESTART)):
        changed = cov.copy()
        changed[1, 1] *= factor
        assert noise.position_noise(s, _fix(changed))[3] == expected, factor
    white_only = GnssNoise(config, StateLayout())
    assert white_only.position_noise(_state(), _fix(cov))[3] == NOISE_KEPT
