"""The demo figure: the live node's and the offline replay's errors against the truth in one
plot (matplotlib, Agg, object-oriented API: no pyplot state, no display).

Left: the track (truth, live, replay) in the tangent plane at the first truth fix [m], the
replay's positions during its GNSS outages drawn over it. Right, against time after the first IMU
sample [s]: horizontal, vertical and yaw error of both runs, the seconds before the first output
(the alignment at rest) and the replay's GNSS outages shaded (the live run had none).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from gnss_ins_common.types import FloatArray
from ins_fusion.replay.plot import track_and_time_panels
from ins_fusion.replay.recorded import RecordedErrors

_RUNS = (("live ins_fusion_node", "tab:blue"), ("offline gnss_ins replay", "tab:orange"))


def plot_demo(
    path: Path | str,
    runs: Sequence[RecordedErrors | None],
    truth_enu_m: FloatArray,
    t0_s: float,
    outages_s: Sequence[tuple[float, float]],
    title: str,
) -> Figure:
    """Save the figure to ``path`` and return it: ``runs`` = (live, replay), either None when
    it has no output; ``truth_enu_m`` (n, 3) the truth track; ``outages_s``: (start, end) [s
    after t0]."""
    fig, track, panels = track_and_time_panels((15, 8), 3, 1.4)
    track.plot(truth_enu_m[:, 0], truth_enu_m[:, 1], "k--", lw=0.8, label="truth")
    for (label, colour), run in zip(_RUNS, runs, strict=True):
        if run is None:
            continue
        track.plot(run.track_enu_m[:, 0], run.track_enu_m[:, 1], lw=1.0, color=colour, label=label)
        t = run.t_s - t0_s
        panels[0].plot(t, np.hypot(run.enu_m[:, 0], run.enu_m[:, 1]), lw=0.8, color=colour)
        panels[1].plot(t, run.enu_m[:, 2], lw=0.8, color=colour, label=label)
        panels[2].plot(run.yaw_t_s - t0_s, run.yaw_deg, lw=0.8, color=colour)
    replay = runs[-1]
    for number, (start, end) in enumerate(outages_s):
        if replay is None:
            break
        inside = (replay.t_s - t0_s >= start) & (replay.t_s - t0_s <= end)
        track.plot(
            replay.track_enu_m[inside, 0],
            replay.track_enu_m[inside, 1],
            lw=3.0,
            color="tab:red",
            alpha=0.6,
            label=None if number else "replay during its GNSS outages",
        )
    starts = [run.t_s[0] - t0_s for run in runs if run is not None and run.t_s.size]
    aligned_s = min(starts, default=0.0)
    shades = [("0.5", 0.12, [(0.0, aligned_s)], "aligning at rest: no output yet")]
    shades.append(("tab:red", 0.12, list(outages_s), "replay GNSS outage"))
    for ax, label in zip(panels, ("horizontal [m]", "vertical [m]", "yaw [°]"), strict=True):
        for colour, alpha, spans, _ in shades:
            for start, end in spans:
                ax.axvspan(start, end, color=colour, alpha=alpha, lw=0)
        ax.set_ylabel(f"error {label}")
        ax.set_xlim(left=0.0)
        ax.grid(True, lw=0.3)
    panels[0].legend(
        handles=[Patch(color=c, alpha=a, label=name) for c, a, spans, name in shades if spans],
        loc="upper left",
        fontsize="small",
    )
    panels[1].legend(loc="upper left", fontsize="small")
    panels[-1].set_xlabel("time after the first IMU sample [s] (the time of --outage)")
    track.set_xlabel("E [m]")
    track.set_ylabel("N [m]")
    track.set_aspect("equal", adjustable="datalim")
    track.grid(True, lw=0.3)
    track.legend(loc="best", fontsize="small")
    fig.suptitle(title)
    fig.savefig(path, dpi=110)
    return fig
