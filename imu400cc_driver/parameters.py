"""imu400cc_node's parameters and the driver core's configuration from them (no ROS).

``imu400cc_driver.node`` declares them (with the lifecycle's ``autostart``); ``gnss_ins
redecode`` reads them from a parameter file; docs/parameters.md lists them.
"""

from __future__ import annotations

from typing import Any

from gnss_ins_common.axes import AxisMap
from gnss_ins_common.params import Param, needs_values, serial_link_params
from imu400cc_driver.axes import DEFAULT_AXIS_SPEC
from imu400cc_driver.driver import ACCEL_NOISE_DENSITY, GYRO_NOISE_DENSITY, DriverConfig
from imu400cc_driver.protocol import Scaling


def _axis_map_error(spec: list[str]) -> str | None:
    try:
        AxisMap.from_spec(spec)
    except ValueError as exc:
        return str(exc)
    return None


DRIVER_PARAMETERS = (
    *serial_link_params(
        "IMU400CC", 38400, "serial baud rate (the IMU400CC runs at 38400 8N1)", 1.0, 0.1
    ),
    Param(
        "mode",
        "continuous",
        "continuous: 134 Hz stream after 'C'; polled: one 'G' request per sample",
        choices=("continuous", "polled"),
    ),
    Param("poll_rate", 5.0, "request rate in polled mode [Hz]", 0.1, 100.0),
    Param("frame_id", "imu_link", "frame_id of the published messages (FLU, REP-103)"),
    Param("gyro_range_dps", 100.0, "rate range RR of the unit [deg/s] (scaling D-3)", 1.0, 2000.0),
    Param("accel_range_g", 2.0, "accelerometer range GR of the unit [g] (scaling D-2)", 0.5, 50.0),
    Param(
        "axis_map",
        list(DEFAULT_AXIS_SPEC),
        "device axis (with sign) that is each FLU imu_link axis x, y, z; the device is FRD",
        check=_axis_map_error,
    ),
    Param(
        "accel_sign",
        -1.0,
        "multiplies the accelerations: -1 because the unit reads +1 g on z at rest (notes §12.1)",
        -1.0,
        1.0,
        check=lambda v: None if abs(abs(v) - 1.0) < 1e-9 else "must be -1.0 or 1.0",
    ),
    Param("gravity", 9.80665, "value of 1 g used for the accelerometer counts [m/s^2]", 9.7, 9.9),
    Param(
        "gyro_noise_density",
        list(GYRO_NOISE_DENSITY),
        "white rate noise per axis [rad/s/sqrt(Hz)]; covariance = density^2 x 134 Hz",
        0.0,
        1.0,
        check=needs_values(3, "x, y, z"),
    ),
    Param(
        "accel_noise_density",
        list(ACCEL_NOISE_DENSITY),
        "white acceleration noise per axis [m/s^2/sqrt(Hz)]; covariance = density^2 x 134 Hz",
        0.0,
        1.0,
        check=needs_values(3, "x, y, z"),
    ),
    Param("latency", 0.0, "fixed delay from sampling to the packet's first byte [s]", 0.0, 0.1),
    Param(
        "packet_timeout",
        2.0,
        "reconnect (and restart the stream) when bytes arrive but no valid packet for this long,"
        " e.g. noise on the line after the unit power-cycled [s]; at least 3 poll periods",
        0.2,
        60.0,
    ),
    Param("temperature_rate", 1.0, "publish rate of imu/temperature [Hz]", 0.1, 134.0),
    Param(
        "raw_output",
        True,
        "publish every read from the port on imu/raw (gnss_ins_msgs/SerialChunk) and each"
        " (re)open, for recordings that gnss_ins redecode can decode again",
    ),
)


def driver_config(p: dict[str, Any]) -> DriverConfig:
    """The driver core's configuration from the validated parameters."""
    gyro, accel = p["gyro_noise_density"], p["accel_noise_density"]
    return DriverConfig(
        continuous=p["mode"] == "continuous",
        baud=p["baud"],
        poll_rate_hz=p["poll_rate"],
        latency_s=p["latency"],
        scaling=Scaling(p["gyro_range_dps"], p["accel_range_g"]),
        axis_map=AxisMap.from_spec(p["axis_map"]),
        accel_sign=p["accel_sign"],
        gravity_m_s2=p["gravity"],
        gyro_noise_density=(gyro[0], gyro[1], gyro[2]),
        accel_noise_density=(accel[0], accel[1], accel[2]),
        temperature_rate_hz=p["temperature_rate"],
    )
