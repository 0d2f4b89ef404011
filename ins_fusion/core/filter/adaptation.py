"""What the data say about the noise: online estimates that let the filter outgrow the user's
noise values when a real vehicle is noisier than the datasheet (no ROS, no engine state).

Two estimators, each bounded below by the user's values (they are a floor, never lowered):

- ``ImuNoiseMonitor``: the white-noise density of the IMU output at a time scale the filter
  integrates it over (``block_s``, 0.05 s), from the Hadamard variance of block means. For block
  means ȳ_k over τ of white noise of density N, D_k = ȳ_k - 2ȳ_{k-1} + ȳ_{k-2} has E[D²] = 6 N²/τ,
  and a motion that changes linearly over three blocks cancels; so N² = τ E[D²]/6. Vibration
  well above 1/τ (an engine at 30-40 Hz) largely averages out in the block means as it does in
  the velocity increments the filter integrates; vibration and road noise near or below 1/τ,
  which do corrupt them, are counted. In a moving car this is 10-100 times the datasheet density
  (issue 10; the comma2k19 windshield phone: docs/accuracy.md). τ is short because real motion
  below a few hertz (turns, braking, body pitch) also passes the second difference and would be
  counted as noise: on the simulated test pattern (imu400cc, VRW 0.020 m/s/√h) τ = 0.05 s reads
  0.022, τ = 0.1 s 0.051; on the real drive τ = 0.05 s gives the smaller outage drifts
  (docs/fusion.md).
- ``WhiteNoiseMonitor``: the white (epoch-to-epoch) part of a GNSS receiver's position error
  per axis, as a share of the variance it reports, from the innovation ν_k of each fix minus
  the residual r_{k-1} the previous fix left after its update: with white errors e_k of
  variance σ², ν_k - r_{k-1} = (e_k - ε_k⁻) - (e_{k-1} - ε_{k-1}⁺) = e_k - e_{k-1} - (ε_k⁻ -
  ε_{k-1}⁺), of variance 2σ² plus the state's error growth between the fixes, which the filter
  predicts (H P⁻_k Hᵀ - H P⁺_{k-1} Hᵀ) and which is taken off, whatever the filter's gain. An RTK
  rover's centimetre noise and a stand-alone receiver's metre noise are then told apart without
  a parameter.

Both average squared differences with a time constant (``window``) and clip each new square at
``_CLIP`` times the running mean (a single jump, a pothole or a multipath outlier, cannot
dominate); both report nothing until ``_MIN_COUNT`` differences have been seen.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from gnss_ins_common.types import FloatArray
from ins_fusion.core.compiled import compilable, jit
from ins_fusion.core.filter.update_algebra import projected_variance
from ins_fusion.core.layout import offsets

#: A squared difference above this many times the running mean is clipped to it.
_CLIP = 9.0
#: Differences needed before an estimate is reported.
_MIN_COUNT = 10
#: Layout of ImuNoiseMonitor.block, all the monitor keeps (``block_push`` updates it).
B_LAYOUT = (
    ("start", 1),  # the open block's start [s] (NaN: none)
    ("sum", 6),  # its sums of ω (3) and f (3)
    ("n", 1),  # and their count
    ("tau", 1),  # the block length τ [s]
    ("prev", 2 * 6),  # the means of the last two closed blocks (older first, 6 each)
    ("held", 1),  # how many of those are held (0-2)
    ("mean", 6),  # the running mean squares (gyro 3, accelerometer 3)
    ("gyro_n", 1),  # the gyro's count
    ("accel_n", 1),  # the accelerometer's count
    ("window", 1),  # the running mean's time constant [s]
    ("version", 1),  # the estimate's version (+1 whenever ``psd`` changes)
)
(
    B_START,
    B_SUM,
    B_N,
    B_TAU,
    B_PREV,
    B_HELD,
    B_MEAN,
    B_GYRO_N,
    B_ACCEL_N,
    B_WINDOW,
    B_VERSION,
    B_SIZE,
) = offsets(B_LAYOUT)


@compilable
def push_square(
    mean: FloatArray, count: int, square: FloatArray, weight: float, window: float
) -> int:
    """Add a per-axis square (3) of ``weight`` (in the units of ``window``) to the running
    ``mean`` (3, in place) of ``count`` squares so far; returns the new count (unchanged, and
    the mean too, when a square is not finite). Plain mean for the first ``_MIN_COUNT``, then
    exponential with gain weight/window and each square clipped at ``_CLIP`` times the mean."""
    for k in range(3):
        if not math.isfinite(square[k]):
            return count
    count += 1
    if count <= _MIN_COUNT:
        for k in range(3):
            mean[k] = mean[k] + (square[k] - mean[k]) / count
        return count
    gain = min(1.0, weight / window)
    for k in range(3):
        clipped = min(square[k], _CLIP * mean[k])
        mean[k] = mean[k] + (clipped - mean[k]) * gain
    return count


class ImuNoiseMonitor:
    """White-equivalent noise density of the IMU's rate and specific force, per imu axis, at
    the filter's time scale (module docstring). Feed every sample; read ``psd``. Its numbers
    live in ``block`` (B_* layout), which the engine's compiled sample intake updates."""

    def __init__(self, block_s: float = 0.05, window_s: float = 10.0) -> None:
        """block_s: block length τ [s]; window_s: time constant of the running mean [s]."""
        self.block = np.zeros(B_SIZE)
        self.block[B_TAU] = block_s
        self.block[B_WINDOW] = window_s
        self._psd: tuple[FloatArray, FloatArray] | None = None
        self._version = 0.0
        self.reset()

    def reset(self) -> None:
        """Forget the blocks (a gap or a reset); the running estimate is kept."""
        self.block[B_START] = math.nan
        self.block[B_SUM : B_N + 1] = 0.0
        self.block[B_HELD] = 0.0

    def push(
        self,
        t_s: float,
        rate: tuple[float, float, float],
        force: tuple[float, float, float],
    ) -> None:
        """One IMU sample at t_s [s]: angular rate [rad/s] and specific force [m/s²]."""
        block_push(self.block, t_s, *rate, *force)

    @property
    def psd(self) -> tuple[FloatArray, FloatArray] | None:
        """(gyro [rad²/s], accelerometer [m²/s³]) white-noise power densities per axis, the
        squares of ARW [rad/√s] and VRW [m/s/√s]; None before enough blocks. The same
        (read-only) objects until the estimate changes."""
        block = self.block
        if block[B_VERSION] != self._version:
            return self.adopt(block[B_VERSION], block[B_MEAN : B_MEAN + 6])
        return self._psd

    def adopt(self, version: float, means: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``psd`` as read when ``block`` was at ``version`` with ``means`` (6: its B_MEAN
        numbers); later reads give it until the version changes (core.engine.sample_runs snapshots
        the estimates a compiled run went through)."""
        gyro = means[:3].copy()
        accel = means[3:6].copy()
        gyro.flags.writeable = accel.flags.writeable = False
        self._version = version
        self._psd = (gyro, accel)
        return self._psd


@jit
def block_push(
    block: FloatArray, t_s: float, wx: float, wy: float, wz: float, fx: float, fy: float, fz: float
) -> None:
    """ImuNoiseMonitor.push on its ``block`` (B_* layout): add the sample to the open block,
    closing it first when it is τ long; a closed block's mean, with the two before it, gives
    D = ȳ_k - 2ȳ_{k-1} + ȳ_{k-2} and the density τ D²/6 into the running means (module
    docstring; B_VERSION counts the estimate's changes)."""
    start = block[B_START]
    if math.isnan(start):
        block[B_START] = t_s
    elif t_s - start >= block[B_TAU] and block[B_N] > 0.0:
        tau = t_s - start
        n = block[B_N]
        means = np.empty(6)
        for k in range(6):
            means[k] = block[B_SUM + k] / n
            block[B_SUM + k] = 0.0
        block[B_N] = 0.0
        block[B_START] = t_s
        held = int(block[B_HELD])
        if held < 2:
            block[B_PREV + 6 * held : B_PREV + 6 * held + 6] = means
            block[B_HELD] = held + 1
        else:
            psd = np.empty(6)
            for k in range(6):
                d = means[k] - 2.0 * block[B_PREV + 6 + k] + block[B_PREV + k]
                psd[k] = d * d * (tau / 6.0)
            window = block[B_WINDOW]
            gyro_mean = block[B_MEAN : B_MEAN + 3]
            accel_mean = block[B_MEAN + 3 : B_MEAN + 6]
            block[B_GYRO_N] = push_square(gyro_mean, int(block[B_GYRO_N]), psd[:3], tau, window)
            block[B_ACCEL_N] = push_square(accel_mean, int(block[B_ACCEL_N]), psd[3:], tau, window)
            if block[B_GYRO_N] >= _MIN_COUNT:
                block[B_VERSION] += 1.0
            block[B_PREV : B_PREV + 6] = block[B_PREV + 6 : B_PREV + 12]
            block[B_PREV + 6 : B_PREV + 12] = means
    block[B_SUM] += wx
    block[B_SUM + 1] += wy
    block[B_SUM + 2] += wz
    block[B_SUM + 3] += fx
    block[B_SUM + 4] += fy
    block[B_SUM + 5] += fz
    block[B_N] += 1.0


#: Layout of WhiteNoiseMonitor.values, all the monitor keeps (``white_push`` updates it).
W_LAYOUT = (
    ("mean", 3),  # the running mean of the normalised squares
    ("count", 1),  # their count (``push_square``)
    ("last_t", 1),  # the previous fix's stamp [s] (NaN: none)
    ("residual", 3),  # its residual [m]
    ("updated", 3),  # its H P⁺ Hᵀ diagonal [m²]
    ("reported", 3),  # its reported variance [m²]
    ("window", 1),  # the time constant [epochs]
    ("max_interval", 1),  # the longest interval differenced [s]
)
(
    W_MEAN,
    W_COUNT,
    W_LAST_T,
    W_RESIDUAL,
    W_UPDATED,
    W_REPORTED,
    W_WINDOW,
    W_MAX_INTERVAL,
    W_SIZE,
) = offsets(W_LAYOUT)


class WhiteNoiseMonitor:
    """White share of a receiver's position variance per NED axis, from consecutive
    innovations (module docstring). Immutable (the engine keeps it in its rolled-back state):
    ``pushed`` returns the updated monitor; its numbers are ``values`` (W_* layout).

    window_epochs: time constant of the running mean [epochs]; consecutive fixes further apart
    than max_interval_s [s] (an outage, a gap) are not differenced.
    """

    __slots__ = ("values",)

    def __init__(self, window_epochs: float = 30.0, max_interval_s: float = 2.0) -> None:
        self.values = np.zeros(W_SIZE)
        self.values[W_LAST_T] = math.nan
        self.values[W_WINDOW] = window_epochs
        self.values[W_MAX_INTERVAL] = max_interval_s

    def with_values(self, values: FloatArray) -> WhiteNoiseMonitor:
        """A monitor of ``values`` (W_* layout; taken, not copied)."""
        other = WhiteNoiseMonitor.__new__(WhiteNoiseMonitor)
        other.values = values
        return other

    def pushed(
        self,
        t_s: float,
        innovation_ned_m: FloatArray,
        residual_ned_m: FloatArray,
        predicted_var_m2: FloatArray,
        updated_var_m2: FloatArray,
        reported_var_m2: FloatArray,
    ) -> WhiteNoiseMonitor:
        """With a fix at t_s [s]: its innovation (measured minus predicted, before the update)
        and residual after the update (the innovation when rejected) [m], the diagonals of
        H P Hᵀ before and after the update and the receiver's reported variance [m²], NED
        (``white_push``)."""
        values = self.values.copy()
        white_push(
            values,
            t_s,
            innovation_ned_m,
            residual_ned_m,
            predicted_var_m2,
            updated_var_m2,
            reported_var_m2,
        )
        return self.with_values(values)

    def pushed_fix(
        self,
        t_s: float,
        innovation_ned_m: FloatArray,
        H: FloatArray,
        dx: FloatArray | None,
        P: FloatArray,
        predicted_var_m2: FloatArray,
        reported_var_m2: FloatArray,
    ) -> WhiteNoiseMonitor:
        """``pushed`` for a fix's update z ≈ H δx (``dx``: the estimate, None when rejected; P
        after the update), which give the residual and the variance after it (compiled:
        ``white_push_fix``)."""
        values = self.values.copy()
        accepted = dx is not None
        estimate = dx if dx is not None else innovation_ned_m
        update = FixUpdate(innovation_ned_m, H, estimate, accepted, P)
        white_push_fix(values, t_s, update, predicted_var_m2, reported_var_m2)
        return self.with_values(values)

    def restarted(self) -> WhiteNoiseMonitor:
        """The next fix starts a new run (after a state jump); the estimate is kept."""
        values = self.values.copy()
        values[W_LAST_T] = math.nan
        return self.with_values(values)

    @property
    def ready(self) -> bool:
        """Whether enough epochs were seen for a ``share``."""
        return bool(self.values[W_COUNT] >= _MIN_COUNT)

    @property
    def share(self) -> FloatArray | None:
        """Estimated white share of the reported variance per NED axis (may exceed 1: the
        receiver reports too little); None before enough epochs."""
        if not self.ready:
            return None
        return self.values[W_MEAN : W_MEAN + 3].copy()


class FixUpdate(NamedTuple):
    """A fix's update z ≈ H δx as ``white_push_fix`` reads it."""

    innovation: FloatArray  #: z [m], NED
    H: FloatArray  #: the model's Jacobian
    dx: FloatArray  #: the estimate δx when accepted (else not read)
    accepted: bool
    P: FloatArray  #: the error covariance after the update


@jit
def white_push_fix(
    values: FloatArray,
    t_s: float,
    update: FixUpdate,
    predicted: FloatArray,
    reported: FloatArray,
) -> None:
    """``white_push`` of a fix's ``update``: the residual z - H δx (z when rejected) and
    diag(H P Hᵀ) are computed here."""
    innovation, H, dx, accepted, P = update
    residual = innovation - H @ dx if accepted else innovation.copy()
    white_push(values, t_s, innovation, residual, predicted, projected_variance(H, P), reported)


@compilable
def white_push(
    values: FloatArray,
    t_s: float,
    innovation: FloatArray,
    residual: FloatArray,
    predicted: FloatArray,
    updated: FloatArray,
    reported: FloatArray,
) -> None:
    """WhiteNoiseMonitor.pushed on its ``values`` (W_* layout, in place). The state's own error
    growth between the two fixes, H P⁻_k Hᵀ - H P⁺_{k-1} Hᵀ, which the filter predicts, is taken
    off the squared difference; the rest is divided by the two reported variances, so the share
    carries over when the fix type changes. A 2-D fix (2 rows) leaves the vertical's numbers
    as they were and pushes the vertical mean itself (no change)."""
    rows = innovation.shape[0]
    dt = t_s - values[W_LAST_T]  # NaN without a previous fix
    if 0.0 < dt <= values[W_MAX_INTERVAL]:
        square = values[W_MEAN : W_MEAN + 3].copy()
        for k in range(rows):
            growth = max(predicted[k] - values[W_UPDATED + k], 0.0)
            step = innovation[k] - values[W_RESIDUAL + k]
            excess = max(step * step - growth, 0.0)
            square[k] = excess / max(reported[k] + values[W_REPORTED + k], 1e-30)
        mean = values[W_MEAN : W_MEAN + 3]
        values[W_COUNT] = push_square(mean, int(values[W_COUNT]), square, 1.0, values[W_WINDOW])
    values[W_LAST_T] = t_s
    values[W_RESIDUAL : W_RESIDUAL + rows] = residual
    values[W_UPDATED : W_UPDATED + rows] = updated
    values[W_REPORTED : W_REPORTED + rows] = reported[:rows]


#: Weight of one normalised innovation in the running NIS mean, and of the mean's log in the
#: process-noise scale, per GNSS measurement (about 20 measurements: 1-2 s at 10 Hz).
_NIS_WEIGHT = 0.05
#: Each normalised innovation counts at most this much (an outlier is not a model error).
_NIS_CLIP = 5.0
#: Range of the process-noise scale.
Q_SCALE_RANGE = (1.0, 100.0)


def adapt_process_noise(nis_mean: float, scale: float, nis_per_dof: float) -> tuple[float, float]:
    """Running mean of the GNSS normalised innovations per degree of freedom and the factor on
    the IMU white process noise it drives, after one more measurement (NIS/dof, clipped at
    ``_NIS_CLIP``). A mean above 1 says the covariance is too small for what the data show
    (unmodelled scale factors, misalignment, vibration below the measured band): the factor
    grows by mean^w per measurement; below 1 it shrinks back towards the user's model (never
    below it). Returns (mean, scale)."""
    sample = min(nis_per_dof, _NIS_CLIP)
    mean = nis_mean + _NIS_WEIGHT * (sample - nis_mean)
    low, high = Q_SCALE_RANGE
    return mean, min(high, max(low, scale * mean**_NIS_WEIGHT))


def fading_factor(
    innovation: FloatArray, predicted: FloatArray, noise: FloatArray, target: float
) -> float:
    """Smallest λ >= 1 with zᵀ(λ H P Hᵀ + R)⁻¹ z <= target (``predicted`` = H P Hᵀ, ``noise``
    = R): the factor on the whole covariance that makes a rejected innovation fit, found by
    bisection on log λ (the NIS falls monotonically with λ). math.inf when no finite λ up to
    1e12 does (the innovation lies where H P Hᵀ has no variance)."""

    def nis(lam: float) -> float:
        try:
            return float(innovation @ np.linalg.solve(lam * predicted + noise, innovation))
        except np.linalg.LinAlgError:
            return math.inf

    if nis(1.0) <= target:
        return 1.0
    high = 1e12
    if not nis(high) <= target:
        return math.inf
    low_log, high_log = 0.0, math.log(high)
    for _ in range(40):
        mid = 0.5 * (low_log + high_log)
        if nis(math.exp(mid)) <= target:
            high_log = mid
        else:
            low_log = mid
    return math.exp(high_log)
