"""The updates at rest, ZUPT and ZARU, each with the covariance step before it in one compiled
call.

While the vehicle stands, every pseudo-measurement epoch files a ZUPT and a ZARU, and every
re-propagation after a late GNSS or attitude message applies them again. The general way
(InsEngine._apply: the covariance step and the prediction, the model ``measurements.zupt_model``
or ``zaru_model``, Corrections.update with the Joseph update and the injection) is four kernels
with Python between them; ``zupt_apply`` and ``zaru_apply`` run the same kernels in the same
order in one call each, so the numbers are the same to the bit, and ``FusedStationary`` keeps
the books. Taken while the heading is known (without it the covariance step decouples the yaw
and the earth rate's horizontal part is unknown) and without the smoother; neither update has
a gate recovery.
"""

from __future__ import annotations

from gnss_ins_common.types import FloatArray
from ins_fusion.core.compiled import jit, kernel_array
from ins_fusion.core.filter.eskf import Columns, ErrorStateFilter, ProcessModel
from ins_fusion.core.filter.state import X_BG, FilterState
from ins_fusion.core.measurements.models import zaru_model, zupt_model
from ins_fusion.core.measurements.nhc import FusedUpdate, step_to, update_and_restart


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
    model = zupt_model(prediction[3], sigma_m_s, size)
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
    lat, _, _, _, mat_nb, _, _ = prediction
    rates_i = (mean_rate_i, x[X_BG : X_BG + 3])
    model = zaru_model(mat_nb, lat, True, rates_i, mat_bi, variance, size)
    accepted, nis, _, P_new = update_and_restart(P, x, model, threshold, columns)
    return stepped, phi, accepted, nis, P_new


class FusedStationary(FusedUpdate):
    """The engine's side of ``zupt_apply`` and ``zaru_apply`` (InsEngine._apply uses them while
    the heading is known and no smoother is attached)."""

    def zupt(self, s: FilterState, kf: ErrorStateFilter, t_m: float, live: bool) -> None:
        """What InsEngine._apply does for a ZUPT record at ``t_m`` (``live``: counted)."""
        stepped, phi, accepted, nis, P = self._kernel(
            zupt_apply,
            (s, kf),
            t_m,
            self._geometry.mat_bi,
            (self._correlation_time_s, self._config.zupt_sigma_m_s, self._gates[2], kf.layout.size),
        )
        self._taken(kf, stepped, phi, P)
        self._booked(s, "zupt", (accepted, nis), 3, live)

    def zaru(
        self,
        s: FilterState,
        kf: ErrorStateFilter,
        record: tuple[float, tuple[FloatArray, float]],
        live: bool,
    ) -> None:
        """What InsEngine._apply does for a ZARU ``record`` = (stamp [s], (mean rate [rad/s],
        imu FRD, span of the rest [s])) (``live``: counted)."""
        t_m, (mean_rate_i, span_s) = record
        stepped, phi, accepted, nis, P = self._kernel(
            zaru_apply,
            (s, kf),
            (t_m, kernel_array(mean_rate_i), self._corrections.zaru_variance(span_s)),
            self._geometry.mat_bi,
            (self._correlation_time_s, self._gates[2], kf.layout.size),
        )
        self._taken(kf, stepped, phi, P)
        self._booked(s, "zaru", (accepted, nis), 3, live)
