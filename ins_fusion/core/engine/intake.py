"""The engine's intake of an IMU sample, compiled (core.compiled): checks, calibration, the
interval's increment, the stop detector's and noise monitor's sample stores, the ZARU sums and,
when nothing else is due first, the strapdown step of the nominal state, in one call.

``take_sample`` does what an ordinary sample needs and returns a code for everything else, which
core.engine.engine handles in Python: a rejected sample (non-finite, beyond the IMU's range, a
duplicate stamp, one stamp in the past), a stream that starts or restarts, and an interval long
enough to be a gap. Every counter and the per-sample scalars live in one array (S_* layout), so
the compiled code and the engine read the same numbers.

Frames: the input is imu_link FLU (REP-145); everything stored is imu FRD.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from gnss_ins_common.types import FloatArray
from ins_fusion.core.compiled import compilable, jit
from ins_fusion.core.filter.adaptation import block_push
from ins_fusion.core.filter.propagation import advance
from ins_fusion.core.layout import offsets
from ins_fusion.core.measurements.stop_detector import ring_push
from ins_fusion.core.nav.calibration import correct_sample
from ins_fusion.core.nav.strapdown import integrate_sample

#: Layout of the intake array (rates and specific forces calibrated, imu FRD).
S_LAYOUT = (
    ("last_t", 1),  # the last accepted sample's stamp [s] (NaN: none)
    ("nominal_dt", 1),  # the running nominal interval [s] (inf: none yet)
    ("last_rate", 3),  # the last accepted sample's rate [rad/s]
    ("last_force", 3),  # its specific force [m/s²]
    ("zaru_sum", 3),  # sum of the rates since the pseudo-measurement interval began (ZARU)
    ("zaru_n", 1),  # their count
    ("samples", 1),  # counter: samples taken
    ("gaps", 1),  # counter: gaps
    ("duplicates", 1),  # counter: duplicates
    ("out_of_order", 1),  # counter: out of order
    ("implausible", 1),  # counter: beyond range
    ("back_run", 1),  # stamps back in a row
    ("max_rate", 1),  # range limit of the rate [rad/s] (imu_link FLU, as received)
    ("max_force", 1),  # range limit of the specific force [m/s²] (likewise)
    ("calibrated", 1),  # 1.0 when a calibration table applies
    ("rate", 3),  # the sample just taken: rate [rad/s]
    ("force", 3),  # the sample just taken: specific force [m/s²]
    ("reading_t", 1),  # the sample to take (``take_sample``'s input): stamp [s]
    ("reading_rate", 3),  # its rate [rad/s], imu_link FLU, as received
    ("reading_force", 3),  # its specific force [m/s²], imu_link FLU, as received
    ("step", 1),  # 1.0: advance the nominal state with it
)
(
    S_LAST_T,
    S_NOMINAL_DT,
    S_LAST_RATE,
    S_LAST_FORCE,
    S_ZARU_SUM,
    S_ZARU_N,
    S_SAMPLES,
    S_GAPS,
    S_DUPLICATES,
    S_OUT_OF_ORDER,
    S_IMPLAUSIBLE,
    S_BACK_RUN,
    S_MAX_RATE,
    S_MAX_FORCE,
    S_CALIBRATED,
    S_RATE,
    S_FORCE,
    S_READING_T,
    S_READING_RATE,
    S_READING_FORCE,
    S_STEP,
    S_SIZE,
) = offsets(S_LAYOUT)

#: ``take_sample`` results below PUSHED: nothing more to do (the sample was counted and
#: dropped), the stream restarts with this sample (a run of stamps in the past), it starts with
#: this sample, the interval is a gap (counted; the engine bridges it).
REJECTED, RESTART, FIRST, GAP, PUSHED = 0, 1, 2, 3, 4
#: Flags added to PUSHED (and returned by ``record_sample``): the stop detector's ring is full,
#: the nominal state was advanced.
RING_FULL, STEPPED = 8, 16

#: An IMU interval longer than this many nominal intervals is a gap (bridged, counted).
GAP_FACTOR = 2.5
#: IMU samples stamped before the last one, in a row, that make a new stream (a reset); fewer
#: are skipped one by one.
BACK_RUN_RESET = 10


class IntakeStores(NamedTuple):
    """The arrays ``take_sample`` reads and writes besides the nominal state."""

    buf: FloatArray  #: the intake array (S_* layout)
    table: FloatArray  #: the calibration table (core.nav.calibration T_* layout)
    integrator: FloatArray  #: core.nav.strapdown.SampleIntegrator.buffer
    ring: FloatArray  #: the stop detector's sample ring (core.measurements.stop_detector)
    block: FloatArray  #: the IMU noise monitor's block (core.filter.adaptation B_* layout)


def new_intake(max_rate_rad_s: float, max_force_m_s2: float, calibrated: bool) -> FloatArray:
    """A fresh intake array (S_* layout) with its limits; no sample yet."""
    buf = np.zeros(S_SIZE)
    buf[S_MAX_RATE], buf[S_MAX_FORCE] = max_rate_rad_s, max_force_m_s2
    buf[S_CALIBRATED] = 1.0 if calibrated else 0.0
    forget_stream(buf)
    return buf


def forget_stream(buf: FloatArray) -> None:
    """No last sample, no nominal interval, no ZARU sums (start, reset); counters kept."""
    buf[S_LAST_T] = math.nan
    buf[S_NOMINAL_DT] = math.inf
    buf[S_LAST_RATE : S_LAST_RATE + 3] = 0.0
    buf[S_LAST_FORCE : S_LAST_FORCE + 3] = 0.0
    clear_zaru(buf)


@compilable
def start_pseudo_interval(buf: FloatArray, t: float, period_s: float) -> float:
    """A pseudo-measurement interval starts at ``t`` [s]: the ZARU sums in ``buf`` cleared;
    returns the stamp of its epoch, the next multiple of ``period_s`` after ``t`` [s]."""
    clear_zaru(buf)
    return (math.floor(t / period_s) + 1.0) * period_s


@compilable
def clear_zaru(buf: FloatArray) -> None:
    """No rates summed for the ZARU in the intake array ``buf`` (S_ZARU_SUM, S_ZARU_N)."""
    buf[S_ZARU_SUM : S_ZARU_SUM + 3] = 0.0
    buf[S_ZARU_N] = 0.0


@compilable
def put_reading(
    buf: FloatArray,
    t: float,
    rate: Sequence[float] | FloatArray,
    force: Sequence[float] | FloatArray,
) -> None:
    """The sample to take next into the intake array ``buf``: stamp [s], rate [rad/s] and
    specific force [m/s²] (imu_link FLU, as received)."""
    buf[S_READING_T] = t
    for k in range(3):
        buf[S_READING_RATE + k] = rate[k]
        buf[S_READING_FORCE + k] = force[k]


@jit
def take_sample(
    buf: FloatArray,
    table: FloatArray,
    integrator: FloatArray,
    ring: FloatArray,
    block: FloatArray,
    x: FloatArray,
    r_bi: FloatArray,
    inc: FloatArray,
) -> int:
    """Take the sample in S_READING_* of the intake array ``buf``: the checks and counters,
    the calibration (``table``: core.nav.calibration T_* layout, when S_CALIBRATED), FLU -> FRD
    into S_RATE/S_FORCE; for an ordinary interval the increment into ``inc`` (``integrator``:
    strapdown.SampleIntegrator.buffer), ``record_sample`` (``ring``, ``block``: the stop
    detector's and noise monitor's stores) and, with S_STEP set, the nominal state ``x``
    advanced (core.filter.propagation.advance; ``r_bi`` imu -> body). Returns a code (module
    constants) plus flags."""
    t = buf[S_READING_T]
    wx, wy, wz = buf[S_READING_RATE], buf[S_READING_RATE + 1], buf[S_READING_RATE + 2]
    fx, fy, fz = buf[S_READING_FORCE], buf[S_READING_FORCE + 1], buf[S_READING_FORCE + 2]
    if not math.isfinite(t + wx + wy + wz + fx + fy + fz):
        buf[S_GAPS] += 1.0  # a corrupt sample is a one-sample gap
        return REJECTED
    if (
        max(abs(wx), abs(wy), abs(wz)) > buf[S_MAX_RATE]
        or max(abs(fx), abs(fy), abs(fz)) > buf[S_MAX_FORCE]
    ):
        buf[S_GAPS] += 1.0  # beyond what the unit can measure: corrupt, a one-sample gap
        buf[S_IMPLAUSIBLE] += 1.0
        return REJECTED
    last = buf[S_LAST_T]
    code = PUSHED
    if t <= last:  # False while there is no last sample (NaN)
        if t == last:
            buf[S_DUPLICATES] += 1.0
            return REJECTED
        # One sample in the past is a fault of that sample (skipped); a run of them is the
        # clock that went back (a restarted recording, a reset device): start again.
        buf[S_BACK_RUN] += 1.0
        if buf[S_BACK_RUN] < BACK_RUN_RESET:
            buf[S_OUT_OF_ORDER] += 1.0
            return REJECTED
        code = RESTART
    buf[S_BACK_RUN] = 0.0
    buf[S_SAMPLES] += 1.0
    if buf[S_CALIBRATED] != 0.0:
        wx, wy, wz, fx, fy, fz = correct_sample(table, wx, wy, wz, fx, fy, fz)
    wy, wz, fy, fz = -wy, -wz, -fy, -fz  # FLU -> FRD
    buf[S_RATE], buf[S_RATE + 1], buf[S_RATE + 2] = wx, wy, wz
    buf[S_FORCE], buf[S_FORCE + 1], buf[S_FORCE + 2] = fx, fy, fz
    if code == RESTART:
        return RESTART
    if math.isnan(last):
        return FIRST
    dt = t - last
    nominal = buf[S_NOMINAL_DT]
    if dt > GAP_FACTOR * nominal:
        buf[S_GAPS] += 1.0
        return GAP
    integrate_sample(integrator, t, (wx, wy, wz, fx, fy, fz), inc)
    buf[S_NOMINAL_DT] = dt if nominal == math.inf else nominal + 0.01 * (dt - nominal)
    flags = record_sample(buf, ring, block, t)
    if buf[S_STEP] != 0.0:
        advance(x, inc, r_bi, False, t)
        flags += STEPPED
    return code + flags


@jit
def record_sample(buf: FloatArray, ring: FloatArray, block: FloatArray, t: float) -> int:
    """The sample in S_RATE/S_FORCE, stamped ``t`` [s], becomes the last one; into the stop
    detector's ring (core.measurements.stop_detector.ring_push), the noise monitor's block
    (core.filter.adaptation.block_push) and the ZARU sums. Returns the RING_FULL flag."""
    wx, wy, wz = buf[S_RATE], buf[S_RATE + 1], buf[S_RATE + 2]
    fx, fy, fz = buf[S_FORCE], buf[S_FORCE + 1], buf[S_FORCE + 2]
    buf[S_LAST_T] = t
    buf[S_LAST_RATE : S_LAST_RATE + 3] = buf[S_RATE : S_RATE + 3]
    buf[S_LAST_FORCE : S_LAST_FORCE + 3] = buf[S_FORCE : S_FORCE + 3]
    flags = 0
    if ring_push(ring, t, wx, wy, wz, fx, fy, fz):
        flags += RING_FULL
    block_push(block, t, wx, wy, wz, fx, fy, fz)
    buf[S_ZARU_SUM] += wx
    buf[S_ZARU_SUM + 1] += wy
    buf[S_ZARU_SUM + 2] += wz
    buf[S_ZARU_N] += 1.0
    return flags
