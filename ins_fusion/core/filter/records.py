"""The records the filter takes in and linearises about: the measurements as the ROS messages
give them (GNSS fix, GNSS velocity, attitude, vehicle speed; ENU/FLU, REP-103) and the nominal
state predicted to a measurement's stamp (``Prediction``; NED/FRD). Their models: each
kind's module of core.measurements (gnss_position, gnss_velocity, attitude, vehicle_speed)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from gnss_ins_common.navsat import HEIGHT_UNKNOWN_VARIANCE_M2
from gnss_ins_common.types import FloatArray
from ins_fusion.core.compiled import compilable


def _array(value: object, shape: tuple[int, ...]) -> FloatArray:
    out = np.asarray(value, dtype=np.float64).reshape(shape)
    out.setflags(write=False)
    return out


@compilable
def height_measured(height_m: float, var_up_m2: float) -> bool:
    """Does a fix measure its height [m] with this vertical variance [m²]? Not when the height
    is not finite or the variance is not below HEIGHT_UNKNOWN_VARIANCE_M2 (or NaN): a 2-D fix
    (gnss_ins_common.navsat), of which only the horizontal position is used."""
    return math.isfinite(height_m) and var_up_m2 < HEIGHT_UNKNOWN_VARIANCE_M2


@dataclass(frozen=True)
class GnssFixMeasurement:
    """Antenna position (gnss/fix): WGS-84 latitude/longitude [deg], ellipsoidal height [m],
    ENU covariance [m²] (3, 3); ``valid`` False for no-fix messages (ignored and counted).

    A 2-D fix (``height_measured`` false) is kept as height NaN with the vertical variance
    HEIGHT_UNKNOWN_VARIANCE_M2 and no vertical correlation: its model has the horizontal rows
    only, and it never starts the filter nor sets the datum."""

    t_s: float
    lat_deg: float
    lon_deg: float
    height_m: float
    cov_enu_m2: FloatArray
    valid: bool = True

    def __post_init__(self) -> None:
        cov = np.array(self.cov_enu_m2, dtype=np.float64).reshape(3, 3)
        if not height_measured(self.height_m, float(cov[2, 2])):
            object.__setattr__(self, "height_m", math.nan)
            cov[2, :] = cov[:, 2] = 0.0
            cov[2, 2] = HEIGHT_UNKNOWN_VARIANCE_M2
        object.__setattr__(self, "cov_enu_m2", _array(cov, (3, 3)))

    @property
    def height_known(self) -> bool:
        """Whether the height is measured (a 3-D fix)."""
        return height_measured(self.height_m, float(self.cov_enu_m2[2, 2]))


@dataclass(frozen=True)
class GnssVelocityMeasurement:
    """Antenna velocity (gnss/vel) in ENU [m/s] with its covariance [m²/s²] (3, 3); a vertical
    variance >= core.measurements.common.UNKNOWN_VELOCITY_VARIANCE (or NaN) means 'vertical
    unknown'."""

    t_s: float
    vel_enu_m_s: FloatArray
    cov_enu_m2_s2: FloatArray

    def __post_init__(self) -> None:
        object.__setattr__(self, "vel_enu_m_s", _array(self.vel_enu_m_s, (3,)))
        object.__setattr__(self, "cov_enu_m2_s2", _array(self.cov_enu_m2_s2, (3, 3)))


@dataclass(frozen=True)
class AttitudeMeasurement:
    """Orientation (gnss/attitude): quaternion (x, y, z, w) of the receiver's vehicle frame
    (FLU) in ENU and the covariance of its roll, pitch, yaw errors about the FLU axes [rad²]
    (3, 3); a variance >= core.measurements.common.UNKNOWN_ANGLE_VARIANCE marks an angle as not
    measured (heading-only receivers)."""

    t_s: float
    quat_enu_flu_xyzw: FloatArray
    cov_rpy_rad2: FloatArray

    def __post_init__(self) -> None:
        object.__setattr__(self, "quat_enu_flu_xyzw", _array(self.quat_enu_flu_xyzw, (4,)))
        object.__setattr__(self, "cov_rpy_rad2", _array(self.cov_rpy_rad2, (3, 3)))


@dataclass(frozen=True)
class VehicleSpeedMeasurement:
    """Forward speed of the vehicle at the speed's measuring point (vehicle/speed: an odometer,
    a DMI, the CAN bus): base_link x [m/s], negative when reversing, and its variance
    [m²/s²] (NaN or <= 0: not given; FusionConfig.speed_sigma_m_s applies)."""

    t_s: float
    speed_m_s: float
    variance_m2_s2: float


class Prediction(NamedTuple):
    """The nominal state at a measurement's stamp (core.filter.propagation.predicted_state,
    built in compiled code too)."""

    #: Latitude, longitude [rad], height [m] of the IMU.
    lat_rad: float
    lon_rad: float
    height_m: float
    #: NED velocity [m/s].
    vel_ned_m_s: FloatArray
    #: Body (base_link FRD) -> NED rotation.
    mat_nb: FloatArray
    #: Corrected rate ω_ib [rad/s] in base_link FRD and in imu FRD.
    rate_b: FloatArray
    rate_i: FloatArray
