"""The attitude update (ADU5) with the covariance step before it in one compiled call.

An attitude receiver's epochs arrive late like the fixes, so each is applied once on arrival
and again in every re-propagation through its stamp. The general way (InsEngine._apply: the
covariance step and the prediction, Corrections._attitude with Geometry.measured_mat_nb and
the model ``measurements.attitude_model``, Corrections.update with the Joseph update and the
injection) is five kernels with Python between them; ``attitude_apply`` runs the same kernels
in the same order in one call, so the numbers are the same to the bit, and ``FusedAttitude``
keeps the books (NIS, gated runs, counters). Taken only where the general way would do nothing
else: the heading known (else the attitude sets it), no time-offset state, no smoother, and no
gate recovery possible.
"""

from __future__ import annotations

from gnss_ins_common.types import FloatArray, Quat
from ins_fusion.core.compiled import jit, kernel_array
from ins_fusion.core.filter.eskf import Columns, ErrorStateFilter, ProcessModel
from ins_fusion.core.filter.records import AttitudeMeasurement
from ins_fusion.core.filter.state import X_MOUNTING, FilterState, base_mat_nb
from ins_fusion.core.measurements.models import attitude_model
from ins_fusion.core.measurements.nhc import FusedUpdate, step_to, update_rows
from ins_fusion.core.nav.rotation import as_quat

_KIND = "attitude"


@jit
def attitude_apply(
    P: FloatArray,
    x: FloatArray,
    measured: tuple[float, Quat, FloatArray],
    process: ProcessModel,
    geometry: tuple[FloatArray, Quat],
    columns: Columns,
    constants: tuple[float, tuple[float, float, float], int],
) -> tuple[bool, FloatArray, int, bool, float, FloatArray]:
    """The attitude ``measured`` = (stamp [s], REP-103 orientation (x, y, z, w) of the
    receiver's frame, covariance of its roll, pitch, yaw [rad²]) on the error covariance ``P``
    and the nominal state ``x`` (X_* layout, changed in place; heading known): ``step_to`` the
    stamp, the model of base_link's Euler angles (``geometry``: rotation imu -> body, rotation
    of base_link in the receiver's frame) and ``update_rows``.
    ``constants``: GNSS correlation time [s], the gates of 1, 2 and 3 rows, state size.
    Returns (stepped, Φ of the step (P when none), rows of the model (0: no angle measured),
    accepted, NIS, the new P)."""
    t_m, quat_a, cov_rpy = measured
    mat_bi, q_a_base = geometry
    correlation_time_s, gates, size = constants
    stepped, phi, P, prediction = step_to(P, x, t_m, process, mat_bi, columns, correlation_time_s)
    _, _, _, _, mat_nb, rate_b, _ = prediction
    rows, z, H, R = attitude_model(
        mat_nb,
        base_mat_nb(quat_a, q_a_base),
        cov_rpy,
        (x[X_MOUNTING], x[X_MOUNTING + 1]),
        (rate_b, 0.0),
        size,
        columns[3],
        -1,
    )
    accepted, nis, P_new = update_rows(P, x, rows, (z, H, R), gates, columns)
    return stepped, phi, rows, accepted, nis, P_new


class FusedAttitude(FusedUpdate):
    """The engine's side of ``attitude_apply`` (InsEngine._apply uses it where ``usable``)."""

    def usable(self, s: FilterState, kf: ErrorStateFilter) -> bool:
        """Whether the general way would do just what ``apply`` does."""
        return self._sensor_usable(s, kf, _KIND)

    def apply(
        self, s: FilterState, kf: ErrorStateFilter, att: AttitudeMeasurement, live: bool
    ) -> None:
        """What InsEngine._apply does for an attitude record where ``usable`` (``live``:
        counted)."""
        geometry = self._geometry
        result = self._kernel(
            attitude_apply,
            (s, kf),
            (att.t_s, as_quat(att.quat_enu_flu_xyzw), kernel_array(att.cov_rpy_rad2)),
            (geometry.mat_bi, geometry.q_a_base),
            (self._correlation_time_s, self._gates, kf.layout.size),
        )
        self._sensor_taken((s, kf), _KIND, result, live)
