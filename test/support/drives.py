"""In-process drives through the fusion engine: the simulator's IMU, RTK and attitude streams
delivered in arrival order as the node receives them, and the fused base_link solution compared
with the simulated truth (used by the engine tests and bench/bench_fusion_engine.py)."""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ins_fusion.core.engine.engine import (
    AttitudeMeasurement,
    EngineStatus,
    GnssFixMeasurement,
    GnssVelocityMeasurement,
    InsEngine,
)
from ins_fusion.core.nav import earth
from ins_fusion.core.nav.calibration import ImuCalibration
from ins_fusion.core.nav.rotation import euler_from_quat, quat_nb_from_enu_flu
from ins_fusion.core.settings.config import FusionConfig
from ins_fusion.sim.gnss_model import PROFILES as GNSS_PROFILES
from ins_fusion.sim.gnss_model import GnssErrorModel, GnssFix, GnssSchedule
from ins_fusion.sim.imu_model import PROFILES as IMU_PROFILES
from ins_fusion.sim.imu_model import ImuErrorModel
from ins_fusion.sim.scenarios import SCENARIOS, SURVEY_CAR
from ins_fusion.sim.vehicle import TruthCache, VehicleTruth
from support.paths import REPO

CALIBRATION = REPO / "config" / "imu400cc_calibration.yaml"


#: Drive start in the test pattern (60 s standstill) and the Aalborg outages (notes §8.4):
#: 20 s starting 50, 85 and 145 s after the drive starts.
DRIVE_START_S = 60.0


AALBORG_OUTAGES = tuple((DRIVE_START_S + start, 20.0) for start in (50.0, 85.0, 145.0))


#: Vertical velocity variance of receivers without one (the gnss/vel contract: >= 1e4).
UNKNOWN_VERTICAL_VARIANCE = 1.0e6


Measurement = GnssFixMeasurement | GnssVelocityMeasurement | AttitudeMeasurement


@dataclass
class Drive:
    """Simulated sensor streams and the truth; events are (arrival time, measurement)."""

    truth: VehicleTruth
    imu_t: np.ndarray
    imu_rate: np.ndarray
    imu_force: np.ndarray
    events: list[tuple[float, Measurement]]


def from_fix(fix: GnssFix) -> list[Measurement]:
    """gnss/fix and gnss/vel of one receiver epoch, as the gnss node publishes them."""
    vel = fix.vel_enu_m_s.copy()
    var = np.square(fix.velocity_sigma_enu_m_s)
    if not math.isfinite(vel[2]):
        vel[2], var[2] = 0.0, UNKNOWN_VERTICAL_VARIANCE
    return [
        GnssFixMeasurement(
            fix.t_s,
            math.degrees(fix.lat_rad),
            math.degrees(fix.lon_rad),
            fix.height_m,
            np.diag(np.square(fix.position_sigma_enu_m)),
        ),
        GnssVelocityMeasurement(fix.t_s, vel, np.diag(var)),
    ]


def simulate(
    duration_s: float = 240.0,
    imu_profile: str = "imu400cc",
    seed: int = 1,
    outages: Sequence[tuple[float, float]] = (),
    with_attitude: bool = False,
    scenario: str = "test_pattern",
) -> Drive:
    """Streams of a simulated drive (seeded: IMU errors, RTK and ADU5 noise)."""
    truth = VehicleTruth(SCENARIOS[scenario](duration_s), SURVEY_CAR)
    profile = IMU_PROFILES[imu_profile]
    t = np.arange(0.0, duration_s, 1.0 / profile.rate_hz)
    imu = truth.imu(t)
    rate, force = ImuErrorModel(profile, seed).apply(
        t, imu.rate_flu_rad_s, imu.specific_force_flu_m_s2
    )
    events: list[tuple[float, Measurement]] = []
    gnss_truth = TruthCache(truth.gnss_truths, truth.gnss_truth)
    rtk = GnssErrorModel(
        gnss_truth, GNSS_PROFILES["leica_rtk"], GnssSchedule(tuple(outages)), seed=seed
    )
    for fix in rtk.fixes(0.0, duration_s):
        events += [(fix.arrival_t_s, m) for m in from_fix(fix)]
    if with_attitude:
        adu5 = GnssErrorModel(gnss_truth, GNSS_PROFILES["adu5"], seed=seed + 1000)
        for fix in adu5.fixes(0.0, duration_s):
            assert fix.quat_enu_flu is not None and fix.attitude_sigma_rpy_rad is not None
            cov = np.diag(np.square(fix.attitude_sigma_rpy_rad))
            events.append((fix.arrival_t_s, AttitudeMeasurement(fix.t_s, fix.quat_enu_flu, cov)))
    events.sort(key=lambda e: e[0])
    return Drive(truth, t, rate, force, events)


def deliver(engine: InsEngine, measurement: Measurement) -> None:
    """Hand one measurement to the engine as the node would."""
    if isinstance(measurement, GnssFixMeasurement):
        engine.add_gnss_fix(measurement)
    elif isinstance(measurement, GnssVelocityMeasurement):
        engine.add_gnss_velocity(measurement)
    else:
        engine.add_attitude(measurement)


