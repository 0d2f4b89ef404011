"""The gated measurement update with its recovery, and the books of every update.

``Corrections.update`` is what every kind's handler ends with: the chi-square gate on the
innovation's NIS (threshold core.filter.update_algebra.chi2_threshold), the Joseph update, the
feedback of the estimate into the nominal state and, after ``gate_recovery_count`` gated
updates of a sensor in a row, the recovery that grows the covariance until the measurement
fits. ``Corrections.book`` keeps the books of an update, made here or by a compiled update of
core.measurements: NIS, the process-noise adaptation, the runs of gated updates, the counters.

A measurement kind is a ``Kind`` (its name and how the gate treats it) and a ``KindUpdate``,
both in the kind's module of core.measurements, listed once in core.engine.measurement_kinds;
core.engine.loop registers the handlers in ``Corrections.handlers``. Called, a handler is the
general way: it takes the current nominal state, the filter, the prediction to the
measurement's stamp, the payload and ``live`` (first application: counted; a re-propagation is
not). Its ``fused`` applies the record in one compiled call with the covariance step before it,
where the kind has such a kernel and the general way would do just that; the base gives what
such a kernel reads and leaves in the filter and books.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from gnss_ins_common.types import FloatArray
from ins_fusion.core.compiled import kernel_array
from ins_fusion.core.filter.adaptation import adapt_process_noise, fading_factor
from ins_fusion.core.filter.eskf import ATT, ErrorStateFilter
from ins_fusion.core.filter.propagation import Propagator
from ins_fusion.core.filter.records import Prediction
from ins_fusion.core.filter.state import FilterState, Geometry, LatestInputs, inject
from ins_fusion.core.filter.status import Counters
from ins_fusion.core.filter.update_algebra import chi2_threshold
from ins_fusion.core.measurements.common import Model
from ins_fusion.core.measurements.gnss_noise import GnssNoise
from ins_fusion.core.settings.config import FusionConfig


@dataclass(frozen=True, slots=True)
class Kind:
    """A measurement kind: ``name``, the key of its counters, records and reports; ``adapts``:
    its normalised innovations scale the IMU process noise (adaptation.py); ``recovery_block``:
    the first of the error states a gate recovery widens (Corrections.update), None for none
    (the pseudo-measurements, constraints a real vehicle can break in a skid: their rejections
    stay rejections)."""

    name: str
    adapts: bool = False
    recovery_block: int | None = None


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
        self,
        s: FilterState,
        kf: ErrorStateFilter,
        kind: Kind,
        model: Model,
        live: bool,
        recoverable: bool = True,
    ) -> FloatArray | None:
        """Gated update; inject the estimate into the nominal state and return it (None:
        rejected). ``recoverable`` False: no gate recovery now, whatever the kind (the sensor,
        not the state, may be off)."""
        z, H, R = model
        if not s.heading_known:
            H = H.copy()
            H[:, ATT + 2] = 0.0
        result = kf.update(z, H, R, self._gates[len(z)])
        nis = result.nis  # booked as first tested, also when a recovery follows
        gated = not result.accepted and math.isfinite(nis)
        recover = self._config.gate_recovery_count
        block = kind.recovery_block if recoverable else None
        recovered = False
        runs = s.gated_runs.get(kind.name, 0) + 1
        if gated and recover and block is not None and runs >= recover:
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
        kind: Kind,
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
        name = kind.name
        self.nis[name] = nis
        if kind.adapts and math.isfinite(nis):
            s.nis_mean, s.q_scale = adapt_process_noise(s.nis_mean, s.q_scale, nis / rows)
        gated = not (accepted or recovered) and math.isfinite(nis)
        runs = s.gated_runs
        if gated or runs.get(name, 0):
            s.gated_runs = {**runs, name: runs.get(name, 0) + 1 if gated else 0}
        if live:
            counters = self._counters[name]
            if recovered:
                counters["recoveries"] += 1
            if accepted:
                counters["used"] += 1
            else:
                counters["rejected"] += 1
                counters["gated"] += 1

    def reject(self, kind: Kind, live: bool) -> None:
        """A measurement of ``kind`` not used: counted rejected when ``live``."""
        if live:
            self._counters[kind.name]["rejected"] += 1

    def count_used(self, kind: Kind, live: bool) -> None:
        """A measurement of ``kind`` used outside an update (the heading set from it): counted
        used when ``live``."""
        if live:
            self._counters[kind.name]["used"] += 1

    def too_fast_to_align(self, pred: Prediction, live: bool, kind: Kind) -> bool:
        """Heading unknown and moving: GNSS updates would need the yaw; count them rejected."""
        if float(np.hypot(pred.vel_ned_m_s[0], pred.vel_ned_m_s[1])) < _ALIGN_MAX_SPEED_M_S:
            return False
        self.reject(kind, live)
        return True


class EngineParts(NamedTuple):
    """The parts of the engine a kind's update is built with."""

    geometry: Geometry
    propagator: Propagator
    corrections: Corrections
    gnss_noise: GnssNoise
    latest: LatestInputs


class KindUpdate(ABC):
    """The base of each measurement kind's update (module docstring): what its compiled update
    reads (the configuration, the geometry, the propagator's white-noise densities, the gates)
    and what its kernel leaves in the filter and in the books."""

    def __init__(self, config: FusionConfig, parts: EngineParts) -> None:
        self._config = config
        self._geometry = parts.geometry
        self._propagator = parts.propagator
        self._corrections = corrections = parts.corrections
        self._correlation_time_s = config.gnss_correlation_time_s
        self._gates = (corrections.gate(1), corrections.gate(2), corrections.gate(3))

    @staticmethod
    def wanted(config: FusionConfig) -> bool:
        """Whether an engine of ``config`` has this kind (its counters and its handler)."""
        return True

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

    def _sensor_usable(self, s: FilterState, kf: ErrorStateFilter, kind: Kind) -> bool:
        """Whether the general way would apply a sensor's update of ``kind`` just as its
        kernel does: the heading known, no smoother (its history hears each step), no
        time-offset state (its terms) and no gate recovery possible (fewer gated updates in a
        row than the recovery needs)."""
        if kf.smoother_hooks is not None or kf.layout.td is not None or not s.heading_known:
            return False
        recover = self._config.gate_recovery_count
        return not recover or s.gated_runs.get(kind.name, 0) + 1 < recover

    def _sensor_taken(
        self,
        state: tuple[FilterState, ErrorStateFilter],
        kind: Kind,
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
        kind: Kind,
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
        self, s: FilterState, kind: Kind, result: tuple[bool, float], rows: int, live: bool
    ) -> None:
        """After an update of ``kind`` with ``rows`` rows a kernel made (``result``: accepted,
        NIS): the state changed when accepted, and its books (Corrections.book)."""
        if result[0]:
            s.changed()
        self._corrections.book(s, kind, result, rows, live)
