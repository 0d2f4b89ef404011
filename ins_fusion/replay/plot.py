"""The replay plot: track, errors with their 3σ bounds, outages shaded (matplotlib, Agg).

Uses the object-oriented ``Figure`` API with the Agg canvas: no pyplot state and no display.
Layout: the track (map frame E/N, fused and reference, outage stretches highlighted) on the
left; position errors E, N, U and attitude errors roll, pitch, yaw against time on the right,
each with the filter's ±3σ bound. Without a reference the error panels show the ±3σ bounds only.
With the RTS-smoothed solution its track, errors and ±3σ bounds are drawn over the forward ones
(green, the bound dashed).
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
from ins_fusion.replay.pipeline import Scored
from ins_fusion.replay.run import SolutionTrack

_OUTAGE_COLOUR = "tab:orange"
_SMOOTHED_COLOUR = "tab:green"


def _shade(ax: Axes, outages: Sequence[Outage]) -> None:
    for outage in outages:
        ax.axvspan(outage.start_s, outage.end_s, color=_OUTAGE_COLOUR, alpha=0.2, lw=0)


def _error_curves(
    ax: Axes,
    t_s: FloatArray,
    error: FloatArray | None,
    sigma: FloatArray,
    smoothed: bool,
) -> None:
    colour, bound, style, name = (
        (_SMOOTHED_COLOUR, _SMOOTHED_COLOUR, "--", "smoothed ")
        if smoothed
        else ("tab:blue", "tab:red", "-", "")
    )
    if error is not None:
        ax.plot(t_s, error, lw=0.8, color=colour, label=f"{name}error")
    ax.plot(t_s, 3.0 * sigma, lw=0.8, ls=style, color=bound, label=f"{name}±3σ")
    ax.plot(t_s, -3.0 * sigma, lw=0.8, ls=style, color=bound)


def plot_replay(
    path: Path | str,
    track: SolutionTrack,
    t0_s: float,
    evaluation: Evaluation | None,
    outages: Sequence[Outage],
    title: str,
    smoothed: Scored | None = None,
) -> None:
    """Save the replay figure to ``path`` (format from its suffix, e.g. .png, .pdf); with
    ``smoothed``, the smoothed solution over the forward one."""
    fig = Figure(figsize=(15, 10), layout="constrained")
    FigureCanvasAgg(fig)
    grid = fig.add_gridspec(6, 2, width_ratios=(1.0, 1.3))
    ax_track = fig.add_subplot(grid[:, 0])
    axes = [fig.add_subplot(grid[i, 1]) for i in range(6)]
    for ax in axes[1:]:
        ax.sharex(axes[0])
    _track_panel(ax_track, track, t0_s, evaluation, outages)
    if smoothed is not None:
        pos = smoothed.compared.pos_enu_m
        ax_track.plot(pos[:, 0], pos[:, 1], lw=1.0, color=_SMOOTHED_COLOUR, label="smoothed")
        ax_track.legend(loc="best", fontsize="small")
    labels = ("E [m]", "N [m]", "U [m]", "roll [°]", "pitch [°]", "yaw [°]")
    runs = [(track, evaluation, False)]
    if smoothed is not None:
        runs.append((smoothed.compared, smoothed.evaluation, True))
    for i, attitude in enumerate((False, True)):
        for run_track, run_evaluation, is_smoothed in runs:
            t, err, sigma = _errors_and_sigma(run_track, t0_s, run_evaluation, attitude)
            for axis in range(3):
                column = None if err is None else err[:, axis]
                _error_curves(axes[3 * i + axis], t, column, sigma[:, axis], is_smoothed)
        for axis in range(3):
            _shade(axes[3 * i + axis], outages)
            axes[3 * i + axis].set_ylabel(labels[3 * i + axis])
            axes[3 * i + axis].grid(True, lw=0.3)
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