def feed(
    engine: InsEngine,
    drive: Drive,
    events: Sequence[tuple[float, Measurement]] | None = None,
    after_sample: Callable[[int], None] | None = None,
) -> None:
    """IMU samples and measurements in arrival order (the rest after the last sample);
    ``after_sample(i)`` after sample i."""
    events = drive.events if events is None else events
    rates, forces = drive.imu_rate.tolist(), drive.imu_force.tolist()
    k = 0
    for i, t in enumerate(drive.imu_t.tolist()):
        while k < len(events) and events[k][0] <= t:
            deliver(engine, events[k][1])
            k += 1
        engine.add_imu(t, rates[i], forces[i])
        if after_sample is not None:
            after_sample(i)
    for _, measurement in events[k:]:  # arriving after the last IMU sample
        deliver(engine, measurement)


@dataclass
class RunResult:
    """The fused base_link solution against the truth at the evaluated stamps (navigating or
    degraded only): ENU position error and covariance, yaw error."""

    t: np.ndarray
    err_enu: np.ndarray
    cov_enu: np.ndarray
    yaw_err_deg: np.ndarray
    states: list[str]
    status: EngineStatus
    cpu_s: float

    @property
    def horizontal(self) -> np.ndarray:
        return np.hypot(self.err_enu[:, 0], self.err_enu[:, 1])

    def at(self, t_s: float) -> int:
        """Index of the last evaluated stamp at or before t_s."""
        return int(np.searchsorted(self.t, t_s + 1e-9) - 1)

    def mask(self, outages: Sequence[tuple[float, float]], inside: bool) -> np.ndarray:
        """Stamps inside (or outside) the outages."""
        within = np.zeros(len(self.t), dtype=bool)
        for start, duration in outages:
            within |= (self.t >= start) & (self.t < start + duration)
        return within if inside else ~within

    def nees(self, mask: np.ndarray) -> np.ndarray:
        """Position NEES (3 dof) at the masked stamps."""
        e, c = self.err_enu[mask], self.cov_enu[mask]
        return np.einsum("ni,ni->n", e, np.linalg.solve(c, e[..., None])[..., 0])

    def within_3_sigma(self, mask: np.ndarray) -> np.ndarray:
        """Fraction of the masked stamps with |error| <= 3σ, per ENU axis."""
        sigma = np.sqrt(np.diagonal(self.cov_enu[mask], axis1=1, axis2=2))
        return np.mean(np.abs(self.err_enu[mask]) <= 3.0 * sigma, axis=0)

    def outage_end_errors(self, outages: Sequence[tuple[float, float]]) -> list[float]:
        """Horizontal error at the end of each outage [m]."""
        return [float(self.horizontal[self.at(start + length)]) for start, length in outages]


def config(**overrides: Any) -> FusionConfig:
    """Default configuration with parameter overrides ('__' stands for '.')."""
    return FusionConfig.from_parameters({k.replace("__", "."): v for k, v in overrides.items()})


def run(
    drive: Drive,
    cfg: FusionConfig | None = None,
    calibration: ImuCalibration | None = None,
    evaluate_hz: float = 10.0,
) -> RunResult:
    """Run the engine over a drive; evaluate the solution at ``evaluate_hz``."""
    engine = InsEngine(cfg or FusionConfig.default(), calibration)
    base = drive.truth.base_link(drive.imu_t)
    step = max(1, round(1.0 / (evaluate_hz * float(np.median(np.diff(drive.imu_t))))))
    rows: list[tuple[float, np.ndarray, np.ndarray, float, str]] = []

    def evaluate(i: int) -> None:
        if i % step:
            return
        sol = engine.solution()
        if sol is None or sol.state == "aligning":
            return
        r_m, r_n = earth.radii_m(float(base.lat_rad[i]))
        lat, lon = math.radians(sol.lat_deg), math.radians(sol.lon_deg)
        err = np.array(
            [
                (lon - base.lon_rad[i]) * (r_n + base.height_m[i]) * math.cos(lat),
                (lat - base.lat_rad[i]) * (r_m + base.height_m[i]),
                sol.height_m - base.height_m[i],
            ]
        )
        yaw_est = euler_from_quat(quat_nb_from_enu_flu(sol.quat_enu_flu_xyzw))[2]
        yaw_err = (yaw_est - euler_from_quat(base.quat_nb[i])[2] + math.pi) % (2 * math.pi)
        rows.append((sol.t_s, err, sol.cov_pos_enu_m2, math.degrees(yaw_err - math.pi), sol.state))

    start = time.process_time()
    feed(engine, drive, after_sample=evaluate)
    cpu = time.process_time() - start
    return RunResult(
        np.array([r[0] for r in rows]),
        np.array([r[1] for r in rows]),
        np.array([r[2] for r in rows]),
        np.array([r[3] for r in rows]),
        [r[4] for r in rows],
        engine.status(),
        cpu,
    )
