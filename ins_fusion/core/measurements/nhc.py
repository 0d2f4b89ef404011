"""The non-holonomic constraint (NHC) with the covariance step before it in one compiled call.

The NHC is the engine's most frequent update (every pseudo-measurement epoch while driving,
again in every re-propagation through it). Applied the general way (InsEngine._apply) it is
five kernels with Python between them: the covariance step to the epoch
(Propagator.propagate_covariance), the prediction (Propagator.predict), the model
(measurements.nhc), the gated Joseph update (ErrorStateFilter.update) and the injection
(state.inject). ``nhc_apply`` runs the same kernels in the same order in one call, so the numbers
are the same to the bit; ``FusedNhc`` gives it its arguments and keeps the books
(Corrections.book). While the heading is known (the NHC is filed only then) and without the
smoother (its recorder is told of the steps in between); else the general way.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from gnss_ins_common.types import FloatArray
from ins_fusion.core.compiled import jit, kernel_array
from ins_fusion.core.filter.eskf import Columns, ErrorStateFilter, ProcessModel
from ins_fusion.core.filter.propagation import Propagator, covariance_step, predicted_state
from ins_fusion.core.filter.state import (
    X_COV_DT,
    X_COV_VEL0,
    X_MOUNTING,
    X_VEL,
    FilterState,
    Geometry,
    inject_nominal,
)
from ins_fusion.core.filter.update_algebra import joseph_update
from ins_fusion.core.measurements.models import nhc_model
from ins_fusion.core.measurements.updates import Corrections
from ins_fusion.core.settings.config import FusionConfig

#: What ``predicted_state`` gives: latitude, longitude [rad], height [m], NED velocity [m/s],
#: C_nb, corrected rate in body and imu FRD [rad/s].
Predicted = tuple[float, float, float, FloatArray, FloatArray, FloatArray, FloatArray]


@jit
def step_to(
    P: FloatArray,
    x: FloatArray,
    t_m: float,
    process: ProcessModel,
    mat_bi: FloatArray,
    columns: Columns,
    correlation_time_s: float,
) -> tuple[bool, FloatArray, FloatArray, Predicted]:
    """What InsEngine._apply does before a model (heading known, no smoother): the covariance
    step over the interval accumulated in ``x`` when there is one (``covariance_step``) and
    the prediction to ``t_m`` [s]. Returns (stepped, Φ of the step (P when none), the new P,
    the prediction)."""
    stepped = not x[X_COV_DT] <= 0.0  # as Propagator.propagate_covariance decides
    phi = P
    if stepped:
        P, phi = covariance_step(P, x, mat_bi, process, columns, correlation_time_s)
    return stepped, phi, P, predicted_state(x, t_m)


@jit
def update_and_restart(
    P: FloatArray,
    x: FloatArray,
    model: tuple[FloatArray, FloatArray, FloatArray],
    threshold: float,
    columns: Columns,
) -> tuple[bool, float, FloatArray, FloatArray]:
    """The gated Joseph update of ``model`` (z, H, R), the injection into ``x`` when accepted
    and the covariance interval going on from the corrected velocity (what Corrections.update
    and InsEngine._apply do after the model; heading known). Returns (accepted, NIS, δx (z
    when rejected), new P (P when rejected))."""
    z, H, R = model
    accepted, nis, dx, P_new = joseph_update(P, z, H, R, threshold)
    if accepted:
        inject_nominal(x, dx, columns)
    restart_interval(x)
    return accepted, nis, dx, P_new


@jit
def update_rows(
    P: FloatArray,
    x: FloatArray,
    rows: int,
    model: tuple[FloatArray, FloatArray, FloatArray],
    gates: tuple[float, float, float],
    columns: Columns,
) -> tuple[bool, float, FloatArray]:
    """``update_and_restart`` of a model of ``rows`` rows (1-3) at the gate of that many
    (``gates``: of 1, 2 and 3 rows); a model without rows (nothing measured) updates nothing,
    and the covariance interval goes on from the velocity all the same. Returns (accepted,
    NIS (NaN without rows), new P)."""
    if rows == 0:
        restart_interval(x)
        return False, math.nan, P
    accepted, nis, _, P_new = update_and_restart(P, x, model, gates[rows - 1], columns)
    return accepted, nis, P_new


@jit
def restart_interval(x: FloatArray) -> None:
    """The covariance interval in ``x`` goes on from the current velocity (after an update,
    as InsEngine._apply)."""
    for k in range(3):
        x[X_COV_VEL0 + k] = x[X_VEL + k]


@jit
def nhc_apply(
    P: FloatArray,
    x: FloatArray,
    t_m: float,
    process: ProcessModel,
    geometry: tuple[FloatArray, FloatArray],
    columns: Columns,
    constants: tuple[float, float, float, int],
) -> tuple[bool, FloatArray, bool, float, FloatArray]:
    """The NHC at stamp ``t_m`` [s] on the error covariance ``P`` and the nominal state ``x``
    (core.filter.state X_* layout, changed in place; heading known): ``step_to`` the stamp
    (``process``: ErrorStateFilter.process_model), the model of the base_link origin
    (``geometry``: rotation imu -> body, lever arm from the IMU [m], body FRD) and
    ``update_and_restart`` (``columns``: StateLayout.columns). ``constants``: GNSS
    correlation time [s], NHC σ [m/s], gate, state size.
    Returns (stepped, Φ of the step (P when none), accepted, NIS, the new P)."""
    mat_bi, arm_b = geometry
    sg, _, _, mt, _, _ = columns
    correlation_time_s, sigma_m_s, threshold, size = constants
    stepped, phi, P, prediction = step_to(P, x, t_m, process, mat_bi, columns, correlation_time_s)
    _, _, _, vel_m, mat_nb, rate_b, rate_i_m = prediction
    mounting = (x[X_MOUNTING], x[X_MOUNTING + 1])
    model = nhc_model(
        mat_nb, vel_m, rate_b, rate_i_m, arm_b, mat_bi, sigma_m_s, mounting, size, sg, mt
    )
    accepted, nis, _, P_new = update_and_restart(P, x, model, threshold, columns)
    return stepped, phi, accepted, nis, P_new


class FusedUpdate:
    """What the engine's side of a fused update reads: the configuration, the geometry, the
    propagator (its white-noise densities) and the corrections (gates, books)."""

    def __init__(
        self,
        config: FusionConfig,
        geometry: Geometry,
        propagator: Propagator,
        corrections: Corrections,
    ) -> None:
        self._config = config
        self._geometry = geometry
        self._propagator = propagator
        self._corrections = corrections
        self._correlation_time_s = config.gnss_correlation_time_s
        self._gates = (corrections.gate(1), corrections.gate(2), corrections.gate(3))

    def _kernel(
        self,
        kernel: Callable[..., Any],
        state: tuple[FilterState, ErrorStateFilter],
        measured: Any,
        geometry: Any,
        constants: Any,
    ) -> Any:
        """``kernel``(P, x, ``measured``, process model, ``geometry``, columns, ``constants``)
        on the ``state``'s filter (its white noise set first: read only by a step)."""
        s, kf = state
        kf.set_white_noise(*self._propagator.white_noise(s))
        return kernel(
            kernel_array(kf.P),
            s.x,
            measured,
            kf.process_model(),
            geometry,
            kf.layout.columns,
            constants,
        )

    def _sensor_usable(self, s: FilterState, kf: ErrorStateFilter, kind: str) -> bool:
        """Whether the general way would apply a sensor's update of ``kind`` just as its
        kernel does: the heading known, no smoother (its recorder hears each step), no
        time-offset state (its terms) and no gate recovery possible (fewer gated updates in a
        row than the recovery needs)."""
        if kf.recorder is not None or kf.layout.td is not None or not s.heading_known:
            return False
        recover = self._config.gate_recovery_count
        return not recover or s.gated_runs.get(kind, 0) + 1 < recover

    def _sensor_taken(
        self,
        state: tuple[FilterState, ErrorStateFilter],
        kind: str,
        result: tuple[bool, FloatArray, int, bool, float, FloatArray],
        live: bool,
    ) -> None:
        """What a sensor's kernel ``result`` (stepped, Φ, rows (0: unusable), accepted, NIS,
        new P) leaves in the filter and the books."""
        s, kf = state
        stepped, phi, rows, accepted, nis, P = result
        self._taken(kf, stepped, phi, P)
        if rows == 0:
            self._corrections.reject(kind, live)
            return
        self._booked(s, kind, (accepted, nis), rows, live)

    @staticmethod
    def _taken(kf: ErrorStateFilter, stepped: bool, phi: FloatArray, P: FloatArray) -> None:
        """What the kernel leaves in the filter: Φ of its covariance step (when it made one)
        and the new P."""
        if stepped:
            kf.phi = phi
        kf.P = P

    def _booked(
        self, s: FilterState, kind: str, result: tuple[bool, float], rows: int, live: bool
    ) -> None:
        """After an update of ``kind`` with ``rows`` rows a kernel made (``result``: accepted,
        NIS): the state changed when accepted, and its books (Corrections.book)."""
        if result[0]:
            s.changed()
        self._corrections.book(s, kind, result, rows, live)


class FusedNhc(FusedUpdate):
    """The engine's side of ``nhc_apply`` (InsEngine._apply uses it while no smoother is
    attached)."""

    def apply(self, s: FilterState, kf: ErrorStateFilter, t_m: float, live: bool) -> None:
        """What InsEngine._apply does for an NHC record at ``t_m`` while the heading is known
        (``live``: counted)."""
        geometry = self._geometry
        stepped, phi, accepted, nis, P = self._kernel(
            nhc_apply,
            (s, kf),
            t_m,
            (geometry.mat_bi, kernel_array(geometry.arms(s)[1])),
            (self._correlation_time_s, self._config.nhc_sigma_m_s, self._gates[1], kf.layout.size),
        )
        self._taken(kf, stepped, phi, P)
        self._booked(s, "nhc", (accepted, nis), 2, live)
