"""core.engine.intake.take_sample on its own: the checks of a sample (finite, in range, stamp
after the last), their codes and counters, FLU -> FRD, and the increment of an ordinary interval.

The kernel is called with the argument types the engine passes (floats, a Python bool, the
engine's arrays), so no other signature is compiled (test_compiled.py counts them)."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from ins_fusion.core.engine.intake import (
    BACK_RUN_RESET,
    FIRST,
    GAP,
    PUSHED,
    REJECTED,
    RESTART,
    S_DUPLICATES,
    S_FORCE,
    S_GAPS,
    S_IMPLAUSIBLE,
    S_LAST_T,
    S_NOMINAL_DT,
    S_OUT_OF_ORDER,
    S_RATE,
    S_SAMPLES,
    S_STEP,
    new_intake,
    put_reading,
    take_sample,
)
from ins_fusion.core.filter.adaptation import ImuNoiseMonitor
from ins_fusion.core.filter.state import X_SIZE
from ins_fusion.core.measurements.stop_detector import StopDetector
from ins_fusion.core.nav.calibration import T_SIZE
from ins_fusion.core.nav.strapdown import INCREMENT_SIZE, SampleIntegrator
from ins_fusion.core.settings.config import FusionConfig

MAX_RATE_RAD_S, MAX_FORCE_M_S2 = 5.0, 50.0
DT_S = 0.01
#: A level IMU at rest: no rate, the specific force straight up (imu_link FLU) [m/s²].
REST = ((0.0, 0.0, 0.0), (0.0, 0.0, 9.81))


class Intake:
    """The intake's stores as the engine holds them, and the engine's part of a stream start."""

    def __init__(self) -> None:
        self.buf = new_intake(MAX_RATE_RAD_S, MAX_FORCE_M_S2, False)
        self.integrator = SampleIntegrator()
        config = FusionConfig.from_parameters({})
        self.detector = StopDetector(config.stop_detector, np.eye(3))
        self.monitor = ImuNoiseMonitor()
        self.inc = np.empty(INCREMENT_SIZE)

    def take(self, t: float, rate: tuple[float, ...], force: tuple[float, ...]) -> int:
        """take_sample without the strapdown step; a first sample starts the stream as
        EngineLoop._start_stream does."""
        put_reading(self.buf, float(t), rate, force)
        self.buf[S_STEP] = 0.0
        code = take_sample(
            self.buf,
            np.zeros(T_SIZE),
            self.integrator.buffer,
            self.detector.ring,
            self.monitor.block,
            np.zeros(X_SIZE),
            np.eye(3).ravel(),
            self.inc,
        )
        if code == FIRST:
            frd = self.buf[S_RATE : S_FORCE + 3]
            self.integrator.push(t, tuple(frd[:3]), tuple(frd[3:]))
            self.buf[S_LAST_T] = t
        return int(code)

    def stream(self, n: int, rate=REST[0], force=REST[1]) -> None:
        """``n`` samples every DT_S from 0 s."""
        for k in range(n):
            self.take(k * DT_S, rate, force)


def test_first_sample_starts_the_stream_and_the_next_is_ordinary() -> None:
    intake = Intake()
    assert intake.take(0.0, *REST) == FIRST
    code = intake.take(DT_S, *REST)
    assert code >= PUSHED and code & 3 == 0  # ordinary, flags above
    assert intake.buf[S_SAMPLES] == 2.0
    assert intake.buf[S_NOMINAL_DT] == DT_S


def test_the_sample_is_stored_in_frd() -> None:
    """REP-145 FLU in, FRD stored: y and z change sign, x stays."""
    intake = Intake()
    intake.take(0.0, (0.1, 0.2, 0.3), (1.0, 2.0, 9.0))
    np.testing.assert_array_equal(intake.buf[S_RATE : S_RATE + 3], [0.1, -0.2, -0.3])
    np.testing.assert_array_equal(intake.buf[S_FORCE : S_FORCE + 3], [1.0, -2.0, -9.0])


def test_an_ordinary_interval_gives_the_increment_of_a_steady_turn() -> None:
    """A constant rate ω about up and the force of gravity over dt: the increment holds dt, the
    angle ω dt about FRD z (down: -ω dt) and the velocity change f dt (FRD)."""
    omega = 0.3
    intake = Intake()
    intake.stream(3, (0.0, 0.0, omega))
    inc = intake.inc
    assert inc[0] == DT_S
    np.testing.assert_allclose(inc[1:4], [0.0, 0.0, -omega * DT_S], atol=1e-12)
    # Rotating at ω, a constant force in the rotating frame picks up a sculling term of
    # order ω dt (below 1e-3 relative here).
    np.testing.assert_allclose(inc[4:7], [0.0, 0.0, -9.81 * DT_S], rtol=2e-3, atol=1e-12)


def test_duplicate_and_past_stamps_are_rejected_and_counted() -> None:
    intake = Intake()
    intake.stream(5)
    last = 4 * DT_S
    assert intake.take(last, *REST) == REJECTED
    assert intake.buf[S_DUPLICATES] == 1.0
    assert intake.take(last - 0.5 * DT_S, *REST) == REJECTED
    assert intake.buf[S_OUT_OF_ORDER] == 1.0
    assert intake.buf[S_LAST_T] == last  # the stream goes on from the last good sample
    assert intake.take(last + DT_S, *REST) >= PUSHED


def test_a_run_of_past_stamps_restarts_the_stream() -> None:
    """One stamp in the past is a faulty sample; BACK_RUN_RESET in a row, a clock that went
    back."""
    intake = Intake()
    intake.stream(5)
    codes = [intake.take(-1.0 + k * DT_S, *REST) for k in range(BACK_RUN_RESET)]
    assert codes[:-1] == [REJECTED] * (BACK_RUN_RESET - 1)
    assert codes[-1] == RESTART
    assert intake.buf[S_OUT_OF_ORDER] == BACK_RUN_RESET - 1


def test_a_long_interval_is_a_gap() -> None:
    """More than GAP_FACTOR (2.5) nominal intervals since the last sample: a gap; 2 are not."""
    intake = Intake()
    intake.stream(5)
    assert intake.take(6 * DT_S, *REST) >= PUSHED  # 2 intervals
    assert intake.take(9 * DT_S, *REST) == GAP  # 3 intervals
    assert intake.buf[S_GAPS] == 1.0


@settings(max_examples=50, deadline=None)
@given(axis=st.integers(0, 5), bad=st.sampled_from([math.nan, math.inf, -math.inf]))
def test_a_non_finite_value_is_a_one_sample_gap(axis: int, bad: float) -> None:
    intake = Intake()
    intake.stream(3)
    values = [0.0, 0.0, 0.0, 0.0, 0.0, 9.81]
    values[axis] = bad
    before = intake.buf.copy()
    assert intake.take(3 * DT_S, values[:3], values[3:]) == REJECTED
    assert intake.buf[S_GAPS] == before[S_GAPS] + 1.0
    assert intake.buf[S_SAMPLES] == before[S_SAMPLES]
    assert intake.buf[S_LAST_T] == before[S_LAST_T]


@settings(max_examples=100, deadline=None)
@given(axis=st.integers(0, 5), excess=st.floats(1.0001, 100.0), sign=st.sampled_from([-1, 1]))
def test_a_value_beyond_the_range_is_implausible(axis: int, excess: float, sign: int) -> None:
    """|rate| > MAX_RATE or |force| > MAX_FORCE on any axis: rejected, counted implausible and
    as a gap; at the limit itself the sample is taken."""
    limit = MAX_RATE_RAD_S if axis < 3 else MAX_FORCE_M_S2
    intake = Intake()
    intake.stream(3)
    values = [0.0, 0.0, 0.0, 0.0, 0.0, 9.81]
    values[axis] = sign * limit * excess
    assert intake.take(3 * DT_S, values[:3], values[3:]) == REJECTED
    assert intake.buf[S_IMPLAUSIBLE] == 1.0 and intake.buf[S_GAPS] == 1.0
    values[axis] = sign * limit
    assert intake.take(4 * DT_S, values[:3], values[3:]) >= PUSHED
    assert intake.buf[S_IMPLAUSIBLE] == 1.0
