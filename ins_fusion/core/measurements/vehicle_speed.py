"""The vehicle speed (odometer, DMI, CAN): its model and its update, in one place.

The speed s̃ is the forward speed of the vehicle at the measuring point P (``speed.lever_arm``),
along base_link x, with a scale error k_s (tyre radius, load, pressure) estimated as a state
(core.filter.eskf, ``StateLayout.ks``):

    s̃ = (1 + k_s) e_xᵀ (I - [μ×]) (C_nbᵀ v + ω_b × r) + n,   σ_n = max(message σ, speed.sigma)

with v the NED velocity of the IMU point, ω_b the corrected body rate, r the lever arm from
the IMU to P (base_link FRD) and μ the residual mounting (pitch, yaw) when estimated, as the
NHC takes it (core.measurements.nhc). With the NHC (no lateral or vertical velocity) it
completes the velocity in the vehicle frame: what an outage lacks most, the along-track speed.

Linearised in the error state (C_true = (I + [ψ×]) C, ω_true = ω - R_bi (δb_g + ...)):
H: δv -> g a C_nbᵀ, ψ -> g a C_nbᵀ [v×], gyro errors -> g a (-[r×]) dω_b, δμ_y -> -g v_b,z,
δμ_z -> +g v_b,y, δk_s -> the predicted forward speed, with g = 1 + k̂_s and a = e_xᵀ (I - [μ×])
the vehicle's forward axis in the body frame (v_b = C_nbᵀ v + ω_b × r).

A wheel that slips under braking (or spins under traction) breaks the model. Readings taken
while the IMU measures a forward acceleration beyond ``speed.max_accel`` (low-passed over
0.1 s) are not used (counted rejected): tyre slip grows with the longitudinal force, so that
is where it happens. The update is gated (chi-square, 1 degree of freedom) and never recovered
by widening the covariance: the gate keeps out what slip remains (a locked wheel, ice). While
the heading is unknown only readings near standstill are used (the yaw enters the forward
direction).
"""

from __future__ import annotations

import math

import numpy as np

from gnss_ins_common.types import FloatArray
from ins_fusion.core.compiled import jit
from ins_fusion.core.filter.eskf import ATT, VEL, Columns, ErrorStateFilter, StateLayout
from ins_fusion.core.filter.records import Prediction, VehicleSpeedMeasurement
from ins_fusion.core.filter.state import FilterState
from ins_fusion.core.measurements.common import Model, gyro_error_columns
from ins_fusion.core.measurements.gate import Kind, KindUpdate
from ins_fusion.core.nav.rotation import skew
from ins_fusion.core.settings.config import FusionConfig

#: The vehicle's speed readings (no recovery: the tyres may slip).
SPEED = Kind("vehicle_speed")


def speed_variance(measured: VehicleSpeedMeasurement, least_sigma_m_s: float) -> float:
    """The variance of one speed reading [m²/s²]: the message's when it is given and larger
    than ``least_sigma_m_s``² (NaN, inf or <= 0: not given), else that."""
    floor = least_sigma_m_s**2
    given = measured.variance_m2_s2
    return given if math.isfinite(given) and given > floor else floor


@jit
def speed_model(
    prediction: tuple[FloatArray, FloatArray, FloatArray, FloatArray],
    arm_b: FloatArray,
    mat_bi: FloatArray,
    calibration: tuple[tuple[float, float], float],
    reading: tuple[float, float],
    size: int,
    columns: Columns,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(z, H, R) of one speed reading (module docstring). ``prediction``: C_nb, NED velocity
    [m/s], corrected rate in body and imu FRD [rad/s]; ``arm_b``: IMU -> measuring point [m]
    (base_link FRD); ``calibration``: the residual mounting (pitch, yaw) [rad] and the speed
    scale estimate k̂_s; ``reading``: the measured speed [m/s] and its variance [m²/s²];
    ``columns``: StateLayout.columns (-1: block not estimated)."""
    mat_nb, vel, rate_b, rate_i = prediction
    (pitch, yaw), scale = calibration
    measured, variance = reading
    mt, ks = columns.mt, columns.ks
    c_bn = np.ascontiguousarray(mat_nb.T)
    v_b = c_bn @ vel + skew(rate_b) @ arm_b
    axis = np.array((1.0, yaw, -pitch))  # e_xᵀ (I - [μ×]): the vehicle's forward axis in b
    forward = axis @ v_b
    gain = 1.0 + scale
    H = np.zeros((1, size))
    H[0, VEL : VEL + 3] = gain * (axis @ c_bn)
    H[0, ATT : ATT + 3] = gain * (axis @ (c_bn @ skew(vel)))
    gyro_error_columns(H, gain * (axis @ -skew(arm_b)).reshape((1, 3)), mat_bi, rate_i, columns)
    if mt >= 0:
        H[0, mt] = -gain * v_b[2]
        H[0, mt + 1] = gain * v_b[1]
    if ks >= 0:
        H[0, ks] = forward
    z = np.array((measured - gain * forward,))
    return z, H, np.array(((variance,),))


def vehicle_speed(
    pred: Prediction,
    layout: StateLayout,
    arm_b: FloatArray,
    mat_bi: FloatArray,
    s: FilterState,
    reading: tuple[float, float],
) -> Model:
    """``speed_model`` for a prediction, the state ``s``'s mounting and speed scale and a
    reading (speed [m/s], variance [m²/s²])."""
    return speed_model(
        (pred.mat_nb, pred.vel_ned_m_s, pred.rate_b, pred.rate_i),
        arm_b,
        mat_bi,
        (s.mounting, s.speed_scale),
        reading,
        layout.size,
        layout.columns,
    )


class SpeedUpdate(KindUpdate):
    """The engine's update of vehicle speed readings (core.measurements.gate.KindUpdate; no
    compiled update)."""

    @staticmethod
    def wanted(config: FusionConfig) -> bool:
        """Only an engine that uses the speed has the kind (one without reports what it did
        before there was one)."""
        return config.use_speed

    def __call__(
        self,
        s: FilterState,
        kf: ErrorStateFilter,
        pred: Prediction,
        measured: VehicleSpeedMeasurement,
        live: bool,
    ) -> None:
        corrections = self._corrections
        if not math.isfinite(measured.speed_m_s):
            corrections.reject(SPEED, live)
            return
        if not s.heading_known and corrections.too_fast_to_align(pred, live, SPEED):
            return
        forward_accel = float(pred.mat_nb[:, 0] @ np.asarray(s.accel_lp))
        if abs(forward_accel) > self._config.speed_max_accel_m_s2:  # the tyres may slip
            corrections.reject(SPEED, live)
            return
        reading = (measured.speed_m_s, speed_variance(measured, self._config.speed_sigma_m_s))
        geometry = self._geometry
        model = vehicle_speed(pred, kf.layout, geometry.speed_arm(s), geometry.mat_bi, s, reading)
        corrections.update(s, kf, SPEED, model, live)
