"""Errors of a fused track against a reference, and their statistics.

The fused solution (of base_link, or moved to the reference's frame by ins_fusion.replay.frames)
is interpolated at the reference stamps (linearly for position, velocity and covariances,
spherically for the orientation); a stamp is evaluated when it lies between two aligned
solutions at most ``max_gap_s`` apart. Errors are estimate minus truth:
position and velocity in the ENU tangent plane at the engine's datum [m, m/s], attitude as
differences of the REP-103 roll, pitch, yaw angles (z-y'-x'' of FLU in ENU) [deg], wrapped to
(-180, 180].

Consistency: the NEES e^T P^-1 e (3 degrees of freedom; mean 3 for a consistent filter) of the
position errors with the fused position covariance, and of the attitude errors with the fused
attitude covariance (the small rotations about the ENU axes of the filter's attitude error,
taken to the roll, pitch and yaw errors by ``rpy_covariance``), and the fraction of stamps at
which every component (or one: the yaw) lies within its ±3σ bound.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from gnss_ins_common.types import BoolArray, FloatArray
from ins_fusion.core.nav import earth
from ins_fusion.replay.inputs import Reference, Series
from ins_fusion.replay.outages import Outage, mask
from ins_fusion.replay.run import SolutionTrack

#: Degrees of freedom of the position and of the attitude NEES.
NEES_DOF = 3


@dataclass(frozen=True)
class Errors:
    """Errors at the evaluated reference stamps: t_rel_s (m,) [s after the first IMU stamp],
    error (m, 3) and its filter covariance (m, 3, 3), in_outage (m,)."""

    t_rel_s: FloatArray
    error: FloatArray
    cov: FloatArray
    in_outage: BoolArray

    @classmethod
    def empty(cls) -> Errors:
        """No evaluated stamps (statistics of it are None)."""
        return cls(np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3, 3)), np.zeros(0, np.bool_))

    @property
    def sigma(self) -> FloatArray:
        """Filter standard deviations of the three components (m, 3)."""
        return np.sqrt(np.maximum(np.diagonal(self.cov, axis1=1, axis2=2), 0.0))


@dataclass(frozen=True)
class Evaluation:
    """Position errors ENU [m] and the reference positions in the map frame at those stamps
    (m, 3); attitude errors roll/pitch/yaw [deg] (covariance: of the roll/pitch/yaw errors
    [deg²], see ``rpy_covariance``) and velocity errors ENU [m/s] (None without an attitude or
    velocity reference)."""

    position: Errors
    reference_enu_m: FloatArray
    attitude: Errors | None
    velocity: Errors | None


@dataclass(frozen=True)
class Sampled:
    """The track interpolated at some stamps; ``valid`` marks the stamps that could be."""

    valid: BoolArray
    lower: NDArray[np.intp]
    weight: FloatArray


def sample(track: SolutionTrack, t_s: FloatArray, max_gap_s: float) -> Sampled:
    """Bracketing solutions (index of the lower one, weight of the upper one) of each stamp."""
    n = len(track.t_s)
    if n < 2:
        zeros = np.zeros(len(t_s))
        return Sampled(zeros.astype(np.bool_), zeros.astype(np.intp), zeros)
    lower = np.clip(np.searchsorted(track.t_s, t_s, side="right") - 1, 0, n - 2)
    t_lo, t_hi = track.t_s[lower], track.t_s[lower + 1]
    valid = (
        (t_s >= t_lo)
        & (t_s <= t_hi)
        & (t_hi - t_lo <= max_gap_s)
        & track.aligned[lower]
        & track.aligned[lower + 1]
    )
    weight = np.clip((t_s - t_lo) / np.maximum(t_hi - t_lo, 1e-9), 0.0, 1.0)
    return Sampled(valid, lower, weight)


def lerp(values: FloatArray, s: Sampled) -> FloatArray:
    """Per-solution values (n, ...) linearly interpolated at the valid sampled stamps."""
    lo, w = s.lower[s.valid], s.weight[s.valid]
    w = w.reshape((-1,) + (1,) * (values.ndim - 1))
    result: FloatArray = (1.0 - w) * values[lo] + w * values[lo + 1]
    return result


def slerp(quats: FloatArray, s: Sampled) -> Rotation:
    """Per-solution orientations (n, 4) (x, y, z, w) spherically interpolated at the valid
    sampled stamps."""
    lo, w = s.lower[s.valid], s.weight[s.valid]
    r0, r1 = Rotation.from_quat(quats[lo]), Rotation.from_quat(quats[lo + 1])
    return r0 * Rotation.from_rotvec((r0.inv() * r1).as_rotvec() * w[:, None])


def rpy_deg(rotation: Rotation) -> FloatArray:
    """REP-103 roll, pitch, yaw [deg] (n, 3) of FLU-in-ENU orientations."""
    return np.asarray(rotation.as_euler("ZYX", degrees=True)[..., ::-1], dtype=np.float64)


def wrap_deg(angle_deg: FloatArray) -> FloatArray:
    """Angles wrapped to (-180, 180] [deg]."""
    wrapped = np.asarray(180.0 - np.mod(180.0 - angle_deg, 360.0), dtype=np.float64)
    return wrapped


def rpy_covariance(cov_att_enu_rad2: FloatArray, yaw_deg: FloatArray) -> FloatArray:
    """Covariance [deg²] (n, 3, 3) of small roll, pitch, yaw errors from that of the attitude
    errors about the ENU axes [rad²]: roll about the level forward axis (cos ψ, sin ψ, 0),
    pitch about the level left axis (-sin ψ, cos ψ, 0), yaw about up (small tilt)."""
    psi = np.radians(yaw_deg)
    c, s = np.cos(psi), np.sin(psi)
    axes = np.zeros((len(psi), 3, 3))
    axes[:, 0, 0], axes[:, 0, 1] = c, s
    axes[:, 1, 0], axes[:, 1, 1] = -s, c
    axes[:, 2, 2] = 1.0
    cov: FloatArray = axes @ cov_att_enu_rad2 @ axes.transpose(0, 2, 1) * np.degrees(1.0) ** 2
    return cov


def map_enu(geodetic: FloatArray, datum: tuple[float, float, float]) -> FloatArray:
    """WGS-84 points (m, 3) (lat_deg, lon_deg, height_m) in the map frame: ENU [m] (m, 3) in the
    tangent plane at ``datum`` (lat_deg, lon_deg, height_m), as the engine's pos_enu_m."""
    lat0, lon0, h0 = datum
    points = np.asarray(geodetic, dtype=np.float64).reshape(-1, 3)
    enu: FloatArray = earth.geodetic_to_enu(
        np.radians(points[:, 0]),
        np.radians(points[:, 1]),
        points[:, 2],
        float(np.radians(lat0)),
        float(np.radians(lon0)),
        h0,
    ).reshape(-1, 3)
    return enu


