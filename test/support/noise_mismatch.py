"""The engine given a user's noise parameters on the simulated drives of mismatch_drives.py,
and the reference filter on the same drives: the harness of test/core/engine/test_noise_mismatch.py
and of the benches bench/bench_noise_mismatch.py and bench/bench_self_calibration.py.

The filter's parameters are what a user has (``datasheet_parameters``: the IMU profile's own
white-noise densities and bias instabilities in the parameter units, everything else default;
no calibration file), or, in the explicitly "exact" runs (``exact_parameters``), the densities
root-sum-squared with the vibration's low-frequency-equivalent density. The reference filter
(test/support/reference_ekf.py) gets the exact simulated noise and the true initial state.

Errors are of base_link, estimate minus truth, in the tangent plane at base_link's start
(pymap3d), evaluated at 10 Hz stamps from ``EVALUATE_FROM_S`` on.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
import pymap3d
from scipy.spatial.transform import Rotation

from ins_fusion.core.engine.engine import (
    EngineStatus,
    GnssFixMeasurement,
    GnssVelocityMeasurement,
    InsEngine,
)
from ins_fusion.core.nav.units import STANDARD_GRAVITY_M_S2, to_deg_h, to_deg_sqrt_h, to_m_s_sqrt_h
from ins_fusion.core.settings.config import FusionConfig
from ins_fusion.sim.imu_model import ImuProfile
from ins_fusion.sim.scenarios import SURVEY_CAR
from ins_fusion.sim.vehicle import VehicleTruth
from support.mismatch_drives import Streams
from support.reference_ekf import ReferenceEkf, ReferenceNoise

Array = np.ndarray
#: Errors count from here on (20 s into the drive, after the engine's course alignment).
EVALUATE_FROM_S = 30.0
EVALUATE_HZ = 10.0


# ------------------------------------------------------------------------ parameters


#: The gyro scale-factor accuracy [ppm] and misalignment [mrad] a user gives (scale-factor states
#: of that σ, misalignment turn noise): the STIM300's datasheet (Oslo notes §5; the simulated
#: errors are per-power-up draws of this size). The IMU400CC keeps the engine's defaults (no
#: scale states, no misalignment): its measured scale factors differ by the sign of the rate
#: (Aalborg notes §3.3: y +0.83 % / -0.82 %), which symmetric scale-factor states cannot
#: represent; given its datasheet's 1 % as states, the self-calibration bench's outage drifts
#: grew from 0.41 to 0.55 m RMS (docs/accuracy.md).
DATASHEET_GYRO_AXIS_ERRORS = {"stim300": (500.0, 1.0), "imu400cc": (0.0, 0.0)}


def datasheet_parameters(profile: ImuProfile) -> dict[str, Any]:
    """What a user types from the datasheet: the profile's white-noise densities and bias
    instabilities and the gyro's scale-factor accuracy and misalignment in the parameter
    units, everything else default."""
    mg = 1e-3 * STANDARD_GRAVITY_M_S2
    scale_ppm, misalignment_mrad = DATASHEET_GYRO_AXIS_ERRORS[profile.name]
    return {
        "imu_noise.gyro_arw": [to_deg_sqrt_h(x) for x in profile.gyro.noise_density],
        "imu_noise.accel_vrw": [to_m_s_sqrt_h(x) for x in profile.accel.noise_density],
        "imu_noise.gyro_bias_instability": [to_deg_h(x) for x in profile.gyro.bias_instability],
        "imu_noise.accel_bias_instability": [x / mg for x in profile.accel.bias_instability],
        "imu_noise.gyro_scale_sigma": scale_ppm,
        "imu_noise.gyro_misalignment": misalignment_mrad,
    }


def exact_parameters(profile: ImuProfile, density: tuple[Array, Array]) -> dict[str, Any]:
    """The datasheet parameters with the vibration's equivalent density root-sum-squared into
    the white-noise densities (the simulator's truth: only for the "exact" runs)."""
    params = datasheet_parameters(profile)
    gyro = np.hypot(np.array(profile.gyro.noise_density), density[0])
    accel = np.hypot(np.array(profile.accel.noise_density), density[1])
    params["imu_noise.gyro_arw"] = [to_deg_sqrt_h(float(x)) for x in gyro]
    params["imu_noise.accel_vrw"] = [to_m_s_sqrt_h(float(x)) for x in accel]
    return params


# ------------------------------------------------------------------------------ runs


@dataclass
class Track:
    """A filter's base_link solution against the truth at the evaluated stamps: ENU position
    error [m] and covariance [m²]; roll/pitch/yaw error [rad] and σ from the filter's attitude
    covariance (NaN for the reference); status, fixes delivered and the stamps [s] by which a
    GNSS position gate recovery had happened (engine only, seen at the 10 Hz stamps)."""

    t: Array
    err_enu: Array
    cov_enu: Array
    att_err: Array
    att_sigma: Array
    status: EngineStatus | None
    fixes: int
    cpu_s: float
    recovery_t: tuple[float, ...] = ()

    def window(self, start_s: float = EVALUATE_FROM_S, end_s: float = math.inf) -> Array:
        return (self.t >= start_s) & (self.t < end_s)

    def nees(self, mask: Array) -> float:
        e, c = self.err_enu[mask], self.cov_enu[mask]
        return float(np.mean(np.einsum("ni,ni->n", e, np.linalg.solve(c, e[..., None])[..., 0])))

    def within_3_sigma(self, mask: Array) -> float:
        """Fraction of the stamps with every E, N, U component inside its own 3σ."""
        sigma = np.sqrt(np.diagonal(self.cov_enu[mask], axis1=1, axis2=2))
        return float(np.mean(np.all(np.abs(self.err_enu[mask]) <= 3.0 * sigma, axis=1)))

    def attitude_within_3_sigma(self, mask: Array) -> Array:
        """Fraction of the stamps with the roll, pitch, yaw error inside 3σ, per angle."""
        return np.mean(np.abs(self.att_err[mask]) <= 3.0 * self.att_sigma[mask], axis=0)

    def horizontal(self) -> Array:
        return np.hypot(self.err_enu[:, 0], self.err_enu[:, 1])

    def horizontal_rms(self, mask: Array) -> float:
        return float(np.sqrt(np.mean(self.horizontal()[mask] ** 2)))

    def horizontal_at(self, t_s: float) -> float:
        """Horizontal error at the last stamp at or before t_s [m]."""
        return float(self.horizontal()[int(np.searchsorted(self.t, t_s + 1e-9)) - 1])

    def gated_fraction(self) -> float:
        assert self.status is not None
        return self.status.measurements["gnss_position"]["gated"] / max(self.fixes, 1)


def _plane_origin(truth: VehicleTruth) -> tuple[float, float, float]:
    base = truth.base_link(np.array([0.0]))
    return float(base.lat_rad[0]), float(base.lon_rad[0]), float(base.height_m[0])


def _to_plane(origin: tuple[float, float, float], lat: Array, lon: Array, h: Array) -> Array:
    e, n, u = pymap3d.geodetic2enu(lat, lon, h, *origin, deg=False)
    return np.column_stack([e, n, u])


_ENU_FROM_NED = Rotation.from_matrix([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
_FLU_FROM_FRD = Rotation.from_matrix(np.diag([1.0, -1.0, -1.0]))


def _rpy(enu_flu: Rotation) -> Array:
    """NED roll, pitch, yaw of base_link (FRD) from its FLU -> ENU rotation, (n, 3)."""
    nb = _ENU_FROM_NED.inv() * enu_flu * _FLU_FROM_FRD
    return nb.as_euler("ZYX")[:, ::-1]


def _attitude_errors(est_xyzw: Array, true_xyzw: Array, cov_att_enu: Array) -> tuple[Array, Array]:
    """Roll/pitch/yaw error (wrapped) and its σ from the ENU attitude covariance, mapped to the
    Euler angles by a numerical Jacobian (small rotations about E, N, U)."""
    est = Rotation.from_quat(est_xyzw)
    rpy_est = _rpy(est)
    err = rpy_est - _rpy(Rotation.from_quat(true_xyzw))
    err = (err + math.pi) % (2.0 * math.pi) - math.pi
    h = 1e-6
    jac = np.empty((len(est_xyzw), 3, 3))
    for i in range(3):
        d = _rpy(Rotation.from_rotvec(np.eye(3)[i] * h) * est) - rpy_est
        jac[:, :, i] = ((d + math.pi) % (2.0 * math.pi) - math.pi) / h
    cov = np.einsum("nij,njk,nlk->nil", jac, cov_att_enu, jac)
    return err, np.sqrt(np.diagonal(cov, axis1=1, axis2=2))


def run_engine(streams: Streams, parameters: dict[str, Any]) -> Track:
    """The engine over the streams with a parameter dict (FusionConfig.from_parameters),
    IMU samples and measurements in arrival order, solution read at 10 Hz."""
    engine = InsEngine(FusionConfig.from_parameters(parameters))
    events: list[tuple[float, int, GnssFixMeasurement | GnssVelocityMeasurement]] = []
    for f in streams.fixes:
        fix = GnssFixMeasurement(
            f.t_s, math.degrees(f.lat_rad), math.degrees(f.lon_rad), f.height_m, f.cov_enu_m2
        )
        events.append((f.arrival_t_s, 0, fix))
    for v in streams.velocities:
        events.append((v.arrival_t_s, 1, GnssVelocityMeasurement(v.t_s, v.vel_enu_m_s, v.cov_enu)))
    events.sort(key=lambda e: (e[0], e[1]))
    step = max(1, round(streams.profile.rate_hz / EVALUATE_HZ))
    rows: list[tuple[int, Any]] = []
    recoveries: list[float] = []
    rates, forces = streams.rate.tolist(), streams.force.tolist()
    k = 0
    start = time.process_time()
    for i, t in enumerate(streams.imu_t.tolist()):
        while k < len(events) and events[k][0] <= t:
            m = events[k][2]
            if isinstance(m, GnssFixMeasurement):
                engine.add_gnss_fix(m)
            else:
                engine.add_gnss_velocity(m)
            k += 1
        engine.add_imu(t, rates[i], forces[i])
        if i % step == 0:
            sol = engine.solution()
            if sol is not None and sol.state != "aligning":
                rows.append((i, sol))
            count = engine.status().measurements["gnss_position"]["recoveries"]
            recoveries += [t] * (count - len(recoveries))
    cpu = time.process_time() - start
    index = np.array([i for i, _ in rows])
    sols = [s for _, s in rows]
    origin = _plane_origin(streams.truth)
    base = streams.truth.base_link(streams.imu_t[index])
    est = _to_plane(
        origin,
        np.radians([s.lat_deg for s in sols]),
        np.radians([s.lon_deg for s in sols]),
        np.array([s.height_m for s in sols]),
    )
    true = _to_plane(origin, base.lat_rad, base.lon_rad, base.height_m)
    att_err, att_sigma = _attitude_errors(
        np.array([s.quat_enu_flu_xyzw for s in sols]),
        base.quat_enu_flu,
        np.array([s.cov_att_enu_rad2 for s in sols]),
    )
    return Track(
        streams.imu_t[index],
        est - true,
        np.array([s.cov_pos_enu_m2 for s in sols]),
        att_err,
        att_sigma,
        engine.status(),
        len(streams.fixes),
        cpu,
        tuple(recoveries),
    )


def reference_noise(streams: Streams) -> ReferenceNoise:
    """The simulated noise as the reference filter takes it: white densities ⊕ the vibration's
    equivalent density, Gauss-Markov biases, random walks, and the turn-on distribution (fixed
    bias plus the g-dependent gyro bias at rest as the mean; σ of the per-power-up draw ⊕ the
    Gauss-Markov stationary σ)."""
    p = streams.profile
    g, a = p.gyro, p.accel
    rest_g = np.array(p.gyro_g_sensitivity) @ np.array([0.0, 0.0, STANDARD_GRAVITY_M_S2])
    return ReferenceNoise(
        gyro_density=np.hypot(np.array(g.noise_density), streams.vibration_density[0]),
        accel_density=np.hypot(np.array(a.noise_density), streams.vibration_density[1]),
        gyro_bias_sigma=np.array(g.bias_instability),
        gyro_bias_time_s=np.array(g.bias_correlation_time_s),
        accel_bias_sigma=np.array(a.bias_instability),
        accel_bias_time_s=np.array(a.bias_correlation_time_s),
        gyro_random_walk=np.array(g.random_walk),
        accel_random_walk=np.array(a.random_walk),
        gyro_bias_initial=np.array(g.bias) + rest_g,
        gyro_bias_initial_sigma=np.hypot(np.array(g.bias_sigma), np.array(g.bias_instability)),
        accel_bias_initial=np.array(a.bias),
        accel_bias_initial_sigma=np.hypot(np.array(a.bias_sigma), np.array(a.bias_instability)),
    )


def run_reference(streams: Streams, output_t: Array | None = None) -> Track:
    """The reference filter (test/support/reference_ekf.py) on the same streams, started at the true
    state of the IMU at the first sample; base_link position at ``output_t`` (default: every
    10 Hz stamp of the IMU grid)."""
    truth = streams.truth
    mounting = SURVEY_CAR.imu
    if any(mounting.rpy_rad):
        raise ValueError("the reference filter assumes imu_link axes = base_link axes")
    imu_arm = np.array(mounting.lever_arm_flu_m)
    antenna_arm = np.array(SURVEY_CAR.gnss_antenna_flu_m) - imu_arm
    origin = _plane_origin(truth)
    ekf = ReferenceEkf(origin, reference_noise(streams), antenna_arm)
    t0 = float(streams.imu_t[0])
    start = truth.imu(np.array([t0]))
    vel_ned = start.vel_ned_m_s[0]
    state = (
        t0,
        _to_plane(origin, start.lat_rad, start.lon_rad, start.height_m)[0],
        np.array([vel_ned[1], vel_ned[0], -vel_ned[2]]),
        Rotation.from_quat(start.quat_enu_flu[0]).as_matrix(),
    )
    lat = np.array([f.lat_rad for f in streams.fixes])
    lon = np.array([f.lon_rad for f in streams.fixes])
    hgt = np.array([f.height_m for f in streams.fixes])
    plane = _to_plane(origin, lat, lon, hgt)
    fixes = [(f.t_s, plane[k], f.cov_enu_m2) for k, f in enumerate(streams.fixes)]
    if output_t is None:
        step = max(1, round(streams.profile.rate_hz / EVALUATE_HZ))
        output_t = streams.imu_t[::step]
    begin = time.process_time()
    result = ekf.run(streams.imu_t, streams.rate, streams.force, state, fixes, output_t, -imu_arm)
    cpu = time.process_time() - begin
    base = truth.base_link(result.t_s)
    true = _to_plane(origin, base.lat_rad, base.lon_rad, base.height_m)
    nan = np.full((len(result.t_s), 3), math.nan)
    return Track(result.t_s, result.pos_m - true, result.cov_m2, nan, nan, None, len(fixes), cpu)
