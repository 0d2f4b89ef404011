"""The GNSS position noise model of the engine: the receiver's reported covariance split into a
white part (the measurement noise R) and a time-correlated part (Gauss-Markov error states,
when ``gnss_correlation_time`` > 0), and the restarts of those states. Covariances NED [m²]."""

from __future__ import annotations

import math

import numpy as np

from gnss_ins_common.types import FloatArray, Vec3
from ins_fusion.core.compiled import jit, kernel_array
from ins_fusion.core.filter.eskf import POS, ErrorStateFilter, StateLayout
from ins_fusion.core.filter.records import GnssFixMeasurement
from ins_fusion.core.filter.state import X_GNSS_ERROR, X_GNSS_VARIANCE, FilterState, restart_block
from ins_fusion.core.measurements.common import ned_cov
from ins_fusion.core.nav.rotation import MAT_ENU_NED
from ins_fusion.core.settings.config import FusionConfig

#: Largest factor by which a fix's covariance grows when its epochs scatter more than reported.
_MAX_GNSS_INFLATION = 100.0
#: A change of the receiver's reported variance by more than this factor restarts the
#: correlated GNSS error states (another fix type).
_GNSS_NOISE_JUMP = 1.5
#: What a fix asks of the correlated GNSS error states (``GnssNoise.position_noise``): nothing,
#: a restart (``GnssNoise.restart_error``), their new variance (``set_correlated_variance``).
NOISE_KEPT, NOISE_RESTART, NOISE_MOVED = 0, 1, 2
#: The white share before it is measured (core.filter.adaptation.WhiteNoiseMonitor.share None).
_NO_SHARE = np.full(3, math.nan)


class GnssNoise:
    """White/correlated split of a fix's covariance (see the module docstring)."""

    def __init__(self, config: FusionConfig, layout: StateLayout) -> None:
        self._layout = layout
        self._scale_sq = config.gnss_position_noise_scale**2
        self._white_fraction = config.gnss_white_fraction
        self._white_var_ned = np.square(MAT_ENU_NED @ config.gnss_white_sigma_enu_m)

    def position_noise(
        self, s: FilterState, fix: GnssFixMeasurement
    ) -> tuple[FloatArray, FloatArray, FloatArray, int]:
        """(white covariance NED [m²], correlated variance per NED axis [m²], reported variance
        per NED axis (the receiver's, times gnss_position_noise_scale²) [m²], what the
        correlated error states need: NOISE_*) of a fix for state ``s``. Compiled
        (``_position_noise``).

        The white part is what the data say (core.filter.adaptation.WhiteNoiseMonitor: consecutive
        innovations), at least ``gnss_noise.white_sigma``² or ``gnss_noise.white_fraction`` of
        the receiver's variance, at most that variance; before the data say anything, the
        floor. The rest is the time-correlated error. A receiver whose epochs scatter more than
        it reports gets its whole covariance scaled up to the measured white part (at most
        ``_MAX_GNSS_INFLATION`` times). Correlations between axes are kept. The correlated
        states restart when the reported variance moved by more than ``_GNSS_NOISE_JUMP``
        times since they last did (another fix type), else take the new split's variance.
        """
        return _position_noise(
            kernel_array(fix.cov_enu_m2),
            *self.settings(s),
            (self._layout.gp is not None, fix.height_known),
            s.gnss_reported,
            s.gnss_variance,
        )

    def settings(self, s: FilterState) -> tuple[float, FloatArray, float, FloatArray]:
        """What ``_position_noise`` reads of the configuration and of ``s``: the scale², the
        white floor per NED axis [m²], the white fraction and the measured white share (NaN:
        none)."""
        share = s.gnss_white.share
        return (
            self._scale_sq,
            self._white_var_ned,
            self._white_fraction,
            _NO_SHARE if share is None else share,
        )

    def restart_position(
        self, s: FilterState, kf: ErrorStateFilter, fix: GnssFixMeasurement
    ) -> None:
        """Position error (and correlated GNSS error) as after taking the position from a fix:
        δp = -(white + correlated error of the fix)."""
        white, correlated, reported, _ = self.position_noise(s, fix)
        P = kf.P.copy()
        restart_block(P, POS, white + np.diag(correlated))
        kf.P = P
        gp = self._layout.gp
        if gp is not None:
            self.restart_error(s, kf, correlated, reported)
            P = kf.P.copy()
            P[POS : POS + 3, gp : gp + 3] = P[gp : gp + 3, POS : POS + 3] = -np.diag(correlated)
            kf.P = P

    def restart_error(
        self, s: FilterState, kf: ErrorStateFilter, correlated: FloatArray, reported: FloatArray
    ) -> None:
        """A new correlated GNSS error process (start, or the receiver's σ jumped: another fix
        type, e.g. RTK float after an outage): uncorrelated, at its stationary variance
        ``correlated``; ``reported``: the fix's reported variance (``position_noise``)."""
        gp = self._layout.gp
        assert gp is not None
        P_before = kf.P
        P = kf.P.copy()
        restart_block(P, gp, np.diag(correlated))
        kf.P = P
        s.gnss_reported = (float(reported[0]), float(reported[1]), float(reported[2]))
        s.gnss_error = (0.0, 0.0, 0.0)
        self.set_correlated_variance(s, kf, correlated)
        if kf.smoother_hooks is not None:  # smoother hook: the GNSS error states restart
            kf.smoother_hooks.on_restart(P_before, kf.P, range(gp, gp + 3))

    @staticmethod
    def set_correlated_variance(
        s: FilterState, kf: ErrorStateFilter, correlated: FloatArray
    ) -> None:
        """Stationary variance of the correlated GNSS error process per NED axis [m²].

        The error of a Gauss-Markov process is never less certain than the process itself: an
        error state whose variance exceeds the new stationary one (the measured split moved
        towards white) is shrunk to it, estimate and covariance by the same factor (x -> D x,
        P -> D P D). Left at the old variance it would take the navigation error as the
        receiver's: a white receiver's first fixes, split by the prior as mostly correlated,
        held the position 2 m off for a minute (docs/accuracy.md)."""
        gp = kf.layout.gp
        P_before = kf.P
        shrunk, kf.P, factors = shrink_correlated(
            kernel_array(kf.P), s.x, kernel_array(correlated), -1 if gp is None else gp
        )
        kf.gnss_variance = s.gnss_variance
        if shrunk and kf.smoother_hooks is not None:  # smoother hook: a transition x -> D x
            kf.smoother_hooks.on_transition(P_before, np.diag(factors), kf.P)


