"""The demo figure: time axes start at the first IMU sample with the alignment shaded and
named, the replay's outages shaded in the error panels and drawn on the track, no stand-in
artist at t = 0 (a legend entry once drew a line there and pulled the axis to -5 s)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ins_fusion.replay.plot_demo import plot_demo
from ins_fusion.replay.recorded import RecordedErrors

OUTAGE_S = (40.0, 60.0)


def _run(first_s: float, seed: int) -> RecordedErrors:
    """A run with outputs every 0.1 s from ``first_s`` to 90 s on a circle of 50 m."""
    rng = np.random.default_rng(seed)
    t = np.arange(first_s, 90.0, 0.1)
    track = np.column_stack([50 * np.cos(t / 20), 50 * np.sin(t / 20), np.zeros_like(t)])
    return RecordedErrors(
        t_s=t + 1000.0,
        enu_m=rng.normal(0.0, 0.05, (t.size, 3)),
        yaw_t_s=t + 1000.0,
        yaw_deg=rng.normal(0.0, 0.2, t.size),
        track_enu_m=track,
        datum=(57.0, 10.0, 40.0),
    )


def test_the_alignment_and_the_outages_are_shaded_and_drawn_on_the_track(tmp_path: Path) -> None:
    live, replay = _run(8.0, 1), _run(7.5, 2)
    fig = plot_demo(
        tmp_path / "demo.png", (live, replay), live.track_enu_m, 1000.0, [OUTAGE_S], "test"
    )
    assert (tmp_path / "demo.png").stat().st_size > 0
    track, *panels = fig.axes
    for ax in panels:
        assert ax.get_xlim()[0] == 0.0
        spans = sorted(
            tuple(np.round(p.get_x() + np.array([0.0, p.get_width()]), 6)) for p in ax.patches
        )
        assert spans == [(0.0, 7.5), OUTAGE_S]
        for line in ax.get_lines():  # every line is a run's data, none a stand-in at t = 0
            assert np.ptp(np.asarray(line.get_xdata(), float)) > 0.0
    names = [text.get_text() for text in panels[0].get_legend().get_texts()]
    assert names == ["aligning at rest: no output yet", "replay GNSS outage"]
    drawn = [line for line in track.get_lines() if line.get_label().startswith("replay during")]
    assert len(drawn) == 1
    x = np.asarray(drawn[0].get_xdata(), float)
    inside = (replay.t_s - 1000.0 >= OUTAGE_S[0]) & (replay.t_s - 1000.0 <= OUTAGE_S[1])
    np.testing.assert_array_equal(x, replay.track_enu_m[inside, 0])


def test_a_replay_without_output_or_outages_still_plots(tmp_path: Path) -> None:
    live = _run(8.0, 1)
    fig = plot_demo(tmp_path / "demo.png", (live, None), live.track_enu_m, 1000.0, [], "test")
    names = [text.get_text() for text in fig.axes[1].get_legend().get_texts()]
    assert names == ["aligning at rest: no output yet"]
