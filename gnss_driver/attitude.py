"""ADU5 attitude angles -> vehicle orientation in ENU with a covariance (no ROS).

The ADU5 body reference frame (BRF) has X right, Y forward, Z up; pitch κ is about X, roll ε
about Y and heading φ about Z, clockwise from true north, relative to the local tangent plane
(imu400cc-aalborg-notes.md §7.3, §11.2 item 2). How the three angles compose is a convention
(``ANGLE_CONVENTIONS``, the gnss_node parameter ``adu5_angle_convention``):

- ``heading_pitch_roll`` (default): a vehicle's Euler angles, heading, then pitch about the
  turned X, then roll about the turned-and-pitched Y (positive pitch = nose up, positive roll =
  right side down): ``R_enu_brf = Rz(-φ) · Rx(κ) · Ry(ε)`` (scipy ``"ZXY"``). Heading and pitch
  are then the azimuth and elevation of the first antenna vector V12 (BRF Y), and roll the tilt of
  the antenna plane about it, whatever the heading: the geometric meaning an attitude receiver's
  angles have.
- ``report_fixed_axes``: the Aalborg report's own reading (§7.5): rotations of the ADU frame
  about *fixed* axes in the order φ, κ, ε, i.e. ``R_enu_brf = Ry(ε) · Rx(κ) · Rz(-φ)`` (scipy
  extrinsic ``"zxy"``). The report takes it from an earlier project report that is not among the
  documents; it makes pitch a rotation about the east axis whatever the heading, so at heading
  90° it is what a vehicle calls roll. At heading 0 the two agree to second order in the tilt
  (0.02° at 1° pitch and roll); elsewhere they differ by up to about twice the tilt (at heading
  90°, pitch 2°, roll 3° the two readings are 5.1° apart).

The documents do not give the receiver's own definition (the calibration dialog's note on it is
not legible in the report), so the default follows the geometry above and the report's reading
is one parameter away.

With all angles zero the BRF axes are east, north, up. The vehicle frame is FLU (REP-103):
x = BRF Y, y = -BRF X, z = BRF Z, i.e. ``R_brf_flu = Rz(+90°)``; so a vehicle heading north
has ENU yaw +90°.

Installation offsets (heading, pitch, roll) are the attitude of the antenna BRF relative to
the vehicle, as the ADU5's ``$PASHS,3DF,OFS`` takes them (notes §7.3: pitch 1.14°, roll -1.48°,
heading 0.00° on the report's car). The receiver removes them itself when they were uploaded;
``offsets_deg`` here is for offsets the driver must remove instead:
``R_enu_flu = R_enu_brf · R_ofs⁻¹ · R_brf_flu``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from gnss_ins_common.message_fields import UNKNOWN_VARIANCE

#: BRF -> FLU axes: a +90° turn about up.
R_BRF_FLU = Rotation.from_euler("z", 90.0, degrees=True)

#: 1-sigma accuracy at the report's ~4 m antenna separation: roll ε 0.24°, pitch κ 0.14°,
#: yaw φ 0.07° (notes §7.3, App. F.1, [Thales 2002, p. 161]) as (roll, pitch, yaw) [deg].
DEFAULT_SIGMA_RPY_DEG = (0.24, 0.14, 0.07)
#: PAT quality limits MRMS <= 5 mm, BRMS <= 4 cm (notes §7.3, [Thales 2002, p. 167]) [m].
MRMS_LIMIT_M = 0.005
BRMS_LIMIT_M = 0.04


#: scipy Euler sequence (heading, pitch, roll about Z, X, Y) per angle convention.
_SEQUENCES = {"heading_pitch_roll": "ZXY", "report_fixed_axes": "zxy"}
ANGLE_CONVENTIONS = tuple(_SEQUENCES)
DEFAULT_ANGLE_CONVENTION = "heading_pitch_roll"


def brf_rotation(
    heading_deg: float,
    pitch_deg: float,
    roll_deg: float,
    convention: str = DEFAULT_ANGLE_CONVENTION,
) -> Rotation:
    """``R_enu_brf`` from ADU5 heading, pitch, roll [deg] in one of ``ANGLE_CONVENTIONS``
    (module docstring)."""
    return Rotation.from_euler(
        _SEQUENCES[convention], [-heading_deg, pitch_deg, roll_deg], degrees=True
    )


def brf_angles(
    r_enu_brf: Rotation, convention: str = DEFAULT_ANGLE_CONVENTION
) -> tuple[float, float, float]:
    """Inverse of ``brf_rotation``: (heading in [0, 360), pitch, roll) [deg]."""
    z, x, y = r_enu_brf.as_euler(_SEQUENCES[convention], degrees=True)
    return float((-z) % 360.0), float(x), float(y)


@dataclass(frozen=True)
class AttitudeConfig:
    """How ADU5 angles become a vehicle orientation and its covariance.

    ``sigma_rpy_deg``: nominal 1-sigma of (roll, pitch, yaw) [deg]; ``offsets_deg``: installation
    offsets (heading, pitch, roll) [deg] the driver removes (zeros when the receiver does);
    ``convention``: how the angles compose, one of ``ANGLE_CONVENTIONS``.
    """

    sigma_rpy_deg: tuple[float, float, float] = DEFAULT_SIGMA_RPY_DEG
    offsets_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    mrms_limit_m: float = MRMS_LIMIT_M
    brms_limit_m: float = BRMS_LIMIT_M
    convention: str = DEFAULT_ANGLE_CONVENTION

    def __post_init__(self) -> None:
        if self.convention not in _SEQUENCES:
            raise ValueError(
                f"ADU5 angle convention {self.convention!r}: one of {', '.join(_SEQUENCES)}"
            )


@dataclass(frozen=True, slots=True)
class Orientation:
    """Vehicle orientation: quaternion (x, y, z, w) of R_enu_flu and the 3x3 covariance of the
    roll, pitch, yaw errors about the FLU axes [rad^2] (sensor_msgs/Imu convention)."""

    quat_enu_flu_xyzw: tuple[float, float, float, float]
    cov_rpy_rad2: tuple[float, ...]
    scale: float
    """Factor the nominal sigmas were multiplied by (> 1 when MRMS or BRMS exceed their limits)."""


class AttitudeConverter:
    """ADU5 BRF angles -> ``Orientation`` for a configuration."""

    def __init__(self, config: AttitudeConfig) -> None:
        """Precompute the fixed part ``R_ofs⁻¹ · R_brf_flu``."""
        self.config = config
        self._r_brf_flu = brf_rotation(*config.offsets_deg, config.convention).inv() * R_BRF_FLU
        self._var_rpy = [math.radians(s) ** 2 for s in config.sigma_rpy_deg]

    def quality_scale(self, mrms_m: float | None, brms_m: float | None) -> float:
        """Sigma multiplier: max(1, MRMS/limit, BRMS/limit); unknown values count as in limits."""
        scale = 1.0
        if mrms_m is not None:
            scale = max(scale, mrms_m / self.config.mrms_limit_m)
        if brms_m is not None:
            scale = max(scale, brms_m / self.config.brms_limit_m)
        return scale

    def convert(
        self,
        heading_deg: float,
        pitch_deg: float,
        roll_deg: float,
        mrms_m: float | None = None,
        brms_m: float | None = None,
    ) -> Orientation:
        """Orientation of the vehicle from ADU5 angles [deg] and PAT quality values [m]."""
        scale = self.quality_scale(mrms_m, brms_m)
        r_enu_flu = (
            brf_rotation(heading_deg, pitch_deg, roll_deg, self.config.convention) * self._r_brf_flu
        )
        variances = [v * scale * scale for v in self._var_rpy]
        return Orientation(_quat(r_enu_flu), _diag(variances), scale)

    def convert_heading(self, heading_deg: float) -> Orientation:
        """Orientation from a true heading alone (HDT): roll and pitch unknown."""
        r_enu_flu = brf_rotation(heading_deg, 0.0, 0.0) * R_BRF_FLU
        variances = [UNKNOWN_VARIANCE, UNKNOWN_VARIANCE, self._var_rpy[2]]
        return Orientation(_quat(r_enu_flu), _diag(variances), 1.0)


def _quat(rotation: Rotation) -> tuple[float, float, float, float]:
    x, y, z, w = rotation.as_quat(canonical=True)
    return float(x), float(y), float(z), float(w)


def _diag(values: Sequence[float]) -> tuple[float, ...]:
    return tuple(float(v) for v in np.diag(values).ravel())
