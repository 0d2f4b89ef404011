"""The replay plot: track, errors with their 3σ bounds, outages shaded (matplotlib, Agg).

Uses the object-oriented ``Figure`` API with the Agg canvas: no pyplot state and no display.
Layout: the track (map frame E/N, fused and reference) on the left, each outage's fused stretch
drawn as a line with the reference over it and the drift at its end written beside; position
errors E, N, U and attitude errors roll, pitch, yaw against time on the right, each with the
filter's ±3σ bound. Without a reference the error panels show what the bag measured instead:
the GNSS fixes (those an outage withheld included) minus the fused antenna position, and the
attitude measurements minus the fused attitude, with the fixes on the track. With the
RTS-smoothed solution its track, errors and ±3σ bounds are drawn over the forward ones (green,
the bound dashed).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from scipy.spatial.transform import Rotation

from gnss_ins_common.types import FloatArray, Vec3
from ins_fusion.core.filter.records import AttitudeMeasurement, GnssFixMeasurement
from ins_fusion.replay.inputs import Measurement
from ins_fusion.replay.metrics import Evaluation, map_enu, rpy_covariance, rpy_deg, wrap_deg
from ins_fusion.replay.outages import Outage, mask
from ins_fusion.replay.pipeline import Scored
from ins_fusion.replay.run import SolutionTrack

_OUTAGE_COLOUR = "tab:orange"
_SMOOTHED_COLOUR = "tab:green"
_MEASURED_COLOUR = "tab:purple"


@dataclass(frozen=True)
class Measured:
    """What the bag measured against the fused solution, for a plot without a reference:
    ``fix_t_s`` (n,) [s after t0], ``fix_enu_m`` (n, 3) the fixes in the map frame,
    ``fix_minus_fused_m`` (n, 3) fix minus the fused antenna position (E, N, U); ``att_t_s``
    (m,), ``att_minus_fused_deg`` (m, 3) attitude measurement minus fused roll, pitch, yaw."""

    fix_t_s: FloatArray
    fix_enu_m: FloatArray
    fix_minus_fused_m: FloatArray
    att_t_s: FloatArray
    att_minus_fused_deg: FloatArray


def measured(
    track: SolutionTrack,
    measurements: Sequence[tuple[int, str, Measurement]],
    datum: tuple[float, float, float],
    gnss_lever_arm_flu_m: Vec3,
    t0_s: float,
) -> Measured:
    """The fixes and attitudes of ``measurements`` (all of them: an outage's too) against the
    base_link ``track``, at the track's solution nearest each stamp (interpolated position)."""
    fixes = [m for _, _, m in measurements if isinstance(m, GnssFixMeasurement) and m.valid]
    fixes = [m for m in fixes if track.t_s[0] <= m.t_s <= track.t_s[-1]]
    t_fix = np.array([m.t_s for m in fixes], dtype=np.float64)
    enu = map_enu(np.array([(m.lat_deg, m.lon_deg, m.height_m) for m in fixes]), datum)
    near = _nearest(track.t_s, t_fix)
    pos = np.column_stack([np.interp(t_fix, track.t_s, track.pos_enu_m[:, k]) for k in range(3)])
    arm = Rotation.from_quat(track.quat_enu_flu_xyzw[near]).apply(np.asarray(gnss_lever_arm_flu_m))
    attitudes = [m for _, _, m in measurements if isinstance(m, AttitudeMeasurement)]
    attitudes = [m for m in attitudes if track.t_s[0] <= m.t_s <= track.t_s[-1]]
    t_att = np.array([m.t_s for m in attitudes], dtype=np.float64)
    rpy = rpy_deg(Rotation.from_quat(np.array([m.quat_enu_flu_xyzw for m in attitudes])))
    fused = rpy_deg(Rotation.from_quat(track.quat_enu_flu_xyzw[_nearest(track.t_s, t_att)]))
    return Measured(
        t_fix - t0_s,
        enu,
        (enu - pos - arm.reshape(-1, 3)).reshape(-1, 3),
        t_att - t0_s,
        wrap_deg(rpy.reshape(-1, 3) - fused.reshape(-1, 3)),
    )


def _nearest(t_s: FloatArray, at_s: FloatArray) -> FloatArray:
    """Index of the element of the sorted ``t_s`` nearest each of ``at_s``."""
    right = np.clip(np.searchsorted(t_s, at_s), 1, max(len(t_s) - 1, 1))
    left = right - 1
    index: FloatArray = np.where(at_s - t_s[left] <= t_s[right] - at_s, left, right)
    return np.minimum(index, len(t_s) - 1)


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
    measured: Measured | None = None,
) -> Figure:
    """Save the replay figure to ``path`` (format from its suffix, e.g. .png, .pdf) and return
    it; each error panel is scaled to the navigation after the alignment settled; with
    ``smoothed``, the smoothed solution over the forward one; with ``measured`` (used when
    there is no ``evaluation``), the measurements against the fused solution."""
    fig, ax_track, axes = track_and_time_panels((15, 10), 6, 1.3)
    _track_panel(ax_track, track, t0_s, evaluation, outages)
    if evaluation is None and measured is not None:
        _measured_panels(ax_track, axes, measured)
    if smoothed is not None:
        pos = smoothed.compared.pos_enu_m
        ax_track.plot(pos[:, 0], pos[:, 1], lw=1.0, color=_SMOOTHED_COLOUR, label="smoothed")
        ax_track.legend(loc="best", fontsize="small")
    labels = ("E [m]", "N [m]", "U [m]", "roll [°]", "pitch [°]", "yaw [°]")
    runs = [(track, evaluation, False)]
    if smoothed is not None:
        runs.append((smoothed.compared, smoothed.evaluation, True))
    for i, attitude in enumerate((False, True)):
        settled_s = np.inf
        for run_track, run_evaluation, is_smoothed in runs:
            t, err, sigma = _errors_and_sigma(run_track, t0_s, run_evaluation, attitude)
            settled_s = min(settled_s, settled_from(t, sigma))
            for axis in range(3):
                column = None if err is None else err[:, axis]
                _error_curves(axes[3 * i + axis], t, column, sigma[:, axis], is_smoothed)
        for axis in range(3):
            _shade(axes[3 * i + axis], outages)
            _scale_from(axes[3 * i + axis], settled_s)
            axes[3 * i + axis].set_ylabel(labels[3 * i + axis])
            axes[3 * i + axis].grid(True, lw=0.3)
    axes[0].legend(loc="upper right", fontsize="small")
    axes[-1].set_xlabel("time after the first IMU sample [s]")
    fig.suptitle(title)
    fig.savefig(path, dpi=110)
    return fig


