"""core.filter.timeline: ``extend_run`` (a compiled run's entries in one call) keeps the same
history as appending the entries one by one, whatever the batches and the history length, and the
entries it gives back are the run's."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from ins_fusion.core.engine.measurement_kinds import MEASUREMENT_NAMES
from ins_fusion.core.filter.adaptation import WhiteNoiseMonitor
from ins_fusion.core.filter.state import X_SIZE, X_T
from ins_fusion.core.filter.status import new_counters
from ins_fusion.core.filter.timeline import Entry, RunEntries, Timeline

_INC = np.zeros(7)
_WHITE = WhiteNoiseMonitor()


def _entry(t_s: float) -> Entry:
    return Entry(t_s, _INC, None, None, None)  # type: ignore[arg-type]


def _run(stamps: list[float]) -> RunEntries:
    """A run of entries at ``stamps``: increment j filled with j, two noises, two covariances
    and a change of the gated-update runs half-way, a measurement at its first entry."""
    m = len(stamps)
    incs = np.arange(m, dtype=float)[:, None] * np.ones(7)
    xs = np.zeros((m, X_SIZE))
    xs[:, X_T] = stamps
    noises = [(np.ones(3), np.ones(3)), None]
    covariances = [np.eye(2), 2.0 * np.eye(2)]
    gated = [(0, {}), (m // 2, {"nhc": 1})]
    return RunEntries(
        stamps,
        (incs, xs),
        (noises, [j % 2 for j in range(m)]),
        (covariances, [1 - j % 2 for j in range(m)]),
        (_WHITE, gated),
        {0: [(stamps[0], 0, 0, "nhc", None)]},
    )


@settings(max_examples=80, deadline=None)
@given(
    st.floats(0.05, 3.0),
    st.lists(st.tuples(st.floats(1e-3, 0.4), st.integers(1, 40)), min_size=1, max_size=60),
)
def test_extend_keeps_the_history_of_appending_one_by_one(history_s, batches):
    one_by_one = Timeline(history_s, MEASUREMENT_NAMES)
    batched = Timeline(history_s, MEASUREMENT_NAMES)
    one_by_one.start(_entry(0.0))
    batched.start(_entry(0.0))
    t = 0.0
    for dt, count in batches:
        stamps = []
        for _ in range(count):
            t += dt
            stamps.append(t)
            one_by_one.append(_entry(t))
        batched.extend_run(_run(stamps))
        assert len(batched) == len(one_by_one)
        assert [batched.entry(i).t_s for i in range(len(batched))] == [
            one_by_one.entry(i).t_s for i in range(len(one_by_one))
        ]
    # The oldest entry decides what is too old: the same answer from both.
    oldest = one_by_one.entry(0).t_s
    for timeline in (one_by_one, batched):
        counters = new_counters(MEASUREMENT_NAMES)
        assert timeline.add("gnss_position", oldest - 1e-6, None, counters, True) is None
        assert counters["gnss_position"]["too_old"] == 1


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 30), st.integers(0, 29))
def test_a_run_gives_back_its_entries(m, j):
    j %= m
    stamps = [0.01 * (i + 1) for i in range(m)]
    run = _run(stamps)
    timeline = Timeline(10.0, MEASUREMENT_NAMES)
    timeline.start(_entry(0.0))
    timeline.extend_run(run)
    entry = timeline.entry(j + 1)
    assert timeline.entry(j + 1) is entry  # built once, then kept
    state, covariance = entry.checkpoint
    assert entry.t_s == stamps[j] == state.t_s
    assert entry.inc.tolist() == [float(j)] * 7
    assert entry.gap is None
    assert entry.noise is run.noises[j % 2] and state.imu_psd is entry.noise
    assert covariance is run.covariances[1 - j % 2]
    assert state.gnss_white is _WHITE
    assert state.gated_runs == ({"nhc": 1} if j >= m // 2 else {})
    assert entry.measurements == ([(stamps[0], 0, 0, "nhc", None)] if j == 0 else [])


def test_plain_entries_are_read_and_refiled_without_building_the_others():
    stamps = [0.01 * (i + 1) for i in range(6)]
    timeline = Timeline(10.0, MEASUREMENT_NAMES)
    timeline.start(_entry(0.0))
    timeline.extend_run(_run(stamps))
    assert timeline.plain_from(1) == ([], None)  # its first entry has a measurement
    incs, noise = timeline.plain_from(2)  # the densities change at the next entry
    assert [inc.tolist() for inc in incs] == [[1.0] * 7] and noise is None
    first = timeline.entry(4)  # built: read as it is
    assert len(timeline.plain_from(4)[0]) == 1
    xs = np.full((2, X_SIZE), 7.0)
    covariance = np.eye(2)
    refiled = RunEntries(
        timeline.stamps(4, 6),
        (np.zeros((2, 7)), xs),
        ([None], [0, 0]),
        ([covariance], [0, 0]),
        (_WHITE, [(0, {})]),
        {},
    )
    last = (first.checkpoint[0], 3.0 * np.eye(2))
    timeline.refile(4, refiled, last)
    assert timeline.entry(4) is not first
    assert timeline.entry(4).checkpoint[0].x.tolist() == [7.0] * X_SIZE
    assert timeline.entry(4).checkpoint[1] is covariance
    assert timeline.entry(5).checkpoint == last and timeline.entry(5).t_s == stamps[4]
    assert timeline.entry(3).t_s == stamps[2] and timeline.entry(6).t_s == stamps[5]
