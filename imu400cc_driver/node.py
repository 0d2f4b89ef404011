"""imu400cc_node: the Crossbow IMU400CC-100 as sensor_msgs/Imu on the host ROS clock.

Serial bytes are read on the link's thread and handed to the ROS-free ``ImuDriver``, which
frames them and stamps each packet with the device clock mapped to the host clock (the sample
time, not the read time); the samples are published straight from that thread, so a busy
executor adds no latency, as serialized messages (``messages.SampleWriter``). Publishes
``imu/data_raw`` (REP-145: FLU ``imu_link``, SI units, orientation_covariance[0] = -1),
``imu/temperature``, ``/diagnostics`` and, with ``raw_output``, ``imu/raw``
(gnss_ins_msgs/SerialChunk): every read as the driver was fed it, with the receive time in ns
that the driver got, gathered into one message every 0.1 s (gnss_ins_common.serial_reads), and
every (re)open of the port, in every lifecycle state, for ``gnss_ins redecode``
(docs/redecode.md).
"""

from __future__ import annotations

import time
from typing import Any

from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from sensor_msgs.msg import Imu, Temperature

from gnss_ins_common import ros_diagnostics as diag
from gnss_ins_common.message_fields import seconds_of_ns, stamp_ns
from gnss_ins_common.rates import RateMeter
from gnss_ins_common.ros_endpoints import Endpoints
from gnss_ins_common.ros_lifecycle import AUTOSTART, ManagedSerialDriver
from gnss_ins_common.ros_node_main import run_node
from gnss_ins_common.ros_params import declare_parameters
from gnss_ins_common.ros_serial import (
    RAW_PERIOD_S,
    RawPublisher,
    node_time_s,
    start_serial_link,
)
from gnss_ins_common.serial_link import LinkSettings, SerialLink
from imu400cc_driver.driver import ImuDriver, ImuSample
from imu400cc_driver.link import configure_device, stop_stream
from imu400cc_driver.messages import SampleWriter
from imu400cc_driver.parameters import DRIVER_PARAMETERS, driver_config
from imu400cc_driver.protocol import Command

#: The declared parameters: the driver's (imu400cc_driver/parameters.py) and the lifecycle's.
PARAMETERS = (*DRIVER_PARAMETERS, AUTOSTART)


#: imu/raw messages kept for a late subscriber (a recorder that matched after the first reads):
#: ~20 s of reads at RAW_PERIOD_S a message, and the port events among them.
RAW_HISTORY = 200


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
        # Serialized once and rewritten in place: no Python message built and converted.
        self._writer = SampleWriter(
            self._driver, self._frame_id, Imu, Temperature, serialize_message
        )
        # Since the last status: at 134 Hz one period is enough, and a rate back to normal
        # shows at once after a gap (a window would keep it low for its length).
        self._rate = RateMeter(time.monotonic(), window_s=0.0)
        self._serial_number: int | None = None
        self._opened = False  # the port was opened before (the driver then starts anew)

        qos = QoSProfile(depth=200, reliability=ReliabilityPolicy.RELIABLE)
        endpoints = Endpoints(self)
        self._imu_pub = endpoints.publisher(Imu, "imu/data_raw", qos)
        self._temp_pub = endpoints.publisher(Temperature, "imu/temperature", 10)
        # Latched: a recorder that matches a (re)started node late still gets its first reads
        # (RAW_HISTORY: ~20 s of reads, ~0.2 MB).
        raw_qos = QoSProfile(
            depth=RAW_HISTORY,
            reliability=ReliabilityPolicy.RELIABLE,
            durability=DurabilityPolicy.TRANSIENT_LOCAL,
        )
        self._raw = (
            RawPublisher(endpoints, "imu/raw", self._frame_id, raw_qos) if p["raw_output"] else None
        )
        if self._raw is not None:  # the last reads before a silence: published all the same
            self.create_timer(RAW_PERIOD_S, diag.guarded(self, self._flush_raw))
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

    def close(self) -> None:
        """Stop the link, then publish the reads still held."""
        super().close()
        if self._raw is not None:
            self._raw.flush()

    # ---- serial side (link thread) ----------------------------------------------------------
    def _on_open(self, port: Any) -> None:
        info = configure_device(port, self._driver.config.continuous, log=self.get_logger().warning)
        self._serial_number = info.serial_number
        if self._opened:  # a reconnect or a new configure: the stream and its timer start anew
            self._driver.reset()
        if self._raw is not None:
            self._raw.event(not self._opened, stamp_ns(node_time_s(self)))
        self._opened = True

    def _on_data(self, chunk: bytes, received_s: float) -> None:
        time_ns = stamp_ns(received_s)  # the driver gets the time imu/raw records, to the bit
        if self._raw is not None:
            self._raw.data(chunk, time_ns)
        samples = self._driver.feed(chunk, seconds_of_ns(time_ns))
        link = self.link
        if samples and link is not None:
            link.note_valid()
        for sample in samples:
            self._publish(sample)

    def _publish(self, sample: ImuSample) -> None:
        if not self.publishing():
            return
        imu, temperature = self._writer.write(sample)
        self._imu_pub.publish(imu)
        if temperature is not None:
            self._temp_pub.publish(temperature)

    # ---- executor side ----------------------------------------------------------------------
    def _flush_raw(self) -> None:
        """Publish the imu/raw reads held once they are due."""
        if self._raw is not None:
            self._raw.flush(stamp_ns(node_time_s(self)))

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
