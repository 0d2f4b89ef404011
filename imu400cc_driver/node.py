"""imu400cc_node: the Crossbow IMU400CC-100 as sensor_msgs/Imu on the host ROS clock.

Serial bytes are read on the link's thread and handed to the ROS-free ``ImuDriver``, which
frames them and stamps each packet with the device clock mapped to the host clock (the sample
time, not the read time); the samples are published straight from that thread, so a busy
executor adds no latency. Publishes ``imu/data_raw`` (REP-145: FLU ``imu_link``, SI units,
orientation_covariance[0] = -1), ``imu/temperature`` and ``/diagnostics``.
"""

from __future__ import annotations

import time
from typing import Any

from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu, Temperature

from gnss_ins_common import ros_diagnostics as diag
from gnss_ins_common.axes import AxisMap
from gnss_ins_common.message_fields import fill_imu, fill_temperature, stamp_ns
from gnss_ins_common.params import Param, needs_values, serial_link_params
from gnss_ins_common.rates import RateMeter
from gnss_ins_common.ros_endpoints import Endpoints
from gnss_ins_common.ros_lifecycle import AUTOSTART, ManagedSerialDriver
from gnss_ins_common.ros_node_main import run_node
from gnss_ins_common.ros_params import declare_parameters
from gnss_ins_common.ros_serial import start_serial_link
from gnss_ins_common.serial_link import LinkSettings, SerialLink
from imu400cc_driver.axes import DEFAULT_AXIS_SPEC
from imu400cc_driver.driver import (
    ACCEL_NOISE_DENSITY,
    GYRO_NOISE_DENSITY,
    DriverConfig,
    ImuDriver,
    ImuSample,
)
from imu400cc_driver.link import configure_device, stop_stream
from imu400cc_driver.protocol import TEMPERATURE_VARIANCE_C2, Command, Scaling


def _axis_map_error(spec: list[str]) -> str | None:
    try:
        AxisMap.from_spec(spec)
    except ValueError as exc:
        return str(exc)
    return None


PARAMETERS = (
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
    AUTOSTART,
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


class Imu400ccNode(ManagedSerialDriver):
    """The driver node, a managed node (gnss_ins_common.ros_lifecycle); see the module
    docstring."""

    def __init__(self, **kwargs: Any) -> None:
        """Declare and validate the parameters; with ``autostart`` configure (the port opened
        in the background) and activate."""
        super().__init__("imu400cc_node", **kwargs)
        p = declare_parameters(self, PARAMETERS)
        self.params = p
        self._driver = ImuDriver(driver_config(p))
        config = self._driver.config
        if not config.axis_map.proper:
            self.get_logger().warning(
                f"axis_map {p['axis_map']} is a mirror image (left-handed): check the mounting"
            )
        self._frame_id = p["frame_id"]
        self._rate = RateMeter(time.monotonic())
        self._serial_number: int | None = None
        self._opened = False  # the port was opened before (the driver then starts anew)

        qos = QoSProfile(depth=200, reliability=ReliabilityPolicy.RELIABLE)
        endpoints = Endpoints(self)
        self._imu_pub = endpoints.publisher(Imu, "imu/data_raw", qos)
        self._temp_pub = endpoints.publisher(Temperature, "imu/temperature", 10)
        self._diagnostics = diag.DiagnosticsPublisher(self, endpoints)
        self.create_timer(p["diagnostics_period"], diag.guarded(self, self._publish_diagnostics))
        if not config.continuous:
            self.create_timer(1.0 / p["poll_rate"], diag.guarded(self, self._poll))

        self.start_managed(p["autostart"], before_close=stop_stream)

    def open_link(self) -> SerialLink:
        """The serial link (configure); polled: one packet per poll period, so its time-outs
        are at least three of them."""
        p = self.params
        min_timeout_s = 0.0 if self._driver.config.continuous else 3.0 / p["poll_rate"]
        link = start_serial_link(
            self,
            LinkSettings(
                port=p["port"],
                baud=p["baud"],
                stall_timeout_s=max(p["stall_timeout"], min_timeout_s),
                valid_timeout_s=max(p["packet_timeout"], min_timeout_s),
            ),
            self._on_open,
            self._on_data,
        )
        self.get_logger().info(
            f"reading IMU400CC on {p['port']} at {p['baud']} baud, {p['mode']} mode"
        )
        return link

    # ---- serial side (link thread) ----------------------------------------------------------
    def _on_open(self, port: Any) -> None:
        info = configure_device(port, self._driver.config.continuous, log=self.get_logger().warning)
        self._serial_number = info.serial_number
        if self._opened:  # a reconnect or a new configure: the stream and its timer start anew
            self._driver.reset()
        self._opened = True

    def _on_data(self, chunk: bytes, received_s: float) -> None:
        samples = self._driver.feed(chunk, received_s)
        link = self.link
        if samples and link is not None:
            link.note_valid()
        for sample in samples:
            self._publish(sample)

    def _publish(self, sample: ImuSample) -> None:
        if not self.publishing():
            return
        stamp = stamp_ns(sample.stamp_s)
        meas = sample.measurement
        driver = self._driver
        msg = fill_imu(
            Imu(),
            stamp,
            self._frame_id,
            meas.rate_flu_rad_s,
            meas.specific_force_flu_m_s2,
            driver.gyro_variance,
            driver.accel_variance,
        )
        self._imu_pub.publish(msg)
        if sample.with_temperature:
            self._temp_pub.publish(
                fill_temperature(
                    Temperature(),
                    stamp,
                    self._frame_id,
                    meas.temperature_c,
                    TEMPERATURE_VARIANCE_C2,
                )
            )

    # ---- executor side ----------------------------------------------------------------------
    def _poll(self) -> None:
        link = self.link
        if link is not None:
            link.write(Command.GET_PACKET.wire)

    def _publish_diagnostics(self) -> None:
        driver, link = self._driver, self.link_stats
        rate = self._rate.rate_hz(driver.stats.samples, time.monotonic())
        expected = driver.config.sample_rate_hz
        if (problem := self.lifecycle_problem()) is not None:
            level, message = problem
        elif not self.port_open:
            level, message = diag.ERROR, f"port closed: {link.last_error or 'opening'}"
        elif rate < 0.9 * expected:
            level, message = diag.WARN, f"rate {rate:.1f} Hz below {expected:.0f} Hz"
        else:
            level, message = diag.OK, "streaming"
        values = {
            "port": self.params["port"],
            "mode": self.params["mode"],
            "rate_hz": rate,
            "expected_rate_hz": expected,
            **driver.counters(),
            "held_while_inactive": self.held_while_inactive,
            "reconnects": link.reconnects,
            "stalls": link.stalls,
            "invalid_stalls": link.invalid_stalls,
            "temperature_c": driver.stats.last_temperature_c,
            "serial_number": self._serial_number if self._serial_number is not None else "unknown",
            "last_error": link.last_error,
        }
        hardware_id = f"IMU400CC {self._serial_number or self.params['port']}"
        self._diagnostics.publish(
            diag.make_status(f"{self.get_name()}: IMU400CC", hardware_id, level, message, values)
        )


def main(args: list[str] | None = None) -> int:
    """Console-script entry point (``ros2 run gnss_ins imu400cc_node``)."""
    return run_node(Imu400ccNode, args)