def settled_from(t_s: FloatArray, sigma: FloatArray) -> float:
    """When the alignment's uncertainty has settled [s, as ``t_s``]: the first time at which
    every axis's σ (n, 3) is within twice its median over the run (an outage's growth later is
    part of the navigation, not of the alignment)."""
    if not len(t_s):
        return float("inf")
    settled = sigma <= 2.0 * np.median(sigma, axis=0)
    first = [int(np.argmax(column)) if column.any() else len(t_s) - 1 for column in settled.T]
    return float(t_s[max(first)])


def _scale_from(ax: Axes, settled_s: float) -> None:
    """Y limits from every curve of ``ax`` after ``settled_s`` (the alignment before it is
    drawn, clipped, but does not set the scale)."""
    values = [
        np.asarray(line.get_ydata(), dtype=float)[
            np.asarray(line.get_xdata(), dtype=float) >= settled_s
        ]
        for line in ax.get_lines()
    ]
    shown = np.concatenate(values) if values else np.empty(0)
    shown = shown[np.isfinite(shown)]
    if shown.size:
        low, high = float(shown.min()), float(shown.max())
        pad = 0.05 * (high - low) or 1e-3
        ax.set_ylim(low - pad, high + pad)


def track_and_time_panels(
    size_in: tuple[float, float], rows: int, time_width: float
) -> tuple[Figure, Axes, list[Axes]]:
    """A figure (Agg canvas) with a track panel on the left and ``rows`` panels on the right
    sharing their time axis, ``time_width`` times as wide as the track."""
    fig = Figure(figsize=size_in, layout="constrained")
    FigureCanvasAgg(fig)
    grid = fig.add_gridspec(rows, 2, width_ratios=(1.0, time_width))
    track = fig.add_subplot(grid[:, 0])
    panels = [fig.add_subplot(grid[i, 1]) for i in range(rows)]
    for ax in panels[1:]:
        ax.sharex(panels[0])
    return fig, track, panels


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
    t = track.t_s - t0_s
    for number, outage in enumerate(outages):
        inside = mask(t, [outage])
        if not inside.any():
            continue
        label = "fused in an outage" if number == 0 else None
        ax.plot(*pos[inside, :2].T, lw=2.0, color=_OUTAGE_COLOUR, label=label, zorder=3)
        if evaluation is None:
            continue
        truth, ref_t = evaluation.reference_enu_m, evaluation.position.t_rel_s
        within = mask(ref_t, [outage])
        ax.plot(*truth[within, :2].T, lw=0.8, ls="--", color="black", zorder=4)
        end = np.flatnonzero(inside)[-1]
        at_end = np.column_stack([np.interp(t[end], ref_t, truth[:, k]) for k in range(2)])[0]
        drift = float(np.hypot(*(pos[end, :2] - at_end)))
        ax.annotate(
            f"{drift:.1f} m",
            (float(pos[end, 0]), float(pos[end, 1])),
            xytext=(4, 4),
            textcoords="offset points",
            fontsize="small",
            color=_OUTAGE_COLOUR,
        )
    ax.set_xlabel("E [m]")
    ax.set_ylabel("N [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, lw=0.3)
    ax.legend(loc="best", fontsize="small")


def _measured_panels(ax_track: Axes, axes: Sequence[Axes], data: Measured) -> None:
    """Fixes on the track; fix minus fused (E, N, U) and attitude minus fused (roll, pitch, yaw)
    as dots on the error panels."""
    ax_track.plot(
        *data.fix_enu_m[:, :2].T, ".", ms=2, color=_MEASURED_COLOUR, label="GNSS fixes", zorder=5
    )
    ax_track.legend(loc="best", fontsize="small")
    rows = (
        (0, data.fix_t_s, data.fix_minus_fused_m, "fix − fused antenna"),
        (3, data.att_t_s, data.att_minus_fused_deg, "measured − fused"),
    )
    for first, t, values, label in rows:
        for axis in range(3):
            axes[first + axis].plot(
                t, values[:, axis], ".", ms=2, color=_MEASURED_COLOUR, label=label
            )
    axes[3].legend(loc="upper right", fontsize="small")
