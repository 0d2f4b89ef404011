"""The Whittle-likelihood fit of the Gauss-Markov bias (ins_fusion.noise_id.whittle and
likelihood): the expected periodogram of differenced block means is the mean periodogram of the
simulator's own processes, and known terms come back within their stated uncertainty.

Records at 1 Hz, 60 000 s, T = 30 s: 2000 correlation times, σ to about 2 %, about 10 s.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from ins_fusion.core.nav.units import deg_h, deg_sqrt_h, m_s_sqrt_h, mg
from ins_fusion.noise_id.analysis import GYRO, identify, shortcomings
from ins_fusion.noise_id.record import sample_clock
from ins_fusion.noise_id.synthetic import static_record
from ins_fusion.noise_id.whittle import (
    BIAS,
    LOG_TIME,
    SpectralModel,
    _Columns,
    blocks,
    expected_errors,
)
from ins_fusion.sim.imu_model import ImuProfile, TriadErrors
from ins_fusion.sim.noise import GaussMarkov, RandomWalk, WhiteNoise

pytestmark = pytest.mark.slow


def _same(value: float) -> tuple[float, float, float]:
    return (value, value, value)


FAST = ImuProfile(
    "fast",
    1.0,
    gyro=TriadErrors(
        noise_density=_same(deg_sqrt_h(0.5)),
        bias_instability=_same(deg_h(8.0)),
        bias_correlation_time_s=_same(30.0),
    ),
    accel=TriadErrors(
        noise_density=_same(m_s_sqrt_h(0.05)),
        bias_instability=_same(mg(0.1)),
        bias_correlation_time_s=_same(30.0),
        random_walk=_same(mg(0.002)),
    ),
)


def test_expected_periodogram_is_the_mean_periodogram():
    """2000 records of white noise + Gauss-Markov + random walk (sim.noise), 61 blocks of 2 s:
    the mean tapered periodogram of their differenced block means is the debiased Whittle
    expectation (leakage included) within 10 % at every frequency (the mean's own scatter is
    about 2.5 %)."""
    rate, per_block, n_blocks, records = 10.0, 20, 61, 2000
    white, sigma, time_constant, walk = 1e-3, 2e-4, 10.0, 2e-5
    rng = np.random.default_rng(0)
    dt = np.full(per_block * n_blocks, 1.0 / rate)
    values = (
        WhiteNoise(np.full(records, white), rng).sample(dt)
        + GaussMarkov(np.full(records, sigma), np.full(records, time_constant), rng).sample(dt)
        + RandomWalk(np.full(records, walk), rng).sample(dt)
    )
    mean = np.mean(
        [blocks(values[:, j], rate, per_block).periodogram for j in range(records)], axis=0
    )
    model = SpectralModel(white**2, sigma**2, walk**2, time_constant)
    expected = _Columns(n_blocks - 1, per_block / rate).at(time_constant) @ model.coefficients
    assert mean == pytest.approx(expected, rel=0.10)


@pytest.fixture(scope="module")
def reports():
    records = [static_record(FAST, 60_000.0, seed=seed) for seed in (1, 2)]
    return [identify(r, sample_clock(r.t_s), "fast") for r in records]


def test_known_bias_comes_back_within_its_stated_uncertainty(reports):
    """Every σ and T within 3 of their stated 1σ, and their errors over the stated 1σ scatter
    like a unit normal (rms between 0.6 and 1.5: intervals neither too narrow nor too wide);
    the stated 1σ is the bound for the true noise within 30 %, and small enough for the tool to
    accept the bias."""
    scores = []
    for report in reports:
        assert shortcomings(report, ("white", "bias")) == []
        for axis in report.axes:
            triad = FAST.gyro if axis.sensor is GYRO else FAST.accel
            truth = SpectralModel(
                triad.noise_density[0] ** 2,
                triad.bias_instability[0] ** 2,
                triad.random_walk[0] ** 2,
                triad.bias_correlation_time_s[0],
            )
            bias = axis.terms.bias
            assert bias is not None
            bound = expected_errors(truth, 1.0, 60_000)
            assert bias.errors == pytest.approx((bound[BIAS], bound[LOG_TIME]), rel=0.30)
            sigma, time = math.sqrt(truth.bias), truth.time_constant_s
            score = (
                math.log(bias.sigma.value / sigma) / bias.errors[0],
                math.log(bias.time_constant_s / time) / bias.errors[1],
            )
            assert max(abs(z) for z in score) <= 3.0
            assert bias.sigma.low < bias.sigma.value < bias.sigma.high
            scores += score
    assert 0.6 <= math.sqrt(np.mean(np.square(scores))) <= 1.5


def test_a_random_walk_stands_out_only_where_there_is_one(reports):
    for report in reports:
        for axis in report.axes:
            assert axis.terms.random_walk.visible == (axis.sensor is not GYRO)
