"""Sensors on the vehicle: mountings and the truth callables the emulators use.

``VehicleTruth.imu_truth(t)`` gives what a perfect IMU in imu_link reads (REP-145: FLU, specific
force with +g up at rest, rate in rad/s); ``VehicleTruth.gnss_truth(t)`` gives the GNSS antenna's
position and velocity and the base_link attitude; ``VehicleTruth.odometer(t)`` the forward speed
of the odometer's wheel. Batch forms over arrays of times serve the bag writer; the scalar forms
serve the real-time emulators and the GNSS error model, through a ``TruthCache`` where speed
matters.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Generic, TypeVar

import numpy as np
from scipy.spatial.transform import Rotation

from gnss_ins_common.types import FloatArray
from ins_fusion.sim.trajectory import FrameTruth, Mounting, Trajectory

T = TypeVar("T")


@dataclass(frozen=True)
class VehicleSetup:
    """Where the sensors sit on base_link (REP-103 FLU): the IMU frame (lever arm and mounting
    rotation of imu_link), the GNSS antenna phase centre and the odometer's measuring point (a
    wheel hub; lever arms only)."""

    imu: Mounting = field(default_factory=Mounting)
    gnss_antenna_flu_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    odometer_flu_m: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class GnssTruth:
    """Truth a GNSS receiver measures at t_s: antenna position (WGS-84, ellipsoidal height) and
    velocity (ENU), and the attitude of base_link (FLU -> ENU quaternion, scalar last)."""

    t_s: float
    lat_rad: float
    lon_rad: float
    height_m: float
    vel_enu_m_s: FloatArray
    quat_enu_flu: FloatArray


class VehicleTruth:
    """Truth of a trajectory seen by the sensors of a vehicle setup."""

    def __init__(self, trajectory: Trajectory, setup: VehicleSetup = VehicleSetup()) -> None:
        self.trajectory = trajectory
        self.setup = setup
        self._antenna = Mounting(lever_arm_flu_m=setup.gnss_antenna_flu_m)
        self._odometer = Mounting(lever_arm_flu_m=setup.odometer_flu_m)

    @property
    def duration_s(self) -> float:
        """Length of the trajectory [s]."""
        return self.trajectory.duration_s

    def base_link(self, t_s: FloatArray) -> FrameTruth:
        """Truth of base_link at times t_s (for /ground_truth)."""
        return self.trajectory.frame_truth(t_s)

    def imu(self, t_s: FloatArray) -> FrameTruth:
        """Truth of imu_link at times t_s; rate_flu_rad_s / specific_force_flu_m_s2 are what a
        perfect REP-145 IMU reads."""
        return self.trajectory.frame_truth(t_s, self.setup.imu)

    def antenna(self, t_s: FloatArray) -> FrameTruth:
        """Truth of the GNSS antenna phase centre at times t_s (its frame has base_link's
        orientation)."""
        return self.trajectory.frame_truth(t_s, self._antenna)

    def odometer(self, t_s: FloatArray) -> tuple[FloatArray, FloatArray]:
        """What an odometer measures at times t_s: the forward speed (base_link x) of its
        measuring point [m/s], and base_link's acceleration along its path [m/s²] (slip)."""
        point = self.trajectory.frame_truth(t_s, self._odometer)
        forward_ned = Rotation.from_quat(point.quat_nb).as_matrix()[:, :, 0]
        forward_m_s = np.einsum("ni,ni->n", forward_ned, point.vel_ned_m_s)
        return forward_m_s, self.trajectory.path_speed(t_s)[1]

    def imu_truths(self, t_s: FloatArray) -> list[tuple[FloatArray, FloatArray]]:
        """``imu_truth`` at each of the times t_s, from one batch evaluation."""
        truth = self.imu(t_s)
        return list(zip(truth.rate_flu_rad_s, truth.specific_force_flu_m_s2, strict=True))

    def imu_truth(self, t_s: float) -> tuple[FloatArray, FloatArray]:
        """(rate_flu_rad_s, specific_force_flu_m_s2) of a perfect IMU at one time, shape (3,)."""
        return self.imu_truths(np.array([t_s]))[0]

    def gnss_truths(self, t_s: FloatArray) -> list[GnssTruth]:
        """``gnss_truth`` at each of the times t_s, from one batch evaluation."""
        a = self.antenna(t_s)
        return [
            GnssTruth(float(t), float(lat), float(lon), float(h), vel, quat)
            for t, lat, lon, h, vel, quat in zip(
                a.t_s, a.lat_rad, a.lon_rad, a.height_m, a.vel_enu_m_s, a.quat_enu_flu, strict=True
            )
        ]

    def gnss_truth(self, t_s: float) -> GnssTruth:
        """Antenna position/velocity and base_link attitude at one time."""
        return self.gnss_truths(np.array([t_s]))[0]


class TruthCache(Generic[T]):
    """A scalar truth callable (``imu_truth``, ``gnss_truth``) answered from batches.

    ``fill(t_s)`` evaluates the batch form at times t_s, replacing the previous batch; a call at
    one of those times (to 1 µs) is a look-up, any other time is computed on its own, or, with
    ``ahead`` (offsets [s]), starts a new batch at ``t + ahead``. A single evaluation costs about
    1 ms; a batch of a second of IMU samples about 2 ms (bench/bench_simulate.py).
    """

    def __init__(
        self,
        batch: Callable[[FloatArray], Sequence[T]],
        single: Callable[[float], T],
        ahead: FloatArray | None = None,
    ) -> None:
        self._batch = batch
        self._single = single
        self._ahead = ahead
        self._table: dict[int, T] = {}

    def fill(self, t_s: FloatArray) -> None:
        """Compute the truth at times t_s [s] in one batch."""
        self._table = dict(zip(_microseconds(t_s), self._batch(t_s), strict=True))

    def __call__(self, t_s: float) -> T:
        value = self._table.get(round(t_s * 1e6))
        if value is not None:
            return value
        if self._ahead is None:
            return self._single(t_s)
        self.fill(t_s + self._ahead)
        return self._table[round(t_s * 1e6)]


def _microseconds(t_s: FloatArray) -> list[int]:
    return [int(k) for k in np.rint(np.asarray(t_s, dtype=np.float64) * 1e6)]
