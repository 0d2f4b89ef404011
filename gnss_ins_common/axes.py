"""Signed axis permutations between a device's own axes and a REP-103 frame (no ROS, no I/O).

A strapdown unit's axes are usually a signed permutation of the body frame: ``AxisMap`` turns
device-axis vectors into the target frame and back, and carries a device's per-axis calibration
terms (bias, sign-dependent scale factors, cross-axis matrices) over with them.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Final

import numpy as np
from numpy.typing import ArrayLike, NDArray

_AXIS_NAMES: Final = "xyz"
_AXIS_TERM: Final = re.compile(r"([+-]?)([xyz])")


@dataclass(frozen=True, slots=True)
class AxisMap:
    """Signed permutation: FLU axis i = ``signs[i]`` * device axis ``indices[i]``."""

    indices: tuple[int, int, int]
    signs: tuple[float, float, float]

    def __post_init__(self) -> None:
        if sorted(self.indices) != [0, 1, 2] or any(s not in (1.0, -1.0) for s in self.signs):
            raise ValueError(f"not a signed permutation: {self.indices!r}, {self.signs!r}")

    @classmethod
    def from_spec(cls, spec: Sequence[str]) -> AxisMap:
        """Parse e.g. ``["x", "-y", "-z"]``: spec[i] is the device axis (optionally signed) that
        is FLU axis i. Exactly three terms, each of x, y, z once; ValueError otherwise."""
        if isinstance(spec, str) or len(spec) != 3:
            raise ValueError(f"axis spec needs three terms like ['x', '-y', '-z'], got {spec!r}")
        matches = [_AXIS_TERM.fullmatch(str(term).strip().lower()) for term in spec]
        axes = {m.group(2) for m in matches if m is not None}
        if None in matches or len(axes) != 3:
            raise ValueError(
                f"axis spec {list(spec)!r}: each of x, y, z exactly once, optionally signed + or -"
            )
        (i0, s0), (i1, s1), (i2, s2) = (
            (_AXIS_NAMES.index(m.group(2)), -1.0 if m.group(1) == "-" else 1.0)
            for m in matches
            if m is not None
        )
        return cls(indices=(i0, i1, i2), signs=(s0, s1, s2))

    @property
    def spec(self) -> tuple[str, str, str]:
        """The canonical spec, e.g. ``("x", "-y", "-z")``."""
        s0, s1, s2 = (
            ("-" if sign < 0 else "") + _AXIS_NAMES[index]
            for index, sign in zip(self.indices, self.signs, strict=True)
        )
        return (s0, s1, s2)

    @property
    def matrix(self) -> NDArray[np.float64]:
        """3x3 matrix M with ``v_flu = M @ v_device``."""
        matrix = np.zeros((3, 3))
        matrix[[0, 1, 2], list(self.indices)] = self.signs
        return matrix

    @property
    def proper(self) -> bool:
        """True for a rotation (det +1). A reflection is only right for a left-handed device
        frame, which App. B.5 (y left, z down) would imply against §7.4 (notes §12 item 2)."""
        return bool(np.linalg.det(self.matrix) > 0)

    def to_flu(self, vec: ArrayLike) -> NDArray[np.float64]:
        """Device-axis vector(s), shape (..., 3), in imu_link FLU axes."""
        device = _as_vectors(vec)
        flu: NDArray[np.float64] = device[..., list(self.indices)] * np.asarray(self.signs)
        return flu

    def from_flu(self, vec: ArrayLike) -> NDArray[np.float64]:
        """Inverse of to_flu: FLU vector(s), shape (..., 3), in device axes."""
        flu = _as_vectors(vec)
        device = np.empty_like(flu)
        device[..., list(self.indices)] = flu * np.asarray(self.signs)
        return device

    def permute_to_flu(self, vec: ArrayLike) -> NDArray[np.float64]:
        """Per-axis magnitudes (noise densities, σ), shape (..., 3), onto the FLU axes: the
        permutation without the signs."""
        device = _as_vectors(vec)
        flu: NDArray[np.float64] = device[..., list(self.indices)]
        return flu

    def scale_pair_to_flu(
        self, positive: ArrayLike, negative: ArrayLike, sign: float = 1.0
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Scale-factor errors for positive and negative device input, shape (3,), as the FLU
        axes see them when the output is also multiplied by ``sign`` (±1, e.g. an accelerometer
        that reports minus the specific force): a FLU axis that reads minus its device axis
        takes the device's negative-input value for its positive input, and vice versa."""
        pos, neg = self.permute_to_flu(positive), self.permute_to_flu(negative)
        flipped = np.asarray(self.signs) * sign < 0.0
        return np.where(flipped, neg, pos), np.where(flipped, pos, neg)

    def matrix_to_flu(self, matrix: ArrayLike) -> NDArray[np.float64]:
        """A 3x3 device-axis linear map (misalignment, g-sensitivity) in FLU axes: M A Mᵀ."""
        m = self.matrix
        flu: NDArray[np.float64] = m @ np.asarray(matrix, dtype=np.float64) @ m.T
        return flu


def _as_vectors(vec: ArrayLike) -> NDArray[np.float64]:
    array = np.asarray(vec, dtype=np.float64)
    if array.ndim == 0 or array.shape[-1] != 3:
        raise ValueError(f"expected 3-vectors (shape (..., 3)), got shape {array.shape}")
    return array
