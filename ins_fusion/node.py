"""ins_fusion_node: GNSS-aided INS on ROS 2, a thin layer over ``ins_fusion.core.engine.engine``.

Subscribes ``imu/data_raw`` (sensor_msgs/Imu), ``gnss/fix`` (NavSatFix), ``gnss/vel``
(TwistWithCovarianceStamped, ENU), ``gnss/attitude`` (Imu orientation) and, with ``speed.use``,
``vehicle/speed`` (TwistWithCovarianceStamped) or ``vehicle/odometry`` (nav_msgs/Odometry): the
forward speed, twist.linear.x; publishes
``ins/odometry`` (nav_msgs/Odometry in ``map`` = ENU tangent plane at the datum, child
``base_link``), ``ins/fix`` (NavSatFix of base_link), ``ins/imu`` (orientation of base_link with
bias-corrected rates), ``/diagnostics`` and TF (ins_fusion.adapters.tf_frames: the odometry's
transform on ``/tf`` per ``tf_mode``, the sensor frames on ``/tf_static``). Outputs are published
from the IMU callback of the sample they are due at: the first at or past each tick of
``output_rate`` (ins_fusion.core.output.output_clock, the rule replay records by), as soon as it
is processed. The IMU samples between two outputs are held and given to the engine together, in
their order, with the next output's sample, before the next GNSS message or status, or when MAX_HELD
wait: the engine computes the same numbers, and its code runs once per output instead of once per
sample, each time after a wake-up with the CPU's caches cold (docs/benchmarks.md). All callbacks
run on one executor thread, so the engine needs no locking; measurements are applied at their own
stamps by the engine (late GNSS data are rolled back and re-propagated there).

An IMU watchdog ticks every ``imu_timeout`` / 2: when no IMU message arrived for ``imu_timeout``
the node's state is ``no_imu`` (ERROR on /diagnostics, published at once and logged once) until
samples come again; the IMU callback only counts them.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from typing import Any

from geometry_msgs.msg import TwistWithCovarianceStamped
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from sensor_msgs.msg import Imu, NavSatFix, Temperature

from gnss_ins_common import ros_diagnostics as diag
from gnss_ins_common.navsat import SERVICE_GPS, CovarianceType
from gnss_ins_common.rates import IMU400CC_RATE_HZ as NOMINAL_RATE_HZ
from gnss_ins_common.ros_endpoints import Endpoints
from gnss_ins_common.ros_node_main import run_node
from gnss_ins_common.ros_params import declare_parameters
from gnss_ins_common.types import FloatArray
from ins_fusion.adapters import cdr_fields, messages_in, tf_frames
from ins_fusion.adapters.cdr_fields import CdrError
from ins_fusion.adapters.cdr_out import OutputWriter
from ins_fusion.adapters.position_use import PositionUse
from ins_fusion.adapters.status_log import WARN, StatusLog
from ins_fusion.core.engine.engine import InsEngine
from ins_fusion.core.engine.warm_up import warm_up
from ins_fusion.core.measurements.gnss_position import POSITION
from ins_fusion.core.output.output_clock import OutputClock
from ins_fusion.core.output.output_numbers import fault_report
from ins_fusion.core.output.solution import STATE, STATES, T
from ins_fusion.core.settings.config import FusionConfig
from ins_fusion.core.settings.params import PARAMETERS as FUSION_PARAMETERS
from ins_fusion.ros_tf import TfBroadcaster, transform_template

#: One table for the node and `gnss_ins replay` (ins_fusion/core/settings/params.py).
PARAMETERS = FUSION_PARAMETERS
#: Most IMU samples held between outputs (0.24 s at 134 Hz, for a low output_rate).
MAX_HELD = 32


class InsFusionNode(Node):
    """The fusion node; see the module docstring."""

    def __init__(self, **kwargs: Any) -> None:
        """Declare and validate the parameters, build the engine, subscribe and advertise."""
        super().__init__("ins_fusion_node", **kwargs)
        values = declare_parameters(self, PARAMETERS)
        self.params = values
        config = FusionConfig.from_parameters(values)
        warm_up_s = warm_up()  # the kernels ready before the first sample
        if warm_up_s > 2.0:  # compiled now, not from numba's cache
            self.get_logger().info(
                f"compiled the engine's kernels in {warm_up_s:.0f} s (first start "
                "after an install or update; later starts load them from the cache)"
            )
        self.engine = InsEngine(config)
        self._map_frame = tf_frames.world_frame(values)
        self._base_frame = config.base_frame
        self._output_clock = OutputClock(config.output_rate_hz)
        # IMU samples not yet given to the engine: those between two outputs are taken together
        # at the next output, GNSS message or status (module docstring).
        self._held = messages_in.HeldImu(MAX_HELD)
        # Variance of one bias-corrected rate sample: white-noise density^2 x the IMU rate.
        gyro_psd = float(config.imu_noise.gyro_psd.mean())
        rate_variance = gyro_psd * NOMINAL_RATE_HZ
        self._outputs = output_writer(self._map_frame, self._base_frame, rate_variance)
        self._published = 0
        self._invalid_outputs = 0
        self._bad_imu_messages = 0
        self._imu_received = 0  # IMU messages so far (the watchdog compares counts)
        self._imu_watch = _ImuWatch(time.monotonic())
        self._degraded_after_s = config.degraded_after_s
        # IMU stamp [s] from which the state is 'navigating' again after an outage; None: not
        # recovering (never degraded, or degraded now). -inf: navigating from the start.
        self._navigating_since_s: float | None = -math.inf
        self._fixes_received = 0
        self._position_use = PositionUse(time.monotonic())  # why degraded, in numbers
        self._status_log = StatusLog()  # what /diagnostics shows, on the console (rate-limited)

        sensor_qos = QoSProfile(depth=200, reliability=ReliabilityPolicy.BEST_EFFORT)
        endpoints = Endpoints(self)
        # Serialized: the node needs three numbers of each message (ins_fusion.adapters.cdr_fields).
        # Best effort, REP-2003's QoS for a sensor-data consumer (about a point of CPU less than
        # reliable, docs/benchmarks.md); qos_overrides./imu/data_raw.subscription.reliability:
        # reliable restores retransmission. A lost sample is bridged and counted (imu_gaps).
        endpoints.subscription(
            Imu, "imu/data_raw", self._on_imu, sensor_qos, raw=True, overridable=True
        )
        endpoints.subscription(NavSatFix, "gnss/fix", self._on_fix, 20)
        endpoints.subscription(TwistWithCovarianceStamped, "gnss/vel", self._on_velocity, 20)
        endpoints.subscription(Imu, "gnss/attitude", self._on_attitude, 20)
        if config.use_speed:  # the forward speed: either message (docs/fusion.md)
            endpoints.subscription(TwistWithCovarianceStamped, "vehicle/speed", self._on_speed, 50)
            endpoints.subscription(Odometry, "vehicle/odometry", self._on_speed, 50)
        endpoints.subscription(Temperature, "imu/temperature", self._on_temperature, 10)
        self._temperature_c = math.nan
        self._odom_pub = endpoints.publisher(Odometry, "ins/odometry", 50)
        self._fix_pub = endpoints.publisher(NavSatFix, "ins/fix", 50)
        self._imu_pub = endpoints.publisher(Imu, "ins/imu", 50)
        self._diagnostics = diag.DiagnosticsPublisher(self, endpoints)
        self._tf = TfBroadcaster(
            self, tf_frames.static_transforms(values), dynamic=values["tf_mode"] != "none"
        )
        self.create_timer(
            values["diagnostics_period"], diag.guarded(self, self._publish_diagnostics)
        )
        self.create_timer(values["imu_timeout"] / 2.0, diag.guarded(self, self._watch_imu))
        self.get_logger().info(
            f"fusing imu/data_raw + gnss/* into ins/odometry at {config.output_rate_hz:g} Hz"
        )

    # ---- inputs -------------------------------------------------------------------------------
    def _on_imu(self, data: bytes) -> None:
        self._imu_received += 1
        try:
            sample = cdr_fields.imu_sample(data)
        except CdrError as exc:  # not from a conforming middleware; counted, never fatal
            self._bad_imu_messages += 1
            self.get_logger().error(str(exc), throttle_duration_sec=10.0)
            return
        self._held.hold(sample)
        # Build the solution (not free) only when an output is due by the sample's stamp (a
        # stamp before the last output, a bag played again: the clock starts anew).
        due = self._output_clock.due(sample.t_s)
        if due or self._held.full:
            self._take_held()
        if due:
            row = self.engine.solution_row()
            if row is not None:
                self._output_clock.taken(sample.t_s)
                self._publish(row)

    def _take_held(self) -> None:
        """The IMU samples held since the last output, into the engine in their order (its
        compiled runs, as a replay's)."""
        self._held.take(self.engine)

    def _on_fix(self, msg: NavSatFix) -> None:
        self._fixes_received += 1
        self._take_held()
        self.engine.add_gnss_fix(messages_in.fix_measurement(msg))

    def _on_velocity(self, msg: TwistWithCovarianceStamped) -> None:
        self._take_held()
        self.engine.add_gnss_velocity(messages_in.velocity_measurement(msg))

    def _on_speed(self, msg: TwistWithCovarianceStamped | Odometry) -> None:
        self._take_held()
        self.engine.add_vehicle_speed(messages_in.speed_measurement(msg))

    def _on_attitude(self, msg: Imu) -> None:
        self._take_held()
        self.engine.add_attitude(messages_in.attitude_measurement(msg))

    def _temperature_ok(self, celsius: float) -> bool:
        """Inside the calibration's temperature range (True without a calibration or reading)."""
        calibration = self.engine.calibration
        return (
            calibration is None or math.isnan(celsius) or calibration.in_temperature_range(celsius)
        )

    def _on_temperature(self, msg: Temperature) -> None:
        if self._temperature_ok(self._temperature_c) and not self._temperature_ok(msg.temperature):
            calibration = self.engine.calibration
            assert calibration is not None
            self.get_logger().warning(  # once per excursion, not per message
                f"IMU temperature {msg.temperature:.1f} degC is outside the calibration's "
                f"range {calibration.temperature_range_c} degC"
            )
        self._temperature_c = msg.temperature

    def _watch_imu(self) -> None:
        """Two ticks without an IMU message (``imu_timeout``): no_imu, said at once; the first
        message after it ends it, said at once too."""
        watch, now = self._imu_watch, time.monotonic()
        if self._imu_received != watch.count:
            first = watch.count == 0
            watch.count, watch.last_change_s, watch.quiet_ticks = self._imu_received, now, 0
            if watch.silent:
                watch.silent = False
                self.get_logger().info(
                    "first IMU message on imu/data_raw" if first else "imu/data_raw is back"
                )
                self._publish_diagnostics()
            return
        watch.quiet_ticks += 1
        if watch.quiet_ticks >= 2 and not watch.silent:
            watch.silent = True
            self._position_use.imu_gap(now)
            if self._imu_received:
                self.get_logger().error(
                    f"no IMU message on imu/data_raw for {now - watch.last_change_s:.1f} s:"
                    " not navigating (state no_imu)"
                )
            else:  # starting before the IMU driver: the status says no_imu all the same
                self.get_logger().info("waiting for the first IMU message on imu/data_raw")
            self._publish_diagnostics()

    # ---- outputs ------------------------------------------------------------------------------
    def _publish(self, row: FloatArray) -> None:
        # Serialized once and rewritten in place (adapters.cdr_out): no Python message to convert.
        outputs = self._outputs.write(row)
        if outputs is None:  # a non-finite value or covariance: counted, not sent
            self._invalid_outputs += 1
            self.get_logger().error(
                f"solution at {row[T]:.3f} s ({STATES[int(row[STATE])]}) not published:"
                f" {fault_report(row)}",
                throttle_duration_sec=10.0,
            )
            return
        self._odom_pub.publish(outputs.odometry)
        self._tf.send(outputs.transform)
        self._fix_pub.publish(outputs.fix)
        self._imu_pub.publish(outputs.imu)
        self._published += 1

    def _state_level(
        self, state: str, t_s: float | None, positions: Mapping[str, int]
    ) -> tuple[bytes, str]:
        """Level and message of the navigation state at IMU stamp ``t_s``. 'aligning' and
        'degraded' (no GNSS position used for degraded_after_s) are WARN, never ERROR: the
        outputs stay valid, with a covariance that grows honestly. After an outage the level
        returns to OK only once positions have kept the state 'navigating' for another
        degraded_after_s, so sparse fixes in an outage do not flip it between OK and WARN.
        ``positions``: the engine's counters of GNSS positions (why it is degraded)."""
        use, now = self._position_use, time.monotonic()
        use.update(positions, self._fixes_received, now)
        if state == "degraded":
            self._navigating_since_s = None
            return diag.WARN, use.degraded(positions, self._fixes_received, now)
        if state != "navigating":
            return diag.WARN, state
        if self._navigating_since_s is None and t_s is not None:
            self._navigating_since_s = t_s
        since = self._navigating_since_s
        if since is None or t_s is None or t_s - since < self._degraded_after_s:
            return diag.WARN, f"navigating again after {use.cause()}, not yet settled"
        return diag.OK, state

    def _publish_diagnostics(self) -> None:
        self._take_held()
        status = self.engine.status()
        solution = self.engine.solution()
        level, message = self._state_level(
            status.state, solution.t_s if solution else None, status.measurements[POSITION.name]
        )
        if status.aligning:
            message = f"aligning: {status.aligning}"
        temperature_ok = self._temperature_ok(self._temperature_c)
        if status.last_reset_reason:
            message = f"{message}; last reset: {status.last_reset_reason}"
        if not temperature_ok and (calibration := self.engine.calibration) is not None:
            low, high = calibration.temperature_range_c or (math.nan, math.nan)
            level = diag.WARN
            message = (
                f"{message}; IMU temperature {self._temperature_c:.1f} °C outside the"
                f" calibration's {low:g}..{high:g} °C"
            )
        logger = self.get_logger()
        for log_level, line in self._status_log.update(status, time.monotonic()):
            if log_level == WARN:  # one severity per call site (rclpy)
                logger.warning(line)
            else:
                logger.info(line)
        if status.warnings:
            level, message = diag.WARN, f"{message}; {status.warnings[-1]}"
        state, silent_s = status.state, time.monotonic() - self._imu_watch.last_change_s
        if self._imu_watch.silent:
            state, level = "no_imu", diag.ERROR
            message = f"no_imu: no IMU message for {silent_s:.1f} s, not navigating"
        values: dict[str, object] = {
            "state": state,
            "imu_silent_s": round(silent_s, 2),
            "imu_samples": status.imu_samples,
            "imu_gaps": status.imu_gaps,
            "imu_duplicates": status.imu_duplicates,
            "imu_out_of_order": status.imu_out_of_order,
            "imu_implausible": status.imu_implausible,
            "bad_imu_messages": self._bad_imu_messages,
            "resets": status.resets,
            "rollbacks": status.rollbacks,
            "stationary": status.stationary,
            "outputs_published": self._published,
            "outputs_invalid": self._invalid_outputs,
            "imu_temperature_c": self._temperature_c,
            "temperature_in_calibration_range": temperature_ok,
        }
        for name, counters in status.measurements.items():
            for counter, count in counters.items():
                values[f"{name}.{counter}"] = count
        for name, nis in status.nis.items():
            values[f"{name}.last_nis"] = nis
        for name, value in status.adapted.items():  # the noise the filter adapted to
            values[f"adapted.{name}"] = value
        for name, value in status.calibration.items():  # time offset and mounting estimates
            values[f"calibration.{name}"] = value
        if solution is not None:
            for axis, value in zip("xyz", solution.gyro_bias_flu_rad_s, strict=True):
                values[f"gyro_bias_{axis}_deg_h"] = math.degrees(value) * 3600.0
            for axis, value in zip("xyz", solution.accel_bias_flu_m_s2, strict=True):
                values[f"accel_bias_{axis}_mg"] = value / 9.80665 * 1000.0
            values["horizontal_sigma_m"] = math.sqrt(
                solution.cov_pos_enu_m2[0, 0] + solution.cov_pos_enu_m2[1, 1]
            )
        self._diagnostics.publish(
            diag.make_status(f"{self.get_name()}: INS", "gnss_ins", level, message, values)
        )


class _ImuWatch:
    """The IMU watchdog's memory: the message count at its last change and when (monotonic s),
    ticks since, and whether the IMU is reported silent."""

    def __init__(self, now_s: float) -> None:
        self.count = 0
        self.last_change_s = now_s
        self.quiet_ticks = 0
        self.silent = False


def output_writer(map_frame: str, base_frame: str, rate_variance_rad2_s2: float) -> OutputWriter:
    """The outputs' serialized templates: frame ids, the fix's service and covariance type."""
    odometry = Odometry(child_frame_id=base_frame)
    odometry.header.frame_id = map_frame
    fix = NavSatFix(position_covariance_type=int(CovarianceType.KNOWN))
    fix.header.frame_id = base_frame
    fix.status.service = SERVICE_GPS
    imu = Imu()
    imu.header.frame_id = base_frame
    return OutputWriter(
        *(bytes(serialize_message(msg)) for msg in (odometry, fix, imu)),
        transform_template(map_frame, base_frame),
        rate_variance_rad2_s2,
    )


def main(args: list[str] | None = None) -> int:
    """Console-script entry point (``ros2 run gnss_ins ins_fusion_node``)."""
    return run_node(InsFusionNode, args)
