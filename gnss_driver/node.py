"""gnss_node: one NMEA GNSS receiver (Leica RTK rover, Ashtech ADU5, generic) on the host clock.

Serial bytes are read on the link's thread and handed to the ROS-free ``GnssDriver``, which
groups the sentences into epochs and stamps each with its UTC time mapped onto the host clock;
results are published straight from that thread (an epoch ended by an idle line is published
from a timer). Publishes ``gnss/fix`` (NavSatFix), ``gnss/vel`` (TwistWithCovarianceStamped,
ENU), ``gnss/attitude`` (Imu with orientation only), ``gnss/time_reference`` (TimeReference)
and ``/diagnostics``; the receiver's raw traffic (``nmea`` out, RTCM 3 corrections in on
``rtcm``, what is written to it on ``to_device/*``) is gnss_driver/ros_receiver_io.py's.
docs/gnss.md describes parameters, topics and covariance rules.
"""

from __future__ import annotations

import collections
import math
import threading
import time
from typing import Any

from geometry_msgs.msg import TwistWithCovarianceStamped
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu, NavSatFix, TimeReference

from gnss_driver import geoid
from gnss_driver.commands import Answer, CommandResult, run_setup
from gnss_driver.corrections import CorrectionQueue
from gnss_driver.driver import EpochOutput, GnssDriver
from gnss_driver.fix_type import FixType
from gnss_driver.messages import TOPICS, MessageClasses, epoch_messages
from gnss_driver.parameters import DRIVER_PARAMETERS, adu5_setup, driver_config
from gnss_driver.profiles import PROFILES, Receiver, default_setup_commands
from gnss_driver.ros_receiver_io import ReceiverTraffic
from gnss_ins_common import ros_diagnostics as diag
from gnss_ins_common.message_fields import seconds_of_ns, stamp_ns
from gnss_ins_common.rates import RateMeter
from gnss_ins_common.ros_endpoints import Endpoints
from gnss_ins_common.ros_lifecycle import AUTOSTART, ManagedSerialDriver
from gnss_ins_common.ros_node_main import run_node
from gnss_ins_common.ros_params import declare_parameters
from gnss_ins_common.ros_serial import node_time_s, start_serial_link
from gnss_ins_common.serial_link import LinkSettings, SerialLink

#: The declared parameters: the driver's (gnss_driver/parameters.py) and the lifecycle's.
PARAMETERS = (*DRIVER_PARAMETERS, AUTOSTART)

#: The node's message classes (gnss_driver/messages.py).
_CLASSES = MessageClasses(NavSatFix, TwistWithCovarianceStamped, Imu, TimeReference)
#: Latency samples averaged for the diagnostics.
_LATENCY_WINDOW = 50


