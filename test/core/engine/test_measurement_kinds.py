"""core.engine.measurement_kinds: one line per kind, and the kinds an engine has."""

from __future__ import annotations

from ins_fusion.core.engine.engine import InsEngine
from ins_fusion.core.engine.measurement_kinds import MEASUREMENT_NAMES, MEASUREMENTS, kinds_of
from ins_fusion.core.settings.config import FusionConfig


def test_each_kind_once_with_its_own_name() -> None:
    assert len(set(MEASUREMENT_NAMES)) == len(MEASUREMENTS)
    updates = [update for _, update in MEASUREMENTS if update is not None]
    assert len(set(updates)) == len(updates)
    # Counted only: set by the velocity's update or the start-up, never a record of its own.
    assert [kind.name for kind, update in MEASUREMENTS if update is None] == ["course_heading"]


def test_an_engine_has_the_speed_only_when_it_uses_it() -> None:
    plain = FusionConfig.from_parameters({})
    speed = FusionConfig.from_parameters({"speed.use": True})
    assert kinds_of(speed) == MEASUREMENT_NAMES
    assert kinds_of(plain) == tuple(n for n in MEASUREMENT_NAMES if n != "vehicle_speed")
    for config in (plain, speed):
        engine = InsEngine(config)
        assert tuple(engine.status().measurements) == kinds_of(config)
        assert set(engine._corrections.handlers) == set(kinds_of(config)) - {"course_heading"}


def test_only_the_sensor_kinds_adapt_and_recover() -> None:
    adapting = {kind.name for kind, _ in MEASUREMENTS if kind.adapts}
    recovering = {kind.name for kind, _ in MEASUREMENTS if kind.recovery_block is not None}
    assert adapting == {"gnss_position", "gnss_velocity"}
    assert recovering == {"gnss_position", "gnss_velocity", "attitude"}
