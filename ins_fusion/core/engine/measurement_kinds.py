"""Every measurement kind of the engine, one line each. A kind's module of core.measurements
holds the rest: its ``Kind`` (the name its counters, records and reports go by, and how the gate
treats it), its model, its noise and its update (core.measurements.gate.KindUpdate)."""

from __future__ import annotations

from ins_fusion.core.measurements.attitude import ATTITUDE, AttitudeUpdate
from ins_fusion.core.measurements.gate import EngineParts, Kind, KindUpdate
from ins_fusion.core.measurements.gnss_position import POSITION, PositionUpdate
from ins_fusion.core.measurements.gnss_velocity import COURSE_HEADING, VELOCITY, VelocityUpdate
from ins_fusion.core.measurements.nhc import NHC, NhcUpdate
from ins_fusion.core.measurements.stationary import ZARU, ZUPT, ZaruUpdate, ZuptUpdate
from ins_fusion.core.measurements.vehicle_speed import SPEED, SpeedUpdate
from ins_fusion.core.settings.config import FusionConfig

#: Each kind with its update (None: counted by another kind's update). The order is the one in
#: which the timeline applies records of one stamp and the reports list the counters.
MEASUREMENTS: tuple[tuple[Kind, type[KindUpdate] | None], ...] = (
    (POSITION, PositionUpdate),
    (VELOCITY, VelocityUpdate),
    (ATTITUDE, AttitudeUpdate),
    (ZUPT, ZuptUpdate),
    (ZARU, ZaruUpdate),
    (NHC, NhcUpdate),
    (COURSE_HEADING, None),  # by the velocity's update and the start-up
    (SPEED, SpeedUpdate),
)

#: The names of every kind, in that order.
MEASUREMENT_NAMES = tuple(kind.name for kind, _ in MEASUREMENTS)


def kinds_of(config: FusionConfig) -> tuple[str, ...]:
    """The names of the kinds an engine of ``config`` has (``KindUpdate.wanted``)."""
    return tuple(
        kind.name for kind, update in MEASUREMENTS if update is None or update.wanted(config)
    )


def updates_of(config: FusionConfig, parts: EngineParts) -> dict[str, KindUpdate]:
    """Each kind's update an engine of ``config`` has, by name, built from ``parts``."""
    return {
        kind.name: update(config, parts)
        for kind, update in MEASUREMENTS
        if update is not None and update.wanted(config)
    }
