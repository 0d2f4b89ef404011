"""The gated measurement update with its recovery, and the books of every update.

``Corrections.update`` is what every kind's handler ends with: the chi-square gate on the
innovation's NIS (threshold core.filter.update_algebra.chi2_threshold), the Joseph update, the
feedback of the estimate into the nominal state and, after ``gate_recovery_count`` gated
updates of a sensor in a row, the recovery that grows the covariance until the measurement
fits. ``Corrections.book`` keeps the books of an update, made here or by a compiled update of
core.measurements: NIS, the process-noise adaptation, the runs of gated updates, the counters.

``KindUpdate`` is the base of each kind's update, one class in the kind's module (gnss_position,
gnss_velocity, attitude, stationary, nhc, vehicle_speed), registered in ``Corrections.handlers``
by core.engine.loop. Called, it is the handler of the general way: it takes the current nominal
state, the filter, the prediction to the measurement's stamp, the payload and ``live`` (first
application: counted; a re-propagation is not). Its ``fused`` applies the record in one compiled
call with the covariance step before it, where the kind has such a kernel and the general way
would do just that; the base gives what such a kernel reads and leaves in the filter and books.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import Any

import numpy as np

from gnss_ins_common.types import FloatArray
from ins_fusion.core.compiled import kernel_array
from ins_fusion.core.filter.adaptation import adapt_process_noise, fading_factor
from ins_fusion.core.filter.eskf import ATT, POS, VEL, ErrorStateFilter
from ins_fusion.core.filter.propagation import Propagator
from ins_fusion.core.filter.records import Prediction
from ins_fusion.core.filter.state import FilterState, Geometry, inject
from ins_fusion.core.filter.status import Counters
from ins_fusion.core.filter.update_algebra import chi2_threshold
from ins_fusion.core.measurements.common import Model
from ins_fusion.core.settings.config import FusionConfig

#: The measurements whose normalised innovations scale the IMU process noise (adaptation.py).
_ADAPTING_KINDS = frozenset({"gnss_position", "gnss_velocity"})
#: The error states a gate recovery widens, per sensor measurement (Corrections.update); the
#: pseudo-measurements (ZUPT, ZARU, NHC) are constraints a real vehicle can break (a skid),
#: so their rejections stay rejections.
_RECOVERY_BLOCKS = {"gnss_position": POS, "gnss_velocity": VEL, "attitude": ATT}
#: While the heading is unknown, GNSS updates are applied only below this speed [m/s].
_ALIGN_MAX_SPEED_M_S = 1.0


class Corrections:
    """The gated update and the books (see the module docstring); ``handlers`` maps each
    measurement kind to its handler. ``counters`` and ``nis`` are the engine's (updated in
    place); ``fading`` is the last gate recovery's factor (1 = none)."""

    def __init__(self, config: FusionConfig, counters: Counters) -> None:
        self._config = config
        self._counters = counters
        self._gates = {dof: chi2_threshold(config.gate_probability, dof) for dof in (1, 2, 3)}
        self.nis = dict.fromkeys(counters, math.nan)
        self.fading = 1.0
        self.handlers: dict[str, KindUpdate] = {}

    def update(
        self, s: FilterState, kf: ErrorStateFilter, kind: str, model: Model, live: bool
    ) -> FloatArray | None:
        """Gated update; inject the estimate into the nominal state and return it (None:
        rejected)."""
        z, H, R = model
        if not s.heading_known:
            H = H.copy()
            H[:, ATT + 2] = 0.0
        result = kf.update(z, H, R, self._gates[len(z)])
        nis = result.nis  # booked as first tested, also when a recovery follows
        gated = not result.accepted and math.isfinite(nis)
        recover = self._config.gate_recovery_count
        block = _RECOVERY_BLOCKS.get(kind)
        if kind == "gnss_position" and not s.gnss_white.ready:
            block = None  # the receiver's noise is not learnt yet: it, not the state, may be off
        recovered = False
        if gated and recover and block is not None and s.gated_runs.get(kind, 0) + 1 >= recover:
            # The filter has rejected this sensor `recover` times running: its state, not the
            # sensor, is the likelier culprit (a state that went wrong and a covariance too
            # small to admit the fix, e.g. IMU noise far above the model). Grow the whole
            # covariance (attitude, biases, velocity with position: fading memory) by the least
            # factor that makes the innovation typical (NIS = dof), apply it. Only if no factor
            # does (the innovation lies outside what P spans) widen what the sensor measures.
            factor = fading_factor(z, H @ kf.P @ H.T, R, float(len(z)))
            P_before = kf.P
            if math.isfinite(factor):
                kf.scale(factor)
                self.fading = factor
            else:
                kf.widen(z, H, R, block)
            if kf.smoother_hooks is not None:  # smoother hook: the recovery's noise
                kf.smoother_hooks.on_noise(P_before, kf.P)
            result = kf.update(z, H, R, math.inf)
            recovered = True
        self.book(s, kind, (result.accepted, nis), len(z), live, recovered)
        if result.dx is not None:
            inject(s, kf, result.dx)
        return result.dx

    def gate(self, dof: int) -> float:
        """The gate on the NIS of a measurement of ``dof`` rows."""
        return self._gates[dof]

    def book(
        self,
        s: FilterState,
        kind: str,
        outcome: tuple[bool, float],
        rows: int,
        live: bool,
        recovered: bool = False,
    ) -> None:
        """The books of an update of ``kind`` with ``rows`` rows, made by ``update`` or by a
        compiled update (core.measurements: no gate recovery there): its NIS (``outcome``:
        accepted, NIS as first tested), the process-noise adaptation of a GNSS update, the runs
        of gated updates in ``s`` and, ``live``, its counters (``recovered``: a gate recovery
        admitted it)."""
        accepted, nis = outcome
        self.nis[kind] = nis
        if kind in _ADAPTING_KINDS and math.isfinite(nis):
            s.nis_mean, s.q_scale = adapt_process_noise(s.nis_mean, s.q_scale, nis / rows)
        gated = not (accepted or recovered) and math.isfinite(nis)
        runs = s.gated_runs
        if gated or runs.get(kind, 0):
            s.gated_runs = {**runs, kind: runs.get(kind, 0) + 1 if gated else 0}
        if live:
            counters = self._counters[kind]
            if recovered:
                counters["recoveries"] += 1
            if accepted:
                counters["used"] += 1
            else:
                counters["rejected"] += 1
                counters["gated"] += 1

    def reject(self, kind: str, live: bool) -> None:
        """A measurement of ``kind`` not used: counted rejected when ``live``."""
        if live:
            self._counters[kind]["rejected"] += 1

    def count_used(self, kind: str, live: bool) -> None:
        """A measurement of ``kind`` used outside an update (the heading set from it): counted
        used when ``live``."""
        if live:
            self._counters[kind]["used"] += 1

    def too_fast_to_align(self, pred: Prediction, live: bool, kind: str) -> bool:
        """Heading unknown and moving: GNSS updates would need the yaw; count them rejected."""
        if float(np.hypot(pred.vel_ned_m_s[0], pred.vel_ned_m_s[1])) < _ALIGN_MAX_SPEED_M_S:
            return False
        self.reject(kind, live)
        return True


