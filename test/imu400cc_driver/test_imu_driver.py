"""ImuDriver, the ROS-free IMU400CC driver core: bytes and receive times in, stamped imu_link
samples out (no rclpy, no serial port)."""

from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from support.imu_strategies import int16s

from gnss_ins_common.axes import AxisMap
from gnss_ins_common.rates import IMU400CC_RATE_HZ
from imu400cc_driver.axes import PacketConverter
from imu400cc_driver.device_clock import PACKET_TRANSMISSION_S
from imu400cc_driver.driver import DriverConfig, ImuDriver, ImuSample
from imu400cc_driver.protocol import PACKET_LENGTH, RawPacket, Scaling, encode_packet

START_S = 1.7e9  # an epoch-sized host clock
#: Timer step per packet [counts] (notes §2.6).
STEP = 9412


def _packets(rates: list[tuple[int, int, int]], first_timer: int = 41606) -> list[RawPacket]:
    """Packets with these rates, fixed accelerations and temperature, timer counting down."""
    return [
        RawPacket(r, (100, -200, 10923), 1514, (first_timer - STEP * i) % 65536)
        for i, r in enumerate(rates)
    ]


def _feed(
    driver: ImuDriver,
    packets: list[RawPacket],
    cuts: list[int],
    start_s: float = START_S,
    period_s: float = 1.0 / IMU400CC_RATE_HZ,
) -> list[ImuSample]:
    """Packet i sampled at ``start_s + i * period_s``, its bytes on a 38400-baud wire right after;
    the stream read in chunks cut at ``cuts`` [bytes], each received when its last byte arrived."""
    wire = b"".join(encode_packet(p) for p in packets)
    byte_s = 10 / 38400

    def arrival_s(index: int) -> float:
        packet, byte = divmod(index, PACKET_LENGTH)
        return start_s + packet * period_s + (byte + 1) * byte_s

    bounds = [0, *sorted({c for c in cuts if 0 < c < len(wire)}), len(wire)]
    return [
        sample
        for a, b in itertools.pairwise(bounds)
        for sample in driver.feed(wire[a:b], arrival_s(b - 1))
    ]


@settings(max_examples=60, deadline=None, derandomize=True)
@given(
    st.lists(st.tuples(int16s, int16s, int16s), min_size=2, max_size=60),
    st.lists(st.integers(0, 60 * PACKET_LENGTH), max_size=40),
)
def test_any_chunking_gives_every_packet_once_in_imu_link_with_sample_stamps(rates, cuts):
    config = DriverConfig(temperature_rate_hz=IMU400CC_RATE_HZ / 4)
    driver = ImuDriver(config)
    packets = _packets(rates)
    samples = _feed(driver, packets, cuts)

    convert = PacketConverter(config.scaling, config.axis_map, config.accel_sign)
    expected = [convert(p) for p in packets]
    assert len(samples) == len(packets) == driver.stats.samples
    for sample, meas in zip(samples, expected, strict=True):
        assert np.array_equal(sample.measurement.rate_flu_rad_s, meas.rate_flu_rad_s)
        assert np.array_equal(
            sample.measurement.specific_force_flu_m_s2, meas.specific_force_flu_m_s2
        )
        assert sample.measurement.timer == meas.timer
    stamps = np.array([s.stamp_s for s in samples])
    assert np.all(np.diff(stamps) > 0)
    # A packet is read at the latest with the next one (which confirms the first) and 17 bytes
    # of the one after: a period and 17 byte times late, less its wire time (7.2 ms); then the
    # earlier reads pull the envelope down. Early only by the nominal tick's 27 ppm (steps of
    # 9412 counts, 9411.75 nominal) over the packets of one read.
    error = stamps - (START_S + np.arange(len(packets)) / IMU400CC_RATE_HZ)
    late_s = 1 / IMU400CC_RATE_HZ + 17 * 10 / 38400 - PACKET_TRANSMISSION_S
    assert np.all(error > -2e-5) and np.all(error < late_s + 1e-6)
    assert [s.with_temperature for s in samples] == [(k + 1) % 4 == 0 for k in range(len(rates))]
    assert driver.stats.last_temperature_c == pytest.approx(expected[-1].temperature_c)
    counters = driver.counters()
    assert counters["packets"] == len(packets)
    assert counters["dropped_packets"] == counters["bad_checksums"] == 0


def test_scaling_axes_sign_and_gravity_come_from_the_config():
    packets = _packets([(1000, -2000, 3000)] * 3)
    config = DriverConfig(
        scaling=Scaling(gyro_range_dps=200.0, accel_range_g=4.0),
        axis_map=AxisMap.from_spec(["y", "x", "-z"]),
        accel_sign=1.0,
        gravity_m_s2=9.81,
    )
    sample = _feed(ImuDriver(config), packets, [])[0]
    dps_per_count, g_per_count = 200.0 * 1.5 / 2**15, 4.0 * 1.5 / 2**15  # (D-3), (D-2)
    rate = np.radians([-2000 * dps_per_count, 1000 * dps_per_count, -3000 * dps_per_count])
    force = np.array([-200, 100, -10923]) * g_per_count * 9.81
    assert sample.measurement.rate_flu_rad_s == pytest.approx(rate)
    assert sample.measurement.specific_force_flu_m_s2 == pytest.approx(force)


