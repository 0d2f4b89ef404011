"""A simulated drive as the ROS topics the drivers publish, message by message (no ROS).

What ``gnss_ins simulate`` writes to a bag (docs/simulator.md): every message with its
header.stamp and the time it reaches the host (``log_ns``), both in ns since the Unix epoch on
one clock that is also UTC (simulation time 0 = ``start_ns``).

| topic | frame | stamp | received |
|---|---|---|---|
| /imu/data_raw (Imu) | imu_link | sample time | + 4.6875 ms (18 bytes at 38400 baud) |
| /imu/temperature (Temperature) | imu_link | every 134th sample | as that sample |
| /gnss/fix, /gnss/vel, /gnss/time_reference | gnss_link | epoch (UTC) | + receiver latency |
| /gnss/attitude (Imu, orientation only) | gnss_link | ADU5 epoch | + ADU5 latency |
| /vehicle/speed (TwistWithCovarianceStamped) | base_link | middle of a count | its end |
| /ground_truth/fix, /vel, /attitude | base_link | truth time | at once |

Names, frames and types from ins_fusion.bags.topics (``TOPICS``); velocities are
TwistWithCovarianceStamped in ENU.

Contents are the drivers' (their own ``fill_*`` functions): the IMU400CC node's covariances
(per-sample variance of the simulated noise, which for the band-limited imu400cc is its default
(7.14) σ²) and its temperature counts; the GNSS messages are gnss_node's reading of the receivers'
NMEA (sim.receivers); the odometer's (only with ``SimulationConfig.odometer``) its forward
speed in linear.x with the profile's stated variance, y, z and the angular part unknown. The
truth is exact: covariances 0, the angular part of the velocity and the rate and acceleration
of the attitude marked as absent.
"""

from __future__ import annotations

import bisect
import dataclasses
import itertools
import math
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any, NamedTuple, TypeVar

import numpy as np

from gnss_driver.profiles import Receiver
from gnss_driver.solution import fill_gnss_fix
from gnss_ins_common.message_fields import (
    UNKNOWN_VARIANCE,
    fill_imu,
    fill_navsatfix,
    fill_orientation,
    fill_temperature,
    fill_time_reference,
    fill_velocity,
)
from gnss_ins_common.navsat import SERVICE_GPS, CovarianceType, NavSatStatus
from gnss_ins_common.types import FloatArray
from imu400cc_driver.device_clock import PACKET_TRANSMISSION_S
from imu400cc_driver.protocol import TEMPERATURE_VARIANCE_C2, Scaling
from ins_fusion.bags.messages import new_message
from ins_fusion.bags.topics import (
    FIX_TYPE,
    GNSS_ATTITUDE,
    GNSS_FIX,
    GNSS_FRAME,
    GNSS_TIME,
    GNSS_VEL,
    IMU_DATA,
    IMU_FRAME,
    IMU_TEMPERATURE,
    IMU_TYPE,
    SPEED_FRAME,
    TOPICS,
    TRUTH_ATTITUDE,
    TRUTH_FIX,
    TRUTH_FRAME,
    TRUTH_VEL,
    VEHICLE_SPEED,
    VELOCITY_TYPE,
)
from ins_fusion.sim import gnss_model, imu_model, vibration
from ins_fusion.sim.gnss_model import GnssErrorModel, GnssSchedule, SkyMask, SkyZone
from ins_fusion.sim.imu_model import ImuErrorModel
from ins_fusion.sim.odometer_model import OdometerModel, OdometerProfile
from ins_fusion.sim.receivers import ReceiverModel
from ins_fusion.sim.scenarios import SCENARIOS, SURVEY_CAR
from ins_fusion.sim.vehicle import TruthCache, VehicleTruth
from ins_fusion.sim.vibration import Vibration

#: Default start (simulation time 0) of a bag, so that a seed always gives the same bag.
DEFAULT_START_NS = int(datetime(2024, 6, 1, 10, 0, 0, tzinfo=UTC).timestamp()) * 1_000_000_000
#: imu400cc_node publishes imu/temperature with every this many samples (temperature_rate 1 Hz).
TEMPERATURE_EVERY = 134
_TRANSMISSION_NS = round(PACKET_TRANSMISSION_S * 1e9)
_SCALING = Scaling()
#: GNSS receivers that print through the Leica rover's sentences (no attitude).
POSITION_RECEIVERS = tuple(
    name for name, p in gnss_model.PROFILES.items() if p.attitude_sigma_rpy_rad is None
)


class Event(NamedTuple):
    """One message: when the host receives it [ns since the epoch], topic, rosbags message."""

    log_ns: int
    topic: str
    message: Any


