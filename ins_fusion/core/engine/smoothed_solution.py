"""The engine's side of the RTS smoother: what a record snapshots, and the smoothed solution.

``attach_history(engine)`` gives the engine a ``SmootherHistory`` (core.smoother.history)
whose snapshot at each transition is the engine's ``solution()`` at that moment (the prior x̂_j⁻
of the step, on the engine's final timeline) packed into a row, with ``engine.solution_jacobian``:
the derivatives of base_link's ENU position, velocity and attitude and of imu_link's attitude
(errors about the ENU axes) with respect to the error states ``solution_states`` (position,
velocity, attitude, gyro bias and the mounting states), the same Jacobian that gives the
solution's covariances. A snapshot taken
while the engine re-propagates after a late measurement has the newest IMU sample's rate
(solution() holds no other): its rate and the lever arm's ω × r part of the velocity are those
of up to one measurement latency later.

``smoothed_rows(history)`` runs the backward pass and moves each snapshot (a row of
core.output.solution_rows: the solution, compact) by the smoothed change J (e + c): position (the
ENU offset also to latitude, longitude, height), velocity, orientation (the small rotation about the
ENU axes, left-multiplied: R_true = exp([δθ×]) R, as the engine injects ψ), the gyro and
accelerometer biases by their smoothed errors; covariances J P^s Jᵀ. The rate, the mounting and
the state name stay the forward filter's. One solution per stamp (of several transitions at one
stamp, the last holds the step's result), in time order, from the first stamp with the heading
known.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from gnss_ins_common.types import FloatArray, IntArray
from ins_fusion.core.engine.engine import InsEngine
from ins_fusion.core.filter.eskf import BA, BG, StateLayout
from ins_fusion.core.nav import earth
from ins_fusion.core.nav.rotation import frd_to_flu, quat_from_rotvec, quat_multiply, quat_normalize
from ins_fusion.core.output import solution_rows as rows
from ins_fusion.core.output.solution import E_ATT, E_ATT_IMU, E_POS, E_VEL
from ins_fusion.core.smoother.history import SmoothedEpoch, SmootherHistory, Snapshot

#: Extra margin on the engine's history for rollbacks [s].
_HORIZON_MARGIN_S = 2.0


def solution_states(layout: StateLayout) -> IntArray:
    """Error states the solution's Jacobian is over: position, velocity, attitude, gyro bias
    (0-11), then the mounting pitch and yaw when estimated (as InsEngine.solution)."""
    extra = [] if layout.mt is None else [layout.mt, layout.mt + 1]
    return np.array([*range(BG + 3), *extra], dtype=np.int64)


def attach_history(
    engine: InsEngine, chunk_records: int = 4096, directory: Path | None = None
) -> SmootherHistory:
    """The history of ``engine``'s forward run, set as its smoother hooks (see SmootherHistory for
    ``chunk_records`` and ``directory``)."""

    def snapshot() -> Snapshot:
        row = engine.solution_row()
        assert row is not None  # transitions happen only once the filter runs
        return Snapshot(
            float(row[rows.T]),
            row,
            engine.solution_jacobian,
            rows.STATES[int(row[rows.STATE])] != "aligning",
        )

    history = SmootherHistory(
        engine.layout.size,
        solution_states(engine.layout),
        snapshot,
        engine.config.history_s + _HORIZON_MARGIN_S,
        chunk_records,
        directory,
    )
    engine.smoother_hooks = history
    return history


def _smoothed(epoch: SmoothedEpoch) -> FloatArray:
    row, delta, cov = epoch.row.copy(), epoch.delta, epoch.cov
    lat_rad, height = math.radians(row[rows.LAT]), float(row[rows.HEIGHT])
    r_m, r_n = earth.radii_m(lat_rad)
    d_east, d_north, d_up = delta[E_POS : E_POS + 3].tolist()
    row[rows.LAT] += math.degrees(d_north / (r_m + height))
    row[rows.LON] += math.degrees(d_east / ((r_n + height) * math.cos(lat_rad)))
    row[rows.HEIGHT] += d_up
    row[rows.POS] += delta[E_POS : E_POS + 3]
    row[rows.VEL] += delta[E_VEL : E_VEL + 3]
    rx, ry, rz = delta[E_ATT : E_ATT + 3].tolist()
    x, y, z, w = row[rows.QUAT].tolist()
    row[rows.QUAT] = quat_normalize(quat_multiply(quat_from_rotvec(rx, ry, rz), (x, y, z, w)))
    for field, first in (
        (rows.COV_POS, E_POS),
        (rows.COV_VEL, E_VEL),
        (rows.COV_ATT, E_ATT),
        (rows.COV_ATT_IMU, E_ATT_IMU),
    ):
        row[field] = cov[first : first + 3, first : first + 3].ravel()
    row[rows.GYRO] += frd_to_flu(epoch.error[BG : BG + 3])
    row[rows.ACCEL] += frd_to_flu(epoch.error[BA : BA + 3])
    return row


def smoothed_rows(history: SmootherHistory) -> FloatArray:
    """The smoothed base_link solution at every recorded stamp, as rows of
    core.output.solution_rows (see the module docstring), in time order."""
    buffer = rows.RowBuffer()
    last_t = math.inf
    for epoch in history.backward():
        if epoch.t_s < last_t:
            buffer.append(_smoothed(epoch))
            last_t = epoch.t_s
    return buffer.rows()[::-1].copy()
