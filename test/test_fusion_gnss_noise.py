"""core.gnss_noise: the correlated GNSS error states follow the measured white/correlated split."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ins_fusion.core.config import FusionConfig
from ins_fusion.core.eskf import POS, ErrorStateFilter, StateLayout
from ins_fusion.core.gnss_noise import GnssNoise
from ins_fusion.core.rotation import quat_from_euler
from ins_fusion.core.state import FilterState
from ins_fusion.core.strapdown import NavState


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
