"""Free-inertial replay: the Aalborg report's own evaluation of the IMU (§9.1.3-§9.1.5).

The report let its INS start from the RTK position and the attitude of the standstill before
each drive, then navigate the 180 s drive on the IMU alone, and compared it with RTK at 5, 10,
15, 20, 30, 40, 50, 60, 120 and 180 s after the drive began (Aalborg notes §8.2-§8.3). Over
its six clean runs it gives, per elapsed time, for the horizontal distance ("2D") and the Down
deviation ("1D"):

    σ_pos = sqrt(Σ d² / n)                 (9.3), the report's accuracy (RMS over the runs)
    σ_afv = sqrt(Σ (μ - d)² / (n - 1))     (9.4), its precision (spread about the mean μ)

``gnss_ins replay BAG --free-inertial START`` reproduces the setting: every GNSS message
stamped from START [s after the first IMU stamp] on is withheld (an outage to the end of the
bag), and the pseudo-measurements that would aid the INS without GNSS (zero-velocity,
zero-angular-rate, non-holonomic) are off for the whole run; before START the engine aligns and
calibrates on GNSS (and ADU5 attitude) as usual. d is taken from the withheld GNSS fixes, as the
report took it from RTK: the fused antenna minus the fix (ins_fusion.replay.withheld),
interpolated linearly to START + each elapsed time; horizontal d is the distance, Down d the
signed deviation downwards. One bag is one run (n = 1: σ_afv undefined); bench/
bench_free_inertial.py combines simulated runs as the report combined its six drives.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from gnss_ins_common.types import FloatArray
from ins_fusion.replay.outages import Outage
from ins_fusion.replay.withheld import WithheldEvaluation

#: Elapsed times of the report's tables [s after the drive began] (Aalborg notes §8.3).
ELAPSED_S = (5.0, 10.0, 15.0, 20.0, 30.0, 40.0, 50.0, 60.0, 120.0, 180.0)
#: Aiding the report's free INS did not have.
UNAIDED: dict[str, Any] = {"use_zupt": False, "use_zaru": False, "use_nhc": False}


def outage(start_s: float, duration_s: float) -> Outage:
    """The outage that withholds GNSS from start_s [s after the first IMU stamp] to the end of a
    bag of duration_s [s]."""
    return Outage(start_s, max(duration_s - start_s, 0.0) + 1.0)


@dataclass(frozen=True)
class Drift:
    """Deviations of one free-inertial run at ``elapsed_s`` [s after START]: horizontal
    distance and Down deviation [m] (nan where no withheld fix brackets the time)."""

    elapsed_s: tuple[float, ...]
    horizontal_m: FloatArray
    down_m: FloatArray


def drift(withheld: WithheldEvaluation, start_s: float, elapsed_s: Sequence[float]) -> Drift:
    """The run's deviations from the withheld fixes (ENU error = antenna − fix), linearly
    interpolated to start_s + each elapsed time [s after the first IMU stamp]."""
    errors = withheld.errors
    t = start_s + np.asarray(elapsed_s, dtype=np.float64)
    if len(errors.t_rel_s) < 2:
        nan = np.full(len(t), math.nan)
        return Drift(tuple(elapsed_s), nan, nan.copy())
    inside = (t >= errors.t_rel_s[0]) & (t <= errors.t_rel_s[-1])
    enu = np.stack([np.interp(t, errors.t_rel_s, errors.error[:, k]) for k in range(3)], axis=1)
    horizontal = np.where(inside, np.hypot(enu[:, 0], enu[:, 1]), math.nan)
    down = np.where(inside, -enu[:, 2], math.nan)
    return Drift(tuple(elapsed_s), horizontal, down)


def sigma_pos(d: FloatArray) -> FloatArray:
    """(9.3) over the runs (axis 0): sqrt(Σ d² / n) [m]."""
    values = np.asarray(d, dtype=np.float64)
    return np.asarray(np.sqrt(np.mean(values**2, axis=0)), dtype=np.float64)


def sigma_afv(d: FloatArray) -> FloatArray:
    """(9.4) over the runs (axis 0): sqrt(Σ (μ - d)² / (n - 1)) [m]; nan for one run."""
    values = np.asarray(d, dtype=np.float64)
    if values.shape[0] < 2:
        return np.full(values.shape[1:], math.nan)
    return np.asarray(np.std(values, axis=0, ddof=1), dtype=np.float64)


def report_section(run: Drift, start_s: float) -> dict[str, Any]:
    """The JSON report's ``free_inertial`` section (nan -> None)."""

    def values(array: FloatArray) -> list[float | None]:
        return [float(v) if math.isfinite(v) else None for v in array]

    return {
        "start_s": start_s,
        "unaided": dict(UNAIDED),
        "elapsed_s": list(run.elapsed_s),
        "horizontal_m": values(run.horizontal_m),
        "down_m": values(run.down_m),
    }


def format_drift(run: Drift, start_s: float) -> str:
    """A table: elapsed time, horizontal distance and Down deviation (the report's 2D and 1D)."""

    def cells(array: FloatArray) -> str:
        return "".join(f"{v:>9.2f}" if math.isfinite(v) else f"{'-':>9}" for v in array)

    return "\n".join(
        [
            f"free-inertial from {start_s:g} s (GNSS withheld, no ZUPT/ZARU/NHC); d against the"
            " withheld fixes",
            f"{'elapsed s':<14}" + "".join(f"{t:>9g}" for t in run.elapsed_s),
            f"{'horizontal m':<14}" + cells(run.horizontal_m),
            f"{'down m':<14}" + cells(run.down_m),
        ]
    )
