"""One run of the fusion core over replay inputs, as fast as the CPU allows.

The engine is fed exactly what ins_fusion_node would receive, in the bag's receive order, minus
the GNSS messages (fix, velocity, attitude) stamped inside an injected outage. The fused base_link
solution is recorded at ``output_rate`` (the node's publish rate): at the first IMU sample at or
after each tick k / output_rate after the first IMU stamp. With ``smooth`` the run is also
recorded for the RTS smoother (ins_fusion.core.engine.smoothed_solution), whose backward pass gives
the smoothed solution at every covariance step once the forward run is done.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from gnss_ins_common.types import BoolArray, FloatArray
from ins_fusion.core.compiled import kernel_array
from ins_fusion.core.engine.engine import EngineStatus, InsEngine, InsSolution
from ins_fusion.core.engine.smoothed_solution import attach_history, smoothed_rows
from ins_fusion.core.engine.warm_up import warm_up
from ins_fusion.core.filter.records import GnssFixMeasurement
from ins_fusion.core.output import solution_rows
from ins_fusion.core.output.output_clock import output_ticks
from ins_fusion.core.settings.config import FusionConfig
from ins_fusion.replay.inputs import Measurement, ReplayInputs
from ins_fusion.replay.outages import Outage, in_any

#: IMU samples between two calls of a replay's progress callback.
_PROGRESS = 2048


@dataclass(frozen=True)
class SolutionTrack:
    """Fused base_link solutions in time order, held as rows of core.output.solution_rows (``rows``;
    ``solutions``: each InsSolution built when asked for; see InsSolution for frames and units),
    with the fields the evaluation uses stacked over time: t_s (n,), pos_enu_m (n, 3),
    quat_enu_flu_xyzw (n, 4), vel_enu_m_s (n, 3), cov_pos_enu_m2 / cov_vel_enu /
    cov_att_enu_rad2 / cov_att_imu_enu_rad2 (imu_link's attitude, InsSolution) (n, 3, 3);
    ``aligned`` (n,) is False while the engine is still 'aligning' (heading unknown). A track
    moved to another frame (replay.frames) replaces the stacked fields; ``rows`` stay those of
    base_link."""

    rows: FloatArray
    t_s: FloatArray
    pos_enu_m: FloatArray
    quat_enu_flu_xyzw: FloatArray
    vel_enu_m_s: FloatArray
    cov_pos_enu_m2: FloatArray
    cov_vel_enu: FloatArray
    cov_att_enu_rad2: FloatArray
    aligned: BoolArray
    cov_att_imu_enu_rad2: FloatArray

    @classmethod
    def from_rows(cls, rows: FloatArray) -> SolutionTrack:
        """The track of an (n, solution_rows.WIDTH) array of rows (the fields are views)."""
        rows = rows.reshape(-1, solution_rows.WIDTH)
        return cls(
            rows,
            rows[:, solution_rows.T],
            rows[:, solution_rows.POS],
            rows[:, solution_rows.QUAT],
            rows[:, solution_rows.VEL],
            rows[:, solution_rows.COV_POS].reshape(-1, 3, 3),
            rows[:, solution_rows.COV_VEL].reshape(-1, 3, 3),
            rows[:, solution_rows.COV_ATT].reshape(-1, 3, 3),
            rows[:, solution_rows.STATE] != solution_rows.STATES.index("aligning"),
            rows[:, solution_rows.COV_ATT_IMU].reshape(-1, 3, 3),
        )

    @classmethod
    def from_solutions(cls, solutions: Sequence[InsSolution]) -> SolutionTrack:
        """Stack a sequence of solutions (may be empty)."""
        return cls.from_rows(np.array([solution_rows.pack(s) for s in solutions]))

    @property
    def solutions(self) -> Sequence[InsSolution]:
        """The recorded base_link solutions."""
        return solution_rows.Solutions(self.rows)

    @property
    def rate_flu_rad_s(self) -> FloatArray:
        """Bias-corrected base_link rates (n, 3) [rad/s]."""
        return self.rows[:, solution_rows.RATE]

    @property
    def imu_mounting_rpy_rad(self) -> FloatArray:
        """The engine's estimated IMU mounting (n, 3) [rad]; NaN rows where not estimated."""
        return self.rows[:, solution_rows.MOUNTING]


@dataclass(frozen=True)
class FusionRun:
    """Result of one engine run: the recorded track, the engine's final status and datum
    (lat_deg, lon_deg, height_m of the map frame; None without any fix), the GNSS messages
    dropped by outages per topic role, the output rate [Hz], the wall time of the run [s], the
    engine's configuration and the fixes the outages withheld (``fix`` role, valid or not, in
    receive order); with smoothing, the smoothed track (one solution per covariance step) and
    the wall time of the backward pass [s]."""

    track: SolutionTrack
    status: EngineStatus
    datum: tuple[float, float, float] | None
    dropped: dict[str, int]
    output_rate_hz: float
    fusion_time_s: float
    config: FusionConfig
    withheld_fixes: tuple[GnssFixMeasurement, ...] = ()
    smoothed: SolutionTrack | None = None
    smoothing_time_s: float = 0.0


def run_fusion(
    inputs: ReplayInputs,
    parameters: Mapping[str, Any],
    outages: Sequence[Outage] = (),
    progress: Callable[[int, int], None] | None = None,
    smooth: bool = False,
) -> FusionRun:
    """Run a fresh engine configured by the flat parameter dict (validated against
    ins_fusion.core.settings.params.PARAMETERS) over ``inputs``; ``progress(done, total)`` counts
    IMU samples; ``smooth``: also the RTS smoother's backward pass. Inputs with a vehicle speed
    turn ``speed.use`` on."""
    if inputs.has_speed:
        parameters = {**parameters, "speed.use": True}
    config = FusionConfig.from_parameters(parameters)
    warm_up()  # the kernels compiled or loaded before the timed run (once per process)
    engine = InsEngine(config)
    history = attach_history(engine) if smooth else None
    start = time.perf_counter()
    t0 = inputs.t0_s
    kept: list[tuple[int, str, Measurement]] = []
    dropped = {"fix": 0, "vel": 0, "attitude": 0}  # a GNSS outage's; the speed goes on
    withheld: list[GnssFixMeasurement] = []
    for item in inputs.measurements:
        if item[1] in dropped and in_any(item[2].t_s - t0, outages):
            dropped[item[1]] += 1
            if isinstance(item[2], GnssFixMeasurement):
                withheld.append(item[2])
        else:
            kept.append(item)
    feed: dict[str, Callable[[Any], None]] = {
        "fix": engine.add_gnss_fix,
        "vel": engine.add_gnss_velocity,
        "attitude": engine.add_attitude,
    }
    if inputs.has_speed:
        feed["speed"] = engine.add_vehicle_speed
    imu = inputs.imu
    t_s, rate, force = (kernel_array(v) for v in (imu.t_s, imu.rate_flu_rad_s, imu.force_flu_m_s2))
    ticks = output_ticks(t_s, t0, config.output_rate_hz)
    solutions = solution_rows.RowBuffer()
    j, n_kept, total = 0, len(kept), len(imu)
    k = 0
    while k < total:  # the samples up to the next measurement's arrival in one call
        while j < n_kept and kept[j][0] <= k:
            feed[kept[j][1]](kept[j][2])
            j += 1
        stop = min(kept[j][0] if j < n_kept else total, (k // _PROGRESS + 1) * _PROGRESS)
        engine.add_imu_series(t_s, rate, force, ticks, (k, stop), solutions)
        k = stop
        if progress is not None and k % _PROGRESS == 0:
            progress(k, total)
    for _, role, measurement in kept[j:]:
        feed[role](measurement)
    if progress is not None:
        progress(total, total)
    status = engine.status()
    fusion_time = time.perf_counter() - start
    smoothed, smoothing_time = None, 0.0
    if history is not None:
        history.finish(engine.covariance)
        smoothed = SolutionTrack.from_rows(smoothed_rows(history))
        history.close()
        smoothing_time = time.perf_counter() - start - fusion_time
    return FusionRun(
        SolutionTrack.from_rows(solutions.rows()),
        status,
        engine.datum,
        dropped,
        config.output_rate_hz,
        fusion_time,
        config,
        tuple(withheld),
        smoothed,
        smoothing_time,
    )
