"""``InsSolution`` as one row of float64 numbers, to hold many of them compactly (a replay's
tracks, the smoother's records): 54 numbers (432 bytes) against about 2 kB for the object.

Columns: t_s; lat_deg, lon_deg, height_m; pos_enu_m (3); vel_enu_m_s (3); quat_enu_flu_xyzw (4);
rate_flu_rad_s (3); cov_pos_enu_m2, cov_vel_enu, cov_att_enu_rad2 (9 each, row-major);
gyro_bias_flu_rad_s (3); accel_bias_flu_m_s2 (3); imu_mounting_rpy_rad (3, NaN = None); the
state as its index in ``STATES``. Units and frames as InsSolution.
"""

from __future__ import annotations

from array import array
from collections.abc import Sequence
from typing import overload

import numpy as np

from gnss_ins_common.types import FloatArray
from ins_fusion.core.engine import InsSolution

STATES = ("aligning", "navigating", "degraded")
T, LAT, LON, HEIGHT = 0, 1, 2, 3
POS, VEL, QUAT, RATE = slice(4, 7), slice(7, 10), slice(10, 14), slice(14, 17)
COV_POS, COV_VEL, COV_ATT = slice(17, 26), slice(26, 35), slice(35, 44)
GYRO, ACCEL, MOUNTING, STATE = slice(44, 47), slice(47, 50), slice(50, 53), 53
WIDTH = 54
_NO_MOUNTING = (np.nan, np.nan, np.nan)


def pack(solution: InsSolution) -> FloatArray:
    """The row of one solution."""
    mounting = solution.imu_mounting_rpy_rad
    return np.concatenate(
        (
            (solution.t_s, solution.lat_deg, solution.lon_deg, solution.height_m),
            solution.pos_enu_m,
            solution.vel_enu_m_s,
            solution.quat_enu_flu_xyzw,
            solution.rate_flu_rad_s,
            np.ravel(solution.cov_pos_enu_m2),
            np.ravel(solution.cov_vel_enu),
            np.ravel(solution.cov_att_enu_rad2),
            solution.gyro_bias_flu_rad_s,
            solution.accel_bias_flu_m_s2,
            _NO_MOUNTING if mounting is None else mounting,
            (STATES.index(solution.state),),
        ),
        dtype=np.float64,
    )


def unpack(row: FloatArray) -> InsSolution:
    """The solution of one row (its arrays are copies)."""
    mounting = row[MOUNTING]
    return InsSolution(
        t_s=float(row[T]),
        lat_deg=float(row[LAT]),
        lon_deg=float(row[LON]),
        height_m=float(row[HEIGHT]),
        pos_enu_m=row[POS].copy(),
        vel_enu_m_s=row[VEL].copy(),
        quat_enu_flu_xyzw=row[QUAT].copy(),
        rate_flu_rad_s=row[RATE].copy(),
        cov_pos_enu_m2=row[COV_POS].reshape(3, 3).copy(),
        cov_vel_enu=row[COV_VEL].reshape(3, 3).copy(),
        cov_att_enu_rad2=row[COV_ATT].reshape(3, 3).copy(),
        gyro_bias_flu_rad_s=row[GYRO].copy(),
        accel_bias_flu_m_s2=row[ACCEL].copy(),
        state=STATES[int(row[STATE])],
        imu_mounting_rpy_rad=None if np.isnan(mounting).any() else mounting.copy(),
    )


class RowBuffer:
    """Rows appended one at a time, 8 bytes a number (``array``), as an (n, WIDTH) array."""

    def __init__(self) -> None:
        self._data = array("d")

    def append(self, row: FloatArray) -> None:
        self._data.frombytes(np.ascontiguousarray(row, dtype=np.float64).tobytes())

    def rows(self) -> FloatArray:
        """The rows so far (a view of the buffer: append no more after taking it)."""
        return np.frombuffer(self._data, dtype=np.float64).reshape(-1, WIDTH)


class Solutions(Sequence[InsSolution]):
    """The solutions of an (n, WIDTH) array of rows, each built when asked for."""

    def __init__(self, rows: FloatArray) -> None:
        self._rows = rows

    def __len__(self) -> int:
        return len(self._rows)

    @overload
    def __getitem__(self, index: int) -> InsSolution: ...

    @overload
    def __getitem__(self, index: slice) -> Sequence[InsSolution]: ...

    def __getitem__(self, index: int | slice) -> InsSolution | Sequence[InsSolution]:
        if isinstance(index, slice):
            return Solutions(self._rows[index])
        return unpack(self._rows[index])
