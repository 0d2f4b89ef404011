"""Figures (matplotlib, Agg canvas, no pyplot state): a calibration's data, specific force and
rate against time with the segments used shaded and labelled; the six positions of the
procedure (docs/calibration.md)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from mpl_toolkits.mplot3d.art3d import Poly3DCollection

from ins_fusion.bags.imu import ImuRecord
from ins_fusion.calibration_id.axes import DEFAULT_POSITIONS
from ins_fusion.calibration_id.procedures import up_attitude
from ins_fusion.calibration_id.segments import Kind, Segment

#: Samples drawn per record at most (decimated evenly).
MAX_POINTS = 20000
_COLOURS = {Kind.STATIC: "tab:green", Kind.ROTATION: "tab:orange"}


def plot_segments(
    records: Sequence[ImuRecord],
    segments: Sequence[Segment],
    labels: Sequence[str],
    path: Path,
    title: str,
) -> None:
    """Write the figure: records side by side on one time axis (s after the first stamp of
    each, offset so they follow each other), segments shaded green (static) or orange
    (rotation) with their labels."""
    figure = Figure(figsize=(11.0, 6.0), layout="constrained")
    FigureCanvasAgg(figure)
    force_ax, rate_ax = figure.subplots(2, 1, sharex=True)
    offsets, offset = [], 0.0
    for k, record in enumerate(records):
        offsets.append(offset - float(record.t_s[0]))
        step = max(1, math.ceil(len(record.t_s) / MAX_POINTS))
        t = record.t_s[::step] + offsets[-1]
        for axis, colour in zip("xyz", ("tab:red", "tab:green", "tab:blue"), strict=True):
            i = "xyz".index(axis)
            first = k == 0
            force_ax.plot(
                t,
                record.force_flu_m_s2[::step, i],
                colour,
                lw=0.6,
                label=f"f {axis}" if first else None,
            )
            rate_ax.plot(
                t,
                np.degrees(record.rate_flu_rad_s[::step, i]),
                colour,
                lw=0.6,
                label=f"ω {axis}" if first else None,
            )
        offset = float(t[-1]) + 10.0
        if k:
            for ax in (force_ax, rate_ax):
                ax.axvline(offsets[-1] + float(record.t_s[0]), color="k", lw=0.8, ls="--")
    for s, label in zip(segments, labels, strict=True):
        t0, t1 = s.t_start_s + offsets[s.record], s.t_end_s + offsets[s.record]
        for ax in (force_ax, rate_ax):
            ax.axvspan(t0, t1, color=_COLOURS[s.kind], alpha=0.15, lw=0)
        force_ax.annotate(
            label,
            (0.5 * (t0 + t1), 1.0),
            xycoords=("data", "axes fraction"),
            ha="center",
            va="bottom",
            fontsize=7,
            rotation=90 if len(labels) > 12 else 0,
        )
    force_ax.set_ylabel("specific force [m/s²]")
    rate_ax.set_ylabel("rate [deg/s]")
    rate_ax.set_xlabel("time [s] (bags one after the other)" if len(records) > 1 else "time [s]")
    for ax in (force_ax, rate_ax):
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize=7, ncols=3)
    figure.suptitle(title)
    figure.savefig(path, dpi=110)


def plot_positions(path: Path) -> None:
    """Write the six positions of docs/calibration.md: the unit as a box with its imu_link
    axes (x red, y green, z blue; the case's +z face shaded), each position with one axis up."""
    figure = Figure(figsize=(11.0, 6.5), layout="constrained")
    FigureCanvasAgg(figure)
    half = np.array([1.0, 0.7, 0.35])  # box half-sizes along imu_link x, y, z
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half
    faces = [[0, 1, 3, 2], [4, 5, 7, 6], [0, 1, 5, 4], [2, 3, 7, 6], [0, 2, 6, 4], [1, 3, 7, 5]]
    for k, name in enumerate(DEFAULT_POSITIONS):
        axis = "xyz".index(name[1])
        attitude = up_attitude(axis, 1.0 if name[0] == "+" else -1.0, math.radians(-30.0))
        ax = figure.add_subplot(2, 3, k + 1, projection="3d")
        world = attitude.apply(corners)
        polygons = [world[f] for f in faces]
        colours = ["0.85"] * 6
        colours[faces.index([1, 3, 7, 5])] = "tab:blue"  # the corners with z = +half
        ax.add_collection3d(
            Poly3DCollection(polygons, facecolors=colours, edgecolors="0.3", alpha=0.35)
        )
        for i, colour in enumerate(("tab:red", "tab:green", "tab:blue")):
            tip = attitude.apply(np.eye(3)[i] * (half[i] + 0.9))
            ax.quiver(0, 0, 0, *tip, color=colour, lw=2, arrow_length_ratio=0.15)
            ax.text(*(tip * 1.12), "xyz"[i], color=colour, fontsize=11, weight="bold")
        ax.quiver(1.9, -1.9, -1.2, 0, 0, 1.0, color="k", lw=1, arrow_length_ratio=0.2)
        ax.text(1.9, -1.9, -0.1, "up", fontsize=8)
        for setter in (ax.set_xlim, ax.set_ylim, ax.set_zlim):
            setter(-2.0, 2.0)
        ax.set_box_aspect((1, 1, 1))
        ax.set_axis_off()
        ax.set_title(f"position {k + 1}: {name} up", fontsize=10)
    figure.suptitle(
        "six-position procedure: imu_link axis up in each position (blue face: the case's +z)"
    )
    figure.savefig(path, dpi=100)
