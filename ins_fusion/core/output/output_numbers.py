"""The numbers the outputs carry, from a solution row (core.output.solution), compiled in one call.

For each output tick the node (and a replay writing its bag) needs the solution's validity and
the float64 runs of nav_msgs/Odometry, sensor_msgs/NavSatFix and the ins/imu sensor_msgs/Imu
(adapters.cdr_out writes them into serialized messages). Built here in one compiled call from
the row: about 2 µs, against some 200 µs for the same numpy steps on the solution object.

Conventions (REP-103/105, nav_msgs/Odometry): pose in ``map`` = the ENU tangent plane at the
datum, orientation of base_link (FLU) in ENU, pose covariance over (x, y, z, rotation about X,
Y, Z of the parent frame), row-major 6x6; twist in base_link (FLU): velocity and its covariance
rotated into the body; angular rate bias-corrected, its variance per axis given.

``NUMBERS`` layout (float64):
- ``ODOMETRY`` (85): position (3), orientation x y z w (4), pose covariance (36), linear
  velocity FLU (3), angular velocity FLU (3), twist covariance (36); ``TRANSFORM`` its first 7;
- ``FIX`` (12): latitude, longitude [deg], ellipsoidal height [m], ENU covariance (9) [m²];
- ``IMU`` (37): orientation (4), its covariance (9) [rad²], angular velocity (3), its
  covariance (9), linear acceleration (3) = 0, its covariance (9) with [0] = -1 (none, REP-145).
"""

from __future__ import annotations

import math

import numpy as np

from gnss_ins_common.types import FloatArray
from ins_fusion.core.compiled import compilable, jit
from ins_fusion.core.layout import offsets
from ins_fusion.core.nav.rotation import mat_from_quat
from ins_fusion.core.output.solution import (
    COV_ATT,
    COV_POS,
    COV_VEL,
    HEIGHT,
    LAT,
    LON,
    NAVIGATION_FIELDS,
    POS,
    QUAT,
    RATE,
    VEL,
)

#: Layout of the outputs' numbers (core.layout): Odometry's pose (position ENU [m], orientation
#: FLU -> ENU (x, y, z, w)), its 6x6 covariance, its twist (velocity and rate in base_link FLU)
#: and 6x6 covariance; NavSatFix's latitude, longitude [deg], altitude [m] and 3x3 ENU
#: covariance [m²]; Imu's orientation, its covariance, rate, rate covariance, acceleration and
#: acceleration covariance (-1: not given).
NUMBERS_LAYOUT = (
    ("o_position", 3),
    ("o_quat", 4),
    ("o_pose_cov", 36),
    ("o_vel", 3),
    ("o_rate", 3),
    ("o_twist_cov", 36),
    ("f_position", 3),
    ("f_cov", 9),
    ("i_quat", 4),
    ("i_cov", 9),
    ("i_rate", 3),
    ("i_rate_cov", 9),
    ("i_accel", 3),
    ("i_accel_cov", 9),
)
(
    _O_POSITION,
    _O_QUAT,
    _O_POSE_COV,
    _O_VEL,
    _O_RATE,
    _O_TWIST_COV,
    _F_POSITION,
    _F_COV,
    _I_QUAT,
    _I_COV,
    _I_RATE,
    _I_RATE_COV,
    _I_ACCEL,
    _I_ACCEL_COV,
    NUMBERS,
) = offsets(NUMBERS_LAYOUT)
#: Each message's numbers, and the transform's (the pose).
ODOMETRY = slice(_O_POSITION, _F_POSITION)
TRANSFORM = slice(_O_POSITION, _O_POSE_COV)
FIX = slice(_F_POSITION, _I_QUAT)
IMU = slice(_I_QUAT, NUMBERS)

#: Relative tolerance on negative covariance eigenvalues (rounding in a PSD matrix).
PSD_TOLERANCE = 1e-9
#: Tolerance on the asymmetry of a covariance, relative to the scale of the element's row and
#: column (√(C_ii C_jj)): an off-diagonal element many orders below the variances differs from
#: its mirror by rounding of that size, not of its own.
SYMMETRY_TOLERANCE = 1e-9


#: The covariances a row's outputs carry, in the order row_fault checks them.
CHECKED_COVARIANCES = (("position", COV_POS), ("velocity", COV_VEL), ("attitude", COV_ATT))
#: What a 3x3 covariance can fail, in the order _matrix_fault checks it.
_MATRIX_FAULTS = ("not finite", "not symmetric", "not positive semi-definite")
#: row_fault's answers, by index: publishable, or the first check the row fails.
FAULTS = (
    "none",
    "a non-finite number in the state",
    *(f"{name} covariance {fault}" for name, _ in CHECKED_COVARIANCES for fault in _MATRIX_FAULTS),
)
_FIRST_COVARIANCE_FAULT = 2


