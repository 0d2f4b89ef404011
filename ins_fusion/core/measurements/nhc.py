"""The non-holonomic constraint (NHC): its model, its handler and its compiled update with the
covariance step before it.

The model (``nhc``, compiled ``nhc_model``): no lateral or vertical velocity of base_link's
origin in the vehicle frame. The handler (``NhcUpdate``) builds it and calls Corrections.update
(core.measurements.gate), never with a gate recovery. The stop detector files an NHC at every
pseudo-measurement epoch while the vehicle moves with the heading known.

The NHC is the engine's most frequent update (every pseudo-measurement epoch while driving,
again in every re-propagation through it). Applied the general way (InsEngine._apply) it is
five kernels with Python between them: the covariance step to the epoch
(Propagator.propagate_covariance), the prediction (Propagator.predict), the model
(``nhc_model``), the gated Joseph update (ErrorStateFilter.update) and the injection
(state.inject). ``nhc_apply`` runs the same kernels in the same order in one call (the steps
every compiled update shares, core.measurements.common: ``step_to``, ``update_and_restart``), so
the numbers are the same to the bit; ``NhcUpdate.fused`` gives it its arguments and keeps the books
(core.measurements.gate: KindUpdate, Corrections.book). While the heading is known (the NHC is
filed only then) and without the smoother (its history is told of the steps in between); else
the general way.
"""

from __future__ import annotations

import numpy as np

from gnss_ins_common.types import FloatArray
from ins_fusion.core.compiled import compilable, jit, kernel_array
from ins_fusion.core.filter.eskf import (
    ATT,
    VEL,
    Columns,
    ErrorStateFilter,
    ProcessModel,
    StateLayout,
)
from ins_fusion.core.filter.records import Prediction
from ins_fusion.core.filter.state import (
    X_HEADING_KNOWN,
    X_MOUNTING,
    FilterState,
    nav_speeds,
)
from ins_fusion.core.measurements.common import (
    Model,
    gyro_error_columns,
    step_to,
    update_and_restart,
)
from ins_fusion.core.measurements.gate import Kind, KindUpdate
from ins_fusion.core.nav.rotation import skew

#: The non-holonomic constraint's epochs (no recovery: a skid breaks it).
NHC = Kind("nhc")


def nhc(
    pred: Prediction,
    layout: StateLayout,
    arm_b: FloatArray,
    mat_bi: FloatArray,
    sigma_m_s: float,
    mounting_rad: tuple[float, float] = (0.0, 0.0),
) -> Model:
    """No lateral or vertical velocity of the point ``arm_b`` (base_link origin) in the
    vehicle frame: v_b = C_nbᵀ v + ω_b × r in base_link, turned into the vehicle frame by the
    residual mounting μ = (pitch, yaw) about base_link FRD y and z, C_vb = I - [μ×]:
    lateral v_b,y - μ_z v_b,x, vertical v_b,z + μ_y v_b,x. H: δv -> C_nbᵀ, ψ -> C_nbᵀ [v×],
    gyro errors -> -[r×] dω_b (``gyro_error_columns``), δμ_y -> +v_b,x
    (vertical), δμ_z -> -v_b,x (lateral) (the mounting's second-order terms in H left out).
    Compiled (``nhc_model``)."""
    return nhc_model(
        pred,
        arm_b,
        mat_bi,
        sigma_m_s,
        mounting_rad,
        layout.size,
        layout.columns,
    )


@jit
def nhc_model(
    pred: Prediction,
    arm_b: FloatArray,
    mat_bi: FloatArray,
    sigma_m_s: float,
    mounting_rad: tuple[float, float],
    size: int,
    columns: Columns,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``nhc``'s model from the prediction and the layout's size and columns (-1: state not
    estimated)."""
    mat_nb, vel, rate_b, rate_i = pred.mat_nb, pred.vel_ned_m_s, pred.rate_b, pred.rate_i
    c_bn = np.ascontiguousarray(mat_nb.T)
    v_b = c_bn @ vel + skew(rate_b) @ arm_b
    H = np.zeros((3, size))
    H[:, VEL : VEL + 3] = c_bn
    H[:, ATT : ATT + 3] = c_bn @ skew(vel)
    gyro_error_columns(H, -skew(arm_b), mat_bi, rate_i, columns)
    mt = columns.mt
    pitch, yaw = mounting_rad
    forward = v_b[0]
    predicted = np.array((v_b[1] - yaw * forward, v_b[2] + pitch * forward))
    if mt >= 0:
        H[1, mt + 1] = -forward
        H[2, mt] = forward
    return -predicted, H[1:].copy(), np.eye(2) * sigma_m_s**2


@compilable
def nhc_due(x: FloatArray, use_nhc: bool, min_speed_m_s: float) -> bool:
    """Whether a pseudo-measurement epoch without a stop files an NHC: ``use_nhc``, the heading
    of the nominal state ``x`` (X_* layout) known and its horizontal speed above
    ``min_speed_m_s`` [m/s]."""
    return use_nhc and x[X_HEADING_KNOWN] != 0.0 and nav_speeds(x)[0] > min_speed_m_s


class NhcUpdate(KindUpdate):
    """The engine's update of NHC records (core.measurements.gate.KindUpdate; no payload): the
    model of the base_link origin with the residual mounting and the gated update; ``fused``
    with ``nhc_apply``."""

    def __call__(
        self, s: FilterState, kf: ErrorStateFilter, pred: Prediction, _: None, live: bool
    ) -> None:
        geometry = self._geometry
        sigma_m_s = self._config.nhc_sigma_m_s
        model = nhc(pred, kf.layout, geometry.arms(s)[1], geometry.mat_bi, sigma_m_s, s.mounting)
        self._corrections.update(s, kf, NHC, model, live)

    def fused(
        self, s: FilterState, kf: ErrorStateFilter, record: tuple[float, None], live: bool
    ) -> bool:
        if not self._pseudo_usable(s, kf):
            return False
        geometry = self._geometry
        result = self._kernel(
            nhc_apply,
            (s, kf),
            record[0],
            (geometry.mat_bi, kernel_array(geometry.arms(s)[1])),
            (self._correlation_time_s, self._config.nhc_sigma_m_s, self._gates[1], kf.layout.size),
        )
        return self._pseudo_taken((s, kf), NHC, result, 2, live)


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
    correlation_time_s, sigma_m_s, threshold, size = constants
    stepped, phi, P, prediction = step_to(P, x, t_m, process, mat_bi, columns, correlation_time_s)
    mounting = (x[X_MOUNTING], x[X_MOUNTING + 1])
    model = nhc_model(
        prediction,
        arm_b,
        mat_bi,
        sigma_m_s,
        mounting,
        size,
        columns,
    )
    accepted, nis, _, P_new = update_and_restart(P, x, model, threshold, columns)
    return stepped, phi, accepted, nis, P_new
