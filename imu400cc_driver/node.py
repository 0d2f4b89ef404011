"""imu400cc_node: the Crossbow IMU400CC-100 as sensor_msgs/Imu on the host ROS clock.

Serial bytes are read on the link's thread, framed, stamped with the device clock mapped to the
host clock (the sample time, not the read time) and published straight from that thread, so a
busy executor adds no latency. Publishes ``imu/data_raw`` (REP-145: FLU ``imu_link``, SI units,
orientation_covariance[0] = -1), ``imu/temperature`` and ``/diagnostics``.
"""

from __future__ import annotations

import math
import threading
import time
from typing import Any

from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu, Temperature

from gnss_ins_common import ros_diagnostics as diag
from gnss_ins_common.axes import AxisMap
from gnss_ins_common.message_fields import fill_imu, fill_temperature, stamp_ns
from gnss_ins_common.params import Param
from gnss_ins_common.ros_endpoints import Endpoints
from gnss_ins_common.ros_node_main import run_node
from gnss_ins_common.ros_params import declare_parameters
from gnss_ins_common.ros_serial import start_serial_link
from gnss_ins_common.serial_link import LinkSettings
from imu400cc_driver.axes import DEFAULT_AXIS_SPEC, packet_to_measurement
from imu400cc_driver.device_clock import NOMINAL_RATE_HZ, NOMINAL_TICK_S, DeviceClock
from imu400cc_driver.framer import PacketFramer
from imu400cc_driver.link import configure_device, stop_stream
from imu400cc_driver.protocol import PACKET_LENGTH, TEMPERATURE_VARIANCE_C2, Command, Scaling


def _axis_map_error(spec: list[str]) -> str | None:
    try:
        AxisMap.from_spec(spec)
    except ValueError as exc:
        return str(exc)
    return None


def _three_values(values: list[float]) -> str | None:
    return None if len(values) == 3 else "needs three values (x, y, z)"


#: Per-sample sigma of (7.14) (imu400cc-aalborg-notes.md §1.3) at 134 Hz as densities:
#: density = sigma / sqrt(134 Hz).
_GYRO_DENSITY = [round(s / math.sqrt(NOMINAL_RATE_HZ), 9) for s in (0.0041, 0.0040, 0.0048)]
_ACCEL_DENSITY = [round(s / math.sqrt(NOMINAL_RATE_HZ), 9) for s in (0.0029, 0.0038, 0.0036)]

PARAMETERS = (
    Param("port", "/dev/ttyUSB0", "serial device of the IMU400CC"),
    Param("baud", 38400, "serial baud rate (the IMU400CC runs at 38400 8N1)", 1200, 921600),
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
        _GYRO_DENSITY,
        "white rate noise per axis [rad/s/sqrt(Hz)]; covariance = density^2 x 134 Hz",
        0.0,
        1.0,
        check=_three_values,
    ),
    Param(
        "accel_noise_density",
        _ACCEL_DENSITY,
        "white acceleration noise per axis [m/s^2/sqrt(Hz)]; covariance = density^2 x 134 Hz",
        0.0,
        1.0,
        check=_three_values,
    ),
    Param("latency", 0.0, "fixed delay from sampling to the packet's first byte [s]", 0.0, 0.1),
    Param("stall_timeout", 1.0, "reconnect when no byte arrives for this long [s]", 0.1, 60.0),
    Param(
        "packet_timeout",
        2.0,
        "reconnect (and restart the stream) when bytes arrive but no valid packet for this long,"
        " e.g. noise on the line after the unit power-cycled [s]; at least 3 poll periods",
        0.2,
        60.0,
    ),
    Param("temperature_rate", 1.0, "publish rate of imu/temperature [Hz]", 0.1, 134.0),
    Param("diagnostics_period", 1.0, "period of the /diagnostics status [s]", 0.1, 60.0),
)


