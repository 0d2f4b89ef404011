"""Simulated laboratory procedures (Aalborg notes §4.5-§4.6): true motion -> IMU record.

A procedure is a list of steps, each a stretch of time with an attitude of imu_link in ENU:
``Hold`` (static), ``Turn`` (to the next attitude by the shortest rotation, smooth rate
profile, as a person turns the unit over) and ``Spin`` (about a body axis on a turn table: a
rate ramps up in ``ramp_s``, stays constant and ramps down, turning ``angle`` in all). The
unit turns about its own centre, so the true specific force is gravity, f = C_nᵇ (0, 0, g) in
imu_link, and the true rate is the body rate plus the earth rate C_nᵇ Ω (0, cos φ, sin φ).
``simulate`` passes this through ins_fusion.sim's ImuErrorModel (turn-on bias, g-dependent gyro
bias, asymmetric scale, misalignment, noise, quantisation) and, optionally, a wrong driver
axis mapping (imu400cc_driver.axes). The procedures below follow docs/calibration.md.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from gnss_ins_common.axes import AxisMap
from gnss_ins_common.types import FloatArray
from ins_fusion.bags.imu import ImuRecord
from ins_fusion.calibration_id.model import Site
from ins_fusion.sim.drive import DEFAULT_START_NS
from ins_fusion.sim.imu_model import ImuErrorModel, ImuProfile

#: Temperature messages per second (imu400cc_node's temperature_rate).
TEMPERATURE_RATE_HZ = 1.0


@dataclass(frozen=True)
class Hold:
    """Static at an attitude (imu_link -> ENU) for duration_s [s]; after a Spin, the attitude
    the spin ended at."""

    attitude: Rotation
    duration_s: float


@dataclass(frozen=True)
class Turn:
    """Turn to ``attitude`` in duration_s [s] (shortest rotation, rate profile sin²)."""

    attitude: Rotation
    duration_s: float


@dataclass(frozen=True)
class Spin:
    """Rotate about body axis ``axis`` (unit vector, imu_link) by ``angle_rad`` [rad, signed]
    at ``rate_rad_s`` [rad/s, > 0], ramping the rate up and down in ramp_s [s] each."""

    axis: FloatArray
    angle_rad: float
    rate_rad_s: float
    ramp_s: float = 2.0

    @property
    def duration_s(self) -> float:
        """Total time: the ramps turn rate × ramp_s together."""
        return abs(self.angle_rad) / self.rate_rad_s + self.ramp_s


Step = Hold | Turn | Spin


def up_attitude(axis: int, sign: float, heading_rad: float = 0.0) -> Rotation:
    """imu_link -> ENU with imu_link axis ``sign``·``axis`` pointing up, then turned by
    heading_rad about the vertical."""
    up = np.zeros(3)
    up[axis] = sign
    align, _ = Rotation.align_vectors([[0.0, 0.0, 1.0]], [up])
    return Rotation.from_euler("z", heading_rad) * align


def salychev_attitude(axis: int, sign: float) -> Rotation:
    """Salychev setup (notes §4.6): imu_link ``sign``·``axis`` up, the two horizontal positive
    axes pointing south-east and south-west (ENU)."""
    up = np.zeros(3)
    up[axis] = sign
    a, b = (k for k in range(3) if k != axis)
    south_east = np.array([1.0, -1.0, 0.0]) / math.sqrt(2.0)
    south_west = np.array([-1.0, -1.0, 0.0]) / math.sqrt(2.0)
    body = np.zeros((3, 3))  # rows: ENU direction of imu_link x, y, z
    body[axis] = [0.0, 0.0, sign]
    body[a], body[b] = south_east, south_west
    if np.linalg.det(body) < 0:
        body[a], body[b] = south_west, south_east
    return Rotation.from_matrix(body.T)


def tilted(attitude: Rotation, sigma_rad: float, rng: np.random.Generator) -> Rotation:
    """An attitude with a random level error: rotated about the ENU east and north axes by
    N(0, sigma_rad²) each (a unit set up with levels of that accuracy)."""
    east, north = rng.normal(0.0, sigma_rad, 2)
    return Rotation.from_rotvec([east, north, 0.0]) * attitude


def six_position(
    hold_s: float,
    turn_s: float,
    salychev: bool = False,
    heading_rad: float = 0.3,
    level_sigma_rad: float = 0.0,
    seed: int = 0,
) -> list[Step]:
    """The six positions in the order of axes.DEFAULT_POSITIONS (+z, -z, +x, -x, +y, -y up),
    each with a random level error of level_sigma_rad [rad]."""
    rng = np.random.default_rng(seed)
    attitudes = [
        tilted(
            salychev_attitude(axis, sign) if salychev else up_attitude(axis, sign, heading_rad),
            level_sigma_rad,
            rng,
        )
        for axis, sign in ((2, 1.0), (2, -1.0), (0, 1.0), (0, -1.0), (1, 1.0), (1, -1.0))
    ]
    return multi_position(attitudes, hold_s, turn_s)


def positions_26() -> list[Rotation]:
    """26 attitudes (S4 fixture, notes §4.1): the 6 faces, 12 edges and 8 corners up."""
    directions = [np.array(d, dtype=np.float64) for d in np.ndindex(3, 3, 3) if d != (1, 1, 1)]
    rotations = []
    for k, d in enumerate(directions):
        up = (d - 1.0) / np.linalg.norm(d - 1.0)
        align, _ = Rotation.align_vectors([[0.0, 0.0, 1.0]], [up])
        rotations.append(Rotation.from_euler("z", 0.7 * k) * align)
    return rotations


def multi_position(attitudes: Sequence[Rotation], hold_s: float, turn_s: float) -> list[Step]:
    """Static at each attitude in turn."""
    steps: list[Step] = []
    for k, attitude in enumerate(attitudes):
        steps += [Turn(attitude, turn_s)] if k else []
        steps.append(Hold(attitude, hold_s))
    return steps


def turn_table(
    angle_rad: float, rate_rad_s: float, static_s: float, ramp_s: float = 2.0
) -> list[Step]:
    """Turn-table procedure (§4.6): each positive imu_link axis pointing down on the table,
    static_s [s] at rest, one spin each way by angle_rad at rate_rad_s, at rest again. Serves
    D1 (the steady part of a spin) and D2 (the whole spin); angle_rad must be whole turns."""
    steps: list[Step] = []
    for axis in range(3):
        attitude = up_attitude(axis, -1.0)
        steps += [Turn(attitude, 5.0)] if axis else []
        steps.append(Hold(attitude, static_s))
        for sign in (1.0, -1.0):
            e = np.zeros(3)
            e[axis] = 1.0
            steps += [Spin(e, sign * angle_rad, rate_rad_s, ramp_s), Hold(attitude, static_s)]
    return steps


def _smooth(s: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Profile 0 -> 1 with zero rate at both ends: (value, derivative) for s in [0, 1]."""
    return s - np.sin(2.0 * math.pi * s) / (2.0 * math.pi), 1.0 - np.cos(2.0 * math.pi * s)


