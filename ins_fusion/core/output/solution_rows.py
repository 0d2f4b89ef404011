"""``InsSolution`` as one row of float64 numbers, to hold many of them compactly (a replay's
tracks, the smoother's records): 63 numbers (504 bytes) against about 2 kB for the object.
The columns (T, LAT, ... WIDTH) are those of core.output.solution, which builds the rows.
"""

from __future__ import annotations

from array import array
from collections.abc import Sequence
from typing import overload

import numpy as np

from gnss_ins_common.types import FloatArray
from ins_fusion.core.output.solution import (
    ACCEL,
    COV_ATT,
    COV_ATT_IMU,
    COV_POS,
    COV_VEL,
    GYRO,
    HEIGHT,
    LAT,
    LON,
    MOUNTING,
    POS,
    QUAT,
    RATE,
    STATE,
    STATES,
    VEL,
    WIDTH,
    InsSolution,
    T,
    unpack,
)

__all__ = [
    "ACCEL",
    "COV_ATT",
    "COV_ATT_IMU",
    "COV_POS",
    "COV_VEL",
    "GYRO",
    "HEIGHT",
    "LAT",
    "LON",
    "MOUNTING",
    "POS",
    "QUAT",
    "RATE",
    "STATE",
    "STATES",
    "VEL",
    "WIDTH",
    "RowBuffer",
    "Solutions",
    "T",
    "pack",
    "unpack",
]
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
            np.ravel(
                solution.cov_att_enu_rad2
                if solution.cov_att_imu_enu_rad2 is None
                else solution.cov_att_imu_enu_rad2
            ),
        ),
        dtype=np.float64,
    )


class RowBuffer:
    """Rows appended as they come, 8 bytes a number (``array``), as an (n, WIDTH) array."""

    def __init__(self) -> None:
        self._data = array("d")

    def append(self, rows: FloatArray) -> None:
        """A row (WIDTH,) or rows (m, WIDTH), in order."""
        self._data.frombytes(np.ascontiguousarray(rows, dtype=np.float64).tobytes())

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
