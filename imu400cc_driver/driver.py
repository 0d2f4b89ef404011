"""The IMU400CC driver without ROS: serial bytes in, stamped measurements out.

``ImuDriver.feed(chunk, receive_time_s)`` runs what imu400cc_node does with each read:

- ``PacketFramer`` cuts the bytes into packets (in continuous mode a packet must also fit the
  stream: its device-timer step, or the packet after it);
- ``DeviceClock`` stamps the packets of one read together, with their sample times on the host
  clock from the device timer (all packets of a read share its receive time, so that a stalled
  read is not taken for lost packets; docs/timing.md);
- ``PacketConverter`` turns them into ``imu_link`` (FLU) SI values with the unit's scaling,
  axis map, accelerometer sign and gravity (notes §2.4, §11.1 items 4-5);
- every ``temperature_every``-th sample also carries the temperature for ``imu/temperature``.

The IMU twin of ``gnss_driver.driver.GnssDriver``; the node wires it to a serial link, publishers
and /diagnostics. "notes" is shared/reference/imu400cc-aalborg-notes.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from gnss_ins_common.axes import AxisMap
from gnss_ins_common.rates import IMU400CC_RATE_HZ
from gnss_ins_common.types import Vec3
from imu400cc_driver.axes import (
    DEFAULT_ACCEL_SIGN,
    DEFAULT_AXIS_SPEC,
    STANDARD_GRAVITY_M_S2,
    ImuMeasurement,
    PacketConverter,
)
from imu400cc_driver.device_clock import NOMINAL_TICK_S, DeviceClock
from imu400cc_driver.framer import PacketFramer
from imu400cc_driver.protocol import PACKET_LENGTH, Scaling

#: Bits on the wire per byte: start bit, 8 data bits, stop bit (8N1; notes §2.1).
BITS_PER_BYTE = 10


def _density(sigmas: Vec3) -> Vec3:
    """White-noise density [unit/sqrt(Hz)] of per-sample sigmas at 134 Hz: sigma / sqrt(rate)."""
    x, y, z = (round(s / math.sqrt(IMU400CC_RATE_HZ), 9) for s in sigmas)
    return (x, y, z)


#: Per-sample sigmas of (7.14) at 134 Hz (notes §1.3) as densities: rate [rad/s/sqrt(Hz)] and
#: acceleration [m/s^2/sqrt(Hz)] per axis.
GYRO_NOISE_DENSITY = _density((0.0041, 0.0040, 0.0048))
ACCEL_NOISE_DENSITY = _density((0.0029, 0.0038, 0.0036))


def _default_axis_map() -> AxisMap:
    return AxisMap.from_spec(list(DEFAULT_AXIS_SPEC))


@dataclass(frozen=True)
class DriverConfig:
    """Everything the driver core needs to know about the unit and its link.

    ``continuous``: the 134 Hz stream ('C'), else one packet per poll at ``poll_rate_hz`` [Hz].
    ``latency_s``: the unit's fixed delay from sampling to the packet's first byte [s].
    ``temperature_rate_hz``: how often a sample carries the temperature [Hz].
    """

    continuous: bool = True
    baud: int = 38400
    poll_rate_hz: float = 5.0
    latency_s: float = 0.0
    scaling: Scaling = field(default_factory=Scaling)
    axis_map: AxisMap = field(default_factory=_default_axis_map)
    accel_sign: float = DEFAULT_ACCEL_SIGN
    gravity_m_s2: float = STANDARD_GRAVITY_M_S2
    gyro_noise_density: Vec3 = GYRO_NOISE_DENSITY
    accel_noise_density: Vec3 = ACCEL_NOISE_DENSITY
    temperature_rate_hz: float = 1.0

    @property
    def sample_rate_hz(self) -> float:
        """Samples per second the unit sends: 134 Hz streaming, else the poll rate [Hz]."""
        return IMU400CC_RATE_HZ if self.continuous else self.poll_rate_hz


@dataclass(frozen=True, slots=True)
class ImuSample:
    """One stamped measurement: ``stamp_s`` is its sample time on the host clock [s];
    ``with_temperature``: publish the temperature with it too."""

    stamp_s: float
    measurement: ImuMeasurement
    with_temperature: bool


@dataclass(slots=True)
class DriverStats:
    """Counters of the driver core itself (framer and clock have their own)."""

    samples: int = 0
    #: Temperature of the latest sample [degC]; NaN before the first.
    last_temperature_c: float = math.nan


class ImuDriver:
    """Framer + device clock + conversion to imu_link; see the module docstring.

    One thread feeds; ``stats`` and ``counters`` may be read from another.
    """

    def __init__(self, config: DriverConfig) -> None:
        """Set up the framer and the device clock for the mode and the link of ``config``."""
        self.config = config
        continuous = config.continuous
        self.framer = PacketFramer(confirm_with_next_packet=continuous)
        self.clock = DeviceClock(
            nominal_tick_s=NOMINAL_TICK_S,
            nominal_period_s=1.0 / IMU400CC_RATE_HZ if continuous else None,
            transmission_s=PACKET_LENGTH * BITS_PER_BYTE / config.baud,
            latency_s=config.latency_s,
            # Polled: fewer samples, so a shorter warm-up and silences longer than a poll period.
            min_points=134 if continuous else 10,
            max_gap_s=1.0 if continuous else max(1.0, 3.0 / config.poll_rate_hz),
        )
        self._convert = PacketConverter(
            config.scaling, config.axis_map, config.accel_sign, config.gravity_m_s2
        )
        self.temperature_every = max(1, round(config.sample_rate_hz / config.temperature_rate_hz))
        #: Variance of one sample [(rad/s)^2, (m/s^2)^2] per axis: density^2 x 134 Hz.
        self.gyro_variance = tuple(d * d * IMU400CC_RATE_HZ for d in config.gyro_noise_density)
        self.accel_variance = tuple(d * d * IMU400CC_RATE_HZ for d in config.accel_noise_density)
        self.stats = DriverStats()

    def reset(self) -> None:
        """Start afresh after the port was reopened: the stream and its timer start anew
        (counters are kept)."""
        self.framer.reset()
        self.clock.reset()

    def feed(self, chunk: bytes, receive_time_s: float) -> list[ImuSample]:
        """Bytes read at host time ``receive_time_s`` [s] -> the samples they completed."""
        packets = self.framer.feed(chunk)
        stamps = self.clock.stamp_chunk([raw.timer for raw in packets], receive_time_s)
        convert, stats = self._convert, self.stats
        samples = []
        for raw, stamp in zip(packets, stamps, strict=True):
            measurement = convert(raw)
            stats.samples += 1
            stats.last_temperature_c = measurement.temperature_c
            with_temperature = stats.samples % self.temperature_every == 0
            samples.append(ImuSample(stamp.host_stamp_s, measurement, with_temperature))
        return samples

    def counters(self) -> dict[str, float]:
        """Framer and device-clock counters and clock estimates for /diagnostics."""
        framer, clock = self.framer.stats, self.clock
        return {
            "packets": framer.packets,
            "bad_checksums": framer.bad_checksums,
            "unconfirmed": framer.unconfirmed,
            "skipped_bytes": framer.skipped_bytes,
            "resyncs": framer.resyncs,
            "dropped_packets": clock.dropped_packets,
            "timer_gaps": clock.timer_gaps,
            "wraps_taken_back": clock.wraps_taken_back,
            "clock_resets": clock.resets,
            "tick_period_us": clock.tick_period_s * 1e6,
            "clock_drift_ppm": clock.drift_ppm,
            "clock_jitter_ms": clock.jitter_s * 1e3,
        }
