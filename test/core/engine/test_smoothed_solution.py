"""The smoother's history on the real engine (core.engine.smoothed_solution.attach_history): the
hooks do not change the forward solution, late measurements (rollbacks, re-propagation) leave the
records of the final timeline, and the smoothed solution beats the forward one in an outage."""

from __future__ import annotations

import math

import numpy as np
import pytest
from support.drives import CALIBRATION, Drive, config, feed, simulate

from ins_fusion.core.engine.engine import InsEngine, InsSolution
from ins_fusion.core.engine.smoothed_solution import attach_history, smoothed_rows
from ins_fusion.core.nav import earth
from ins_fusion.core.nav.calibration import ImuCalibration
from ins_fusion.core.output.solution_rows import unpack

DURATION_S = 70.0
#: GNSS (fix, velocity, attitude) withheld by stamp, as `gnss_ins replay --outage` does [s].
OUTAGE = (40.0, 12.0)


@pytest.fixture(scope="module")
def drive() -> Drive:
    return simulate(DURATION_S, seed=5, with_attitude=True, scenario="figure_eight")


def _engine(**overrides) -> InsEngine:
    cfg = config(**{"alignment__duration": 5.0, **overrides})
    return InsEngine(cfg, ImuCalibration.from_yaml(CALIBRATION))


def _late(drive: Drive, after_s: float, delay_s: float) -> list:
    """Every measurement arriving after ``after_s`` delivered ``delay_s`` later."""
    return [(t + delay_s if t >= after_s else t, m) for t, m in drive.events]


def _smoothed(engine: InsEngine, drive: Drive, events=None) -> list[InsSolution]:
    history = attach_history(engine, chunk_records=256)  # several chunks go to disk
    feed(engine, drive, events=events)
    history.finish(engine.covariance)
    assert history.bytes_on_disk > 0
    solutions = [unpack(row) for row in smoothed_rows(history)]
    history.close()
    return solutions


def test_the_hooks_leave_the_forward_solution_unchanged(drive):
    plain, recorded = _engine(), _engine()
    attach_history(recorded)
    events = _late(drive, 20.0, 0.3)  # with rollbacks
    outputs: dict[str, list[InsSolution]] = {"plain": [], "recorded": []}
    for name, engine in (("plain", plain), ("recorded", recorded)):

        def after(i: int, engine=engine, out=outputs[name]) -> None:
            if i % 67 == 0 and (solution := engine.solution()) is not None:
                out.append(solution)

        feed(engine, drive, events=events, after_sample=after)
    assert len(outputs["plain"]) == len(outputs["recorded"]) > 50
    for a, b in zip(outputs["plain"], outputs["recorded"], strict=True):
        assert a.t_s == b.t_s
        np.testing.assert_array_equal(a.pos_enu_m, b.pos_enu_m)
        np.testing.assert_array_equal(a.cov_pos_enu_m2, b.cov_pos_enu_m2)
    assert recorded.status().rollbacks > 20


def test_late_measurements_leave_the_records_of_the_final_timeline():
    # Pseudo-measurements off and P propagated per sample: the forward result is then a
    # function of the set of measurements alone (test_fusion_engine), so is the smoothed one.
    # The IMU at base_link: a snapshot taken while re-propagating has the newest sample's rate
    # (solution() knows no other), which with a lever arm would move the velocity by ω × r.
    cfg = {
        "use_zupt": False,
        "use_zaru": False,
        "use_nhc": False,
        "covariance_interval": 0.0,
        "imu_lever_arm": [0.0, 0.0, 0.0],
    }
    short = simulate(30.0, seed=6, with_attitude=True, scenario="figure_eight")
    in_time = _smoothed(_engine(**cfg), short)
    late_engine = _engine(**cfg)
    late = _smoothed(late_engine, short, _late(short, 15.0, 0.8))
    assert late_engine.status().replayed_samples > 1500
    assert [s.t_s for s in late] == [s.t_s for s in in_time]
    for a, b in zip(in_time, late, strict=True):
        assert b.lat_deg == pytest.approx(a.lat_deg, abs=1e-10)  # 0.01 mm
        assert b.lon_deg == pytest.approx(a.lon_deg, abs=1e-10)
        np.testing.assert_allclose(b.vel_enu_m_s, a.vel_enu_m_s, atol=1e-6)
        np.testing.assert_allclose(b.cov_pos_enu_m2, a.cov_pos_enu_m2, atol=1e-9)


def _horizontal_errors(solutions: list[InsSolution], drive: Drive) -> tuple[np.ndarray, ...]:
    t = np.array([s.t_s for s in solutions])
    truth = drive.truth.base_link(t)
    errors = []
    for i, s in enumerate(solutions):
        r_m, r_n = earth.radii_m(float(truth.lat_rad[i]))
        north = (math.radians(s.lat_deg) - truth.lat_rad[i]) * (r_m + truth.height_m[i])
        east = (math.radians(s.lon_deg) - truth.lon_rad[i]) * (r_n + truth.height_m[i])
        errors.append(math.hypot(east * math.cos(truth.lat_rad[i]), north))
    return t, np.array(errors)


def test_the_smoothed_solution_bridges_the_outage(drive):
    engine = _engine()
    forward: list[InsSolution] = []

    def after(i: int) -> None:
        if i % 13 == 0 and (s := engine.solution()) is not None and s.state != "aligning":
            forward.append(s)

    start, end = OUTAGE[0], OUTAGE[0] + OUTAGE[1]
    events = [(t, m) for t, m in drive.events if not start <= m.t_s < end]
    history = attach_history(engine)
    feed(engine, drive, events=events, after_sample=after)
    history.finish(engine.covariance)
    smoothed = [unpack(row) for row in smoothed_rows(history)]
    t_f, e_f = _horizontal_errors(forward, drive)
    t_s, e_s = _horizontal_errors(smoothed, drive)
    forward_max = e_f[(t_f >= start) & (t_f < end)].max()
    smoothed_max = e_s[(t_s >= start) & (t_s < end)].max()
    assert smoothed_max < 0.5 * forward_max
    sigma = np.array([math.sqrt(np.trace(s.cov_pos_enu_m2[:2, :2])) for s in smoothed])
    assert np.mean(e_s <= 3.0 * sigma) > 0.9