class KindUpdate(ABC):
    """The base of each measurement kind's update (module docstring): what its compiled update
    reads (the configuration, the geometry, the propagator's white-noise densities, the gates)
    and what its kernel leaves in the filter and in the books."""

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

    @abstractmethod
    def __call__(
        self, s: FilterState, kf: ErrorStateFilter, pred: Prediction, payload: Any, live: bool
    ) -> None:
        """The general way's update of a record with ``payload`` after the covariance step and
        the prediction ``pred`` to its stamp (``live``: counted)."""

    def fused(
        self, s: FilterState, kf: ErrorStateFilter, record: tuple[float, Any], live: bool
    ) -> bool:
        """Apply ``record`` = (stamp [s], payload) in one compiled call with the covariance step
        before it, where the general way would do just that (``live``: counted); False: the
        general way applies it (always, for a kind without a compiled update)."""
        return False

    @staticmethod
    def _pseudo_usable(s: FilterState, kf: ErrorStateFilter) -> bool:
        """Whether the general way would apply a pseudo-measurement just as its kernel does:
        the heading known and no smoother (its history hears each step)."""
        return kf.smoother_hooks is None and s.heading_known

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
        kernel does: the heading known, no smoother (its history hears each step), no
        time-offset state (its terms) and no gate recovery possible (fewer gated updates in a
        row than the recovery needs)."""
        if kf.smoother_hooks is not None or kf.layout.td is not None or not s.heading_known:
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

    def _pseudo_taken(
        self,
        state: tuple[FilterState, ErrorStateFilter],
        kind: str,
        result: tuple[bool, FloatArray, bool, float, FloatArray],
        rows: int,
        live: bool,
    ) -> bool:
        """What a pseudo-measurement's kernel ``result`` (stepped, Φ, accepted, NIS, new P) of a
        model of ``rows`` rows leaves in the filter and the books; True (applied)."""
        s, kf = state
        stepped, phi, accepted, nis, P = result
        self._taken(kf, stepped, phi, P)
        self._booked(s, kind, (accepted, nis), rows, live)
        return True

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