@dataclass(frozen=True)
class SkyZoneSpec:
    """A sky-visibility zone around the place base_link passes at route time t_s [s]: radius
    [m] and visible satellites (see gnss_model.SkyMask)."""

    t_s: float
    radius_m: float
    satellites: int = 0


@dataclass(frozen=True)
class SimulationConfig:
    """What to simulate: a scenario and duration [s], the IMU profile (``band_limited`` white
    noise), the position receiver (None: none) and the ADU5, ``gnss_noise_scale`` multiplying
    every error of both receivers (0 = exact fixes and attitudes, as reported σ unchanged),
    scheduled outages (start, duration [s]) and sky zones, truth rate [Hz], seed, the UTC time
    of simulation time 0 [ns], and the engine/road vibration the IMU senses (a profile of
    sim.vibration.PROFILES: ``none``, ``car`` (the default: the project's own drives are not
    kinder than a car on a road), ``rough``). ``imu_rate_hz`` / ``gnss_rate_hz`` replace the
    nominal output rate [Hz] of the IMU profile / the position receiver (None: the profile's).
    ``odometer``: the odometer on /vehicle/speed (None: none, the bag as without it)."""

    scenario: str = "test_pattern"
    duration_s: float = 240.0
    imu: str = "imu400cc"
    band_limited: bool = True
    gnss: str | None = "leica_rtk"
    adu5: bool = True
    gnss_noise_scale: float = 1.0
    outages: tuple[tuple[float, float], ...] = ()
    sky_zones: tuple[SkyZoneSpec, ...] = ()
    truth_rate_hz: float = 50.0
    seed: int = 0
    start_ns: int = DEFAULT_START_NS
    vibration: str = "car"
    imu_rate_hz: float | None = None
    gnss_rate_hz: float | None = None
    odometer: OdometerProfile | None = None


def _ns(t_s: FloatArray) -> FloatArray:
    return np.rint(np.asarray(t_s, dtype=np.float64) * 1e9)


def _grid(rate_hz: float, t_start_s: float, t_end_s: float) -> FloatArray:
    """Times k / rate_hz in [t_start_s, t_end_s) [s]."""
    first, stop = (math.ceil(t * rate_hz - 1e-6) for t in (t_start_s, t_end_s))
    return np.arange(first, stop, dtype=np.float64) / rate_hz


_Profile = TypeVar("_Profile", imu_model.ImuProfile, gnss_model.GnssProfile)


def _with_rate(profile: _Profile, rate_hz: float | None) -> _Profile:
    """``profile`` with its output rate replaced by ``rate_hz`` [Hz] (None: unchanged)."""
    if rate_hz is None:
        return profile
    if not rate_hz > 0.0:
        raise ValueError(f"{profile.name}: rate must be positive, got {rate_hz:g} Hz")
    return dataclasses.replace(profile, rate_hz=rate_hz)


