"""The emulated rover's side of RTCM 3 corrections: which solution the frames it got allow.

A rover holds an RTK fixed solution while corrections keep arriving, falls back to RTK float
when they stop (its ambiguities age) and to a standalone (SPS) solution after that. The position
error of a float or standalone solution is a first-order Gauss-Markov process per axis with a
seeded RNG, so a run is repeatable; an RTK fixed position is the truth (the error is reset).
"""

from __future__ import annotations

import math
import random
import threading
from dataclasses import dataclass

from gnss_ins_common.rtcm import RtcmFramer


@dataclass(frozen=True)
class SolutionKind:
    """A solution without fixed ambiguities: GGA quality, LLQ coordinate quality [m] and the
    1-sigma of the position error per horizontal axis (vertical 1.5 times) [m]."""

    quality: int
    coordinate_quality_m: float
    sigma_m: float


RTK_FLOAT = SolutionKind(5, 0.3, 0.2)
STANDALONE = SolutionKind(1, 3.0, 1.5)
#: Correlation time of the float and standalone position errors [s].
POSITION_ERROR_TAU_S = 30.0
_AXIS_SCALE = (1.0, 1.0, 1.5)  # east, north, up


class RoverCorrections:
    """Valid frames out of the bytes written to the rover, and the solution they allow: RTK fixed
    while the last frame arrived at most ``rtk_hold_s`` ago, RTK float for ``float_hold_s`` after
    that, then standalone (also before the first frame). Thread-safe."""

    def __init__(self, rtk_hold_s: float, float_hold_s: float, seed: int = 0) -> None:
        """Hold times [s]; ``seed`` of the position errors."""
        self.rtk_hold_s = rtk_hold_s
        self.float_hold_s = float_hold_s
        self._lock = threading.Lock()
        self._framer = RtcmFramer()
        self._received = bytearray()
        self._last_frame_s = -math.inf
        self._rng = random.Random(seed)
        self._error_enu_m = (0.0, 0.0, 0.0)

    @property
    def received(self) -> bytes:
        """The whole valid frames received, in order."""
        with self._lock:
            return bytes(self._received)

    @property
    def frames(self) -> int:
        """Valid frames received."""
        with self._lock:
            return self._framer.stats.frames

    def reset(self) -> None:
        """Forget a partial frame (a new port)."""
        with self._lock:
            self._framer.reset()

    def take(self, data: bytes, now_s: float) -> bytes:
        """Bytes written to the rover at host time ``now_s`` [s]: keeps the valid frames and
        returns the other bytes (commands), in order."""
        other = bytearray()
        with self._lock:
            frames = self._framer.feed(data, other)
            for frame in frames:
                self._received += frame
            if frames:
                self._last_frame_s = now_s
        return bytes(other)

    def solution(
        self, now_s: float, step_s: float
    ) -> tuple[SolutionKind | None, tuple[float, float, float]]:
        """The solution at host time ``now_s`` [s] (None: RTK fixed) and its position error ENU
        [m], advanced by ``step_s`` [s] since the last call."""
        with self._lock:
            since_s = now_s - self._last_frame_s
        if since_s <= self.rtk_hold_s:
            self._error_enu_m = (0.0, 0.0, 0.0)
            return None, self._error_enu_m
        kind = RTK_FLOAT if since_s <= self.rtk_hold_s + self.float_hold_s else STANDALONE
        decay = math.exp(-step_s / POSITION_ERROR_TAU_S)
        drive = math.sqrt(1.0 - decay * decay) * kind.sigma_m
        east, north, up = (
            decay * error + drive * scale * self._rng.gauss()
            for error, scale in zip(self._error_enu_m, _AXIS_SCALE, strict=True)
        )
        self._error_enu_m = (east, north, up)
        return kind, self._error_enu_m
