"""Withheld GNSS fixes: an outage's own check of the dead-reckoned solution, without a reference.

An injected outage drops the GNSS fixes stamped inside it (ins_fusion.replay.run); the engine
never sees them, so they are independent measurements of where the antenna was while the INS
coasted. Each withheld fix is compared with the fused antenna position at its stamp:

- antenna = base_link position + R(q_enu_base) · ``gnss_lever_arm`` (base_link FLU [m]), per
  recorded solution (ins_fusion.replay.frames.moved_track), then interpolated at the fix stamp
  as the reference is (ins_fusion.replay.metrics: linear, only between two aligned solutions at
  most ``max_gap_s`` apart);
- error e = fused antenna − fix, ENU in the map frame (tangent plane at the engine's datum) [m];
- covariance S = P_filter + R_fix: P_filter the fused antenna covariance (base_link position
  covariance plus the attitude covariance mapped through the lever arm, [a×] P_att [a×]^T;
  without the position-attitude cross-covariance, which the solution does not carry), R_fix the
  fix's own NavSatFix covariance (ENU) — the fix is noisy too;
- NEES e^T S^-1 e (3 degrees of freedom; mean 3 when both covariances are right) and whether
  every ENU component lies within ±3 sqrt(S_ii).

Limits: the "error" contains the fix's own error (noise, multipath, a bias shared by all fixes),
so a drift below the GNSS accuracy is not resolved; invalid fixes (no fix, unknown covariance)
are withheld but not compared.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from gnss_ins_common.types import FloatArray
from ins_fusion.core.filter.records import GnssFixMeasurement
from ins_fusion.replay import metrics
from ins_fusion.replay.frames import moved_track
from ins_fusion.replay.metrics import Errors
from ins_fusion.replay.outages import Outage
from ins_fusion.replay.run import SolutionTrack


@dataclass(frozen=True)
class WithheldEvaluation:
    """Errors at the compared withheld fixes (``errors``: t_rel_s, antenna − fix ENU [m], S =
    P_filter + R_fix [m²]; in_outage all True), the filter's antenna covariance P_filter there
    (m, 3, 3) [m²], and the stamps of every withheld fix, compared or not (k,) [s after t0]."""

    errors: Errors
    filter_cov: FloatArray
    withheld_t_rel_s: FloatArray

    @classmethod
    def empty(cls) -> WithheldEvaluation:
        """No withheld fix compared (statistics of it are None)."""
        return cls(Errors.empty(), np.zeros((0, 3, 3)), np.zeros(0))


def evaluate_withheld(
    track: SolutionTrack,
    fixes: Sequence[GnssFixMeasurement],
    datum: tuple[float, float, float],
    t0_s: float,
    gnss_lever_arm_flu_m: Sequence[float],
    max_gap_s: float = 0.5,
) -> WithheldEvaluation:
    """Compare the fused antenna with each withheld fix (see the module docstring); ``datum``
    of the map frame (lat_deg, lon_deg, height_m), ``t0_s`` the first IMU stamp [s]."""
    if not fixes:
        return WithheldEvaluation.empty()
    fixes = sorted(fixes, key=lambda f: f.t_s)
    t_s = np.array([f.t_s for f in fixes], dtype=np.float64)
    valid = np.array([f.valid for f in fixes], dtype=np.bool_)
    antenna = moved_track(track, gnss_lever_arm_flu_m)
    s = metrics.sample(antenna, t_s, max_gap_s)
    s = metrics.Sampled(s.valid & valid, s.lower, s.weight)
    compared = [f for f, ok in zip(fixes, s.valid, strict=True) if ok]
    if not compared:
        return WithheldEvaluation(Errors.empty(), np.zeros((0, 3, 3)), t_s - t0_s)
    geodetic = np.array([(f.lat_deg, f.lon_deg, f.height_m) for f in compared])
    fix_enu = metrics.map_enu(geodetic, datum)
    fix_cov = np.array([f.cov_enu_m2 for f in compared], dtype=np.float64)
    filter_cov = metrics.lerp(antenna.cov_pos_enu_m2, s)
    t_rel = t_s[s.valid] - t0_s
    errors = Errors(
        t_rel,
        metrics.lerp(antenna.pos_enu_m, s) - fix_enu,
        filter_cov + fix_cov,
        np.ones(len(t_rel), dtype=np.bool_),
    )
    return WithheldEvaluation(errors, filter_cov, t_s - t0_s)


def withheld_stats(evaluation: WithheldEvaluation, outage: Outage) -> dict[str, object]:
    """One outage's withheld fixes: start_s, duration_s, withheld_fixes (dropped fix messages
    stamped in the window), evaluated_fixes (compared), horizontal_error_end_m at the last
    compared fix and the filter's horizontal σ there (sqrt(P_EE + P_NN) of P_filter),
    horizontal_error_max_m, vertical_error_max_m [m], and nees {dof, mean,
    within_3sigma_fraction, samples} against S = P_filter + R_fix."""
    errors, window = evaluation.errors, (outage.start_s, outage.end_s)
    inside = (errors.t_rel_s >= window[0]) & (errors.t_rel_s < window[1])
    withheld = evaluation.withheld_t_rel_s
    h = metrics.horizontal(errors)[inside]
    cov = evaluation.filter_cov[inside]
    consistency = metrics.consistency_stats(errors, inside)
    return {
        "start_s": outage.start_s,
        "duration_s": outage.duration_s,
        "withheld_fixes": int(np.count_nonzero((withheld >= window[0]) & (withheld < window[1]))),
        "evaluated_fixes": int(h.size),
        "horizontal_error_end_m": float(h[-1]) if h.size else None,
        "horizontal_sigma_end_m": float(np.sqrt(cov[-1, 0, 0] + cov[-1, 1, 1])) if h.size else None,
        "horizontal_error_max_m": float(h.max()) if h.size else None,
        "vertical_error_max_m": float(np.abs(errors.error[inside, 2]).max()) if h.size else None,
        "nees": {
            "dof": metrics.NEES_DOF,
            **{k: consistency[k] for k in ("mean", "within_3sigma_fraction", "samples")},
        },
    }