def _position(
    track: SolutionTrack,
    ref: Series,
    datum: tuple[float, float, float],
    t0_s: float,
    outages: Sequence[Outage],
    max_gap_s: float,
) -> tuple[Errors, FloatArray]:
    s = sample(track, ref.t_s, max_gap_s)
    truth_enu = map_enu(ref.values[s.valid], datum)
    t_rel = ref.t_s[s.valid] - t0_s
    errors = Errors(
        t_rel,
        lerp(track.pos_enu_m, s) - truth_enu,
        lerp(track.cov_pos_enu_m2, s),
        mask(t_rel, outages),
    )
    return errors, truth_enu


def _attitude(
    track: SolutionTrack, ref: Series, t0_s: float, outages: Sequence[Outage], max_gap_s: float
) -> Errors:
    s = sample(track, ref.t_s, max_gap_s)
    truth_rpy = rpy_deg(Rotation.from_quat(ref.values[s.valid]))
    estimate_rpy = rpy_deg(slerp(track.quat_enu_flu_xyzw, s)) if s.valid.any() else truth_rpy
    t_rel = ref.t_s[s.valid] - t0_s
    return Errors(
        t_rel,
        wrap_deg(estimate_rpy - truth_rpy),
        rpy_covariance(lerp(track.cov_att_enu_rad2, s), truth_rpy[:, 2]),
        mask(t_rel, outages),
    )


def _velocity(
    track: SolutionTrack, ref: Series, t0_s: float, outages: Sequence[Outage], max_gap_s: float
) -> Errors:
    s = sample(track, ref.t_s, max_gap_s)
    t_rel = ref.t_s[s.valid] - t0_s
    return Errors(
        t_rel,
        lerp(track.vel_enu_m_s, s) - ref.values[s.valid],
        lerp(track.cov_vel_enu, s),
        mask(t_rel, outages),
    )


def evaluate(
    track: SolutionTrack,
    reference: Reference,
    datum: tuple[float, float, float],
    t0_s: float,
    outages: Sequence[Outage] = (),
    max_gap_s: float = 0.5,
) -> Evaluation:
    """Errors of ``track`` at the reference stamps (see the module docstring); times in the
    result are relative to ``t0_s``, the first IMU stamp [s]."""
    return Evaluation(
        *_position(track, reference.position, datum, t0_s, outages, max_gap_s),
        None
        if reference.attitude is None
        else _attitude(track, reference.attitude, t0_s, outages, max_gap_s),
        None
        if reference.velocity is None
        else _velocity(track, reference.velocity, t0_s, outages, max_gap_s),
    )


