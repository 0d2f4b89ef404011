"""EnvelopeClockSync: accuracy on synthetic 134 Hz streams (test/support/clock_streams.py), and
hull invariants (hypothesis)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from support.clock_streams import Stream, simulate

from gnss_ins_common import clock_sync
from gnss_ins_common.clock_sync import EnvelopeClockSync
from imu400cc_driver.device_clock import PACKET_TRANSMISSION_S


def _feed(sync: EnvelopeClockSync, stream: Stream) -> np.ndarray:
    """Update with every packet, return each packet's mapped time right after its update."""
    mapped = np.empty(stream.receive_s.size)
    host = stream.receive_s - PACKET_TRANSMISSION_S
    for k, (device, received) in enumerate(
        zip(stream.device_s.tolist(), host.tolist(), strict=True)
    ):
        sync.update(device, received)
        mapped[k] = sync.to_host(device)
    return mapped


# ---- accuracy on synthetic streams ---------------------------------------------------------
@pytest.mark.parametrize("drift_ppm", [100.0, -100.0])
@pytest.mark.parametrize(
    ("window_s", "drift_tolerance_ppm"),
    [(60.0, 3.0), (5.0, 10.0)],  # a short window refills its hull often, but fits less time
)
def test_recovers_sample_times_and_drift(drift_ppm, window_s, drift_tolerance_ppm):
    stream = simulate(90.0, drift_ppm, seed=round(window_s) + (drift_ppm > 0))
    sync = EnvelopeClockSync(window_s=window_s)
    error = _feed(sync, stream) - stream.sample_host_s
    assert np.abs(error[stream.seconds() > 5.0]).max() < 0.2e-3
    assert sync.skew * 1e6 == pytest.approx(drift_ppm, abs=drift_tolerance_ppm)
    assert sync.ready and sync.resets == 0
    assert sync.points == np.count_nonzero(stream.device_s >= stream.device_s[-1] - window_s)
    assert 0.0 < sync.mean_delay_s < sync.jitter_s < 10e-3


def test_follows_a_drift_change_within_a_window():
    stream = simulate(120.0, 100.0, seed=7, drift_after_ppm=-50.0)
    sync = EnvelopeClockSync(window_s=20.0)
    error = _feed(sync, stream) - stream.sample_host_s
    assert sync.skew * 1e6 == pytest.approx(-50.0, abs=3.0)
    assert np.abs(error[stream.seconds() > stream.seconds()[-1] - 20.0]).max() < 0.2e-3


def test_offset_only_until_ready_then_the_line():
    sync = EnvelopeClockSync(min_points=3)
    with pytest.raises(RuntimeError):
        sync.to_host(0.0)
    assert math.isnan(sync.offset_s) and sync.skew == 0.0 and not sync.ready
    sync.update(10.0, 110.5)
    assert sync.to_host(12.0) == 112.5 and sync.offset_s == 100.5
    sync.update(11.0, 111.5 - 1e-3)  # the lowest delay so far, no slope yet
    assert sync.to_host(12.0) == pytest.approx(112.5 - 1e-3) and sync.skew == 0.0
    assert not sync.ready
    sync.update(13.0, 113.5)
    assert sync.ready and sync.points == 3
    assert sync.skew == pytest.approx(0.5e-3)  # the edge (11, 100.499)-(13, 100.5) spans 11.33
    assert sync.to_host(13.0) == pytest.approx(113.5)
    assert sync.offset_s == pytest.approx(100.499 - 11 * 0.5e-3)


def test_repeated_sensor_time_keeps_the_first_pair():
    sync = EnvelopeClockSync()
    sync.update(1.0, 5.0)
    sync.update(1.0, 4.0)
    assert sync.points == 1 and sync.to_host(1.0) == 5.0 and sync.resets == 0


@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_rejects_non_finite_input(bad):
    with pytest.raises(ValueError):
        EnvelopeClockSync().update(bad, 1.0)
    with pytest.raises(ValueError):
        EnvelopeClockSync().update(1.0, bad)


# ---- invariants ----------------------------------------------------------------------------
def test_no_update_rebuilds_the_window(monkeypatch):
    """The hull's front chain is rebuilt a few points per update: over three 60 s windows of a
    134 Hz stream no update pushes more than the rebuild's steps, the new point on the back and
    on the next back (the whole window was once pushed in one update: 7-33 ms of the serial
    reader's time a minute), and the line is still the window's lowest support."""
    pushes = [0]
    push = clock_sync._LowerChain.push

    def counted(chain: clock_sync._LowerChain, p: tuple[float, float]) -> tuple:
        pushes[0] += 1
        return push(chain, p)

    monkeypatch.setattr(clock_sync._LowerChain, "push", counted)
    stream = simulate(200.0, 100.0, seed=3)
    sync = EnvelopeClockSync(window_s=60.0)
    host = stream.receive_s - PACKET_TRANSMISSION_S
    most = 0
    for device, received in zip(stream.device_s.tolist(), host.tolist(), strict=True):
        pushes[0] = 0
        sync.update(device, received)
        most = max(most, pushes[0])
    assert most <= clock_sync.REBUILD_STEPS + 2
    inside = stream.device_s >= stream.device_s[-1] - 60.0
    x, d = stream.device_s[inside], host[inside] - stream.device_s[inside]
    line = np.array([sync.to_host(s) for s in x.tolist()]) - x
    assert np.all(line <= d + 1e-9) and sync.points == x.size
    assert sync.mean_delay_s == pytest.approx(float(np.mean(d - line)), abs=1e-9)


