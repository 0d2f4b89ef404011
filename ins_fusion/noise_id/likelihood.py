"""The bias instability and random walk of an axis from its samples: the Allan fit's terms with
the Gauss-Markov bias and the random walk replaced by the debiased Whittle fit of the samples
(ins_fusion.noise_id.whittle), which uses the whole spectrum and has honest intervals.

The Allan fit keeps the white noise (read at τ = 1 s) and the quantisation. The likelihood
decides whether a Gauss-Markov bias and a random walk stand out and gives their values and
intervals; the fitted Allan model (coefficients, for the plot) takes them over. Where no
Gauss-Markov bias stands out, a flicker floor the Allan fit found (a flat minimum, which the
likelihood's model does not describe) stays, with its read-off; a Gauss-Markov model found by
the likelihood wins over a flicker floor, as the node models every bias as Gauss-Markov.
"""

from __future__ import annotations

import math
from dataclasses import replace

from gnss_ins_common.types import FloatArray
from ins_fusion.noise_id.terms import (
    FLICKER,
    NoiseTerms,
    Term,
    gauss_markov_bias,
    log_normal_term,
)
from ins_fusion.noise_id.whittle import BIAS, LOG_TIME, WALK, fit_whittle


def refine(terms: NoiseTerms, values: FloatArray, rate_hz: float, confidence: float) -> NoiseTerms:
    """terms of the Allan fit of ``values`` (samples [u] at rate_hz) with the likelihood's
    Gauss-Markov bias and random walk."""
    fit = fit_whittle(values, rate_hz)
    model, errors = fit.model, fit.errors
    bias = terms.bias if terms.bias is not None and terms.bias.model == FLICKER else None
    if model.bias > 0.0:
        bias = gauss_markov_bias(
            math.sqrt(model.bias),
            model.time_constant_s,
            (errors[BIAS], errors[LOG_TIME]),
            confidence,
        )
    walk = math.sqrt(model.walk)
    random_walk = (
        log_normal_term(walk, errors[WALK], confidence)
        if model.walk > 0.0
        # Not visible: the Allan curve's bound stays.
        else Term(0.0, 0.0, terms.random_walk.high, False)
    )
    q2, n2, flicker, _ = terms.coefficients
    # The Allan fit's flicker floor where it stays, else the likelihood's σ² (0: no bias).
    bias2 = model.bias if model.bias > 0.0 or bias is None else flicker
    return replace(
        terms, bias=bias, random_walk=random_walk, coefficients=(q2, n2, bias2, model.walk)
    )
