"""Time update of the engine: one IMU increment through the strapdown (with the filter's sensor
error estimates and the mounting), the error covariance every ``covariance_interval``, the
prediction of the nominal state to a measurement's stamp, and the increment that bridges
missing samples.

Frames: imu FRD increments, base_link FRD body, NED navigation (core.strapdown, core.eskf).
"""

from __future__ import annotations

import math

import numpy as np

from gnss_ins_common.types import FloatArray, Vec3
from ins_fusion.core import earth
from ins_fusion.core.adaptation import ImuNoiseMonitor
from ins_fusion.core.config import FusionConfig
from ins_fusion.core.eskf import ATT, VEL, ErrorStateFilter
from ins_fusion.core.measurements import Prediction
from ins_fusion.core.rotation import skew
from ins_fusion.core.state import FilterState, Geometry, decouple_yaw
from ins_fusion.core.strapdown import ImuIncrement, propagate
from ins_fusion.core.timeline import Gap

#: Time constant of the smoothed acceleration and rate of the time-offset model [s].
_ACCEL_SMOOTHING_S = 0.1


class ImuDensities:
    """IMU white-noise densities (gyro, accelerometer) [rad²/s, m²/s³] per imu axis: the user's
    (``floor``) or the measured ones (core.adaptation.ImuNoiseMonitor) where above them."""

    def __init__(self, gyro_psd: FloatArray, accel_psd: FloatArray) -> None:
        self.floor = (gyro_psd, accel_psd)
        self.monitor = ImuNoiseMonitor()
        self._measured: tuple[FloatArray, FloatArray] | None = None
        self._effective = self.floor

    def current(self) -> tuple[FloatArray, FloatArray] | None:
        """The densities in force; None before a measurement (then the floor applies)."""
        measured = self.monitor.psd
        if measured is None:
            return None
        if measured is not self._measured:
            self._measured = measured
            self._effective = (
                np.maximum(self.floor[0], measured[0]),
                np.maximum(self.floor[1], measured[1]),
            )
        return self._effective


def bridge(
    dt: float, last_sample: tuple[Vec3, Vec3], rate_i: Vec3, force_i: Vec3
) -> tuple[ImuIncrement, Gap]:
    """Trapezoidal increment over a gap of ``dt`` [s] from the last sample (rate, force; imu
    FRD) to this one, and its uncertainty. The trapezoid is exact for a rate and force that
    change linearly; for a change at an unknown instant inside the gap (a turn starting) it
    errs by Δ·dt·(1/2 - τ/dt), of RMS Δ·dt/√12, with Δ the change from the last sample to
    this one."""
    rate0, force0 = last_sample
    h = 0.5 * dt
    inc = ImuIncrement(
        dt,
        (h * (rate0[0] + rate_i[0]), h * (rate0[1] + rate_i[1]), h * (rate0[2] + rate_i[2])),
        (
            h * (force0[0] + force_i[0]),
            h * (force0[1] + force_i[1]),
            h * (force0[2] + force_i[2]),
        ),
    )
    k = dt * dt / 12.0
    gap = Gap(
        tuple(k * (a - b) ** 2 for a, b in zip(rate_i, rate0, strict=True)),
        tuple(k * (a - b) ** 2 for a, b in zip(force_i, force0, strict=True)),
    )
    return inc, gap


