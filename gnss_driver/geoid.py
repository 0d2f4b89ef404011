"""EGM96 geoid undulation for altitudes given only above mean sea level (no I/O after import).

A GGA or GNS without the geoid-separation field gives the altitude above mean sea level only;
the height above the WGS-84 ellipsoid is that plus the geoid undulation N. ``undulation_m``
interpolates N bilinearly on the EGM96 15' grid in ``data/egm96_15min.npz`` (data/README.md:
source, licence, and its error against the 5' grid: RMS 0.04 m, at most 0.6 m).
"""

from __future__ import annotations

import functools
import importlib.resources

import numpy as np
import numpy.typing as npt

#: Name of the model, as the diagnostics and docs give it.
MODEL = "EGM96 15' grid"
_STEP_DEG = 0.25


@functools.cache
def _grid() -> npt.NDArray[np.float64]:
    """The undulation grid [m], rows from -90° latitude, columns from -180° longitude."""
    with (
        importlib.resources.files("gnss_driver").joinpath("data/egm96_15min.npz").open("rb") as file
    ):
        second_diff = np.load(file)["undulation_cm_d2"].astype(np.int32)
    cm = np.cumsum(np.cumsum(second_diff, axis=0), axis=1)
    return cm.astype(np.float64) / 100.0


def undulation_m(lat_deg: float, lon_deg: float) -> float:
    """EGM96 geoid height above the WGS-84 ellipsoid [m] at a position [deg]."""
    grid = _grid()
    rows, cols = grid.shape
    y = min(max((lat_deg + 90.0) / _STEP_DEG, 0.0), rows - 1.0)
    x = ((lon_deg + 180.0) % 360.0) / _STEP_DEG
    i, j = min(int(y), rows - 2), min(int(x), cols - 2)
    fy, fx = y - i, x - j
    top = grid[i, j] * (1.0 - fx) + grid[i, j + 1] * fx
    bottom = grid[i + 1, j] * (1.0 - fx) + grid[i + 1, j + 1] * fx
    return float(top * (1.0 - fy) + bottom * fy)
