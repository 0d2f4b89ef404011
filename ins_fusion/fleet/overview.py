"""The overview figure of a batch (matplotlib, Agg canvas): one row per bag, three panels of
horizontal bars: the horizontal errors [m] (RMS against the reference, worst outage end, worst
withheld fix; the smoothed RMS when the batch smoothed), the position NEES mean (dof 3 marked)
and the gated fractions of the GNSS position, velocity and attitude. A bag that failed or has
no solution shows its status instead of bars."""

from __future__ import annotations

import io
import math
from collections.abc import Sequence

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ins_fusion.core.measurements.attitude import ATTITUDE
from ins_fusion.core.measurements.gnss_position import POSITION
from ins_fusion.core.measurements.gnss_velocity import VELOCITY
from ins_fusion.fleet.summary import Row, gated

#: Panels: (title, [(column, legend label)]).
_PANELS = (
    (
        "horizontal error [m]",
        [
            ("horizontal_rms_m", "RMS vs reference"),
            ("outage_end_max_m", "worst outage end"),
            ("withheld_end_max_m", "worst withheld fix"),
            ("smoothed_horizontal_rms_m", "smoothed RMS"),
        ],
    ),
    ("position NEES mean (dof 3)", [("nees_mean", "forward"), ("smoothed_nees_mean", "smoothed")]),
    (
        "gated fraction",
        [
            (gated(POSITION.name), "GNSS position"),
            (gated(VELOCITY.name), "GNSS velocity"),
            (gated(ATTITUDE.name), "GNSS attitude"),
        ],
    ),
)


def _value(row: Row, column: str) -> float:
    value = row.get(column)
    return float(value) if isinstance(value, int | float) and math.isfinite(value) else math.nan


def overview_png(rows: Sequence[Row], title: str) -> bytes:
    """The figure of ``rows`` (summary rows) as PNG bytes."""
    height = 1.5 + 0.35 * len(rows)
    fig = Figure(figsize=(15.0, height), layout="constrained")
    FigureCanvasAgg(fig)
    fig.suptitle(title)
    axes = fig.subplots(1, len(_PANELS), sharey=True)
    y = np.arange(len(rows), dtype=np.float64)
    for ax, (panel_title, series) in zip(axes, _PANELS, strict=True):
        shown = [(c, label) for c, label in series if any(c in row for row in rows)]
        step = 0.8 / max(len(shown), 1)
        for index, (column, label) in enumerate(shown):
            values = [_value(row, column) for row in rows]
            ax.barh(y - 0.4 + step * (index + 0.5), values, height=step, label=label)
        if panel_title.startswith("position NEES"):
            ax.axvline(3.0, color="k", linestyle="--", linewidth=0.8)
        ax.set_title(panel_title)
        ax.grid(axis="x", alpha=0.3)
        if shown:
            ax.legend(fontsize="small", loc="lower right")
    for row_y, row in zip(y, rows, strict=True):
        if row["status"] != "ok":
            axes[0].text(0.0, row_y, f" {row['status']}", va="center", color="tab:red")
    axes[0].set_yticks(y, [str(row["bag"]) for row in rows])
    axes[0].invert_yaxis()
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=100)
    return buffer.getvalue()