class Propagator:
    """Strapdown and covariance propagation of the nominal state (see the module docstring)."""

    def __init__(self, config: FusionConfig, geometry: Geometry, densities: ImuDensities) -> None:
        self._covariance_interval_s = config.covariance_interval_s
        self._gnss_correlation_time_s = config.gnss_correlation_time_s
        self._geometry = geometry
        self._densities = densities

    def step(
        self,
        s: FilterState,
        kf: ErrorStateFilter,
        inc: ImuIncrement,
        gap: Gap | None,
        t: float,
        noise: tuple[FloatArray, FloatArray] | None,
    ) -> None:
        """Correct an increment with the filter's sensor errors and mechanize (``gap``: it
        bridges missing samples; ``noise``: the IMU white-noise densities from now on, None =
        the user's); the covariance follows every ``covariance_interval`` seconds."""
        s.imu_psd = noise
        dt = inc.dt_s
        bg, ba, sg, sa = s.gyro_bias, s.accel_bias, s.gyro_scale, s.accel_scale
        th, dv = inc.dtheta_rad, inc.dvel_m_s
        ti0 = (th[0] - bg[0] * dt) / (1.0 + sg[0])
        ti1 = (th[1] - bg[1] * dt) / (1.0 + sg[1])
        ti2 = (th[2] - bg[2] * dt) / (1.0 + sg[2])
        vi0 = (dv[0] - ba[0] * dt) / (1.0 + sa[0])
        vi1 = (dv[1] - ba[1] * dt) / (1.0 + sa[1])
        vi2 = (dv[2] - ba[2] * dt) / (1.0 + sa[2])
        r0, r1, r2, r3, r4, r5, r6, r7, r8 = self._geometry.r_bi
        tb = (
            r0 * ti0 + r1 * ti1 + r2 * ti2,
            r3 * ti0 + r4 * ti1 + r5 * ti2,
            r6 * ti0 + r7 * ti1 + r8 * ti2,
        )
        vb = (
            r0 * vi0 + r1 * vi1 + r2 * vi2,
            r3 * vi0 + r4 * vi1 + r5 * vi2,
            r6 * vi0 + r7 * vi1 + r8 * vi2,
        )
        inc_b = ImuIncrement(dt, tb, vb)
        v0n, v0e, v0d = s.nav.vel_ned_m_s.tolist()
        nav = propagate(s.nav, inc_b, s.prev_inc if gap is None else None)
        s.set_nav(nav)
        inv_dt = 1.0 / dt
        v1n, v1e, v1d = nav.vel_ned_m_s.tolist()
        an = ((v1n - v0n) * inv_dt, (v1e - v0e) * inv_dt, (v1d - v0d) * inv_dt)
        s.accel_n = an
        rb = s.rate_b = (tb[0] * inv_dt, tb[1] * inv_dt, tb[2] * inv_dt)
        # Acceleration and rate low-passed over ~0.1 s (vibration out) for the time-offset
        # model: their noise would otherwise make H noisy and the estimate wander.
        k, lp, rl = min(1.0, dt / _ACCEL_SMOOTHING_S), s.accel_lp, s.rate_lp
        s.accel_lp = (
            lp[0] + k * (an[0] - lp[0]),
            lp[1] + k * (an[1] - lp[1]),
            lp[2] + k * (an[2] - lp[2]),
        )
        s.rate_lp = (
            rl[0] + k * (rb[0] - rl[0]),
            rl[1] + k * (rb[1] - rl[1]),
            rl[2] + k * (rb[2] - rl[2]),
        )
        s.rate_i = (ti0 * inv_dt, ti1 * inv_dt, ti2 * inv_dt)
        s.prev_inc = inc_b
        s.t_s = t
        if gap is not None:
            mat_ni = s.mat_nb @ self._geometry.mat_bi
            P_before = kf.P
            kf.add_noise(ATT, (mat_ni * gap.angle_var_rad2) @ mat_ni.T)
            kf.add_noise(VEL, (mat_ni * gap.velocity_var_m2_s2) @ mat_ni.T)
            if kf.recorder is not None:  # smoother hook: the gap's noise
                kf.recorder.on_noise(P_before, kf.P)
        cdth, cdv = s.cov_dth, s.cov_dv
        s.cov_dth = (cdth[0] + ti0, cdth[1] + ti1, cdth[2] + ti2)
        s.cov_dv = (cdv[0] + vi0, cdv[1] + vi1, cdv[2] + vi2)
        s.cov_dt += dt
        if s.cov_dt >= self._covariance_interval_s:
            self.propagate_covariance(s, kf)

    def propagate_covariance(self, s: FilterState, kf: ErrorStateFilter) -> None:
        """Propagate P over the accumulated interval with its mean specific force (NED from the
        velocity change; Coriolis, < 3e-3 m/s², left out of F)."""
        if s.cov_dt <= 0.0:
            return
        nav = s.nav
        inv_dt = 1.0 / s.cov_dt
        force_n = (nav.vel_ned_m_s - s.cov_vel0) * inv_dt
        force_n[2] -= earth.normal_gravity_m_s2(nav.lat_rad, nav.height_m)
        vn, ve, vd = nav.vel_ned_m_s.tolist()
        gyro_psd, accel_psd = s.imu_psd or self._densities.floor
        kf.set_white_noise(gyro_psd * s.q_scale, accel_psd * s.q_scale)
        P_before = kf.P
        kf.propagate(
            s.cov_dt,
            s.mat_nb @ self._geometry.mat_bi,
            force_n,
            np.array(s.cov_dv) * inv_dt,
            np.array(s.cov_dth) * inv_dt,
            nav.lat_rad,
            nav.height_m,
            (vn, ve, vd),
        )
        if kf.recorder is not None:  # smoother hook: a covariance step
            kf.recorder.on_transition(P_before, kf.phi, kf.P)
        if kf.layout.gp is not None:  # the estimate of a Gauss-Markov error decays
            decay = math.exp(-s.cov_dt / self._gnss_correlation_time_s)
            e = s.gnss_error
            s.gnss_error = (e[0] * decay, e[1] * decay, e[2] * decay)
        s.cov_dt = 0.0
        s.cov_dth = s.cov_dv = (0.0, 0.0, 0.0)
        s.cov_vel0 = nav.vel_ned_m_s
        if not s.heading_known:
            decouple_yaw(kf)

    @staticmethod
    def predict(s: FilterState, kf: ErrorStateFilter, t_m: float) -> Prediction:
        """The nominal state carried from the current state to t_m (< one IMU interval)."""
        nav, dt = s.nav, t_m - s.t_s
        rate_b = np.array(s.rate_b)
        if dt == 0.0:
            return Prediction(
                nav.lat_rad,
                nav.lon_rad,
                nav.height_m,
                nav.vel_ned_m_s,
                s.mat_nb,
                rate_b,
                np.array(s.rate_i),
                kf.layout,
            )
        vel = nav.vel_ned_m_s + np.array(s.accel_n) * dt
        mean_vel = 0.5 * (nav.vel_ned_m_s + vel)
        lat, lon, height = earth.displace(
            nav.lat_rad,
            nav.lon_rad,
            nav.height_m,
            mean_vel[0] * dt,
            mean_vel[1] * dt,
            mean_vel[2] * dt,
        )
        rotation = skew(rate_b * dt)
        return Prediction(
            lat_rad=lat,
            lon_rad=lon,
            height_m=height,
            vel_ned_m_s=vel,
            mat_nb=s.mat_nb @ (np.eye(3) + rotation + 0.5 * rotation @ rotation),
            rate_b=rate_b,
            rate_i=np.array(s.rate_i),
            layout=kf.layout,
        )
