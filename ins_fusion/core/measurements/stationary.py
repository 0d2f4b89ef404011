"""The updates at rest, ZUPT and ZARU: their models, their handlers and their compiled updates,
each with the covariance step before it.

ZUPT (``zupt``, compiled ``zupt_model``): zero velocity of the IMU point. ZARU (``zaru``,
compiled ``zaru_model``, variance ``zaru_variance``): the mean calibrated rate over an interval
at rest measures the gyro bias. The stop detector that files them is
core.measurements.stop_detector; the handlers (``ZuptUpdate``, ``ZaruUpdate``) build the model
and call Corrections.update (core.measurements.gate), never with a gate recovery.

While the vehicle stands, every pseudo-measurement epoch files a ZUPT and a ZARU, and every
re-propagation after a late GNSS or attitude message applies them again. The general way
(InsEngine._apply: the covariance step and the prediction, the model ``zupt_model`` or
``zaru_model``, Corrections.update with the Joseph update and the injection) is four kernels
with Python between them; ``zupt_apply`` and ``zaru_apply`` run the same kernels in the same
order in one call each, so the numbers are the same to the bit, and the ``fused`` of
``ZuptUpdate`` and ``ZaruUpdate`` keeps the books. Taken while the heading is known (without it
the covariance step decouples the yaw and the earth rate's horizontal part is unknown) and
without the smoother; neither update has a gate recovery.
"""

from __future__ import annotations

import numpy as np

from gnss_ins_common.types import FloatArray
from ins_fusion.core.compiled import jit, kernel_array
from ins_fusion.core.filter.eskf import (
    BG,
    VEL,
    Columns,
    ErrorStateFilter,
    ProcessModel,
    StateLayout,
)
from ins_fusion.core.filter.records import Prediction
from ins_fusion.core.filter.state import X_BG, FilterState
from ins_fusion.core.measurements.common import Model, step_to, update_and_restart
from ins_fusion.core.measurements.gate import Kind, KindUpdate
from ins_fusion.core.nav.levelling import earth_rate_body_rad_s, unknown_earth_rate_rad_s
from ins_fusion.core.settings.config import FusionConfig

#: Zero velocity at rest and zero angular rate at rest (no recovery: constraints).
ZUPT = Kind("zupt")
ZARU = Kind("zaru")


def zupt(pred: Prediction, layout: StateLayout, sigma_m_s: float) -> Model:
    """Zero velocity of the IMU point: H: δv -> I. Compiled (``zupt_model``)."""
    return zupt_model(kernel_array(pred.vel_ned_m_s), sigma_m_s, layout.size)