@jit
def shrink_correlated(
    P: FloatArray, x: FloatArray, correlated: FloatArray, gp: int
) -> tuple[bool, FloatArray, FloatArray]:
    """``GnssNoise.set_correlated_variance`` on P and the state array ``x`` (X_* layout, its
    stationary variance set, its correlated error estimate shrunk in place); ``gp``: the
    error states' first column (-1: none). Returns (shrunk, P (a new array when shrunk), the
    factors D on the states)."""
    size = P.shape[0]
    factors = np.ones(size)
    for k in range(3):
        x[X_GNSS_VARIANCE + k] = correlated[k]
    if gp < 0:
        return False, P, factors
    stays = True
    for k in range(3):
        variance = P[gp + k, gp + k]
        ratio = correlated[k] / (variance if not variance < 1e-300 else 1e-300)
        factors[gp + k] = np.sqrt(ratio if not ratio > 1.0 else 1.0)  # NaN stays NaN
        stays = stays and factors[gp + k] >= 1.0
    if stays:
        return False, P, factors
    for k in range(3):
        x[X_GNSS_ERROR + k] = x[X_GNSS_ERROR + k] * factors[gp + k]
    return True, P * np.outer(factors, factors), factors


@jit
def _position_noise(
    cov_enu: FloatArray,
    scale_sq: float,
    white_var_ned: FloatArray,
    white_fraction: float,
    share: FloatArray,
    kept: tuple[bool, bool],
    reported_before: Vec3,
    variance_before: Vec3,
) -> tuple[FloatArray, FloatArray, FloatArray, int]:
    """``GnssNoise.position_noise`` from the fix's ENU covariance [m²], the configuration
    (``scale_sq``: gnss_position_noise_scale²; the white floor per NED axis [m²] and fraction),
    the measured white ``share`` (NaN: none), ``kept`` = (whether the correlated error states
    are kept, whether the fix measures its height) and their reported and stationary variances
    [m²] at their last (re)start and update. A 2-D fix leaves the vertical's reported and
    correlated variance as they were and does not restart nor move them."""
    correlated_states, vertical = kept
    axes = 3 if vertical else 2
    total = ned_cov(cov_enu) * scale_sq
    white, correlated, reported = np.empty(3), np.empty(3), np.empty(3)
    scale = np.empty(3)
    for k in range(3):
        variance = total[k, k]
        reported[k] = variance
        w = variance  # all white without correlated error states
        if correlated_states:
            w = min(variance, max(white_var_ned[k], white_fraction * variance))
        if not math.isnan(share[k]):
            w = min(max(w, share[k] * variance), _MAX_GNSS_INFLATION * variance)
        white[k] = w
        correlated[k] = max(variance - w, 0.0)
        scale[k] = math.sqrt(w / max(variance, 1e-30))
    if not vertical:
        reported[2], correlated[2] = reported_before[2], variance_before[2]
    for i in range(3):
        for j in range(3):
            total[i, j] = total[i, j] * (scale[i] * scale[j])
    action = NOISE_KEPT
    if correlated_states:
        moved = False
        low, high = math.inf, -math.inf
        for k in range(axes):
            ratio = reported[k] / max(reported_before[k], 1e-12)
            low, high = min(low, ratio), max(high, ratio)
            moved = moved or correlated[k] != variance_before[k]
        if high > _GNSS_NOISE_JUMP or low < 1.0 / _GNSS_NOISE_JUMP:
            action = NOISE_RESTART
        elif moved:
            action = NOISE_MOVED
    return total, correlated, reported, action