def _best_supporting_value(x: np.ndarray, d: np.ndarray, x_at: float) -> float:
    """Brute force: the highest value at ``x_at`` of a line through two points below all."""
    i, j = np.triu_indices(x.size, 1)
    slope = (d[j] - d[i]) / (x[j] - x[i])
    lines = d[i, None] + slope[:, None] * (x[None, :] - x[i, None])
    below_all = np.all(lines <= d[None, :] + 1e-12, axis=1)
    return float(np.max((d[i] + slope * (x_at - x[i]))[below_all]))


steps = st.lists(
    st.tuples(
        st.floats(1e-3, 1.0),  # sensor-time step [s]
        st.floats(0.0, 0.05),  # receive delay [s]
    ),
    min_size=1,
    max_size=40,
)


@settings(max_examples=150, deadline=None, derandomize=True)
@given(
    steps,
    st.floats(-1e-3, 1e-3),
    st.floats(0.5, 5.0),
    st.floats(-1e3, 1e3),
    st.integers(1, 8),
)
def test_line_is_the_lowest_envelope_of_the_window(pairs, skew, window_s, start_s, min_points):
    sync = EnvelopeClockSync(window_s=window_s, min_points=min_points, max_jump_s=2.0)
    sensor = start_s + np.cumsum([dx for dx, _ in pairs])
    host = 30.0 + (1.0 + skew) * sensor + np.array([delay for _, delay in pairs])
    since_first = sensor - sensor[0]  # the window is [newest - window_s, newest], as the class
    for k in range(sensor.size):  # computes it (relative to the first point)
        sync.update(float(sensor[k]), float(host[k]))
        inside = slice(int(np.searchsorted(since_first, since_first[k] - window_s)), k + 1)
        x, d = sensor[inside], host[inside] - sensor[inside]
        line = np.array([sync.to_host(float(s)) for s in x]) - x
        assert sync.points == x.size and sync.ready == (x.size >= min_points)
        assert np.all(line <= d + 1e-9)  # never above a point of the window
        x_mean = float(x.mean())
        if x.size < max(min_points, 2):
            best = float(d.min())  # offset only, through the lowest point
        else:  # the supporting line with the least mean distance to the points
            best = _best_supporting_value(x - x[0], d, x_mean - x[0])
        assert sync.to_host(x_mean) - x_mean == pytest.approx(best, abs=1e-9)
        assert sync.mean_delay_s == pytest.approx(float(np.mean(d - line)), abs=1e-9)
        assert sync.jitter_s**2 == pytest.approx(float(np.mean((d - line) ** 2)), abs=1e-14)


@settings(max_examples=100, deadline=None, derandomize=True)
@given(steps, st.floats(-0.5, 0.5), st.floats(1e-4, 0.1))
def test_a_skew_limit_keeps_the_line_under_the_window_at_a_plausible_slope(pairs, trend, max_skew):
    """Delays that shrink or grow for a while (a backlog read out) tilt the free line; the
    limited one keeps its slope within ``max_skew`` and is the same line when the free one is."""
    limited = EnvelopeClockSync(min_points=2, max_skew=max_skew)
    free = EnvelopeClockSync(min_points=2)
    sensor = np.cumsum([dx for dx, _ in pairs])
    host = 30.0 + (1.0 + trend) * sensor + np.array([delay for _, delay in pairs])
    for k in range(sensor.size):
        limited.update(float(sensor[k]), float(host[k]))
        free.update(float(sensor[k]), float(host[k]))
        mapped = np.array([limited.to_host(float(x)) for x in sensor[: k + 1]])
        assert np.all(mapped <= host[: k + 1] + 1e-9)
        assert abs(limited.skew) <= max_skew
        if abs(free.skew) <= max_skew:
            assert limited.to_host(float(sensor[k])) == free.to_host(float(sensor[k]))


def test_a_backlog_read_out_does_not_tilt_a_limited_line():
    # 1 s of 134 Hz packets arriving 200 ms late at first, on time at the end: a sender that
    # fell behind and catches up. The free line takes it for a clock 20 % slow.
    sensor = np.arange(134) / 134
    host = 50.0 + sensor + np.linspace(0.2, 0.0, sensor.size)
    limited = EnvelopeClockSync(min_points=10, max_skew=0.02)
    free = EnvelopeClockSync(min_points=10)
    for x, h in zip(sensor.tolist(), host.tolist(), strict=True):
        limited.update(x, h)
        free.update(x, h)
    assert free.skew == pytest.approx(-0.2, rel=0.01)
    assert limited.skew == -0.02
    assert limited.to_host(1.0) == pytest.approx(host[-1] + (1 - 0.02) / 134)  # the newest


@settings(max_examples=100, deadline=None, derandomize=True)
@given(steps, st.floats(1e-6, 100.0), st.floats(0.0, 1.0))
def test_backwards_step_or_jump_restarts(pairs, back_s, host_s):
    sync = EnvelopeClockSync(max_jump_s=10.0)
    sensor = np.cumsum([dx for dx, _ in pairs])
    for s, (_, delay) in zip(sensor.tolist(), pairs, strict=True):
        sync.update(s, s + delay)
    assert sync.resets == 0
    sync.update(float(sensor[-1]) - back_s, host_s)
    assert sync.resets == 1 and sync.points == 1
    assert sync.to_host(float(sensor[-1]) - back_s) == pytest.approx(host_s)
    sync.update(float(sensor[-1]) + 10.0 + back_s, host_s)  # a jump of over max_jump_s
    assert sync.resets == 2 and sync.points == 1
    sync.reset()
    assert sync.resets == 3 and sync.points == 0 and not sync.ready
