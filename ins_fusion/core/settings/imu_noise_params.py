"""The IMU noise model's parameters (``imu_noise.*``, the first of core.settings.params'
table) and the three-value parameter that table uses.

Defaults and their sources (references are to shared/reference/: "Aalborg"
imu400cc-aalborg-notes.md):

- white noise: the per-axis per-sample σ of Aalborg (7.14) with the bandwidths of §1.3 (25 Hz
  gyro, 75 Hz accelerometer) converted by Aalborg (5.21), RW = 60σ/√BW; the gyro mean 2.96 °/√h
  matches the report's 2.98 °/√h (the datasheet promises < 2.25 °/√h, §1.2);
- bias instability: σ of the six field standstill gyro biases (Aalborg §3.3 Fig. 9-9) and of the
  30-min accelerometer setups (Fig. 5-28); correlation time assumed (no reference value);
- turn-on bias when neither a calibration file nor a standstill gives one: the datasheet bounds
  (Aalborg §1.2, read as 1σ in §1.3.1);
"""

from __future__ import annotations

import math

from gnss_ins_common.params import Param, needs_values

# Per-axis per-sample σ of Aalborg (7.14) [rad/s, m/s²] and the sensor bandwidths of §1.3 [Hz].
_GYRO_SIGMA_7_14 = (0.0041, 0.0040, 0.0048)
_ACCEL_SIGMA_7_14 = (0.0029, 0.0038, 0.0036)
_GYRO_BANDWIDTH_HZ = 25.0
_ACCEL_BANDWIDTH_HZ = 75.0


def _random_walk(sigmas: tuple[float, ...], bandwidth_hz: float, to_user: float) -> list[float]:
    """Aalborg (5.21): RW = 60 σ / √BW in user units (deg/√h or m/s/√h), 3 significant digits."""
    return [float(f"{60.0 * s * to_user / math.sqrt(bandwidth_hz):.3g}") for s in sigmas]


def vector_param(
    name: str, default: list[float], description: str, low: float, high: float, axes: bool = False
) -> Param:
    """A three-value parameter; ``axes``: per sensor axis, one number meaning all three."""
    if axes:
        description += " (one number = the same on every axis)"
    return Param(
        name, default, description, low, high, check=needs_values(3, "x, y, z"), broadcast=axes
    )


IMU_NOISE_PARAMETERS: tuple[Param, ...] = (
    # IMU noise model (continuous densities, Gauss-Markov biases; per imu_link axis x, y, z).
    vector_param(
        "imu_noise.gyro_arw",
        _random_walk(_GYRO_SIGMA_7_14, _GYRO_BANDWIDTH_HZ, 180.0 / math.pi),
        "gyro angle random walk per axis [deg/sqrt(h)]",
        0.0,
        100.0,
        axes=True,
    ),
    vector_param(
        "imu_noise.accel_vrw",
        _random_walk(_ACCEL_SIGMA_7_14, _ACCEL_BANDWIDTH_HZ, 1.0),
        "accelerometer velocity random walk per axis [m/s/sqrt(h)]",
        0.0,
        10.0,
        axes=True,
    ),
    vector_param(
        "imu_noise.gyro_bias_instability",
        [10.8, 6.84, 18.4],
        "gyro bias instability: stationary sigma of the Gauss-Markov bias per axis [deg/h]",
        0.0,
        3600.0,
        axes=True,
    ),
    vector_param(
        "imu_noise.accel_bias_instability",
        [0.4, 0.4, 0.4],
        "accelerometer bias instability: stationary sigma of the Gauss-Markov bias [mg]",
        0.0,
        100.0,
        axes=True,
    ),
    Param(
        "imu_noise.bias_correlation_time",
        300.0,
        "correlation time of the Gauss-Markov biases and scale factors [s]",
        1.0,
        1.0e6,
    ),
    Param(
        "imu_noise.gyro_scale_sigma",
        0.0,
        "sigma of the gyro scale-factor error states [ppm]; 0 = no gyro scale states",
        0.0,
        1.0e5,
    ),
    Param(
        "imu_noise.accel_scale_sigma",
        0.0,
        "sigma of the accelerometer scale-factor error states [ppm]; 0 = no accel scale states",
        0.0,
        1.0e5,
    ),
    Param(
        "imu_noise.gyro_asymmetry_sigma",
        10000.0,
        "sigma of the gyro scale-asymmetry states [ppm] (the part of the scale factor that"
        " changes sign with the rate: S+/- = s +/- a); 0 = none; default: the datasheet's"
        " < 1 % scale accuracy",
        0.0,
        1.0e5,
    ),
    Param(
        "imu_noise.gyro_misalignment",
        0.0,
        "gyro axis misalignment sigma (datasheet) [mrad]: turn-rate-dependent attitude noise",
        0.0,
        100.0,
    ),
    Param(
        "imu_noise.gyro_turn_on_bias",
        1.0,
        "initial gyro bias sigma when no standstill seeds it and no calibration gives one [deg/s]",
        0.0,
        10.0,
    ),
    Param(
        "imu_noise.accel_turn_on_bias",
        8.5,
        "initial accelerometer bias sigma when no calibration file gives one [mg]",
        0.0,
        100.0,
    ),
)
