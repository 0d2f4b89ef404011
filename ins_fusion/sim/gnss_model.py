"""GNSS receiver error model: fix types, correlated errors, latency, outages, multipath
outliers, fix-type changes, and the ADU5 attitude noise.

Per fix type the position error is white noise plus a first-order Gauss-Markov part (the slowly
wandering error of a receiver, NTNU notes §8 Fig. 3.3), per NED axis; velocity errors are white.
Numbers with a reference: RTK 2 cm horizontal / 3 cm vertical and 0.05 m/s (Aalborg notes §7.2
and §10, R of (7.15)); stand-alone (SPS) from the NTNU notes §11 Table 4.1, receiver 2 (mean
deviations 3.61 / 2.32 / 4.08 m and 0.31 / 0.23 / 0.19 m/s, taken as σ); ADU5 attitude σ from
Aalborg notes §7.3 (roll 0.24°, pitch 0.14°, yaw 0.1° measured). RTK float and DGPS levels, the
split between white and correlated parts, correlation times, outlier rates and the RTK
re-convergence time are assumptions (typical receiver behaviour), marked below.

Epochs fall on whole multiples of the receiver period of UTC (``utc_at_zero_s`` places the
simulation clock on UTC). Each fix carries its epoch time and its arrival time (epoch + latency,
NTNU notes §3: 1.24 s for the Q-Free OBU; Aalborg notes §7.1: 0.053 s to send a VTG sentence at
9600 baud).

Outages come from the schedule (no fix at all) or from a sky-visibility mask along the route:
zones (bridges, trees, street canyons) where fewer satellites are visible. With fewer satellites
than a fix type needs (``MIN_SATELLITES``, assumed: 4 for a position, 5 for RTK float, 6 for RTK
fixed) the fix degrades along RTK fixed -> float -> DGPS -> SPS -> none; the DOP, and with it the
error and the reported σ, grows as sqrt(nominal satellites / visible) (assumed). An RTK receiver
that lost its fixed solution (outage or mask) reports float for its re-convergence time after
the sky opens again.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

import numpy as np

from gnss_driver.fix_type import FixType
from gnss_ins_common.types import FloatArray, Vec3
from ins_fusion.core.nav import earth
from ins_fusion.core.nav.rotation import (
    euler_from_quat,
    ned_to_enu,
    quat_enu_flu_from_nb,
    quat_from_euler,
    quat_nb_from_enu_flu,
)
from ins_fusion.sim.noise import GaussMarkov
from ins_fusion.sim.vehicle import GnssTruth, TruthCache

#: Tolerance of epoch times against whole multiples of the period [s].
_TIME_TOLERANCE_S = 1e-6
#: Reorders per-axis standard deviations from NED to ENU (no sign change, unlike vectors).
_NED_TO_ENU_AXES = [1, 0, 2]


@dataclass(frozen=True)
class FixNoise:
    """Error level of one fix type. Position σ per NED axis [m]: white part and Gauss-Markov part
    with its correlation time [s]; velocity σ per NED axis [m/s]; what the receiver reports
    (satellites in use, HDOP)."""

    white_sigma_ned_m: Vec3
    correlated_sigma_ned_m: Vec3
    correlation_time_s: float
    velocity_sigma_ned_m_s: Vec3
    satellites: int
    hdop: float

    @property
    def position_sigma_ned_m(self) -> FloatArray:
        """Total position σ per NED axis [m] (what a receiver would report)."""
        return np.hypot(self.white_sigma_ned_m, self.correlated_sigma_ned_m)


#: Error levels per fix type. RTK: 2/3 cm total split about equally into white and correlated
#: (assumed 60 s); float, DGPS: assumptions; SPS: NTNU receiver 2, mostly correlated (assumed
#: 300 s; the fix wanders at standstill, NTNU notes §8).
FIX_NOISE: dict[FixType, FixNoise] = {
    FixType.RTK_FIXED: FixNoise(
        (0.014, 0.014, 0.021), (0.014, 0.014, 0.021), 60.0, (0.05, 0.05, 0.05), 12, 0.8
    ),
    FixType.RTK_FLOAT: FixNoise(
        (0.05, 0.05, 0.08), (0.2, 0.2, 0.3), 60.0, (0.05, 0.05, 0.08), 11, 0.9
    ),
    FixType.DGPS: FixNoise((0.2, 0.2, 0.4), (0.5, 0.5, 0.9), 120.0, (0.1, 0.1, 0.15), 10, 1.0),
    FixType.SPS: FixNoise((0.5, 0.5, 0.8), (3.57, 2.27, 4.0), 300.0, (0.31, 0.23, 0.19), 8, 1.4),
}

#: Fewest visible satellites for each fix type (assumed typical receiver behaviour: a 3-D fix needs
#: 4, an RTK float solution a fifth, a fixed ambiguity solution a sixth).
MIN_SATELLITES: dict[FixType, int] = {
    FixType.SPS: 4,
    FixType.DGPS: 4,
    FixType.RTK_FLOAT: 5,
    FixType.RTK_FIXED: 6,
}
#: Fix types from best to worst: a masked receiver falls back along this order.
_FIX_ORDER = (FixType.RTK_FIXED, FixType.RTK_FLOAT, FixType.DGPS, FixType.SPS)


@dataclass(frozen=True)
class GnssProfile:
    """A receiver: output rate [Hz], nominal fix type, latency [s], whether it outputs a vertical
    velocity, the RTK re-convergence time after an outage [s] (float fixes meanwhile), multipath
    outliers (probability per epoch, σ of the horizontal jump [m]) and, for attitude receivers,
    the attitude σ (roll, pitch, yaw) [rad]."""

    name: str
    rate_hz: float
    nominal_fix: FixType
    latency_s: float
    vertical_velocity: bool = True
    reconvergence_s: float = 0.0
    outlier_probability: float = 0.0
    outlier_sigma_m: float = 0.0
    attitude_sigma_rpy_rad: Vec3 | None = None


PROFILES: dict[str, GnssProfile] = {
    p.name: p
    for p in (
        # Leica System 500 network RTK, 1 Hz, NMEA at 9600 baud without down velocity (VTG)
        # (Aalborg notes §7.2); re-convergence 30 s and outliers 0.5 % of 0.3 m assumed.
        GnssProfile(
            "leica_rtk",
            1.0,
            FixType.RTK_FIXED,
            0.053,
            vertical_velocity=False,
            reconvergence_s=30.0,
            outlier_probability=0.005,
            outlier_sigma_m=0.3,
        ),
        # Thales/Ashtech ADU5: 5 Hz PAT attitude plus a (D)GPS position of antenna 1
        # (Aalborg notes §7.3); outliers 1 % of 3 m assumed (trees, §7.3 "in practice").
        GnssProfile(
            "adu5",
            5.0,
            FixType.DGPS,
            0.05,
            outlier_probability=0.01,
            outlier_sigma_m=3.0,
            attitude_sigma_rpy_rad=(math.radians(0.24), math.radians(0.14), math.radians(0.1)),
        ),
        # Q-Free OBU receiver 2 (NTNU notes §3, §11): 1 Hz stand-alone, 1.24 s late; outliers
        # 2 % of 20 m assumed (receiver 1 deviated by tens of metres, Table 4.1).
        GnssProfile(
            "qfree_obu",
            1.0,
            FixType.SPS,
            1.24,
            outlier_probability=0.02,
            outlier_sigma_m=20.0,
        ),
    )
}


@dataclass(frozen=True)
class SkyZone:
    """A place along the route with a restricted sky (bridge, trees, street canyon): within
    radius_m of (lat_rad, lon_rad) (WGS-84, horizontal distance) only ``satellites`` are visible."""

    lat_rad: float
    lon_rad: float
    radius_m: float
    satellites: int


@dataclass(frozen=True)
class SkyMask:
    """Sky-visibility zones along a route; open sky elsewhere."""

    zones: tuple[SkyZone, ...] = ()

    def visible_satellites(self, lat_rad: float, lon_rad: float) -> int | None:
        """Satellites visible at a position: the fewest of the zones containing it, or None
        under open sky."""
        visible: int | None = None
        for zone in self.zones:
            r_meridian, r_prime_vertical = earth.radii_m(zone.lat_rad)
            north = (lat_rad - zone.lat_rad) * r_meridian
            east = (lon_rad - zone.lon_rad) * r_prime_vertical * math.cos(zone.lat_rad)
            if math.hypot(north, east) <= zone.radius_m:
                visible = zone.satellites if visible is None else min(visible, zone.satellites)
        return visible


def masked_fix(fix_type: FixType, visible: int | None) -> FixType:
    """The best fix type no better than ``fix_type`` that ``visible`` satellites allow."""
    if visible is None or fix_type == FixType.NO_FIX:
        return fix_type
    for candidate in _FIX_ORDER[_FIX_ORDER.index(fix_type) :]:
        if visible >= MIN_SATELLITES[candidate]:
            return candidate
    return FixType.NO_FIX


@dataclass(frozen=True)
class GnssSchedule:
    """Scripted events: outages as (start_s, duration_s) without any fix, fix-type changes as
    (time_s, fix type in force from then on; FixType.NO_FIX suppresses fixes), and the sky mask
    along the route."""

    outages: tuple[tuple[float, float], ...] = ()
    fix_changes: tuple[tuple[float, FixType], ...] = ()
    sky_mask: SkyMask = field(default_factory=SkyMask)

    def in_outage(self, t_s: float) -> float | None:
        """End time of the outage containing t_s, or None."""
        for start, duration in self.outages:
            if start <= t_s < start + duration:
                return start + duration
        return None


@dataclass(frozen=True)
class GnssFix:
    """One receiver output.

    t_s: epoch (time of validity); arrival_t_s: when the receiver delivers it. Position of the
    antenna (WGS-84) with the receiver-reported σ (ENU) [m]; velocity ENU [m/s] (up is NaN when
    the receiver has none) with σ; attitude of base_link (FLU -> ENU quaternion) and its σ (roll,
    pitch, yaw) [rad] for attitude receivers. ``outlier`` marks a multipath jump (truth, for tests).
    """

    t_s: float
    arrival_t_s: float
    fix_type: FixType
    lat_rad: float
    lon_rad: float
    height_m: float
    position_sigma_enu_m: FloatArray
    vel_enu_m_s: FloatArray
    velocity_sigma_enu_m_s: FloatArray
    satellites: int
    hdop: float
    outlier: bool = False
    quat_enu_flu: FloatArray | None = None
    attitude_sigma_rpy_rad: Vec3 | None = None


@dataclass(frozen=True)
class GnssEpoch:
    """One receiver epoch: epoch and arrival time [s], the fix (None: the receiver reports no
    fix, e.g. in an outage) and the satellites it tracks (0 in a scheduled outage)."""

    t_s: float
    arrival_t_s: float
    fix: GnssFix | None
    satellites: int


@dataclass
class _Streams:
    """Independent random streams, one per error source (block-size independent output)."""

    white: np.random.Generator
    correlated: np.random.Generator
    velocity: np.random.Generator
    outlier: np.random.Generator
    attitude: np.random.Generator

    @classmethod
    def from_seed(cls, seed: int) -> _Streams:
        return cls(*(np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(5)))


class GnssErrorModel:
    """A receiver of a profile observing a truth source, with a schedule, seeded.

    Iterate ``epochs(t_start, t_end)`` (every epoch, with or without a fix) or ``fixes(t_start,
    t_end)`` (the fixes only) in time order; calls must not go back in time. Times are simulation
    times [s]; ``utc_at_zero_s`` is the UTC time [s] of simulation time 0, which sets where the
    whole-period UTC epochs fall. ``noise_scale`` multiplies every measurement error (position,
    velocity, outlier jumps, attitude; 0 = exact fixes); the reported σ, fix types, outages and
    the random sequences stay the same.
    """

    def __init__(
        self,
        truth: Callable[[float], GnssTruth],
        profile: GnssProfile,
        schedule: GnssSchedule = GnssSchedule(),
        seed: int = 0,
        utc_at_zero_s: float = 0.0,
        noise_scale: float = 1.0,
    ) -> None:
        self.truth = truth
        self.profile = profile
        self.schedule = schedule
        self.noise_scale = noise_scale
        period = 1.0 / profile.rate_hz
        phase = utc_at_zero_s - period * round(utc_at_zero_s / period)
        #: Simulation time of epoch index 0 is -phase (epoch k at k * period - phase).
        self._phase_s = phase + period if phase < -_TIME_TOLERANCE_S else phase
        if abs(self._phase_s) < _TIME_TOLERANCE_S:
            self._phase_s = 0.0
        self._rng = _Streams.from_seed(seed)
        self._correlated = {
            kind: GaussMarkov(
                np.array(noise.correlated_sigma_ned_m),
                np.full(3, noise.correlation_time_s),
                self._rng.correlated,
            )
            for kind, noise in FIX_NOISE.items()
        }
        self._next_epoch = 0
        self._reconverged_s = -math.inf
        self._fix_changes = sorted(schedule.fix_changes)

    def _nominal_fix(self, t_s: float) -> FixType:
        fix = self.profile.nominal_fix
        for time_s, changed in self._fix_changes:
            if time_s <= t_s:
                fix = changed
        if fix == FixType.RTK_FIXED and t_s < self._reconverged_s:
            return FixType.RTK_FLOAT
        return fix

    def fixes(self, t_start_s: float, t_end_s: float) -> Iterator[GnssFix]:
        """Fixes with epochs in [t_start_s, t_end_s)."""
        for epoch in self.epochs(t_start_s, t_end_s):
            if epoch.fix is not None:
                yield epoch.fix

    def epochs(self, t_start_s: float, t_end_s: float) -> Iterator[GnssEpoch]:
        """Every epoch in [t_start_s, t_end_s), with its fix or None; a TruthCache truth is
        filled with their times first (one batch, not one evaluation per epoch)."""
        if isinstance(self.truth, TruthCache):
            self.truth.fill(self.epoch_times(t_start_s, t_end_s))
        period = 1.0 / self.profile.rate_hz
        for epoch in range(*self._epoch_range(t_start_s, t_end_s)):
            dt = period * (epoch - self._next_epoch + 1) if self._next_epoch else period
            self._next_epoch = epoch + 1
            yield self._epoch_at(epoch * period - self._phase_s, dt)

    def epoch_times(self, t_start_s: float, t_end_s: float) -> FloatArray:
        """Times [s] of the epochs ``epochs(t_start_s, t_end_s)`` would yield now (e.g. to
        compute their truth in one batch)."""
        period = 1.0 / self.profile.rate_hz
        epochs = np.arange(*self._epoch_range(t_start_s, t_end_s), dtype=np.float64)
        return np.asarray(epochs * period - self._phase_s, dtype=np.float64)

    def _epoch_range(self, t_start_s: float, t_end_s: float) -> tuple[int, int]:
        """Epoch indices [first, stop) with times in [t_start_s, t_end_s), none before the next
        epoch due."""
        period = 1.0 / self.profile.rate_hz

        def index(t_s: float) -> int:
            return math.ceil((t_s + self._phase_s) / period - _TIME_TOLERANCE_S)

        first = max(self._next_epoch, index(t_start_s))
        return first, max(first, index(t_end_s))

    def _epoch_at(self, t_s: float, dt_s: float) -> GnssEpoch:
        profile, rng = self.profile, self._rng
        # Draw every stream every epoch, used or not, so outages do not shift the sequences.
        white = rng.white.standard_normal(3)
        velocity = rng.velocity.standard_normal(3)
        jump = rng.outlier.standard_normal(2)
        is_outlier = bool(rng.outlier.random() < profile.outlier_probability)
        attitude = rng.attitude.standard_normal(3)
        correlated = {
            kind: process.sample(np.array([dt_s]))[0] for kind, process in self._correlated.items()
        }
        arrival = t_s + profile.latency_s
        fix_type = self._nominal_fix(t_s)
        outage_end = self.schedule.in_outage(t_s)
        if outage_end is not None:
            self._reconverged_s = outage_end + profile.reconvergence_s
            return GnssEpoch(t_s, arrival, None, 0)
        if fix_type == FixType.NO_FIX:
            return GnssEpoch(t_s, arrival, None, 0)
        truth = self.truth(t_s)
        visible = self.schedule.sky_mask.visible_satellites(truth.lat_rad, truth.lon_rad)
        fix_type = masked_fix(fix_type, visible)
        if visible is not None and visible < MIN_SATELLITES[FixType.RTK_FIXED]:
            self._reconverged_s = t_s + profile.reconvergence_s
        if fix_type == FixType.NO_FIX:
            return GnssEpoch(t_s, arrival, None, visible or 0)
        noise = FIX_NOISE[fix_type]
        satellites = noise.satellites if visible is None else min(noise.satellites, visible)
        dop_scale = math.sqrt(noise.satellites / satellites)
        err_ned = (np.array(noise.white_sigma_ned_m) * white + correlated[fix_type]) * dop_scale
        if is_outlier:
            err_ned[:2] += profile.outlier_sigma_m * jump
        err_ned *= self.noise_scale
        r_meridian, r_prime_vertical = earth.radii_m(truth.lat_rad)
        vel_err = ned_to_enu(np.array(noise.velocity_sigma_ned_m_s) * velocity * self.noise_scale)
        vel = truth.vel_enu_m_s + vel_err
        vel_sigma = np.array(noise.velocity_sigma_ned_m_s)[_NED_TO_ENU_AXES]
        if not profile.vertical_velocity:
            vel[2] = math.nan
            vel_sigma[2] = math.nan
        quat = None
        if profile.attitude_sigma_rpy_rad is not None:
            draws = attitude * self.noise_scale
            quat = _perturb_attitude(truth.quat_enu_flu, profile.attitude_sigma_rpy_rad, draws)
        fix = GnssFix(
            t_s=t_s,
            arrival_t_s=arrival,
            fix_type=fix_type,
            lat_rad=truth.lat_rad + err_ned[0] / (r_meridian + truth.height_m),
            lon_rad=truth.lon_rad
            + err_ned[1] / ((r_prime_vertical + truth.height_m) * math.cos(truth.lat_rad)),
            height_m=truth.height_m - err_ned[2],
            position_sigma_enu_m=noise.position_sigma_ned_m[_NED_TO_ENU_AXES] * dop_scale,
            vel_enu_m_s=vel,
            velocity_sigma_enu_m_s=vel_sigma,
            satellites=satellites,
            hdop=noise.hdop * dop_scale,
            outlier=is_outlier,
            quat_enu_flu=quat,
            attitude_sigma_rpy_rad=profile.attitude_sigma_rpy_rad,
        )
        return GnssEpoch(t_s, arrival, fix, satellites)


def _perturb_attitude(quat_enu_flu: FloatArray, sigma_rpy: Vec3, draws: FloatArray) -> FloatArray:
    """Base_link attitude with white noise added to its NED roll, pitch and yaw."""
    roll, pitch, yaw = (
        euler_from_quat(quat_nb_from_enu_flu(quat_enu_flu)) + np.array(sigma_rpy) * draws
    )
    return quat_enu_flu_from_nb(quat_from_euler(roll, pitch, yaw))
