"""core.engine.sample_runs via InsEngine.add_imu_series (what a replay runs) and the re-propagation
runs after late measurements: the same rows and counters, to the bit, as feeding the engine
sample by sample with add_imu and solution_row and re-propagating entry by entry, on
a drive with late GNSS data and with damaged IMU data (corrupt samples, a gap, a duplicate
stamp, a stamp out of order, a clock that goes back). With the fused NHC (core.measurements.nhc) as
well, against the engine with the smoother's history attached, which takes every sample and
every update the general way."""

from __future__ import annotations

import numpy as np
import pytest
from support.sample_runs import SETS, damaged, figure_eight, sample_by_sample
from support.sim_bags import TEST_PATTERN_75_S, shared_bag

from gnss_ins_common.params import validate_all
from ins_fusion.core.compiled import kernel_array
from ins_fusion.core.engine import sample_runs
from ins_fusion.core.engine.engine import InsEngine
from ins_fusion.core.measurements.attitude import AttitudeUpdate
from ins_fusion.core.measurements.gnss_position import PositionUpdate
from ins_fusion.core.measurements.gnss_velocity import VelocityUpdate
from ins_fusion.core.measurements.stationary import ZaruUpdate, ZuptUpdate
from ins_fusion.core.output.output_clock import output_ticks
from ins_fusion.core.output.solution_rows import RowBuffer
from ins_fusion.core.settings.config import FusionConfig
from ins_fusion.core.settings.params import PARAMETERS
from ins_fusion.replay.inputs import ReplayInputs, load_bag
from ins_fusion.replay.run import run_fusion
from ins_fusion.replay.topics import TopicMap


@pytest.fixture(scope="module")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> ReplayInputs:
    return figure_eight(tmp_path_factory)


@pytest.fixture(scope="module")
def standstill(tmp_path_factory: pytest.TempPathFactory) -> ReplayInputs:
    return load_bag(
        shared_bag(tmp_path_factory, "test_pattern_75_s", TEST_PATTERN_75_S), TopicMap()
    )


@pytest.mark.parametrize("damage", [False, True], ids=["clean", "damaged"])
@pytest.mark.parametrize("name", list(SETS))
def test_runs_equal_sample_by_sample(inputs: ReplayInputs, name: str, damage: bool) -> None:
    if damage:
        inputs = damaged(inputs)
    parameters = validate_all(PARAMETERS, SETS[name])
    expected_rows, expected_status = sample_by_sample(inputs, parameters, smooth=False)
    run = run_fusion(inputs, parameters)
    assert run.status.rollbacks > 100  # late GNSS data: re-propagation between the runs
    if damage:
        assert run.status.resets >= 1 and run.status.imu_gaps >= 3
        assert run.status.imu_duplicates >= 1 and run.status.imu_out_of_order >= 1
    assert run.track.rows.shape == expected_rows.shape and len(expected_rows) > 3000
    np.testing.assert_array_equal(run.track.rows, expected_rows)
    assert repr(run.status) == repr(expected_status)


def test_with_the_smoother_attached_the_engine_goes_sample_by_sample(inputs: ReplayInputs):
    parameters = validate_all(PARAMETERS, {})
    expected_rows, expected_status = sample_by_sample(inputs, parameters, smooth=True)
    run = run_fusion(inputs, parameters, smooth=True)
    np.testing.assert_array_equal(run.track.rows, expected_rows)
    assert repr(run.status) == repr(expected_status)


