"""The simulated drives of the noise-mismatch harness (noise_mismatch.py): a user's noise
parameters against drives whose noise differs from them.

Streams straight from the ins_fusion.sim API: the trajectory truth of a scenario on the survey
car, the IMU samples of a profile (``stim300`` tactical, ``imu400cc`` MEMS) with optional
engine/road vibration (sim.vibration) added to the true signal before the sensor's errors, and
GNSS from either

- ``rtk``: the Leica RTK receiver model (leica_rtk: 1 Hz, 0.053 s latency, 2/3 cm white plus
  Gauss-Markov error, no vertical velocity, 0.5 % outliers of 0.3 m, RTK float for 30 s after an
  outage), or
- ``white5``: a receiver made here: the true antenna position plus independent N(0, 5 m) per
  ENU axis and epoch at 5 Hz, reported covariance diag(25, 25, 25) m²; the true antenna
  velocity plus N(0, 0.1 m/s) per axis, covariance 0.01 m²/s² (no latency).

Used by test/core/engine/test_noise_mismatch.py and the benches bench/bench_noise_mismatch.py and
bench/bench_self_calibration.py.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
import pymap3d

from ins_fusion.sim.gnss_model import PROFILES as GNSS_PROFILES
from ins_fusion.sim.gnss_model import GnssErrorModel, GnssSchedule
from ins_fusion.sim.imu_model import PROFILES as IMU_PROFILES
from ins_fusion.sim.imu_model import ImuErrorModel, ImuProfile
from ins_fusion.sim.scenarios import SCENARIOS, SURVEY_CAR
from ins_fusion.sim.vehicle import TruthCache, VehicleTruth
from ins_fusion.sim.vibration import (
    PROFILES as VIBRATION_PROFILES,
)
from ins_fusion.sim.vibration import (
    Vibration,
    VibrationProfile,
    equivalent_density,
    speed_factor,
)

Array = np.ndarray
#: Scenario and length of the drives: 10 s standstill, 10 s to 10 m/s, then figure-eights of
#: 40 m radius (turning all the time) and a stop.
SCENARIO = "figure_eight"
DURATION_S = 200.0
#: The white receiver: σ per ENU axis [m], rate [Hz], velocity σ per axis [m/s].
WHITE_SIGMA_M = 5.0
WHITE_RATE_HZ = 5.0
WHITE_VELOCITY_SIGMA_M_S = 0.1
#: Vertical velocity variance of receivers without one (the gnss/vel contract: >= 1e4).
UNKNOWN_VERTICAL_VARIANCE = 1.0e6
GNSS_KINDS = ("rtk", "white5")


@dataclass(frozen=True)
class PositionFix:
    """One gnss/fix: validity and arrival time [s], antenna position (WGS-84 [rad], [m]),
    reported ENU covariance [m²]."""

    t_s: float
    arrival_t_s: float
    lat_rad: float
    lon_rad: float
    height_m: float
    cov_enu_m2: Array


@dataclass(frozen=True)
class VelocityFix:
    """One gnss/vel: validity and arrival time [s], ENU velocity [m/s] and covariance."""

    t_s: float
    arrival_t_s: float
    vel_enu_m_s: Array
    cov_enu: Array


@dataclass
class Streams:
    """A simulated drive: truth, IMU samples (imu_link FLU) and GNSS measurements.

    vibration_density: the vibration's low-frequency-equivalent density per imu axis (gyro
    [rad/√s], accel [m/s/√s]), RMS over the drive's speeds (sim.vibration.equivalent_density).
    """

    truth: VehicleTruth
    profile: ImuProfile
    vibration: VibrationProfile
    vibration_density: tuple[Array, Array]
    gnss: str
    outages: tuple[tuple[float, float], ...]
    imu_t: Array
    rate: Array
    force: Array
    fixes: list[PositionFix]
    velocities: list[VelocityFix]


def _in_outage(t_s: float, outages: Sequence[tuple[float, float]]) -> bool:
    return any(start <= t_s < start + length for start, length in outages)


def drive_truth(
    duration_s: float = DURATION_S,
    scenario: str = SCENARIO,
    imu_mounting_deg: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> VehicleTruth:
    """The survey car on a scenario, its IMU turned by ``imu_mounting_deg`` (REP-103 roll,
    pitch, yaw of imu_link in base_link; the filter is told nothing of it)."""
    rpy = tuple(math.radians(a) for a in imu_mounting_deg)
    setup = replace(SURVEY_CAR, imu=replace(SURVEY_CAR.imu, rpy_rad=rpy))
    return VehicleTruth(SCENARIOS[scenario](duration_s), setup)


def speed_factor_rms(
    truth: VehicleTruth, vib: VibrationProfile, rate_hz: float, duration_s: float
) -> float:
    """RMS over the drive of the vibration's speed factor (σ relative to the reference)."""
    t = np.arange(0.0, duration_s, 1.0 / rate_hz)
    speed = np.linalg.norm(truth.imu(t).vel_ned_m_s, axis=1)
    return float(np.sqrt(np.mean(speed_factor(vib, speed) ** 2)))


def vibration_density(
    vib: VibrationProfile, rate_hz: float, factor_rms: float
) -> tuple[Array, Array]:
    """Equivalent density (gyro, accel) per axis, RMS over the drive's speeds."""
    gyro, accel = equivalent_density(vib, vib.reference_speed_m_s, rate_hz)
    return gyro * factor_rms, accel * factor_rms