# --------------------------------------------------------------------------------------------
# Statistics (JSON-ready: plain floats, None where there is nothing to measure)
# --------------------------------------------------------------------------------------------


def _rms(values: FloatArray) -> float | None:
    return float(np.sqrt(np.mean(np.square(values)))) if values.size else None


def horizontal(errors: Errors) -> FloatArray:
    """Horizontal error magnitudes sqrt(e_E² + e_N²) (m,)."""
    return np.asarray(np.hypot(errors.error[:, 0], errors.error[:, 1]), dtype=np.float64)


def position_stats(errors: Errors) -> dict[str, float | None]:
    """horizontal_rms, vertical_rms, horizontal_p95, horizontal_max, and the horizontal and
    vertical error at the last evaluated stamp (horizontal_final, vertical_final) [m]."""
    h = horizontal(errors)
    return {
        "horizontal_rms": _rms(h),
        "vertical_rms": _rms(errors.error[:, 2]),
        "horizontal_p95": float(np.percentile(h, 95.0)) if h.size else None,
        "horizontal_max": float(h.max()) if h.size else None,
        "horizontal_final": float(h[-1]) if h.size else None,
        "vertical_final": float(errors.error[-1, 2]) if h.size else None,
    }


def velocity_stats(errors: Errors) -> dict[str, float | None]:
    """horizontal_rms, vertical_rms [m/s]."""
    return {"horizontal_rms": _rms(horizontal(errors)), "vertical_rms": _rms(errors.error[:, 2])}


def attitude_stats(errors: Errors) -> dict[str, float | None]:
    """roll_rms, pitch_rms, yaw_rms, yaw_max [deg]."""
    e = errors.error
    return {
        "roll_rms": _rms(e[:, 0]),
        "pitch_rms": _rms(e[:, 1]),
        "yaw_rms": _rms(e[:, 2]),
        "yaw_max": float(np.abs(e[:, 2]).max()) if len(e) else None,
    }


def nees(errors: Errors) -> FloatArray:
    """Normalised estimation error squared e^T P^-1 e per stamp (m,)."""
    if not len(errors.error):
        return np.zeros(0)
    solved = np.linalg.solve(errors.cov, errors.error[:, :, None])[:, :, 0]
    return np.asarray(np.einsum("ij,ij->i", errors.error, solved), dtype=np.float64)


def inside_3sigma(errors: Errors) -> BoolArray:
    """Per stamp and component: the error within ±3σ of its own variance (m, 3)."""
    inside: BoolArray = np.abs(errors.error) <= 3.0 * errors.sigma
    return inside


def within_3sigma(errors: Errors) -> BoolArray:
    """Per stamp: every component of the error within ±3σ of its own variance (m,)."""
    every: BoolArray = np.all(inside_3sigma(errors), axis=1)
    return every


def consistency_stats(errors: Errors, select: BoolArray | None = None) -> dict[str, Any]:
    """Over the stamps ``select`` (all when None): mean (of the NEES, NEES_DOF dof),
    within_3sigma_fraction (every component inside its ±3σ), axis_within_3sigma_fraction (a
    list: each component's own) and samples; None where no stamp is selected."""
    values, inside = nees(errors), inside_3sigma(errors)
    if select is not None:
        values, inside = values[select], inside[select]
    some = bool(values.size)
    return {
        "mean": float(values.mean()) if some else None,
        "within_3sigma_fraction": float(np.all(inside, axis=1).mean()) if some else None,
        "axis_within_3sigma_fraction": [float(f) for f in inside.mean(axis=0)]
        if some
        else [None] * inside.shape[1],
        "samples": int(values.size),
    }


def outage_stats(errors: Errors, outage: Outage) -> dict[str, float | None]:
    """Errors inside one outage window [m]: horizontal at its last reference stamp (and the
    filter's horizontal σ there, sqrt(P_EE + P_NN)), largest horizontal and vertical."""
    inside = (errors.t_rel_s >= outage.start_s) & (errors.t_rel_s < outage.end_s)
    h = horizontal(errors)[inside]
    cov = errors.cov[inside]
    return {
        "start_s": outage.start_s,
        "duration_s": outage.duration_s,
        "horizontal_error_end_m": float(h[-1]) if h.size else None,
        "horizontal_sigma_end_m": float(np.sqrt(cov[-1, 0, 0] + cov[-1, 1, 1])) if h.size else None,
        "horizontal_error_max_m": float(h.max()) if h.size else None,
        "vertical_error_max_m": float(np.abs(errors.error[inside, 2]).max()) if h.size else None,
    }
