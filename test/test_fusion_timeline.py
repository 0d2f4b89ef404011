"""core.timeline: ``extend`` (a compiled run's entries in one call) keeps the same history as
appending the entries one by one, whatever the batches and the history length."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from ins_fusion.core.status import new_counters
from ins_fusion.core.timeline import Entry, Timeline

_INC = np.zeros(7)


def _entry(t_s: float) -> Entry:
    return Entry(t_s, _INC, None, None, None)  # type: ignore[arg-type]


@settings(max_examples=80, deadline=None)
@given(
    st.floats(0.05, 3.0),
    st.lists(st.tuples(st.floats(1e-3, 0.4), st.integers(1, 40)), min_size=1, max_size=60),
)
def test_extend_keeps_the_history_of_appending_one_by_one(history_s, batches):
    one_by_one, batched = Timeline(history_s), Timeline(history_s)
    one_by_one.start(_entry(0.0))
    batched.start(_entry(0.0))
    t = 0.0
    for dt, count in batches:
        entries = []
        for _ in range(count):
            t += dt
            entries.append(_entry(t))
        for entry in entries:
            one_by_one.append(entry)
        batched.extend(entries)
        assert [e.t_s for e in batched.history] == [e.t_s for e in one_by_one.history]
    # The oldest entry decides what is too old: the same answer from both.
    oldest = one_by_one.history[0].t_s
    for timeline in (one_by_one, batched):
        counters = new_counters()
        assert timeline.add("gnss_position", oldest - 1e-6, None, counters, True) is None
        assert counters["gnss_position"]["too_old"] == 1
