"""The engine's side of the RTS smoother: what a record snapshots, and the smoothed solution.

``attach_recorder(engine)`` gives the engine a ``SmootherRecorder`` (core.smoother_recorder)
whose snapshot at each transition is the engine's ``solution()`` at that moment (the prior x̂_j⁻
of the step, on the engine's final timeline) packed into a row, with ``engine.solution_jacobian``:
the derivatives of base_link's ENU position, velocity and attitude (errors about the ENU axes)
with respect to the error states ``solution_states`` (position, velocity, attitude, gyro bias and
the mounting states), the same Jacobian that gives the solution's covariances.

``smoothed_solutions(recorder)`` runs the backward pass and moves each snapshot by the smoothed
change J (e + c): position (the ENU offset also to latitude, longitude, height), velocity,
orientation (the small rotation about the ENU axes, left-multiplied: R_true = exp([δθ×]) R, as
the engine injects ψ), the gyro and accelerometer biases by their smoothed errors; covariances
J P^s Jᵀ. The rate, the mounting and the state name stay the forward filter's. One solution per
stamp (of several transitions at one stamp, the last holds the step's result), in time order,
from the first stamp with the heading known.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from gnss_ins_common.types import FloatArray, IntArray
from ins_fusion.core import earth
from ins_fusion.core.engine import InsEngine, InsSolution
from ins_fusion.core.eskf import BA, BG, StateLayout
from ins_fusion.core.rotation import frd_to_flu, quat_from_rotvec, quat_multiply, quat_normalize
from ins_fusion.core.smoother_recorder import SmoothedEpoch, SmootherRecorder, Snapshot

#: Engine states in the order of their code in a snapshot row.
_STATES = ("aligning", "navigating", "degraded")
#: Columns of a snapshot row.
_T, _LAT, _LON, _HEIGHT = 0, 1, 2, 3
_POS, _VEL, _QUAT, _RATE, _GYRO, _ACCEL, _MOUNT, _STATE = 4, 7, 10, 14, 17, 20, 23, 26
_ROW = 27
#: Extra margin on the engine's history for rollbacks [s].
_HORIZON_MARGIN_S = 2.0


def solution_states(layout: StateLayout) -> IntArray:
    """Error states the solution's Jacobian is over: position, velocity, attitude, gyro bias
    (0-11), then the mounting pitch and yaw when estimated (as InsEngine.solution)."""
    extra = [] if layout.mt is None else [layout.mt, layout.mt + 1]
    return np.array([*range(BG + 3), *extra], dtype=np.int64)


def _row(solution: InsSolution) -> FloatArray:
    row = np.empty(_ROW)
    row[[_T, _LAT, _LON, _HEIGHT]] = (
        solution.t_s,
        solution.lat_deg,
        solution.lon_deg,
        solution.height_m,
    )
    row[_POS:_VEL] = solution.pos_enu_m
    row[_VEL:_QUAT] = solution.vel_enu_m_s
    row[_QUAT:_RATE] = solution.quat_enu_flu_xyzw
    row[_RATE:_GYRO] = solution.rate_flu_rad_s
    row[_GYRO:_ACCEL] = solution.gyro_bias_flu_rad_s
    row[_ACCEL:_MOUNT] = solution.accel_bias_flu_m_s2
    mounting = solution.imu_mounting_rpy_rad
    row[_MOUNT:_STATE] = np.nan if mounting is None else mounting
    row[_STATE] = _STATES.index(solution.state)
    return row


def attach_recorder(
    engine: InsEngine, chunk_records: int = 4096, directory: Path | None = None
) -> SmootherRecorder:
    """A recorder of ``engine``'s forward run, set as its hooks (see SmootherRecorder for
    ``chunk_records`` and ``directory``)."""

    def snapshot() -> Snapshot:
        solution = engine.solution()
        assert solution is not None  # transitions happen only once the filter runs
        return Snapshot(
            solution.t_s,
            _row(solution),
            engine.solution_jacobian,
            solution.state != "aligning",
        )

    recorder = SmootherRecorder(
        engine.layout.size,
        solution_states(engine.layout),
        snapshot,
        engine.config.history_s + _HORIZON_MARGIN_S,
        chunk_records,
        directory,
    )
    engine.recorder = recorder
    return recorder


def _smoothed(epoch: SmoothedEpoch) -> InsSolution:
    row, delta, cov = epoch.row, epoch.delta, epoch.cov
    lat_rad, height = math.radians(row[_LAT]), float(row[_HEIGHT])
    r_m, r_n = earth.radii_m(lat_rad)
    d_east, d_north, d_up = delta[0:3].tolist()
    rx, ry, rz = delta[6:9].tolist()
    x, y, z, w = row[_QUAT:_RATE].tolist()
    quat = quat_normalize(quat_multiply(quat_from_rotvec(rx, ry, rz), (x, y, z, w)))
    mounting = row[_MOUNT:_STATE]
    return InsSolution(
        t_s=float(row[_T]),
        lat_deg=float(row[_LAT]) + math.degrees(d_north / (r_m + height)),
        lon_deg=float(row[_LON]) + math.degrees(d_east / ((r_n + height) * math.cos(lat_rad))),
        height_m=height + d_up,
        pos_enu_m=row[_POS:_VEL] + delta[0:3],
        vel_enu_m_s=row[_VEL:_QUAT] + delta[3:6],
        quat_enu_flu_xyzw=np.array(quat),
        rate_flu_rad_s=np.array(row[_RATE:_GYRO]),
        cov_pos_enu_m2=cov[0:3, 0:3],
        cov_vel_enu=cov[3:6, 3:6],
        cov_att_enu_rad2=cov[6:9, 6:9],
        gyro_bias_flu_rad_s=row[_GYRO:_ACCEL] + frd_to_flu(epoch.error[BG : BG + 3]),
        accel_bias_flu_m_s2=row[_ACCEL:_MOUNT] + frd_to_flu(epoch.error[BA : BA + 3]),
        state=_STATES[int(row[_STATE])],
        imu_mounting_rpy_rad=None if np.isnan(mounting).any() else np.array(mounting),
    )


def smoothed_solutions(recorder: SmootherRecorder) -> list[InsSolution]:
    """The smoothed base_link solution at every recorded stamp (see the module docstring)."""
    solutions: list[InsSolution] = []
    last_t = math.inf
    for epoch in recorder.backward():
        if epoch.t_s < last_t:
            solutions.append(_smoothed(epoch))
            last_t = epoch.t_s
    solutions.reverse()
    return solutions