def scaled_vibration(
    base: VibrationProfile,
    profile: ImuProfile,
    ratio: float,
    truth: VehicleTruth,
    duration_s: float,
) -> VibrationProfile:
    """``base`` with its σ scaled per axis so that its equivalent density (RMS over the drive)
    is ``ratio`` times the profile's white-noise density (a bench-only profile)."""
    factor = speed_factor_rms(truth, base, profile.rate_hz, duration_s)
    gyro, accel = vibration_density(base, profile.rate_hz, factor)
    gyro_scale = ratio * np.array(profile.gyro.noise_density) / gyro
    accel_scale = ratio * np.array(profile.accel.noise_density) / accel
    return replace(
        base,
        name=f"{base.name} x{ratio:g} datasheet",
        gyro_sigma_rad_s=tuple(float(x) for x in np.array(base.gyro_sigma_rad_s) * gyro_scale),
        accel_sigma_m_s2=tuple(float(x) for x in np.array(base.accel_sigma_m_s2) * accel_scale),
    )


def build_streams(
    imu: str | ImuProfile = "imu400cc",
    gnss: str = "rtk",
    vibration: str | VibrationProfile = "none",
    seed: int = 1,
    duration_s: float = DURATION_S,
    outages: Sequence[tuple[float, float]] = (),
    scenario: str = SCENARIO,
    imu_rate_hz: float | None = None,
    imu_mounting_deg: tuple[float, float, float] = (0.0, 0.0, 0.0),
    imu_late_s: float = 0.0,
) -> Streams:
    """A seeded drive (IMU errors, vibration, GNSS noise each from their own seed); ``imu`` a
    profile name or a profile; the IMU turned by ``imu_mounting_deg`` (drive_truth) and
    stamped ``imu_late_s`` [s] later than the GNSS (the GNSS epochs are stamped that much
    early: the same offset, with the truth on the IMU's time base)."""
    truth = drive_truth(duration_s, scenario, imu_mounting_deg)
    profile = IMU_PROFILES[imu] if isinstance(imu, str) else imu
    if imu_rate_hz is not None:
        profile = replace(profile, rate_hz=imu_rate_hz)
    vib = VIBRATION_PROFILES[vibration] if isinstance(vibration, str) else vibration
    t = np.arange(0.0, duration_s, 1.0 / profile.rate_hz)
    true_imu = truth.imu(t)
    speed = np.linalg.norm(true_imu.vel_ned_m_s, axis=1)
    vib_rate, vib_force = Vibration(vib, profile.rate_hz, seed + 7919).sample(t, speed)
    rate, force = ImuErrorModel(profile, seed).apply(
        t, true_imu.rate_flu_rad_s + vib_rate, true_imu.specific_force_flu_m_s2 + vib_force
    )
    factor = float(np.sqrt(np.mean(speed_factor(vib, speed) ** 2)))
    density = vibration_density(vib, profile.rate_hz, factor)
    outages = tuple(outages)
    fixes: list[PositionFix] = []
    velocities: list[VelocityFix] = []
    if gnss == "rtk":
        model = GnssErrorModel(
            TruthCache(truth.gnss_truths, truth.gnss_truth),
            GNSS_PROFILES["leica_rtk"],
            GnssSchedule(outages),
            seed=seed,
        )
        for fix in model.fixes(0.0, duration_s):
            fixes.append(
                PositionFix(
                    fix.t_s - imu_late_s,
                    fix.arrival_t_s,
                    fix.lat_rad,
                    fix.lon_rad,
                    fix.height_m,
                    np.diag(np.square(fix.position_sigma_enu_m)),
                )
            )
            vel = fix.vel_enu_m_s.copy()
            var = np.square(fix.velocity_sigma_enu_m_s)
            if not math.isfinite(vel[2]):
                vel[2], var[2] = 0.0, UNKNOWN_VERTICAL_VARIANCE
            velocities.append(VelocityFix(fix.t_s - imu_late_s, fix.arrival_t_s, vel, np.diag(var)))
    elif gnss == "white5":
        epochs = np.arange(0.0, duration_s, 1.0 / WHITE_RATE_HZ)
        epochs = np.array([e for e in epochs if not _in_outage(float(e), outages)])
        antenna = truth.antenna(epochs)
        rng = np.random.default_rng([seed, 5])
        noise = rng.standard_normal((len(epochs), 3)) * WHITE_SIGMA_M
        vel_noise = rng.standard_normal((len(epochs), 3)) * WHITE_VELOCITY_SIGMA_M_S
        lat, lon, height = pymap3d.enu2geodetic(
            noise[:, 0],
            noise[:, 1],
            noise[:, 2],
            antenna.lat_rad,
            antenna.lon_rad,
            antenna.height_m,
            deg=False,
        )
        pos_cov = np.eye(3) * WHITE_SIGMA_M**2
        vel_cov = np.eye(3) * WHITE_VELOCITY_SIGMA_M_S**2
        vel_enu = antenna.vel_enu_m_s + vel_noise
        for k, t_k in enumerate(epochs.tolist()):
            stamp = t_k - imu_late_s
            fixes.append(
                PositionFix(
                    stamp, t_k, float(lat[k]), float(lon[k]), float(height[k]), pos_cov.copy()
                )
            )
            velocities.append(VelocityFix(stamp, t_k, vel_enu[k].copy(), vel_cov.copy()))
    else:
        raise ValueError(f"unknown GNSS kind {gnss!r} (known: {', '.join(GNSS_KINDS)})")
    return Streams(truth, profile, vib, density, gnss, outages, t, rate, force, fixes, velocities)
