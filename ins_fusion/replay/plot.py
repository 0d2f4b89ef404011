"""The replay plot: track, errors with their 3σ bounds, outages shaded (matplotlib, Agg).

Uses the object-oriented ``Figure`` API with the Agg canvas: no pyplot state and no display.
Layout: the track (map frame E/N, fused and reference, outage stretches highlighted) on the
left; position errors E, N, U and attitude errors roll, pitch, yaw against time on the right,
each with the filter's ±3σ bound. Without a reference the error panels show the ±3σ bounds only.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from scipy.spatial.transform import Rotation

from gnss_ins_common.types import FloatArray
from ins_fusion.replay.metrics import Evaluation, rpy_covariance, rpy_deg
from ins_fusion.replay.outages import Outage, mask
from ins_fusion.replay.run import SolutionTrack

_OUTAGE_COLOUR = "tab:orange"


def _shade(ax: Axes, outages: Sequence[Outage]) -> None:
    for outage in outages:
        ax.axvspan(outage.start_s, outage.end_s, color=_OUTAGE_COLOUR, alpha=0.2, lw=0)


def _error_panel(
    ax: Axes,
    t_s: FloatArray,
    error: FloatArray | None,
    sigma: FloatArray,
    label: str,
    outages: Sequence[Outage],
) -> None:
    if error is not None:
        ax.plot(t_s, error, lw=0.8, color="tab:blue", label="error")
    ax.plot(t_s, 3.0 * sigma, lw=0.8, color="tab:red", label="±3σ")
    ax.plot(t_s, -3.0 * sigma, lw=0.8, color="tab:red")
    _shade(ax, outages)
    ax.set_ylabel(label)
    ax.grid(True, lw=0.3)


def plot_replay(
    path: Path | str,
    track: SolutionTrack,
    t0_s: float,
    evaluation: Evaluation | None,
    outages: Sequence[Outage],
    title: str,
) -> None:
    """Save the replay figure to ``path`` (format from its suffix, e.g. .png, .pdf)."""
    fig = Figure(figsize=(15, 10), layout="constrained")
    FigureCanvasAgg(fig)
    grid = fig.add_gridspec(6, 2, width_ratios=(1.0, 1.3))
    ax_track = fig.add_subplot(grid[:, 0])
    axes = [fig.add_subplot(grid[i, 1]) for i in range(6)]
    for ax in axes[1:]:
        ax.sharex(axes[0])
    _track_panel(ax_track, track, t0_s, evaluation, outages)
    labels = ("E [m]", "N [m]", "U [m]", "roll [°]", "pitch [°]", "yaw [°]")
    for i, attitude in enumerate((False, True)):
        t, err, sigma = _errors_and_sigma(track, t0_s, evaluation, attitude)
        for axis in range(3):
            column = None if err is None else err[:, axis]
            panel = axes[3 * i + axis]
            _error_panel(panel, t, column, sigma[:, axis], labels[3 * i + axis], outages)
    axes[0].legend(loc="upper right", fontsize="small")
    axes[-1].set_xlabel("time after the first IMU sample [s]")
    fig.suptitle(title)
    fig.savefig(path, dpi=110)


def _errors_and_sigma(
    track: SolutionTrack, t0_s: float, evaluation: Evaluation | None, attitude: bool
) -> tuple[FloatArray, FloatArray | None, FloatArray]:
    """Time [s after t0], errors (None without a reference) and σ of position or attitude."""
    if evaluation is not None:
        errors = evaluation.attitude if attitude else evaluation.position
        if errors is not None:
            return errors.t_rel_s, errors.error, errors.sigma
    if attitude:
        yaw = rpy_deg(Rotation.from_quat(track.quat_enu_flu_xyzw))[:, 2]
        cov = rpy_covariance(track.cov_att_enu_rad2, yaw)
    else:
        cov = track.cov_pos_enu_m2
    return track.t_s - t0_s, None, np.sqrt(np.maximum(np.diagonal(cov, axis1=1, axis2=2), 0.0))


def _track_panel(
    ax: Axes,
    track: SolutionTrack,
    t0_s: float,
    evaluation: Evaluation | None,
    outages: Sequence[Outage],
) -> None:
    pos = track.pos_enu_m
    ax.plot(pos[:, 0], pos[:, 1], lw=1.0, color="tab:blue", label="fused")
    if evaluation is not None:
        truth = evaluation.reference_enu_m
        ax.plot(truth[:, 0], truth[:, 1], lw=0.8, ls="--", color="black", label="reference")
    inside = mask(track.t_s - t0_s, outages)
    if inside.any():
        ax.plot(pos[inside, 0], pos[inside, 1], ".", ms=2, color=_OUTAGE_COLOUR, label="outage")
    ax.set_xlabel("E [m]")
    ax.set_ylabel("N [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, lw=0.3)
    ax.legend(loc="best", fontsize="small")
