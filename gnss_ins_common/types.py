"""Type aliases shared by every layer, defined once (import them from here).

Units and frames are not part of these types; each signature's docstring states them.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
"""An array of float64 values of any shape."""
IntArray = NDArray[np.int64]
"""An array of int64 values of any shape."""
BoolArray = NDArray[np.bool_]
"""An array of booleans of any shape."""
Vec3 = tuple[float, float, float]
"""Three components of a vector, x/y/z in the frame its name or docstring gives."""
Mat3 = tuple[Vec3, Vec3, Vec3]
"""A 3x3 matrix as three rows."""
Quat = tuple[float, float, float, float]
"""A unit quaternion (x, y, z, w): Hamilton, scalar last, as in scipy and ROS."""