@pytest.mark.parametrize("baud", [38400, 9600])
def test_the_first_stamp_is_the_receive_time_minus_wire_time_and_latency(baud):
    driver = ImuDriver(DriverConfig(baud=baud, latency_s=2e-3))
    wire = b"".join(encode_packet(p) for p in _packets([(0, 0, 0)] * 2))
    (first, second) = driver.feed(wire, 50.0)
    # Both share the read's time; the first is the device step (1/134 s) before the second.
    assert second.stamp_s == pytest.approx(50.0 - PACKET_LENGTH * 10 / baud - 2e-3)
    assert first.stamp_s == pytest.approx(second.stamp_s - STEP / 9411.75 / IMU400CC_RATE_HZ)
    assert PACKET_LENGTH * 10 / 38400 == PACKET_TRANSMISSION_S


def test_noise_variances_are_the_report_sigmas_squared():
    driver = ImuDriver(DriverConfig())
    # (7.14) per-sample sigmas at 134 Hz (notes §1.3), through densities rounded to 1e-9.
    assert np.sqrt(driver.gyro_variance) == pytest.approx([0.0041, 0.0040, 0.0048], rel=1e-4)
    assert np.sqrt(driver.accel_variance) == pytest.approx([0.0029, 0.0038, 0.0036], rel=1e-4)
    custom = ImuDriver(DriverConfig(gyro_noise_density=(1e-3, 2e-3, 3e-3)))
    assert custom.gyro_variance == pytest.approx([1e-6 * k * k * 134.0 for k in (1, 2, 3)])


def test_polled_mode_takes_each_answer_at_once_and_counts_no_drops():
    config = DriverConfig(continuous=False, poll_rate_hz=5.0, temperature_rate_hz=1.0)
    driver = ImuDriver(config)
    assert driver.temperature_every == 5 and config.sample_rate_hz == 5.0
    timers = [(41606 - round(k * 0.2 / 0.793e-6)) % 65536 for k in range(12)]  # 5 Hz polls
    samples: list[ImuSample] = []
    for k, timer in enumerate(timers):
        answer = encode_packet(dataclasses.replace(_packets([(0, 0, 0)])[0], timer=timer))
        got = driver.feed(answer, 10.0 + 0.2 * k + PACKET_TRANSMISSION_S)
        assert len(got) == 1  # no next packet to wait for
        samples += got
    assert [s.with_temperature for s in samples] == [(k + 1) % 5 == 0 for k in range(12)]
    assert driver.clock.dropped_packets == 0 and driver.clock.timer_gaps == 11


def test_continuous_mode_waits_for_the_packet_that_confirms_the_first():
    driver = ImuDriver(DriverConfig())
    wire = [encode_packet(p) for p in _packets([(0, 0, 0)] * 3)]
    assert driver.feed(wire[0], 1.0) == []
    assert len(driver.feed(wire[1], 1.0075)) == 2
    assert len(driver.feed(wire[2], 1.015)) == 1  # in sync: its timer step fits


def test_lost_packets_and_garbage_are_counted():
    packets = _packets([(0, 0, 0)] * 12)
    driver = ImuDriver(DriverConfig())
    kept = packets[:4] + packets[6:]  # two packets lost on the line
    samples = _feed(driver, kept, [40, 100])
    samples += driver.feed(b"\x01\x02\x03", START_S + 1.0)
    assert len(samples) == 10
    counters = driver.counters()
    assert counters["dropped_packets"] == 2
    assert counters["skipped_bytes"] == 3
    assert counters["clock_resets"] == 0 and counters["wraps_taken_back"] == 0


def test_reset_forgets_the_partial_packet_and_starts_a_new_device_time():
    driver = ImuDriver(DriverConfig())
    before = _feed(driver, _packets([(0, 0, 0)] * 5), [])
    driver.feed(encode_packet(_packets([(0, 0, 0)])[0])[:10], START_S + 0.1)
    driver.reset()
    # The unit restarted: another timer phase, 30 s later; nothing counted as lost.
    after = _feed(driver, _packets([(0, 0, 0)] * 5, first_timer=123), [], START_S + 30.0)
    assert len(before) == len(after) == 5 and driver.stats.samples == 10
    assert after[-1].stamp_s == pytest.approx(START_S + 30.0 + 4 / IMU400CC_RATE_HZ, abs=1e-4)
    counters = driver.counters()
    assert counters["dropped_packets"] == 0 and counters["clock_resets"] == 1
    assert counters["skipped_bytes"] == 10
    assert not math.isnan(driver.stats.last_temperature_c)