def truth(
    steps: Sequence[Step], rate_hz: float, site: Site
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Sample times [s] from 0, true rate [rad/s] and specific force [m/s²] in imu_link (n, 3)."""
    t_all, rate_all, att_all = [], [], []
    t0 = 0.0
    attitude = next(s.attitude for s in steps if not isinstance(s, Spin))
    for step in steps:
        n = max(1, round(step.duration_s * rate_hz))
        t = t0 + np.arange(n) / rate_hz
        s = (t - t0) / step.duration_s
        if isinstance(step, Hold):
            atts = Rotation.concatenate([step.attitude] * n)
            rate = np.zeros((n, 3))
            end = step.attitude
        elif isinstance(step, Turn):
            rotvec = (attitude.inv() * step.attitude).as_rotvec()
            value, slope = _smooth(s)
            atts = attitude * Rotation.from_rotvec(value[:, None] * rotvec)
            rate = slope[:, None] * rotvec / step.duration_s
            end = step.attitude
        else:
            turned, rate_now = _spin_profile(step, t - t0)
            atts = attitude * Rotation.from_rotvec(turned[:, None] * step.axis)
            rate = rate_now[:, None] * step.axis
            end = attitude * Rotation.from_rotvec(step.angle_rad * step.axis)
        t_all.append(t)
        rate_all.append(rate)
        att_all.append(atts)
        attitude = end
        t0 += n / rate_hz
    atts = Rotation.concatenate(att_all)
    to_body = atts.inv()
    rate = np.concatenate(rate_all) + to_body.apply(site.earth_rate_enu_rad_s)
    force = to_body.apply([0.0, 0.0, site.gravity_m_s2])
    return np.concatenate(t_all), rate, np.asarray(force)


def _spin_profile(spin: Spin, t: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Angle turned and rate (signed) at times t from the start of a spin."""
    sign = math.copysign(1.0, spin.angle_rad)
    ramp, total = spin.ramp_s, spin.duration_s
    r = spin.rate_rad_s
    up = np.clip(t / ramp, 0.0, 1.0)
    down = np.clip((total - t) / ramp, 0.0, 1.0)
    # rate r (1 - cos πs)/2 over each ramp (zero slope at both ends), r in between
    rate = r * np.where(t < ramp, 0.5 * (1.0 - np.cos(math.pi * up)), 1.0)
    rate = np.where(total - t < ramp, r * 0.5 * (1.0 - np.cos(math.pi * down)), rate)
    turned = np.where(
        t < ramp,
        r * ramp * 0.5 * (up - np.sin(math.pi * up) / math.pi),
        r * ramp * 0.5 + r * (t - ramp),
    )
    turned = np.where(
        total - t < ramp,
        abs(spin.angle_rad) - r * ramp * 0.5 * (down - np.sin(math.pi * down) / math.pi),
        turned,
    )
    return sign * turned, sign * rate


def simulate(
    steps: Sequence[Step],
    profile: ImuProfile,
    site: Site,
    seed: int,
    name: str = "simulated",
    band_limited: bool = True,
    device_map: tuple[AxisMap, float] | None = None,
    driver_map: tuple[AxisMap, float] | None = None,
    start_ns: int = DEFAULT_START_NS,
) -> tuple[ImuRecord, ImuErrorModel]:
    """The record a procedure gives with an IMU of ``profile`` (and the model, whose turn-on
    draws are the truth). With ``device_map`` (the unit's true axis_map, accel_sign) and
    ``driver_map`` (what the driver is configured with) the published axes are the driver's
    reading of the device's axes."""
    t, rate, force = truth(steps, profile.rate_hz, site)
    model = ImuErrorModel(profile, seed, band_limited)
    rate_m, force_m = model.apply(t, rate, force)
    if device_map is not None and driver_map is not None:
        (device, device_sign), (driver, driver_sign) = device_map, driver_map
        rate_m = driver.to_flu(device.from_flu(rate_m))
        force_m = driver_sign * driver.to_flu(device.from_flu(force_m) / device_sign)
    t_temp = np.arange(0.0, t[-1], 1.0 / TEMPERATURE_RATE_HZ)
    start_s = start_ns / 1e9
    record = ImuRecord(
        start_s + t, rate_m, force_m, start_s + t_temp, model.temperature_c(t_temp), name=name
    )
    return record, model
