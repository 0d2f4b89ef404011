"""The fleet summary of a batch: one row of key figures per bag, as a printed table, CSV and
(when pandas and pyarrow are installed) Parquet.

Columns: bag, status ("ok", "no solution", "failed"), error, duration_s, aligned_at_s,
final_state, resets, ``gated_<measurement>`` (gated / (used + rejected) of each measurement the
engine counts), horizontal_rms_m (against the reference), outage_end_max_m (worst horizontal
error at an outage's end, against the reference), withheld_end_max_m (worst fused antenna minus
withheld fix at an outage's last fix), nees_mean and nees_within_3sigma (position, dof 3),
attitude_nees_mean (roll, pitch, yaw, dof 3) and yaw_within_3sigma (the share of the stamps
with the yaw error inside its ±3σ), the same seven figures of the RTS-smoothed solution
(``smoothed_*``) when the batch smoothed, and the task's seconds and worker host. Empty where a
bag has no such figure.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Mapping, Sequence
from typing import Any

from ins_fusion.core.measurements.attitude import ATTITUDE
from ins_fusion.core.measurements.gnss_position import POSITION
from ins_fusion.core.measurements.gnss_velocity import VELOCITY
from ins_fusion.replay.ranking import RANK_METRICS

Row = dict[str, Any]

#: Accuracy columns: (column name after the prefix, RANK_METRICS name).
_ACCURACY = (
    ("horizontal_rms_m", "horizontal_rms"),
    ("outage_end_max_m", "outage_end_max"),
    ("withheld_end_max_m", "withheld_end_max"),
)


def _accuracy(report: Mapping[str, Any], prefix: str) -> Row:
    row: Row = {
        f"{prefix}{column}": RANK_METRICS[key][0](dict(report)) for column, key in _ACCURACY
    }
    nees = report["nees"]
    row[f"{prefix}nees_mean"] = nees["position_mean"]
    row[f"{prefix}nees_within_3sigma"] = nees["position_within_3sigma_fraction"]
    row[f"{prefix}attitude_nees_mean"] = nees["attitude_mean"]
    row[f"{prefix}yaw_within_3sigma"] = nees["yaw_within_3sigma_fraction"]
    return row


def gated(kind: str) -> str:
    """The column of the gated fraction of the measurement kind named ``kind``."""
    return f"gated_{kind}"


def bag_row(name: str, outcome: Mapping[str, Any], report: Mapping[str, Any] | None) -> Row:
    """The summary row of one bag from its outcome and its report (None: none written)."""
    row: Row = {"bag": name, "status": outcome["status"], "error": outcome["error"]}
    if report is not None:
        row.update(
            duration_s=report["duration_s"],
            aligned_at_s=report["aligned_at_s"],
            final_state=report["final_state"],
            resets=report["resets"],
        )
        for kind, counts in report["measurements"].items():
            tried = counts["used"] + counts["rejected"]
            row[gated(kind)] = counts["gated"] / tried if tried else None
        row.update(_accuracy(report, ""))
        if report.get("smoothed") is not None:
            row.update(_accuracy(report["smoothed"], "smoothed_"))
    row.update(seconds=outcome["seconds"], worker=outcome["worker"])
    return row


def columns(rows: Sequence[Row]) -> list[str]:
    """Every column of ``rows`` in first-seen order, the task's seconds and worker last."""
    names: dict[str, None] = {}
    for row in rows:
        names.update(dict.fromkeys(k for k in row if k not in ("seconds", "worker")))
    return [*names, "seconds", "worker"]


def to_csv(rows: Sequence[Row]) -> bytes:
    """The rows as CSV (empty cells where a bag has no figure)."""
    text = io.StringIO()
    writer = csv.DictWriter(text, columns(rows), lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    return text.getvalue().encode()


def to_parquet(rows: Sequence[Row]) -> bytes | None:
    """The rows as Parquet, None when pandas or pyarrow is not installed."""
    try:
        import pandas
        import pyarrow  # noqa: F401 (pandas' Parquet engine)
    except ImportError:
        return None
    buffer = io.BytesIO()
    pandas.DataFrame(list(rows), columns=columns(rows)).to_parquet(buffer, index=False)
    return buffer.getvalue()


def _cell(value: Any) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.3g}" if abs(value) < 1e4 else f"{value:.0f}"
    return str(value)


#: The printed table: (title, column); a column no bag has is left out.
_TABLE = (
    ("bag", "bag"),
    ("status", "status"),
    ("dur s", "duration_s"),
    ("state", "final_state"),
    ("resets", "resets"),
    ("gated pos", gated(POSITION.name)),
    ("gated vel", gated(VELOCITY.name)),
    ("gated att", gated(ATTITUDE.name)),
    ("horiz rms m", "horizontal_rms_m"),
    ("outage end m", "outage_end_max_m"),
    ("withheld end m", "withheld_end_max_m"),
    ("NEES", "nees_mean"),
    ("att NEES", "attitude_nees_mean"),
    ("yaw in 3σ", "yaw_within_3sigma"),
    ("smoothed rms m", "smoothed_horizontal_rms_m"),
    ("smoothed withheld m", "smoothed_withheld_end_max_m"),
    ("smoothed NEES", "smoothed_nees_mean"),
    ("smoothed att NEES", "smoothed_attitude_nees_mean"),
    ("smoothed yaw in 3σ", "smoothed_yaw_within_3sigma"),
)


def format_summary(rows: Sequence[Row]) -> str:
    """The key figures of every bag as a table, then the error of each failed bag."""
    present = set(columns(rows))
    shown = [(title, key) for title, key in _TABLE if key in present]
    table = [[title for title, _ in shown]]
    table += [[_cell(row.get(key)) for _, key in shown] for row in rows]
    widths = [max(len(line[i]) for line in table) for i in range(len(shown))]
    lines = [
        "  ".join(
            c.ljust(w) if i < 2 else c.rjust(w)
            for i, (c, w) in enumerate(zip(line, widths, strict=True))
        )
        for line in table
    ]
    lines += [f"{row['bag']}: {row['error']}" for row in rows if row["error"]]
    return "\n".join(lines)