class GnssNode(ManagedSerialDriver):
    """The driver node, a managed node (gnss_ins_common.ros_lifecycle); see the module
    docstring."""

    def __init__(self, **kwargs: Any) -> None:
        """Declare and validate the parameters; with ``autostart`` configure (the port opened
        in the background) and activate."""
        super().__init__("gnss_node", **kwargs)
        p = declare_parameters(self, PARAMETERS)
        self.params = p
        self._receiver = Receiver(p["receiver"])
        self._frame_id = p["frame_id"]
        self._commands = p["setup_commands"] or default_setup_commands(
            self._receiver, adu5_setup(p)
        )
        self._rate_hz = (
            1.0 / p["adu5_period"]
            if self._receiver is Receiver.ADU5
            else PROFILES[self._receiver].rate_hz
        )
        self._driver = GnssDriver(driver_config(p))
        self._lock = threading.Lock()
        self._setup_results: list[CommandResult] = []
        self._latencies: collections.deque[float] = collections.deque(maxlen=_LATENCY_WINDOW)
        self._last_fix_type = "none"
        # Satellites used and horizontal σ [m] of the last fix (NaN: not reported / no fix).
        self._last_satellites: int | None = None
        self._last_horizontal_sigma_m = math.nan
        self._last_date_source = "none"
        self._rate = RateMeter(time.monotonic())
        self._attitude_problems = (0, 0)  # resets, degraded at the last diagnostics
        self._publish_errors = 0
        self._last_publish_error = ""

        qos = QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE)
        endpoints = Endpoints(self)
        self._epoch_pubs = {
            topic: endpoints.publisher(msg_type, topic, qos)
            for topic, msg_type in zip(TOPICS, _CLASSES, strict=True)
        }
        self._traffic = ReceiverTraffic(
            self,
            endpoints,
            self._frame_id,
            corrections=(
                CorrectionQueue(p["corrections_max_age"]) if p["corrections_input"] else None
            ),
            nmea_output=p["nmea_output"],
            write=self._write,
        )
        self._diagnostics = diag.DiagnosticsPublisher(self, endpoints)
        self.create_timer(p["diagnostics_period"], diag.guarded(self, self._publish_diagnostics))
        self.create_timer(p["epoch_idle_timeout"] / 2.0, diag.guarded(self, self._flush_idle))

        self.start_managed(p["autostart"], before_close=None)

    def open_link(self) -> SerialLink:
        """The serial link (configure)."""
        p = self.params
        link = start_serial_link(
            self,
            LinkSettings(port=p["port"], baud=p["baud"], stall_timeout_s=p["stall_timeout"]),
            self._on_open,
            self._on_data,
        )
        self.get_logger().info(
            f"reading {self._receiver.value} on {p['port']} at {p['baud']} baud,"
            f" {len(self._commands)} set-up commands"
        )
        return link

    def destroy_node(self) -> None:
        """Stop writing corrections, then destroy the node."""
        self._traffic.stop()
        super().destroy_node()

    # ---- serial side (link thread) ----------------------------------------------------------
    def _write(self, data: bytes) -> bool:
        link = self.link
        return link is not None and link.write(data)

    def _on_open(self, port: Any) -> None:
        with self._lock:
            self._driver.reset()
            self._traffic.publish_opened(stamp_ns(node_time_s(self)))
        results = run_setup(
            port,
            self._commands,
            answer_timeout_s=self.params["setup_answer_timeout"],
            log=self.get_logger().info,
            on_data=lambda chunk: self._on_data(chunk, node_time_s(self)),
            on_sent=lambda command: self._traffic.publish_command(command, node_time_s(self)),
        )
        for result in results:
            if result.answer is Answer.NAK:
                self.get_logger().error(f"receiver rejected {result.command}")
        with self._lock:
            self._setup_results = results

    def _on_data(self, chunk: bytes, received_s: float) -> None:
        time_ns = stamp_ns(received_s)  # the driver gets the time nmea records, to the bit
        lines: list[bytes] = []
        with self._lock:
            outputs = self._driver.feed(chunk, seconds_of_ns(time_ns), lines)
            self._traffic.publish_lines(lines, time_ns)
            self._publish(outputs)

    def _flush_idle(self) -> None:
        with self._lock:
            self._publish(self._driver.flush_idle(node_time_s(self)))

    # ---- messages -----------------------------------------------------------------------------
    def _publish(self, outputs: list[EpochOutput]) -> None:
        if not self.publishing(held=len(outputs)):
            return
        for out in outputs:
            try:
                self._publish_epoch(out)
            except (AssertionError, ValueError, OverflowError) as exc:  # e.g. a UTC past 2038
                self._publish_errors += 1
                self._last_publish_error = repr(exc)[:200]

    def _publish_epoch(self, out: EpochOutput) -> None:
        publishers = self._epoch_pubs
        for topic, msg in epoch_messages(out, self._frame_id, self._receiver.value, _CLASSES):
            publishers[topic].publish(msg)
        if out.fix is not None:
            fix = out.fix
            self._last_fix_type = fix.fix_type.name
            self._last_satellites = fix.satellites
            self._last_horizontal_sigma_m = math.sqrt(fix.cov_enu_m2[0] + fix.cov_enu_m2[4])
        if out.utc is not None and not out.extends:
            self._last_date_source = out.utc.date_source.value
        self._latencies.append(node_time_s(self) - out.stamp_s)

    # ---- diagnostics (executor side) --------------------------------------------------------
    def _publish_diagnostics(self) -> None:
        now = time.monotonic()
        with self._lock:
            driver = self._driver
            reader, solver = driver.reader.stats, driver.solver.stats
            solver_fields = driver.solver.fields
            assembler = driver.assembler.stats
            epochs = driver.stats.epochs
            values: dict[str, object] = {
                "port": self.params["port"],
                "receiver": self._receiver.value,
                "epochs": epochs,
                "sentences": reader.sentences,
                **reader.rejected(),
                "empty_fields": solver_fields.empty_fields,
                "bad_fields": solver_fields.bad_fields,
                **{f"rejected {name}": n for name, n in sorted(solver_fields.rejected.items())},
                "too_few_satellites": solver.too_few_satellites,
                "satellites_unreported": solver.satellites_unreported,
                "fixes_2d": solver.fixes_2d,
                "rejected_2d": solver.rejected_2d,
                "held_altitudes": solver.held_altitudes,
                "geoid_model": geoid.MODEL,
                "geoid_altitudes": solver.geoid_altitudes,
                "internal_errors": driver.stats.internal_errors,
                "last_internal_error": driver.stats.last_internal_error,
                "publish_errors": self._publish_errors,
                "last_publish_error": self._last_publish_error,
                "late_sentences": assembler.late_sentences,
                "extended_epochs": assembler.extended_epochs,
                "duplicate_sentences": assembler.duplicate_sentences,
                "untimed_epochs": assembler.untimed_epochs,
                "last_fix_type": self._last_fix_type,
                "satellites": "-" if self._last_satellites is None else self._last_satellites,
                "horizontal_sigma_m": self._last_horizontal_sigma_m,
                **{f"fixes_{name.lower()}": n for name, n in solver.fixes.items()},
                "attitudes": solver.attitudes,
                "attitude_resets": solver.attitude_resets,
                "attitude_degraded": solver.attitude_degraded,
                "date_source": self._last_date_source,
                "midnight_rollovers": driver.utc.rollovers,
                "clock_ready": driver.clock.ready,
                "time_mode": "gnss" if self.params["use_gnss_time"] else "host",
                "clock_offset_ms": driver.clock_offset_s() * 1e3,
                "clock_skew_ppm": driver.clock.skew * 1e6,
                "receive_delay_ms": driver.clock.mean_delay_s * 1e3,
                "receive_jitter_ms": driver.clock.jitter_s * 1e3,
                "clock_resets": driver.clock.resets,
                "latency_ms": _mean(self._latencies) * 1e3,
                "setup": _setup_summary(self._setup_results),
                "acks": driver.stats.acks,
                "naks": driver.stats.naks,
            }
            no_fix = self._last_fix_type == FixType.NO_FIX.name
            geoid_used = solver.geoid_altitudes > 0
            offset_s = driver.clock_offset_s()
            naks = sum(r.answer is Answer.NAK for r in self._setup_results)
            problems = (solver.attitude_resets, solver.attitude_degraded)
        resets, degraded = (a - b for a, b in zip(problems, self._attitude_problems, strict=True))
        self._attitude_problems = problems
        rate = self._rate.rate_hz(epochs, now)
        link = self.link_stats
        values.update(self._traffic.diagnostics(node_time_s(self)))
        values.update(
            rate_hz=rate,
            expected_rate_hz=self._rate_hz,
            reconnects=link.reconnects,
            stalls=link.stalls,
            write_failures=link.write_failures,
            held_while_inactive=self.held_while_inactive,
            last_error=link.last_error,
        )
        if (problem := self.lifecycle_problem()) is not None:
            level, message = problem
        elif not self.port_open:
            level, message = diag.ERROR, f"port closed: {link.last_error or 'opening'}"
        elif self._rate.settled(now) and not 0.5 <= rate / self._rate_hz <= 1.5:
            level, message = diag.WARN, f"{rate:.1f} epochs/s, expected {self._rate_hz:g}"
        elif no_fix:
            satellites = "?" if self._last_satellites is None else self._last_satellites
            level, message = diag.WARN, f"no fix ({satellites} satellites in the last epoch)"
        elif self.params["use_gnss_time"] and abs(offset_s) > self.params["gnss_time_offset_warn"]:
            level = diag.WARN
            message = f"host - UTC {offset_s * 1e3:.1f} ms: is the host clock disciplined to UTC?"
            self.get_logger().warning(f"use_gnss_time: {message}", throttle_duration_sec=60.0)
        elif resets or degraded:
            level = diag.WARN
            message = f"attitude: {resets} reset, {degraded} above MRMS/BRMS limits"
        elif naks:
            level, message = diag.WARN, f"receiver rejected {naks} set-up command(s)"
        else:
            level, message = diag.OK, f"{self._last_fix_type} fix"
            if geoid_used:
                message += f", altitude with the {geoid.MODEL} geoid"
        name = f"{self.get_name()}: GNSS {self._receiver.value}"
        hardware_id = f"{self._receiver.value} {self.params['port']}"
        self._diagnostics.publish(diag.make_status(name, hardware_id, level, message, values))


def _mean(values: collections.deque[float]) -> float:
    return sum(values) / len(values) if values else math.nan


def _setup_summary(results: list[CommandResult]) -> str:
    counts = collections.Counter(r.answer.value for r in results)
    return ", ".join(f"{n} {answer}" for answer, n in counts.items()) or "none"


def main(args: list[str] | None = None) -> int:
    """Console-script entry point (``ros2 run gnss_ins gnss_node``)."""
    return run_node(GnssNode, args)
