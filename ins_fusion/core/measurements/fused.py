"""Which measurement records the engine applies in one compiled call (the kernels of
core.measurements: nhc, stationary, gnss_velocity, gnss_position, attitude).

InsEngine._apply asks ``FusedUpdates.applied`` first; where no fused update takes the record
(the smoother attached, the heading unknown, the time-offset state, a gate recovery possible,
a kind without one), the general way applies it.
"""

from __future__ import annotations

from typing import Any

from ins_fusion.core.filter.eskf import ErrorStateFilter
from ins_fusion.core.filter.propagation import Propagator
from ins_fusion.core.filter.state import FilterState, Geometry
from ins_fusion.core.measurements.attitude import FusedAttitude
from ins_fusion.core.measurements.gate import Corrections
from ins_fusion.core.measurements.gnss_noise import GnssNoise
from ins_fusion.core.measurements.gnss_position import FusedPosition
from ins_fusion.core.measurements.gnss_velocity import FusedVelocity
from ins_fusion.core.measurements.nhc import FusedNhc
from ins_fusion.core.measurements.stationary import FusedStationary
from ins_fusion.core.settings.config import FusionConfig

#: The pseudo-measurements: fused while the heading is known and no smoother is attached.
_PSEUDO = frozenset({"nhc", "zupt", "zaru"})


class FusedUpdates:
    """The fused NHC, ZUPT, ZARU, GNSS velocity, attitude and GNSS position updates of one
    engine."""

    def __init__(
        self,
        config: FusionConfig,
        geometry: Geometry,
        propagator: Propagator,
        corrections: Corrections,
        gnss_noise: GnssNoise,
    ) -> None:
        self._nhc = FusedNhc(config, geometry, propagator, corrections)
        self._stationary = FusedStationary(config, geometry, propagator, corrections)
        self._velocity = FusedVelocity(config, geometry, propagator, corrections)
        self._attitude = FusedAttitude(config, geometry, propagator, corrections)
        self._position = FusedPosition(config, geometry, (propagator, corrections, gnss_noise))

    def applied(
        self,
        s: FilterState,
        kf: ErrorStateFilter,
        record: tuple[str, float, Any],
        live: bool,
    ) -> bool:
        """Whether a fused update applied ``record`` = (kind, stamp [s], payload) (``live``:
        counted). False: the general way applies it; for a fix, possibly after the
        covariance step the kernel made (core.measurements.gnss_position)."""
        kind, t_m, payload = record
        if kind in _PSEUDO:
            if kf.smoother_hooks is not None or not s.heading_known:
                return False
            if kind == "nhc":
                self._nhc.apply(s, kf, t_m, live)
            elif kind == "zupt":
                self._stationary.zupt(s, kf, t_m, live)
            else:
                self._stationary.zaru(s, kf, (t_m, payload), live)
        elif kind == "gnss_velocity":
            if not self._velocity.usable(s, kf):
                return False
            self._velocity.apply(s, kf, payload, live)
        elif kind == "attitude":
            if not self._attitude.usable(s, kf):
                return False
            self._attitude.apply(s, kf, payload, live)
        elif kind == "gnss_position":
            position = self._position
            return position.usable(s, kf, payload) and position.apply(s, kf, payload, live)
        else:
            return False
        return True
