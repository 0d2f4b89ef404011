"""The Aalborg report's free-inertial metrics (ins_fusion.replay.free_inertial): (9.3) and (9.4)
on the report's printed numbers, and the drift read from the withheld fixes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ins_fusion.replay.free_inertial import ELAPSED_S, drift, outage, sigma_afv, sigma_pos
from ins_fusion.replay.metrics import Errors
from ins_fusion.replay.withheld import WithheldEvaluation


def test_report_metrics_on_its_printed_numbers():
    """Calibration 05 at 30 s (Aalborg notes §8.3): σ_pos2D 7.66 m, σ_afv2D 4.49 m over six
    runs. (9.3)² = μ² + (n-1)/n (9.4)², so six distances of mean μ = 6.47 m and sample spread
    4.49 m give both back."""
    n, spread = 6, 4.49
    mean = math.sqrt(7.66**2 - (n - 1) / n * spread**2)
    assert mean == pytest.approx(6.47, abs=0.01)
    z = np.array([-1.5, -0.8, -0.2, 0.3, 0.9, 1.3])
    z = (z - z.mean()) / z.std(ddof=1)
    d = (mean + spread * z)[:, None]
    assert sigma_pos(d)[0] == pytest.approx(7.66, abs=1e-9)
    assert sigma_afv(d)[0] == pytest.approx(4.49, abs=1e-9)
    assert math.isnan(sigma_afv(d[:1])[0])  # one run has no spread


def test_drift_interpolates_the_withheld_fix_errors():
    """Errors growing as (3t, 4t, -t) m after START = 100 s, fixes at 1 Hz to 160 s: the
    distance is 5t, Down +t; beyond the last fix there is none."""
    t = np.arange(100.0, 161.0)
    elapsed = t - 100.0
    error = np.stack([3.0 * elapsed, 4.0 * elapsed, -elapsed], axis=1)
    errors = Errors(t, error, np.zeros((len(t), 3, 3)), np.ones(len(t), dtype=bool))
    run = drift(WithheldEvaluation(errors, np.zeros((len(t), 3, 3)), t), 100.0, ELAPSED_S)
    np.testing.assert_allclose(run.horizontal_m[:8], 5.0 * np.array(ELAPSED_S[:8]))
    np.testing.assert_allclose(run.down_m[:8], np.array(ELAPSED_S[:8]))
    assert np.isnan(run.horizontal_m[8:]).all() and np.isnan(run.down_m[8:]).all()
    assert np.isnan(drift(WithheldEvaluation.empty(), 100.0, ELAPSED_S).horizontal_m).all()


def test_outage_reaches_past_the_end_of_the_bag():
    window = outage(60.0, 240.0)
    assert window.contains(60.0) and window.contains(240.0) and not window.contains(59.9)