@pytest.mark.parametrize("damage", [False, True], ids=["clean", "damaged"])
@pytest.mark.parametrize("name", ["defaults", "all_states"])
@pytest.mark.parametrize("drive", ["inputs", "standstill"])
def test_the_fast_paths_equal_the_general_path(
    request: pytest.FixtureRequest,
    drive: str,
    name: str,
    damage: bool,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Compiled runs, the fused NHC, ZUPT, ZARU, GNSS velocity, attitude and position (no
    smoother) against sample by sample with the smoother's history attached (no run, every
    update the general way; the history only listens): on the figure eight (driving) and on
    the test pattern (mostly at rest)."""
    inputs = request.getfixturevalue(drive)
    if damage:
        inputs = damaged(inputs)
    parameters = validate_all(PARAMETERS, SETS[name])
    expected_rows, expected_status = sample_by_sample(inputs, parameters, smooth=True)
    taken = _count_runs(monkeypatch)
    fused = {"velocity": 0, "position": 0, "attitude": 0, "zupt": 0, "zaru": 0}
    for kind, update in (
        ("velocity", VelocityUpdate),
        ("position", PositionUpdate),
        ("attitude", AttitudeUpdate),
        ("zupt", ZuptUpdate),
        ("zaru", ZaruUpdate),
    ):
        apply = update.fused

        def counted(*args, kind=kind, apply=apply):  # type: ignore[no-untyped-def]
            done = apply(*args)
            fused[kind] += done  # False: the general way (the position's: after the step)
            return done

        monkeypatch.setattr(update, "fused", counted)
    run = run_fusion(inputs, parameters)
    sensors = min(fused[kind] for kind in ("velocity", "position", "attitude"))
    if drive == "inputs":
        assert run.status.measurements["nhc"]["used"] > 300
        # The runs took pseudo-measurement epochs with their NHC and covariance steps.
        assert taken["nhc"] > 300 and taken["covariances"] > taken["nhc"] + 100
        # The GNSS and attitude updates went through the fused ones, but with the time-offset
        # state.
        assert (sensors > 50) == (name == "defaults"), fused
    else:  # the updates at rest through the fused ones, also with the time-offset state
        assert min(fused["zupt"], fused["zaru"]) > 300, fused
    np.testing.assert_array_equal(run.track.rows, expected_rows)
    assert repr(run.status) == repr(expected_status)


def _count_runs(monkeypatch: pytest.MonkeyPatch) -> dict[str, int]:
    """Totals of what take_run returns from now on: covariances handed back, NHC updates,
    runs ended by an unusable filter."""
    taken = {"covariances": 0, "nhc": 0, "problems": 0}
    take_run = sample_runs.take_run

    def counted(*args):  # type: ignore[no-untyped-def]
        result = take_run(*args)
        taken["covariances"] += result[5]
        taken["nhc"] += result[6]
        taken["problems"] += result[1] == sample_runs.RUN_PROBLEM
        return result

    monkeypatch.setattr(sample_runs, "take_run", counted)
    return taken


def _poisoned(inputs: ReplayInputs, series: bool, at: int):  # type: ignore[no-untyped-def]
    """Rows and status of an engine (defaults) fed ``inputs`` sample by sample (``series``
    False) or in runs between the measurements' arrivals, as the replay feeds it, whose
    covariance turns non-finite after sample ``at``."""
    config = FusionConfig.from_parameters(validate_all(PARAMETERS, {}))
    engine = InsEngine(config)
    feed = {"fix": engine.add_gnss_fix, "vel": engine.add_gnss_velocity}
    imu = inputs.imu
    t_s, rate, force = (kernel_array(a) for a in (imu.t_s, imu.rate_flu_rad_s, imu.force_flu_m_s2))
    ticks = output_ticks(t_s, inputs.t0_s, config.output_rate_hz)
    rows = RowBuffer()
    kept = [m for m in inputs.measurements if m[1] in feed]
    k = j = 0
    for stop in sorted({m[0] for m in kept} | {at + 1, len(t_s)}):
        while j < len(kept) and kept[j][0] <= k:
            feed[kept[j][1]](kept[j][2])
            j += 1
        if stop <= k:
            continue
        if series:
            engine.add_imu_series(t_s, rate, force, ticks, (k, stop), rows)
        else:
            for i in range(k, stop):
                engine.add_imu(float(t_s[i]), rate[i], force[i])
                if ticks[i] and (row := engine.solution_row()) is not None:
                    rows.append(row)
        k = stop
        if k == at + 1:
            P = engine._filter.P.copy()
            P[0, 0] = np.nan
            engine._filter.P = P
    return rows.rows(), engine.status()


def test_a_run_hands_an_unusable_filter_to_the_engine(
    inputs: ReplayInputs, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A covariance gone non-finite inside a run: the run stops after the pseudo-measurement
    epoch that finds it and the engine resets, as sample by sample."""
    # Just before the stamp of a fix that arrives later: its re-propagation (and every later
    # one) starts after the damage instead of undoing it.
    fix = next(
        m for _, role, m in inputs.measurements[len(inputs.measurements) // 2 :] if role == "fix"
    )
    at = int(np.searchsorted(inputs.imu.t_s, fix.t_s)) - 2
    expected_rows, expected_status = _poisoned(inputs, False, at)
    taken = _count_runs(monkeypatch)
    rows, status = _poisoned(inputs, True, at)
    assert taken["problems"] == 1
    assert status.resets == 1 and status.last_reset_reason == "non-finite covariance"
    np.testing.assert_array_equal(rows, expected_rows)
    assert repr(status) == repr(expected_status)
