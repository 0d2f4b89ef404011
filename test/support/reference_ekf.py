"""A reference loosely coupled INS/GNSS filter for the noise-mismatch harness (issue 10), written
independently of ins_fusion.core: numpy, scipy's rotations and pymap3d only.

What it is: a 15-state error-state EKF (position, velocity, attitude, gyro bias, accelerometer
bias) with GNSS position updates only (no velocity, no NHC, no ZUPT, no gating), told the exact
noise the simulator used and started at the true position, velocity and attitude. Its
horizontal RMS on a simulated drive is the bar the engine has to meet.

Frame: a local tangent plane fixed to the Earth at ``origin`` (x east, y north, z up), i.e.
flat-earth navigation over a few km: Earth rate and Coriolis are included, gravity is WGS-84
normal gravity (Somigliana, second-order free-air) along the ellipsoid normal, whose tilt
against the plane is followed to first order (x / R, 1.6e-4 rad per km; the neglected terms are
below 1e-5 m/s² within 5 km of the origin). Transport rate does not exist in an Earth-fixed
plane, so nothing else is neglected but the plane's second-order curvature.

Body frame: the IMU's axes (FLU), attitude C = body -> plane. Strapdown on steps of at most
``step_s`` (10 ms) from the exact integrals of the held samples (each sample holds over the
interval ending at its stamp, cut exactly at fix times), attitude by Rodrigues' formula,
velocity increment rotated with the mid-step attitude (second-order sculling).

Error state x = truth - estimate: δp, δv, φ (C_true = (I + [φ×]) C_est), δb_g, δb_a (body):
    δṗ = δv,  δv̇ = -[(C f)×] φ - 2 Ω × δv - C δb_a,  φ̇ = -Ω × φ - C δb_g,
    δḃ = -δb / τ + w  (first-order Gauss-Markov, q = 2 σ² / τ + random-walk density²).
Covariance steps of at most ``covariance_interval_s`` (0.1 s) with the mean specific force,
Φ = I + F T + (F T)² / 2, trapezoidal Q; Joseph-form updates; feedback after every update.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pymap3d

from gnss_ins_common.types import FloatArray

#: WGS-84: semi-major axis [m], flattening, Earth rate [rad/s], GM [m³/s²].
_A = 6378137.0
_F = 1.0 / 298.257223563
_E2 = _F * (2.0 - _F)
_OMEGA = 7.292115e-5
_GM = 3.986004418e14
#: Somigliana normal gravity: at the equator [m/s²] and the constant k.
_GAMMA_E = 9.7803253359
_K = 0.00193185265241
_M = _OMEGA**2 * _A**2 * (1.0 - _F) * _A / _GM


def normal_gravity(lat_rad: float, height_m: float) -> float:
    """WGS-84 normal gravity [m/s²] (Somigliana, free-air to second order in height)."""
    s2 = math.sin(lat_rad) ** 2
    g0 = _GAMMA_E * (1.0 + _K * s2) / math.sqrt(1.0 - _E2 * s2)
    h = height_m
    return g0 * (1.0 - 2.0 / _A * (1.0 + _F + _M - 2.0 * _F * s2) * h + 3.0 * h * h / _A**2)


def _skew(v: Sequence[float]) -> FloatArray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _rodrigues(v: FloatArray) -> FloatArray:
    """exp([v×]) for a rotation vector v [rad]."""
    angle = math.sqrt(float(v @ v))
    k = _skew(v)
    if angle < 1e-9:
        return np.eye(3) + k + 0.5 * k @ k
    return np.eye(3) + math.sin(angle) / angle * k + (1.0 - math.cos(angle)) / angle**2 * (k @ k)


@dataclass(frozen=True)
class ReferenceNoise:
    """The simulated noise, per body axis: white densities (gyro [rad/√s], accel [m/s/√s]),
    Gauss-Markov bias σ [rad/s, m/s²] and correlation times [s], bias random-walk densities
    [rad/s/√s, m/s²/√s] (added to the Gauss-Markov driving noise), and the initial bias
    estimate and its σ (the turn-on distribution)."""

    gyro_density: FloatArray
    accel_density: FloatArray
    gyro_bias_sigma: FloatArray
    gyro_bias_time_s: FloatArray
    accel_bias_sigma: FloatArray
    accel_bias_time_s: FloatArray
    gyro_random_walk: FloatArray
    accel_random_walk: FloatArray
    gyro_bias_initial: FloatArray
    gyro_bias_initial_sigma: FloatArray
    accel_bias_initial: FloatArray
    accel_bias_initial_sigma: FloatArray


@dataclass(frozen=True)
class ReferenceResult:
    """Estimates at the requested stamps: position of the output point in the plane [m] and
    its covariance [m²]."""

    t_s: FloatArray
    pos_m: FloatArray
    cov_m2: FloatArray


class ReferenceEkf:
    """The reference filter over one record (module docstring)."""

    def __init__(
        self,
        origin: tuple[float, float, float],
        noise: ReferenceNoise,
        antenna_arm_m: Sequence[float],
        step_s: float = 0.01,
        covariance_interval_s: float = 0.1,
    ) -> None:
        """origin: (lat [rad], lon [rad], height [m]) of the plane; antenna_arm_m: antenna
        minus IMU origin in the IMU's FLU axes [m]."""
        self.origin = origin
        self.noise = noise
        self.arm = np.asarray(antenna_arm_m, dtype=np.float64)
        self.step_s = step_s
        self.covariance_interval_s = covariance_interval_s
        lat0 = origin[0]
        self.omega = _OMEGA * np.array([0.0, math.cos(lat0), math.sin(lat0)])
        s2 = math.sin(lat0) ** 2
        self.r_north = _A * (1.0 - _E2) / (1.0 - _E2 * s2) ** 1.5 + origin[2]
        self.r_east = _A / math.sqrt(1.0 - _E2 * s2) + origin[2]

    def to_plane(
        self, lat_rad: FloatArray, lon_rad: FloatArray, height_m: FloatArray
    ) -> FloatArray:
        """WGS-84 positions -> plane coordinates (n, 3) [m]."""
        e, n, u = pymap3d.geodetic2enu(lat_rad, lon_rad, height_m, *self.origin, deg=False)
        return np.column_stack([np.atleast_1d(e), np.atleast_1d(n), np.atleast_1d(u)])

    def gravity(self, p: FloatArray) -> FloatArray:
        """Normal gravity at plane position p [m/s²], in the plane."""
        x, y, z = float(p[0]), float(p[1]), float(p[2])
        lat = self.origin[0] + y / self.r_north
        height = self.origin[2] + z + 0.5 * (x * x + y * y) / self.r_north
        up = np.array([x / self.r_east, y / self.r_north, 1.0])
        up /= math.sqrt(float(up @ up))
        return -normal_gravity(lat, height) * up

    def run(
        self,
        imu_t: FloatArray,
        rate: FloatArray,
        force: FloatArray,
        start: tuple[float, FloatArray, FloatArray, FloatArray],
        fixes: Sequence[tuple[float, FloatArray, FloatArray]],
        output_t: FloatArray,
        output_arm_m: Sequence[float],
    ) -> ReferenceResult:
        """Filter a record.

        imu_t (n,), rate, force (n, 3): IMU samples (FLU, rad/s, m/s²), each held over the
        interval ending at its stamp; start: (t [s], position [m], velocity [m/s] in the plane,
        C body -> plane) of the IMU origin, the truth; fixes: (t [s], antenna position in the
        plane [m], its covariance [m²]) in time order; output_t: stamps to report at (>= start);
        output_arm_m: output point minus IMU origin, FLU [m].
        """
        t0, p, v, C = start
        p, v, C = p.astype(float).copy(), v.astype(float).copy(), C.astype(float).copy()
        nz = self.noise
        bg, ba = nz.gyro_bias_initial.copy(), nz.accel_bias_initial.copy()
        P = np.diag(
            np.concatenate(
                [
                    np.full(3, 1e-6),
                    np.full(3, 1e-6),
                    np.full(3, 1e-10),
                    nz.gyro_bias_initial_sigma**2,
                    nz.accel_bias_initial_sigma**2,
                ]
            )
        )
        out_arm = np.asarray(output_arm_m, dtype=np.float64)
        # Exact integrals of the held samples, as knots for linear interpolation.
        dt = np.diff(imu_t, prepend=imu_t[0] - float(np.median(np.diff(imu_t))))
        knots = np.concatenate([[imu_t[0] - dt[0]], imu_t])
        theta = np.vstack([np.zeros(3), np.cumsum(rate * dt[:, None], axis=0)])
        dvel = np.vstack([np.zeros(3), np.cumsum(force * dt[:, None], axis=0)])
        fix_t = np.array([f[0] for f in fixes if f[0] > t0 and f[0] <= imu_t[-1]])
        fix_by_t = {f[0]: f for f in fixes}
        end = float(min(imu_t[-1], max(output_t[-1], fix_t[-1] if len(fix_t) else t0)))
        grid = np.arange(t0, end, self.step_s)
        cov_grid = np.arange(t0, end, self.covariance_interval_s)
        times = np.unique(np.concatenate([grid, cov_grid, fix_t, output_t, [end]]))
        times = times[(times >= t0) & (times <= end)]
        d_theta = np.diff(
            np.column_stack([np.interp(times, knots, theta[:, i]) for i in range(3)]), axis=0
        )
        d_vel = np.diff(
            np.column_stack([np.interp(times, knots, dvel[:, i]) for i in range(3)]), axis=0
        )
        is_fix = np.isin(times, fix_t)
        is_out = np.isin(times, output_t)
        is_cov = np.isin(times, cov_grid)

        q_bias = np.concatenate(
            [
                2.0 * nz.gyro_bias_sigma**2 / nz.gyro_bias_time_s + nz.gyro_random_walk**2,
                2.0 * nz.accel_bias_sigma**2 / nz.accel_bias_time_s + nz.accel_random_walk**2,
            ]
        )
        decay = np.concatenate([1.0 / nz.gyro_bias_time_s, 1.0 / nz.accel_bias_time_s])
        omega_skew = _skew(self.omega)
        eye15 = np.eye(15)
        out_pos: list[FloatArray] = []
        out_cov: list[FloatArray] = []
        out_t: list[float] = []
        cov_dt, cov_dv = 0.0, np.zeros(3)

        def propagate_covariance() -> None:
            nonlocal P, cov_dt, cov_dv
            if cov_dt <= 0.0:
                return
            f_n = cov_dv / cov_dt
            F = np.zeros((15, 15))
            F[0:3, 3:6] = np.eye(3)
            F[3:6, 3:6] = -2.0 * omega_skew
            F[3:6, 6:9] = -_skew(f_n)
            F[3:6, 12:15] = -C
            F[6:9, 6:9] = -omega_skew
            F[6:9, 9:12] = -C
            F[9:15, 9:15] = -np.diag(decay)
            FT = F * cov_dt
            Phi = eye15 + FT + 0.5 * FT @ FT
            Q = np.zeros((15, 15))
            Q[3:6, 3:6] = (C * nz.accel_density**2) @ C.T
            Q[6:9, 6:9] = (C * nz.gyro_density**2) @ C.T
            Q[9:15, 9:15] = np.diag(q_bias)
            P = Phi @ P @ Phi.T + 0.5 * (Phi @ Q @ Phi.T + Q) * cov_dt
            P = 0.5 * (P + P.T)
            cov_dt, cov_dv = 0.0, np.zeros(3)

        for k in range(len(times)):
            if k:
                h = times[k] - times[k - 1]
                dth = d_theta[k - 1] - bg * h
                dv_b = d_vel[k - 1] - ba * h
                dv_n = C @ _rodrigues(0.5 * dth) @ dv_b
                v_new = v + dv_n + (self.gravity(p) - 2.0 * np.cross(self.omega, v)) * h
                p = p + 0.5 * (v + v_new) * h
                v = v_new
                C = (np.eye(3) - omega_skew * h) @ C @ _rodrigues(dth)
                cov_dt += h
                cov_dv += dv_n
            t = times[k]
            if is_cov[k] or is_fix[k] or is_out[k]:
                propagate_covariance()
            if is_fix[k]:
                _, z, R = fix_by_t[t]
                arm_n = C @ self.arm
                H = np.zeros((3, 15))
                H[:, 0:3] = np.eye(3)
                H[:, 6:9] = -_skew(arm_n)
                y = z - (p + arm_n)
                S = H @ P @ H.T + R
                K = np.linalg.solve(S, H @ P).T
                dx = K @ y
                I_KH = eye15 - K @ H
                P = I_KH @ P @ I_KH.T + K @ R @ K.T
                p = p + dx[0:3]
                v = v + dx[3:6]
                C = _rodrigues(dx[6:9]) @ C
                bg = bg + dx[9:12]
                ba = ba + dx[12:15]
            if is_out[k]:
                arm_n = C @ out_arm
                J = np.zeros((3, 15))
                J[:, 0:3] = np.eye(3)
                J[:, 6:9] = -_skew(arm_n)
                out_t.append(float(t))
                out_pos.append(p + arm_n)
                out_cov.append(J @ P @ J.T)
        return ReferenceResult(np.array(out_t), np.array(out_pos), np.array(out_cov))
