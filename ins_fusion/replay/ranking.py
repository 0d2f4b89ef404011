"""Scores of a replay report for ranking the settings of a sweep (``--rank-by``).

Every score is "lower is better": errors as they are, the position NEES as its distance from
consistency |ln(mean / dof)|, the 3σ fraction as the fraction outside. None when the report
cannot give it (no reference, no outage). ``withheld_*`` scores need no reference: they compare
the fused antenna with the GNSS fixes the outages withheld (ins_fusion.replay.withheld).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

Report = dict[str, Any]
#: Default ranking metric of a sweep.
DEFAULT_RANK_BY = "horizontal_rms"


def _section(section: str, key: str) -> Callable[[Report], float | None]:
    def metric(report: Report) -> float | None:
        values = report.get(section)
        return None if values is None else values.get(key)

    return metric


def _worst_outage(key: str) -> Callable[[Report], float | None]:
    def metric(report: Report) -> float | None:
        values = [o[key] for o in report["outages"] if o[key] is not None]
        return max(values) if values else None

    return metric


def _worst_withheld(key: str) -> Callable[[Report], float | None]:
    def metric(report: Report) -> float | None:
        rows = report.get("withheld_fixes") or []
        values = [o[key] for o in rows if o[key] is not None]
        return max(values) if values else None

    return metric


def _nees_distance(report: Report) -> float | None:
    mean = report["nees"]["position_mean"]
    return None if mean is None or mean <= 0.0 else abs(math.log(mean / report["nees"]["dof"]))


def _outside_3sigma(report: Report) -> float | None:
    fraction = report["nees"]["position_within_3sigma_fraction"]
    return None if fraction is None else 1.0 - fraction


#: --rank-by choices: name -> (score of a report, lower is better; description).
RANK_METRICS: dict[str, tuple[Callable[[Report], float | None], str]] = {
    "horizontal_rms": (_section("position_error_m", "horizontal_rms"), "horizontal RMS [m]"),
    "horizontal_p95": (_section("position_error_m", "horizontal_p95"), "horizontal p95 [m]"),
    "horizontal_max": (_section("position_error_m", "horizontal_max"), "horizontal max [m]"),
    "vertical_rms": (_section("position_error_m", "vertical_rms"), "vertical RMS [m]"),
    "roll_rms": (_section("attitude_error_deg", "roll_rms"), "roll RMS [deg]"),
    "pitch_rms": (_section("attitude_error_deg", "pitch_rms"), "pitch RMS [deg]"),
    "yaw_rms": (_section("attitude_error_deg", "yaw_rms"), "yaw RMS [deg]"),
    "outage_end_max": (
        _worst_outage("horizontal_error_end_m"),
        "worst horizontal error at an outage's end [m]",
    ),
    "outage_max": (_worst_outage("horizontal_error_max_m"), "worst horizontal error in an outage"),
    "withheld_end_max": (
        _worst_withheld("horizontal_error_end_m"),
        "worst horizontal antenna - withheld fix at an outage's last fix [m]",
    ),
    "withheld_max": (
        _worst_withheld("horizontal_error_max_m"),
        "worst horizontal antenna - withheld fix in an outage [m]",
    ),
    "nees": (_nees_distance, "|ln(position NEES mean / 3)|"),
    "outside_3sigma": (_outside_3sigma, "fraction of stamps outside the 3σ bounds"),
}
