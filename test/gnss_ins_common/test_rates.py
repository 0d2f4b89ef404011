"""gnss_ins_common.rates.RateMeter: a rate over a window, not over one diagnostics period."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from gnss_ins_common.rates import RATE_WINDOW_S, RateMeter


def test_a_1_hz_receiver_read_every_second_is_1_hz_whatever_its_phase():
    """Epochs at k + 0.999 s read every second at whole seconds: per period the count is 0, 1 or
    2 by a few ms of jitter; over the window it is 1 Hz within the window's resolution."""
    meter = RateMeter(0.0)
    epochs = [k + 0.999 + (0.002 if k % 3 == 0 else 0.0) for k in range(60)]
    rates = []
    for now in range(1, 60):
        count = sum(t <= now for t in epochs)
        rates.append((now, meter.rate_hz(count, float(now)), meter.settled(float(now))))
    settled = [rate for now, rate, ok in rates if ok]
    assert settled and all(abs(rate - 1.0) <= 1.0 / RATE_WINDOW_S for rate in settled)
    assert [now for now, _, ok in rates if not ok] == list(range(1, int(RATE_WINDOW_S)))


@given(st.floats(0.5, 300.0), st.floats(0.1, 2.0))
def test_a_steady_rate_is_measured_exactly(rate_hz: float, period_s: float):
    meter = RateMeter(0.0)
    for k in range(1, 40):
        now = k * period_s
        measured = meter.rate_hz(round(rate_hz * now * 1000), now)
        assert abs(measured - rate_hz * 1000) <= 1.0 / min(now, RATE_WINDOW_S) + 1e-6 * rate_hz


def test_a_zero_window_is_the_rate_since_the_previous_reading():
    meter = RateMeter(0.0, window_s=0.0)
    assert meter.rate_hz(100, 1.0) == 100.0
    assert meter.rate_hz(100, 2.0) == 0.0  # a gap shows at once
    assert meter.rate_hz(234, 3.0) == 134.0  # and so does the return
