"""The demo figure: the live node's and the offline replay's errors against the truth in one
plot (matplotlib, Agg, object-oriented API: no pyplot state, no display).

Left: the track (truth, live, replay) in the tangent plane at the first truth fix [m]. Right,
against time after the first IMU sample [s]: horizontal, vertical and yaw error of both runs, the
replay's GNSS outages shaded (the live run had none).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

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
) -> None:
    """Save the figure to ``path``: ``runs`` = (live, replay), either None when it has no
    output; ``truth_enu_m`` (n, 3) the truth track; ``outages_s``: (start, end) [s after t0]."""
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
    for ax, label in zip(panels, ("horizontal [m]", "vertical [m]", "yaw [°]"), strict=True):
        for start, end in outages_s:
            ax.axvspan(start, end, color="tab:orange", alpha=0.15, lw=0)
        ax.set_ylabel(f"error {label}")
        ax.grid(True, lw=0.3)
    if outages_s:
        panels[0].axvspan(0.0, 0.0, color="tab:orange", alpha=0.15, label="replay GNSS outage")
        panels[0].legend(loc="upper left", fontsize="small")
    panels[1].legend(loc="upper left", fontsize="small")
    panels[-1].set_xlabel("time after the first IMU sample [s] (the time of --outage)")
    track.set_xlabel("E [m]")
    track.set_ylabel("N [m]")
    track.set_aspect("equal", adjustable="datalim")
    track.grid(True, lw=0.3)
    track.legend(loc="best", fontsize="small")
    fig.suptitle(title)
    fig.savefig(path, dpi=110)