@jit
def zupt_model(
    vel: FloatArray, sigma_m_s: float, size: int
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``zupt``'s model from the predicted NED velocity [m/s], σ [m/s] and the state size."""
    H = np.zeros((3, size))
    for k in range(3):
        H[k, VEL + k] = 1.0
    return -vel, H, np.eye(3) * sigma_m_s**2


def zaru(
    pred: Prediction,
    layout: StateLayout,
    rates_i: tuple[FloatArray, FloatArray],
    mat_bi: FloatArray,
    variance: FloatArray,
    heading_known: bool,
) -> Model:
    """Zero angular rate: the mean calibrated rate (imu FRD) over an interval at rest minus the
    earth rate and the bias estimate (``rates_i``: those two rates [rad/s]) measures the bias
    error (the scale error times the earth rate, < 1e-7 rad/s, is left out); the earth rate's
    horizontal part only with the heading known. H: δb_g -> I. Compiled (``zaru_model``)."""
    mean_rate_i, gyro_bias_i = rates_i
    return zaru_model(
        kernel_array(pred.mat_nb),
        pred.lat_rad,
        heading_known,
        (kernel_array(mean_rate_i), kernel_array(gyro_bias_i)),
        mat_bi,
        kernel_array(variance),
        layout.size,
    )


@jit
def zaru_model(
    mat_nb: FloatArray,
    lat_rad: float,
    heading_known: bool,
    rates_i: tuple[FloatArray, FloatArray],
    mat_bi: FloatArray,
    variance: FloatArray,
    size: int,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``zaru``'s model from the predicted body -> NED rotation and latitude [rad], the mean
    rate and the bias estimate (imu FRD) [rad/s], the rotation imu -> body, the variances
    [rad²/s²] and the state size."""
    mean_rate_i, gyro_bias_i = rates_i
    earth_rate_i = mat_bi.T @ earth_rate_body_rad_s(mat_nb, lat_rad, heading_known)
    H = np.zeros((3, size))
    for k in range(3):
        H[k, BG + k] = 1.0
    return mean_rate_i - earth_rate_i - gyro_bias_i, H, np.diag(variance)


def zaru_variance(config: FusionConfig, span_s: float) -> FloatArray:
    """The variances [rad²/s²] of a ZARU over ``span_s`` [s] at rest with the heading known:
    the gyro's white noise averaged over it and the configured σ."""
    return config.imu_noise.gyro_psd / max(span_s, 1e-3) + config.zaru_sigma_rad_s**2


class ZuptUpdate(KindUpdate):
    """The engine's update of ZUPT records (core.measurements.gate.KindUpdate; no payload);
    ``fused`` with ``zupt_apply``."""

    def __call__(
        self, s: FilterState, kf: ErrorStateFilter, pred: Prediction, _: None, live: bool
    ) -> None:
        model = zupt(pred, kf.layout, self._config.zupt_sigma_m_s)
        self._corrections.update(s, kf, ZUPT, model, live)

    def fused(
        self, s: FilterState, kf: ErrorStateFilter, record: tuple[float, None], live: bool
    ) -> bool:
        if not self._pseudo_usable(s, kf):
            return False
        result = self._kernel(
            zupt_apply,
            (s, kf),
            record[0],
            self._geometry.mat_bi,
            (self._correlation_time_s, self._config.zupt_sigma_m_s, self._gates[2], kf.layout.size),
        )
        return self._pseudo_taken((s, kf), ZUPT, result, 3, live)


class ZaruUpdate(KindUpdate):
    """The engine's update of ZARU records (core.measurements.gate.KindUpdate; payload: the mean
    calibrated rate [rad/s], imu FRD, and the span of the rest [s]): with the heading unknown
    the earth rate's horizontal part is added to the variance; ``fused`` with ``zaru_apply``."""

    def __call__(
        self,
        s: FilterState,
        kf: ErrorStateFilter,
        pred: Prediction,
        payload: tuple[FloatArray, float],
        live: bool,
    ) -> None:
        mean_rate_i, span_s = payload
        variance = zaru_variance(self._config, span_s)
        if not s.heading_known:
            variance = variance + unknown_earth_rate_rad_s(pred.lat_rad) ** 2
        rates_i = (mean_rate_i, s.x[X_BG : X_BG + 3])
        model = zaru(pred, kf.layout, rates_i, self._geometry.mat_bi, variance, s.heading_known)
        self._corrections.update(s, kf, ZARU, model, live)

    def fused(
        self,
        s: FilterState,
        kf: ErrorStateFilter,
        record: tuple[float, tuple[FloatArray, float]],
        live: bool,
    ) -> bool:
        if not self._pseudo_usable(s, kf):
            return False
        t_m, (mean_rate_i, span_s) = record
        result = self._kernel(
            zaru_apply,
            (s, kf),
            (t_m, kernel_array(mean_rate_i), zaru_variance(self._config, span_s)),
            self._geometry.mat_bi,
            (self._correlation_time_s, self._gates[2], kf.layout.size),
        )
        return self._pseudo_taken((s, kf), ZARU, result, 3, live)


@jit
def zupt_apply(
    P: FloatArray,
    x: FloatArray,
    t_m: float,
    process: ProcessModel,
    mat_bi: FloatArray,
    columns: Columns,
    constants: tuple[float, float, float, int],
) -> tuple[bool, FloatArray, bool, float, FloatArray]:
    """The ZUPT at stamp ``t_m`` [s] on the error covariance ``P`` and the nominal state ``x``
    (X_* layout, changed in place; heading known): ``step_to`` the stamp, the model and
    ``update_and_restart``. ``constants``: GNSS correlation time [s], ZUPT σ [m/s], the gate
    of 3 rows, state size. Returns (stepped, Φ of the step (P when none), accepted, NIS, the
    new P)."""
    correlation_time_s, sigma_m_s, threshold, size = constants
    stepped, phi, P, prediction = step_to(P, x, t_m, process, mat_bi, columns, correlation_time_s)
    model = zupt_model(prediction.vel_ned_m_s, sigma_m_s, size)
    accepted, nis, _, P_new = update_and_restart(P, x, model, threshold, columns)
    return stepped, phi, accepted, nis, P_new


@jit
def zaru_apply(
    P: FloatArray,
    x: FloatArray,
    measured: tuple[float, FloatArray, FloatArray],
    process: ProcessModel,
    mat_bi: FloatArray,
    columns: Columns,
    constants: tuple[float, float, int],
) -> tuple[bool, FloatArray, bool, float, FloatArray]:
    """The ZARU ``measured`` = (stamp [s], mean calibrated rate over the rest [rad/s], imu FRD,
    its variances [rad²/s²]) on ``P`` and ``x`` as ``zupt_apply``. ``constants``: GNSS
    correlation time [s], the gate of 3 rows, state size."""
    t_m, mean_rate_i, variance = measured
    correlation_time_s, threshold, size = constants
    stepped, phi, P, prediction = step_to(P, x, t_m, process, mat_bi, columns, correlation_time_s)
    rates_i = (mean_rate_i, x[X_BG : X_BG + 3])
    model = zaru_model(prediction.mat_nb, prediction.lat_rad, True, rates_i, mat_bi, variance, size)
    accepted, nis, _, P_new = update_and_restart(P, x, model, threshold, columns)
    return stepped, phi, accepted, nis, P_new
