"""Typed configuration of the fusion engine, built from the flat parameter dict (SI inside).

The one parameter table is ins_fusion.core.settings.params.PARAMETERS (user units: deg/sqrt(h),
deg/h, mg, ppm, degrees); ``FusionConfig.from_parameters`` validates a flat dict against it (unknown
names and bad values raise gnss_ins_common.params.ParameterValueError) and converts to SI.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gnss_ins_common.params import load_yaml, validate_all
from gnss_ins_common.types import FloatArray, Vec3
from ins_fusion.core.nav.units import deg_h, deg_s, deg_sqrt_h, m_s_sqrt_h, mg, ppm
from ins_fusion.core.settings.params import PARAMETERS

#: Node name of the parameter section in config/ins_fusion.yaml.
NODE_NAME = "ins_fusion_node"


def _vec(values: Any, unit: float = 1.0) -> Vec3:
    return (float(values[0]) * unit, float(values[1]) * unit, float(values[2]) * unit)


@dataclass(frozen=True)
class ImuNoise:
    """Continuous IMU noise model per imu_link axis (SI).

    gyro_arw [rad/sqrt(s)] and accel_vrw [m/s/sqrt(s)]: white-noise densities;
    gyro_bias_instability [rad/s] and accel_bias_instability [m/s²]: stationary σ of the
    first-order Gauss-Markov biases with correlation time bias_correlation_time_s;
    gyro_scale_sigma / accel_scale_sigma: σ of the scale-factor states [fraction], 0 = none;
    gyro_asymmetry_sigma: σ of the gyro scale-asymmetry states [fraction], 0 = none;
    gyro_turn_on_bias [rad/s] / accel_turn_on_bias [m/s²]: initial bias σ without better
    knowledge (no standstill seed, no calibration file).
    """

    gyro_arw: Vec3
    accel_vrw: Vec3
    gyro_bias_instability: Vec3
    accel_bias_instability: Vec3
    bias_correlation_time_s: float
    gyro_scale_sigma: float
    accel_scale_sigma: float
    gyro_asymmetry_sigma: float
    gyro_misalignment: float
    gyro_turn_on_bias: float
    accel_turn_on_bias: float

    @property
    def gyro_psd(self) -> FloatArray:
        """Gyro white-noise power density per axis [rad²/s] (ARW²)."""
        return np.square(self.gyro_arw)

    @property
    def accel_psd(self) -> FloatArray:
        """Accelerometer white-noise power density per axis [m²/s³] (VRW²)."""
        return np.square(self.accel_vrw)


@dataclass(frozen=True)
class StopDetectorConfig:
    """Stop detector (NTNU notes §7): window [s], variance thresholds [(m/s²)², (rad/s)²],
    change of the mean horizontal specific force [m/s²], speed threshold [m/s], hysteresis
    factor, minimum duration [s]."""

    window_s: float
    accel_variance: float
    gyro_variance: float
    accel_change_m_s2: float
    speed_m_s: float
    hysteresis: float
    min_duration_s: float


@dataclass(frozen=True)
class FusionConfig:
    """Everything the engine needs, SI units and radians; see core.settings.params for meanings."""

    imu_noise: ImuNoise
    imu_mounting_rpy_rad: Vec3
    imu_lever_arm_flu_m: Vec3
    gnss_lever_arm_flu_m: Vec3
    attitude_mounting_rpy_rad: Vec3
    imu_range_rate_deg_s: float
    imu_range_accel_g: float
    imu_time_offset_s: float
    estimate_time_offset: bool
    time_offset_sigma_s: float
    estimate_mounting: bool
    mounting_sigma_rad: float
    datum_deg: tuple[float, float, float] | None
    calibration_file: str
    use_gnss_velocity: bool
    use_attitude: bool
    use_zupt: bool
    use_zaru: bool
    use_nhc: bool
    use_course_heading: bool
    gate_probability: float
    gate_recovery_count: int
    gnss_white_sigma_enu_m: Vec3
    gnss_white_fraction: float
    gnss_correlation_time_s: float
    gnss_position_noise_scale: float
    pseudo_measurement_rate_hz: float
    zupt_sigma_m_s: float
    zaru_sigma_rad_s: float
    nhc_sigma_m_s: float
    nhc_min_speed_m_s: float
    use_speed: bool
    speed_lever_arm_flu_m: Vec3
    speed_sigma_m_s: float
    speed_scale_sigma: float
    speed_max_accel_m_s2: float
    speed_time_offset_s: float
    stop_detector: StopDetectorConfig
    alignment_duration_s: float
    course_speed_m_s: float
    moving_tilt_sigma_rad: float
    degraded_after_s: float
    covariance_interval_s: float
    history_s: float
    imu_gap_reset_s: float
    output_rate_hz: float
    map_frame: str
    base_frame: str

    @classmethod
    def from_parameters(cls, values: Mapping[str, Any]) -> FusionConfig:
        """Validate a flat parameter dict (missing names take their defaults) and convert."""
        p = validate_all(PARAMETERS, values)
        datum = p["datum"]
        return cls(
            imu_noise=ImuNoise(
                gyro_arw=_vec(p["imu_noise.gyro_arw"], deg_sqrt_h(1.0)),
                accel_vrw=_vec(p["imu_noise.accel_vrw"], m_s_sqrt_h(1.0)),
                gyro_bias_instability=_vec(p["imu_noise.gyro_bias_instability"], deg_h(1.0)),
                accel_bias_instability=_vec(p["imu_noise.accel_bias_instability"], mg(1.0)),
                bias_correlation_time_s=p["imu_noise.bias_correlation_time"],
                gyro_scale_sigma=ppm(p["imu_noise.gyro_scale_sigma"]),
                accel_scale_sigma=ppm(p["imu_noise.accel_scale_sigma"]),
                gyro_asymmetry_sigma=ppm(p["imu_noise.gyro_asymmetry_sigma"]),
                gyro_misalignment=1e-3 * p["imu_noise.gyro_misalignment"],
                gyro_turn_on_bias=deg_s(p["imu_noise.gyro_turn_on_bias"]),
                accel_turn_on_bias=mg(p["imu_noise.accel_turn_on_bias"]),
            ),
            imu_mounting_rpy_rad=_vec(p["imu_mounting_rpy_deg"], math.pi / 180.0),
            imu_lever_arm_flu_m=_vec(p["imu_lever_arm"]),
            gnss_lever_arm_flu_m=_vec(p["gnss_lever_arm"]),
            attitude_mounting_rpy_rad=_vec(p["attitude_mounting_rpy_deg"], math.pi / 180.0),
            imu_range_rate_deg_s=p["imu_range_rate"],
            imu_range_accel_g=p["imu_range_accel"],
            imu_time_offset_s=p["imu_time_offset"],
            estimate_time_offset=p["self_calibration.time_offset"],
            time_offset_sigma_s=p["self_calibration.time_offset_sigma"],
            estimate_mounting=p["self_calibration.mounting"] and p["use_nhc"],
            mounting_sigma_rad=math.radians(p["self_calibration.mounting_sigma"]),
            datum_deg=_vec(datum) if datum else None,
            calibration_file=p["calibration_file"],
            use_gnss_velocity=p["use_gnss_velocity"],
            use_attitude=p["use_attitude"],
            use_zupt=p["use_zupt"],
            use_zaru=p["use_zaru"],
            use_nhc=p["use_nhc"],
            use_course_heading=p["use_course_heading"],
            gate_probability=p["gate_probability"],
            gate_recovery_count=p["gate_recovery_count"],
            gnss_white_sigma_enu_m=_vec(p["gnss_noise.white_sigma"]),
            gnss_white_fraction=p["gnss_noise.white_fraction"],
            gnss_correlation_time_s=p["gnss_noise.correlation_time"],
            gnss_position_noise_scale=p["gnss_position_noise_scale"],
            pseudo_measurement_rate_hz=p["pseudo_measurement_rate"],
            zupt_sigma_m_s=p["zupt_sigma"],
            zaru_sigma_rad_s=deg_s(p["zaru_sigma"]),
            nhc_sigma_m_s=p["nhc_sigma"],
            nhc_min_speed_m_s=p["nhc_min_speed"],
            use_speed=p["speed.use"],
            speed_lever_arm_flu_m=_vec(p["speed.lever_arm"]),
            speed_sigma_m_s=p["speed.sigma"],
            speed_scale_sigma=p["speed.scale_sigma"] / 100.0,
            speed_max_accel_m_s2=p["speed.max_accel"],
            speed_time_offset_s=p["speed.time_offset"],
            stop_detector=StopDetectorConfig(
                window_s=p["stop_detector.window"],
                accel_variance=p["stop_detector.accel_variance"],
                gyro_variance=p["stop_detector.gyro_variance"],
                accel_change_m_s2=p["stop_detector.accel_change"],
                speed_m_s=p["stop_detector.speed"],
                hysteresis=p["stop_detector.hysteresis"],
                min_duration_s=p["stop_detector.min_duration"],
            ),
            alignment_duration_s=p["alignment.duration"],
            course_speed_m_s=p["alignment.course_speed"],
            moving_tilt_sigma_rad=math.radians(p["alignment.moving_tilt_sigma"]),
            degraded_after_s=p["degraded_after_s"],
            covariance_interval_s=p["covariance_interval"],
            history_s=p["history_s"],
            imu_gap_reset_s=p["imu_gap_reset_s"],
            output_rate_hz=p["output_rate"],
            map_frame=p["map_frame"],
            base_frame=p["base_frame"],
        )

    @classmethod
    def from_yaml(
        cls, path: str | Path, overrides: Mapping[str, Any] | None = None
    ) -> FusionConfig:
        """Configuration from the ``ins_fusion_node`` section of a ROS parameter file."""
        values = load_yaml(Path(path), NODE_NAME, PARAMETERS)
        return cls.from_parameters({**values, **(overrides or {})})

    @classmethod
    def default(cls) -> FusionConfig:
        """The declared defaults (config/ins_fusion.yaml)."""
        return cls.from_parameters({})