class Simulation:
    """The vehicle, its IMU and GNSS receivers of one configuration, seeded.

    ``events(t_start_s, t_end_s)`` produces the messages of a time span (call in time order);
    ``stream()`` all of them in receive order. Also the source of the live emulators: ``vehicle``,
    ``imu_model``, ``vibration_profile`` and ``vibration_seed`` (``Vibration`` of the IMU's
    rate), ``receivers`` (receiver, its error model fed by a truth cache) and
    ``truth_events``.
    """

    def __init__(self, config: SimulationConfig) -> None:
        self.config = config
        trajectory = SCENARIOS[config.scenario](config.duration_s)
        self.vehicle = VehicleTruth(trajectory, SURVEY_CAR)
        # A new child leaves the ones before it (and so every other error source) unchanged.
        imu_seed, gnss_seed, adu5_seed, self.vibration_seed, odometer_seed = (
            int(s.generate_state(1)[0]) for s in np.random.SeedSequence(config.seed).spawn(5)
        )
        self.imu_profile = _with_rate(imu_model.PROFILES[config.imu], config.imu_rate_hz)
        self.imu_model = ImuErrorModel(self.imu_profile, imu_seed, config.band_limited)
        self.vibration_profile = vibration.profile(config.vibration)
        self.vibration = Vibration(
            self.vibration_profile, self.imu_profile.rate_hz, self.vibration_seed
        )
        gyro_sigma, accel_sigma = self.imu_model.noise_sigma()
        self._imu_variances = ((gyro_sigma**2).tolist(), (accel_sigma**2).tolist())
        self.schedule = GnssSchedule(
            outages=config.outages, sky_mask=SkyMask(tuple(map(self._zone, config.sky_zones)))
        )
        receivers = [(config.gnss, Receiver.LEICA, gnss_seed)] if config.gnss else []
        if config.adu5:
            receivers.append(("adu5", Receiver.ADU5, adu5_seed))
        self.receivers: list[tuple[ReceiverModel, GnssErrorModel]] = []
        for profile, receiver, seed in receivers:
            truth = TruthCache(self.vehicle.gnss_truths, self.vehicle.gnss_truth)
            rate_hz = None if receiver is Receiver.ADU5 else config.gnss_rate_hz
            model = GnssErrorModel(
                truth,
                _with_rate(gnss_model.PROFILES[profile], rate_hz),
                self.schedule,
                seed,
                config.start_ns / 1e9,
                config.gnss_noise_scale,
            )
            self.receivers.append((ReceiverModel(receiver), model))
        self.odometer = None
        if config.odometer is not None:
            self.odometer = OdometerModel(config.odometer, self.vehicle.odometer, odometer_seed)

    def _zone(self, spec: SkyZoneSpec) -> SkyZone:
        if not 0.0 <= spec.t_s <= self.config.duration_s:
            raise ValueError(
                f"sky zone at {spec.t_s:g} s: outside the {self.config.duration_s:g} s drive"
            )
        where = self.vehicle.base_link(np.array([spec.t_s]))
        return SkyZone(
            float(where.lat_rad[0]), float(where.lon_rad[0]), spec.radius_m, spec.satellites
        )

    @property
    def topics(self) -> dict[str, str]:
        """Topics (and types) this configuration writes."""
        skip = set() if self.config.gnss else {GNSS_FIX, GNSS_VEL, GNSS_TIME}
        if not self.config.adu5:
            skip.add(GNSS_ATTITUDE)
        topics = {topic: msgtype for topic, msgtype in TOPICS.items() if topic not in skip}
        if self.odometer is not None:
            topics[VEHICLE_SPEED] = VELOCITY_TYPE
        return topics

    def stream(self, block_s: float = 10.0) -> Iterator[Event]:
        """Every message of the drive, in receive order (stable for equal times)."""
        pending: list[Event] = []
        edges = [*np.arange(0.0, self.config.duration_s, block_s), self.config.duration_s]
        for t_start, t_end in itertools.pairwise(edges):
            pending.extend(self.events(float(t_start), float(t_end)))
            pending.sort(key=lambda event: event.log_ns)
            # Later blocks only hold messages stamped, hence received, from t_end on.
            ready = bisect.bisect_left(
                pending, self.config.start_ns + int(_ns(t_end)), key=lambda e: e.log_ns
            )
            yield from pending[:ready]
            del pending[:ready]
        yield from pending

    def events(self, t_start_s: float, t_end_s: float) -> list[Event]:
        """IMU, GNSS, odometer and truth messages read in [t_start_s, t_end_s) (simulation
        time)."""
        return [
            *self.imu_events(t_start_s, t_end_s),
            *self.gnss_events(t_start_s, t_end_s),
            *self.speed_events(t_start_s, t_end_s),
            *self.truth_events(t_start_s, t_end_s),
        ]

    def imu_events(self, t_start_s: float, t_end_s: float) -> list[Event]:
        """/imu/data_raw at the profile's rate and /imu/temperature with every 134th sample."""
        rate_hz = self.imu_profile.rate_hz
        t = _grid(rate_hz, t_start_s, t_end_s)
        if not len(t):
            return []
        truth = self.vehicle.imu(t)
        true_rate, true_force = truth.rate_flu_rad_s, truth.specific_force_flu_m_s2
        if not self.vibration_profile.silent:
            speed = np.linalg.norm(truth.vel_ned_m_s, axis=1)
            vibration_rate, vibration_force = self.vibration.sample(t, speed)
            true_rate, true_force = true_rate + vibration_rate, true_force + vibration_force
        rate, force = self.imu_model.apply(t, true_rate, true_force)
        stamps = (self.config.start_ns + _ns(t).astype(np.int64)).tolist()
        gyro_var, accel_var = self._imu_variances
        events = [
            Event(
                stamp + _TRANSMISSION_NS,
                IMU_DATA,
                fill_imu(new_message(IMU_TYPE), stamp, IMU_FRAME, w, f, gyro_var, accel_var),
            )
            for stamp, w, f in zip(stamps, rate.tolist(), force.tolist(), strict=True)
        ]
        sample_number = np.rint(t * rate_hz).astype(np.int64) + 1
        with_temperature = np.flatnonzero(sample_number % TEMPERATURE_EVERY == 0)
        if len(with_temperature):
            celsius = self.imu_model.temperature_c(t[with_temperature])
            counts = _SCALING.temperature_counts(celsius).counts
            for i, reading in zip(with_temperature, _SCALING.temperature_c(counts), strict=True):
                message = new_message(TOPICS[IMU_TEMPERATURE])
                fill_temperature(
                    message, stamps[i], IMU_FRAME, float(reading), TEMPERATURE_VARIANCE_C2
                )
                events.append(Event(events[i].log_ns, IMU_TEMPERATURE, message))
        return events

    def gnss_events(self, t_start_s: float, t_end_s: float) -> list[Event]:
        """gnss_node's messages of each receiver's epochs in [t_start_s, t_end_s)."""
        events: list[Event] = []
        for receiver, model in self.receivers:
            for epoch in model.epochs(t_start_s, t_end_s):
                stamp, log = (
                    self.config.start_ns + round(t * 1e9) for t in (epoch.t_s, epoch.arrival_t_s)
                )
                solution = receiver.solve(stamp / 1e9, epoch)
                if receiver.receiver is Receiver.ADU5:
                    if solution.attitude is not None:
                        o = solution.attitude.orientation
                        message = fill_orientation(
                            new_message(IMU_TYPE),
                            stamp,
                            GNSS_FRAME,
                            o.quat_enu_flu_xyzw,
                            o.cov_rpy_rad2,
                        )
                        events.append(Event(log, GNSS_ATTITUDE, message))
                    continue
                if solution.fix is not None:
                    message = fill_gnss_fix(new_message(FIX_TYPE), stamp, GNSS_FRAME, solution.fix)
                    events.append(Event(log, GNSS_FIX, message))
                if solution.velocity is not None:
                    v = solution.velocity
                    message = fill_velocity(
                        new_message(VELOCITY_TYPE), stamp, GNSS_FRAME, v.vel_enu_m_s, v.cov_enu
                    )
                    events.append(Event(log, GNSS_VEL, message))
                message = new_message(TOPICS[GNSS_TIME])
                source = receiver.receiver.value
                events.append(
                    Event(
                        log,
                        GNSS_TIME,
                        fill_time_reference(message, stamp, GNSS_FRAME, stamp, source),
                    )
                )
        return events

    def speed_events(self, t_start_s: float, t_end_s: float) -> list[Event]:
        """/vehicle/speed of the odometer's readings in [t_start_s, t_end_s) (none at 0, where
        no period has been counted): stamped at the middle of the counting period, the time of
        validity of its mean speed, received at its end."""
        if self.odometer is None:
            return []
        t = _grid(self.odometer.profile.rate_hz, t_start_s, t_end_s)
        outputs = self.odometer.measure(t[t > 0.0])
        variance = self.odometer.profile.reported_sigma_m_s**2
        covariance = [variance, 0.0, 0.0, 0.0, UNKNOWN_VARIANCE, 0.0, 0.0, 0.0, UNKNOWN_VARIANCE]
        start = self.config.start_ns
        return [
            Event(
                start + int(log),
                VEHICLE_SPEED,
                fill_velocity(
                    new_message(VELOCITY_TYPE),
                    start + int(stamp),
                    SPEED_FRAME,
                    (speed, 0.0, 0.0),
                    covariance,
                ),
            )
            for log, stamp, speed in zip(
                _ns(outputs.t_s), _ns(outputs.mid_s), outputs.speed_m_s.tolist(), strict=True
            )
        ]

    def truth_events(self, t_start_s: float, t_end_s: float) -> list[Event]:
        """/ground_truth/* of base_link at the truth rate, received when stamped."""
        t = _grid(self.config.truth_rate_hz, t_start_s, t_end_s)
        if not len(t):
            return []
        truth = self.vehicle.base_link(t)
        stamps = (self.config.start_ns + _ns(t).astype(np.int64)).tolist()
        lat_deg, lon_deg = np.degrees(truth.lat_rad).tolist(), np.degrees(truth.lon_rad).tolist()
        height, vel_enu = truth.height_m.tolist(), truth.vel_enu_m_s.tolist()
        quat_enu_flu = truth.quat_enu_flu.tolist()
        events: list[Event] = []
        zero = [0.0] * 9
        for i, stamp in enumerate(stamps):
            fix = new_message(FIX_TYPE)
            fill_navsatfix(
                fix,
                stamp,
                TRUTH_FRAME,
                int(NavSatStatus.FIX),
                SERVICE_GPS,
                lat_deg[i],
                lon_deg[i],
                height[i],
                zero,
                int(CovarianceType.KNOWN),
            )
            vel = fill_velocity(new_message(VELOCITY_TYPE), stamp, TRUTH_FRAME, vel_enu[i], zero)
            attitude = fill_orientation(
                new_message(IMU_TYPE), stamp, TRUTH_FRAME, quat_enu_flu[i], zero
            )
            events += [
                Event(stamp, TRUTH_FIX, fix),
                Event(stamp, TRUTH_VEL, vel),
                Event(stamp, TRUTH_ATTITUDE, attitude),
            ]
        return events