class Imu400ccNode(Node):
    """The driver node; see the module docstring."""

    def __init__(self, **kwargs: Any) -> None:
        """Declare and validate the parameters, open the port in the background."""
        super().__init__("imu400cc_node", **kwargs)
        p = declare_parameters(self, PARAMETERS)
        self.params = p
        self._continuous = p["mode"] == "continuous"
        self._frame_id = p["frame_id"]
        self._scaling = Scaling(p["gyro_range_dps"], p["accel_range_g"])
        self._axis_map = AxisMap.from_spec(p["axis_map"])
        if not self._axis_map.proper:
            self.get_logger().warning(
                f"axis_map {p['axis_map']} is a mirror image (left-handed): check the mounting"
            )
        self._accel_sign = p["accel_sign"]
        self._gravity = p["gravity"]
        self._gyro_cov = [d * d * NOMINAL_RATE_HZ for d in p["gyro_noise_density"]]
        self._accel_cov = [d * d * NOMINAL_RATE_HZ for d in p["accel_noise_density"]]
        self._framer = PacketFramer(confirm_with_next_packet=self._continuous)
        self._device_clock = DeviceClock(
            nominal_tick_s=NOMINAL_TICK_S,
            nominal_period_s=1.0 / NOMINAL_RATE_HZ if self._continuous else None,
            transmission_s=PACKET_LENGTH * 10 / p["baud"],
            latency_s=p["latency"],
            # Polled: fewer samples, so a shorter warm-up and silences longer than a poll period.
            min_points=134 if self._continuous else 10,
            max_gap_s=1.0 if self._continuous else max(1.0, 3.0 / p["poll_rate"]),
        )
        self._temperature_every = max(1, round(NOMINAL_RATE_HZ / p["temperature_rate"]))
        if not self._continuous:
            self._temperature_every = max(1, round(p["poll_rate"] / p["temperature_rate"]))
        self._lock = threading.Lock()
        self._published = 0
        self._rate_window: tuple[float, int] = (time.monotonic(), 0)
        self._last_temperature = math.nan
        self._serial_number: int | None = None

        qos = QoSProfile(depth=200, reliability=ReliabilityPolicy.RELIABLE)
        endpoints = Endpoints(self)
        self._imu_pub = endpoints.publisher(Imu, "imu/data_raw", qos)
        self._temp_pub = endpoints.publisher(Temperature, "imu/temperature", 10)
        self._diagnostics = diag.DiagnosticsPublisher(self, endpoints)
        self.create_timer(p["diagnostics_period"], self._publish_diagnostics)
        if not self._continuous:
            self.create_timer(1.0 / p["poll_rate"], self._poll)

        # Polled: one packet per poll period, so wait at least three of them.
        min_timeout_s = 0.0 if self._continuous else 3.0 / p["poll_rate"]
        self._link = start_serial_link(
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

    # ---- serial side (link thread) ----------------------------------------------------------
    def _on_open(self, port: Any) -> None:
        info = configure_device(port, self._continuous, log=self.get_logger().warning)
        self._serial_number = info.serial_number
        if self._link.stats.opens > 1:  # a reconnect: the stream and its timer start anew
            self._framer.reset()
            self._device_clock.reset()

    def _on_data(self, chunk: bytes, received_s: float) -> None:
        packets = self._framer.feed(chunk)
        if packets:
            self._link.note_valid()
        # All packets of one read share its receive time: stamping them together keeps a stalled
        # read from looking like lost packets (docs/timing.md).
        stamps = self._device_clock.stamp_chunk([raw.timer for raw in packets], received_s)
        for raw, stamp in zip(packets, stamps, strict=True):
            meas = packet_to_measurement(
                raw, self._scaling, self._axis_map, self._accel_sign, self._gravity
            )
            self._publish(stamp.host_stamp_s, meas.rate_flu_rad_s, meas.specific_force_flu_m_s2)
            with self._lock:
                self._published += 1
                count = self._published
                self._last_temperature = meas.temperature_c
            if count % self._temperature_every == 0:
                self._publish_temperature(stamp.host_stamp_s, meas.temperature_c)

    def _publish(self, stamp_s: float, rate: Any, force: Any) -> None:
        msg = fill_imu(
            Imu(), stamp_ns(stamp_s), self._frame_id, rate, force, self._gyro_cov, self._accel_cov
        )
        self._imu_pub.publish(msg)

    def _publish_temperature(self, stamp_s: float, celsius: float) -> None:
        msg = fill_temperature(
            Temperature(), stamp_ns(stamp_s), self._frame_id, celsius, TEMPERATURE_VARIANCE_C2
        )
        self._temp_pub.publish(msg)

    # ---- executor side ----------------------------------------------------------------------
    def _poll(self) -> None:
        self._link.write(Command.GET_PACKET.wire)

    def _publish_diagnostics(self) -> None:
        now = time.monotonic()
        with self._lock:
            published = self._published
            temperature = self._last_temperature
        start, start_count = self._rate_window
        rate = (published - start_count) / max(now - start, 1e-9)
        self._rate_window = (now, published)
        framer, clock, link = self._framer.stats, self._device_clock, self._link.stats
        expected = NOMINAL_RATE_HZ if self._continuous else self.params["poll_rate"]
        if not self._link.is_open:
            level, message = diag.ERROR, f"port closed: {link.last_error or 'opening'}"
        elif rate < 0.9 * expected:
            level, message = diag.WARN, f"rate {rate:.1f} Hz below {expected:.0f} Hz"
        else:
            level, message = diag.OK, "streaming"
        values = {
            "port": self.params["port"],
            "mode": self.params["mode"],
            "rate_hz": rate,
            "packets": framer.packets,
            "bad_checksums": framer.bad_checksums,
            "unconfirmed": framer.unconfirmed,
            "skipped_bytes": framer.skipped_bytes,
            "resyncs": framer.resyncs,
            "dropped_packets": clock.dropped_packets,
            "timer_gaps": clock.timer_gaps,
            "clock_resets": clock.resets,
            "tick_period_us": clock.tick_period_s * 1e6,
            "clock_drift_ppm": clock.drift_ppm,
            "clock_jitter_ms": clock.jitter_s * 1e3,
            "reconnects": link.reconnects,
            "stalls": link.stalls,
            "invalid_stalls": link.invalid_stalls,
            "temperature_c": temperature,
            "serial_number": self._serial_number if self._serial_number is not None else "unknown",
            "last_error": link.last_error,
        }
        hardware_id = f"IMU400CC {self._serial_number or self.params['port']}"
        self._diagnostics.publish(
            diag.make_status(f"{self.get_name()}: IMU400CC", hardware_id, level, message, values)
        )

    def close(self) -> None:
        """Stop the stream and the reader thread."""
        self._link.stop(before_close=stop_stream)


def main(args: list[str] | None = None) -> int:
    """Console-script entry point (``ros2 run gnss_ins imu400cc_node``)."""
    return run_node(Imu400ccNode, args)