@compilable
def _matrix_fault(row: FloatArray, start: int) -> int:
    """0 if the 3x3 row-major matrix at ``row[start:start + 9]`` is finite, symmetric and
    positive semi-definite up to rounding, else 1 + the index of the first of _MATRIX_FAULTS."""
    c = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            value = row[start + 3 * i + j]
            if not math.isfinite(value):
                return 1
            c[i, j] = value
    for i in range(3):
        for j in range(3):
            scale = math.sqrt(abs(c[i, i] * c[j, j]))
            if abs(c[i, j] - c[j, i]) > SYMMETRY_TOLERANCE * scale:
                return 2
    eigenvalues = np.linalg.eigvalsh(c)
    return 0 if eigenvalues.min() >= -PSD_TOLERANCE * max(1.0, eigenvalues.max()) else 3


@compilable
def row_fault(row: FloatArray) -> int:
    """Index in FAULTS of the first reason the row is not publishable (0: publishable)."""
    for start, width in NAVIGATION_FIELDS:
        for i in range(start, start + width):
            if not math.isfinite(row[i]):
                return 1
    starts = (COV_POS.start, COV_VEL.start, COV_ATT.start)
    for block in range(3):
        fault = _matrix_fault(row, starts[block])
        if fault:
            return _FIRST_COVARIANCE_FAULT + len(_MATRIX_FAULTS) * block + fault - 1
    return 0


@compilable
def publishable_row(row: FloatArray) -> bool:
    """True if every number of the row that the outputs carry is finite and each covariance
    positive semi-definite (valid or not published)."""
    return row_fault(row) == 0


def fault_report(row: FloatArray) -> str:
    """Why a row is not publishable, with the numbers that fail (for the log)."""
    fault = row_fault(row)
    if fault == 0:
        return "publishable"
    if fault == 1:
        numbers = np.concatenate([row[start : start + width] for start, width in NAVIGATION_FIELDS])
        return f"{FAULTS[fault]}: {np.array2string(numbers, precision=6)}"
    _, block = CHECKED_COVARIANCES[(fault - _FIRST_COVARIANCE_FAULT) // len(_MATRIX_FAULTS)]
    matrix = row[block].reshape(3, 3)
    text = f"{FAULTS[fault]}: {np.array2string(matrix, precision=17)}"
    if not np.isfinite(matrix).all():
        return text
    eigenvalues = np.linalg.eigvalsh(0.5 * (matrix + matrix.T))
    return f"{text}, eigenvalues {np.array2string(eigenvalues, precision=6)}"


@jit
def output_numbers(row: FloatArray, rate_variance_rad2_s2: float, out: FloatArray) -> bool:
    """Fill ``out`` (``NUMBERS``) from a solution row; False (``out`` untouched) when the row is
    not publishable. ``rate_variance_rad2_s2``: variance of each bias-corrected rate axis."""
    if not publishable_row(row):
        return False
    q = QUAT.start
    C = mat_from_quat(row[q], row[q + 1], row[q + 2], row[q + 3])  # FLU -> ENU
    out[:] = 0.0
    for i in range(3):
        out[_O_POSITION + i] = row[POS.start + i]  # position ENU
        out[_O_RATE + i] = row[RATE.start + i]
        out[_I_RATE + i] = row[RATE.start + i]
        out[_I_RATE_COV + 4 * i] = rate_variance_rad2_s2
        out[_O_TWIST_COV + 6 * (3 + i) + 3 + i] = rate_variance_rad2_s2
        v = 0.0
        for k in range(3):
            v += C[k, i] * row[VEL.start + k]
        out[_O_VEL + i] = v
    out[_F_POSITION], out[_F_POSITION + 1], out[_F_POSITION + 2] = row[LAT], row[LON], row[HEIGHT]
    for i in range(4):
        out[_O_QUAT + i] = row[q + i]
        out[_I_QUAT + i] = row[q + i]
    for i in range(3):
        for j in range(3):
            out[_O_POSE_COV + 6 * i + j] = row[COV_POS.start + 3 * i + j]
            out[_O_POSE_COV + 6 * (3 + i) + 3 + j] = row[COV_ATT.start + 3 * i + j]
            out[_F_COV + 3 * i + j] = row[COV_POS.start + 3 * i + j]
            out[_I_COV + 3 * i + j] = row[COV_ATT.start + 3 * i + j]
            # twist covariance C^T Σ C (velocity covariance in the body)
            value = 0.0
            for k in range(3):
                for m in range(3):
                    value += C[k, i] * row[COV_VEL.start + 3 * k + m] * C[m, j]
            out[_O_TWIST_COV + 6 * i + j] = value
    out[_I_ACCEL_COV] = -1.0
    return True
