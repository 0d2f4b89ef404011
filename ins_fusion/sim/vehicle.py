"""Sensors on the vehicle: mountings and the truth callables the emulators use.

``VehicleTruth.imu_truth(t)`` gives what a perfect IMU in imu_link reads (REP-145: FLU, specific
force with +g up at rest, rate in rad/s); ``VehicleTruth.gnss_truth(t)`` gives the GNSS antenna's
position and velocity and the base_link attitude. Batch forms over arrays of times serve the bag
writer; the scalar forms serve the real-time emulators.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ins_fusion.core.rotation import FloatArray
from ins_fusion.sim.trajectory import FrameTruth, Mounting, Trajectory


@dataclass(frozen=True)
class VehicleSetup:
    """Where the sensors sit on base_link (REP-103 FLU): the IMU frame (lever arm and mounting
    rotation of imu_link) and the GNSS antenna phase centre (lever arm only)."""

    imu: Mounting = field(default_factory=Mounting)
    gnss_antenna_flu_m: tuple[float, float, float] = (0.0, 0.0, 0.0)


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

    def imu_truth(self, t_s: float) -> tuple[FloatArray, FloatArray]:
        """(rate_flu_rad_s, specific_force_flu_m_s2) of a perfect IMU at one time, shape (3,)."""
        truth = self.imu(np.array([t_s]))
        return truth.rate_flu_rad_s[0], truth.specific_force_flu_m_s2[0]

    def gnss_truth(self, t_s: float) -> GnssTruth:
        """Antenna position/velocity and base_link attitude at one time."""
        antenna = self.trajectory.frame_truth(np.array([t_s]), self._antenna)
        return GnssTruth(
            t_s=float(t_s),
            lat_rad=float(antenna.lat_rad[0]),
            lon_rad=float(antenna.lon_rad[0]),
            height_m=float(antenna.height_m[0]),
            vel_enu_m_s=antenna.vel_enu_m_s[0],
            quat_enu_flu=antenna.quat_enu_flu[0],
        )
