"""The GNSS velocity update with the covariance step before it in one compiled call.

Every fix comes with a velocity, and both arrive late: each is applied once when it arrives
and again in every re-propagation through its stamp. The general way (InsEngine._apply:
Propagator.propagate_covariance and predict, Corrections._gnss_velocity with the model
``measurements._velocity_model``, Corrections.update with the Joseph update and the injection)
is five kernels with Python between them; ``velocity_apply`` runs the same kernels in the same
order in one call (the NHC's ``step_to`` and ``update_and_restart``), so the numbers are the
same to the bit, and ``FusedVelocity`` keeps the books (NIS, process-noise adaptation, gated
runs, counters). Taken only where the general way would do nothing else: the heading known,
velocity updates on, no time-offset state (its terms), no smoother (its recorder hears each
step), and no gate recovery possible (fewer gated updates in a row than the recovery needs).
"""

from __future__ import annotations

from gnss_ins_common.types import FloatArray
from ins_fusion.core.compiled import jit, kernel_array
from ins_fusion.core.filter.eskf import Columns, ErrorStateFilter, ProcessModel
from ins_fusion.core.filter.records import GnssVelocityMeasurement
from ins_fusion.core.filter.state import FilterState
from ins_fusion.core.measurements.models import _velocity_model
from ins_fusion.core.measurements.nhc import FusedUpdate, step_to, update_rows

_KIND = "gnss_velocity"


@jit
def velocity_apply(
    P: FloatArray,
    x: FloatArray,
    measured: tuple[float, FloatArray, FloatArray],
    process: ProcessModel,
    geometry: tuple[FloatArray, FloatArray],
    columns: Columns,
    constants: tuple[float, tuple[float, float, float], int],
) -> tuple[bool, FloatArray, int, bool, float, FloatArray]:
    """The GNSS velocity ``measured`` = (stamp [s], ENU velocity [m/s], its covariance
    [m²/s²]) on the error covariance ``P`` and the nominal state ``x`` (X_* layout, changed in
    place; heading known): ``step_to`` the stamp, the model of the antenna (``geometry``:
    rotation imu -> body, lever arm of the antenna from the IMU [m], body FRD) and
    ``update_rows``. ``constants``: GNSS correlation time [s], the gates of 1, 2 and 3 rows,
    state size. Returns (stepped, Φ of the step (P when none), rows of the model
    (0: unusable), accepted, NIS, the new P)."""
    t_m, vel_enu, cov_enu = measured
    mat_bi, arm_b = geometry
    correlation_time_s, gates, size = constants
    stepped, phi, P, prediction = step_to(P, x, t_m, process, mat_bi, columns, correlation_time_s)
    _, _, _, vel_m, mat_nb, rate_b, rate_i_m = prediction
    rows, z, H, R = _velocity_model(
        mat_nb, vel_m, rate_b, rate_i_m, arm_b, mat_bi, vel_enu, cov_enu, size, columns[0]
    )
    accepted, nis, P_new = update_rows(P, x, rows, (z, H, R), gates, columns)
    return stepped, phi, rows, accepted, nis, P_new


class FusedVelocity(FusedUpdate):
    """The engine's side of ``velocity_apply`` (InsEngine._apply uses it where ``usable``)."""

    def usable(self, s: FilterState, kf: ErrorStateFilter) -> bool:
        """Whether the general way would do just what ``apply`` does."""
        return self._config.use_gnss_velocity and self._sensor_usable(s, kf, _KIND)

    def apply(
        self, s: FilterState, kf: ErrorStateFilter, vel: GnssVelocityMeasurement, live: bool
    ) -> None:
        """What InsEngine._apply does for a GNSS velocity record where ``usable`` (``live``:
        counted)."""
        geometry = self._geometry
        result = self._kernel(
            velocity_apply,
            (s, kf),
            (vel.t_s, kernel_array(vel.vel_enu_m_s), kernel_array(vel.cov_enu_m2_s2)),
            (geometry.mat_bi, kernel_array(geometry.arms(s)[0])),
            (self._correlation_time_s, self._gates, kf.layout.size),
        )
        self._sensor_taken((s, kf), _KIND, result, live)
