"""Engine/road vibration of the simulated IMU (ins_fusion/sim/vibration.py): per-sample σ of
the profiles, band-limited spectrum, speed scaling, seeding, any sample times, and the
`gnss_ins simulate --vibration` bag and live paths."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import signal

from imu400cc_driver.emulator import SentPacket
from ins_fusion.bags import topics as T  # noqa: N812
from ins_fusion.bags.bag_io import BagReader
from ins_fusion.sim import vibration
from ins_fusion.sim.drive import Simulation, SimulationConfig
from ins_fusion.sim.live import LiveImu
from ins_fusion.sim.vibration import (
    CAR,
    NONE,
    ROUGH,
    Vibration,
    equivalent_density,
    speed_factor,
    vibration_sigma,
)
from ins_fusion.tools import cli

RATE_HZ = 134.0
#: Ten minutes at the IMU400CC rate.
T_LONG = np.arange(round(600 * RATE_HZ)) / RATE_HZ


def _record(vib: vibration.VibrationProfile, speed: float, seed: int = 1) -> np.ndarray:
    """(n, 6) gyro then accel vibration of T_LONG at a constant speed."""
    rate, force = Vibration(vib, RATE_HZ, seed).sample(T_LONG, speed)
    return np.hstack([rate, force])


@pytest.mark.parametrize("vib", [CAR, ROUGH])
def test_per_sample_sigma_is_the_profile_at_the_reference_speed(vib):
    values = _record(vib, vib.reference_speed_m_s)
    expected = np.concatenate(vibration_sigma(vib, vib.reference_speed_m_s))
    assert values.std(axis=0) == pytest.approx(expected, rel=0.04)
    assert np.all(np.abs(values.mean(axis=0)) < 0.02 * expected)  # zero-mean (band-pass)
    assert expected == pytest.approx(np.concatenate([vib.gyro_sigma_rad_s, vib.accel_sigma_m_s2]))


def test_car_profile_is_a_car_on_a_road():
    """The windshield phone of the comma2k19 fixture (its README): accel σ 0.58/0.37/0.52
    m/s², gyro 0.0072/0.0186/0.0029 rad/s at 8-20 m/s."""
    gyro, accel = vibration_sigma(CAR, 15.0)
    assert accel == pytest.approx([0.58, 0.37, 0.52], rel=0.01)
    assert gyro == pytest.approx([0.0072, 0.0186, 0.0029], rel=0.01)
    rough_gyro, rough_accel = vibration_sigma(ROUGH, 15.0)
    assert rough_accel == pytest.approx(2 * accel) and rough_gyro == pytest.approx(2 * gyro)


def test_spectrum_is_band_limited_with_road_and_body_bands():
    values = _record(CAR, 15.0)
    freq, psd = signal.welch(values, fs=RATE_HZ, nperseg=4096, axis=0)
    total = psd.sum(axis=0)
    outside = psd[(freq < 0.25) | (freq > 50.0)].sum(axis=0)
    assert np.all(outside < 0.005 * total)
    road = psd[(freq >= 0.5) & (freq < 5.0)].sum(axis=0) / total
    fractions = np.repeat([CAR.gyro_road_fraction, CAR.accel_road_fraction], 3)
    assert road == pytest.approx(fractions, abs=0.04)
    # The equivalent density is the mean two-sided PSD level over the band (Welch: one-sided).
    in_band = (freq >= 0.5) & (freq <= 40.0)
    density = np.concatenate(equivalent_density(CAR, 15.0, RATE_HZ))
    assert np.sqrt(psd[in_band].mean(axis=0) / 2.0) == pytest.approx(density, rel=0.06)


def test_equivalent_density_is_sigma_over_sqrt_bandwidth():
    gyro, accel = equivalent_density(CAR, 15.0, RATE_HZ)
    # Two Butterworth bands 0.5-5 and 5-40 Hz: B ≈ 2 x 39.5 Hz (a little more for the skirts).
    bandwidth = (np.array(CAR.accel_sigma_m_s2) / accel) ** 2
    assert bandwidth == pytest.approx(np.full(3, 79.0), rel=0.05)
    assert (np.array(CAR.gyro_sigma_rad_s) / gyro) ** 2 == pytest.approx(bandwidth)
    assert equivalent_density(CAR, 0.0, RATE_HZ)[1] == pytest.approx(0.1 * accel)
    assert not np.any(np.concatenate(equivalent_density(NONE, 15.0, RATE_HZ)))


def test_amplitude_scales_with_speed_and_idles_at_standstill():
    reference = np.concatenate(vibration_sigma(CAR, 15.0))
    assert _record(CAR, 0.0).std(axis=0) == pytest.approx(0.1 * reference, rel=0.04)
    assert _record(CAR, 30.0).std(axis=0) == pytest.approx(1.9 * reference, rel=0.04)
    assert speed_factor(CAR, [0.0, 15.0, -15.0, 30.0]) == pytest.approx([0.1, 1.0, 1.0, 1.9])
    # A speed per sample: the amplitude follows it.
    speed = np.where(T_LONG < 300.0, 0.0, 20.0)
    _, force = Vibration(CAR, RATE_HZ, 2).sample(T_LONG, speed)
    still, moving = force[T_LONG < 299.0].std(axis=0), force[T_LONG > 301.0].std(axis=0)
    assert moving / still == pytest.approx(np.full(3, speed_factor(CAR, 20.0) / 0.1), rel=0.1)


def test_none_is_exactly_zero():
    rate, force = Vibration(NONE, RATE_HZ, 0).sample(T_LONG[:500], 20.0)
    assert rate.shape == force.shape == (500, 3)
    assert not np.any(rate) and not np.any(force)


def test_seeds_reproduce_and_blocks_do_not_matter():
    t = T_LONG[:4000]
    whole = np.hstack(Vibration(CAR, RATE_HZ, 5).sample(t, 12.0))
    assert np.array_equal(whole, np.hstack(Vibration(CAR, RATE_HZ, 5).sample(t, 12.0)))
    assert not np.allclose(whole, np.hstack(Vibration(CAR, RATE_HZ, 6).sample(t, 12.0)))
    split = Vibration(CAR, RATE_HZ, 5)
    blocks = [
        np.hstack(split.sample(t[i : i + k], 12.0)) for i, k in ((0, 1), (1, 999), (1000, 3000))
    ]
    assert np.array_equal(np.vstack(blocks), whole)
    seeded = np.random.SeedSequence(5)
    from_sequence = np.hstack(Vibration(CAR, RATE_HZ, seeded).sample(t, 12.0))
    assert np.array_equal(from_sequence, whole)


def test_irregular_times_interpolate_the_grid():
    t = T_LONG[:2000]
    grid = np.hstack(Vibration(CAR, RATE_HZ, 3).sample(t, 15.0))
    # The first sample fixes where the stream starts: keep it.
    kept = np.random.default_rng(0).choice(np.arange(1, len(t)), 1500, replace=False)
    dropped = np.sort(np.append(kept, 0))
    assert np.array_equal(
        np.hstack(Vibration(CAR, RATE_HZ, 3).sample(t[dropped], 15.0)), grid[dropped]
    )
    midpoints = (t[:-1] + t[1:]) / 2.0
    between = np.hstack(Vibration(CAR, RATE_HZ, 3).sample(midpoints, 15.0))
    assert between == pytest.approx((grid[:-1] + grid[1:]) / 2.0, abs=1e-12)


def test_samples_one_at_a_time_denser_than_the_grid_need_no_new_grid_point():
    # The live IMU emulator asks for one sample per call; two calls inside one grid interval
    # (a device clock a little faster than the grid) need no new grid value.
    t = np.arange(40) * 0.4 / RATE_HZ
    whole = np.hstack(Vibration(CAR, RATE_HZ, 4).sample(t, 10.0))
    single = Vibration(CAR, RATE_HZ, 4)
    one_by_one = np.vstack([np.hstack(single.sample([ti], 10.0)) for ti in t])
    assert np.array_equal(one_by_one, whole)


def test_decreasing_times_and_unknown_profiles_are_errors():
    vib = Vibration(CAR, RATE_HZ, 0)
    vib.sample([1.0, 2.0], 10.0)
    with pytest.raises(ValueError, match="decrease"):
        vib.sample([1.5], 10.0)
    with pytest.raises(ValueError, match="decrease"):
        Vibration(CAR, RATE_HZ, 0).sample([2.0, 1.0], 10.0)
    with pytest.raises(ValueError, match=r"unknown vibration profile 'bumpy'.*car"):
        vibration.profile("bumpy")
    with pytest.raises(ValueError, match="unknown vibration profile"):
        Simulation(SimulationConfig(duration_s=1.0, vibration="bumpy"))
    with pytest.raises(SystemExit) as exit_info:
        cli.main(["simulate", "--vibration=bumpy", "--output=unused"])
    assert exit_info.value.code == 2


@settings(max_examples=40, deadline=None)
@given(
    start=st.floats(-1e4, 1e4),
    steps=st.lists(st.floats(0.0, 0.5), min_size=1, max_size=300),
    speed=st.floats(0.0, 60.0),
    rate_hz=st.sampled_from([50.0, 134.0, 500.0]),
    seed=st.integers(0, 2**32 - 1),
)
def test_any_monotonic_times_give_finite_vibration_of_the_right_shape(
    start, steps, speed, rate_hz, seed
):
    t = start + np.cumsum(steps)
    rate, force = Vibration(ROUGH, rate_hz, seed).sample(t, speed)
    assert rate.shape == force.shape == (len(t), 3)
    assert np.all(np.isfinite(rate)) and np.all(np.isfinite(force))
    limit = 12.0 * np.concatenate(vibration_sigma(ROUGH, speed))  # Gaussian: far below 12 σ
    assert np.all(np.abs(np.hstack([rate, force])) <= limit)


#: A few seconds of the 60 km/h drive, IMU only.
CONFIG = SimulationConfig(
    scenario="aalborg_turn", duration_s=6.0, gnss=None, adu5=False, seed=3, vibration="car"
)


def _imu_values(messages: list) -> np.ndarray:
    return np.array(
        [
            [
                m.angular_velocity.x,
                m.angular_velocity.y,
                m.angular_velocity.z,
                m.linear_acceleration.x,
                m.linear_acceleration.y,
                m.linear_acceleration.z,
            ]
            for m in messages
        ]
    )


def _without_vibration() -> np.ndarray:
    """The same drive, seed and IMU errors without vibration."""
    quiet = Simulation(dataclasses.replace(CONFIG, vibration="none"))
    return _imu_values(
        [e.message for e in quiet.imu_events(0.0, CONFIG.duration_s) if e.topic == T.IMU_DATA]
    )


def test_simulate_vibration_car_writes_a_vibrating_imu(tmp_path, capsys):
    path = tmp_path / "drive"
    args = ["simulate", "--scenario=aalborg_turn", "--duration=6", "--gnss=none", "--no-adu5"]
    assert cli.main([*args, "--seed=3", "--vibration=car", f"--output={path}"]) == 0
    assert "vibration car" in capsys.readouterr().out
    with BagReader(path) as reader:
        imu = [m.message for m in reader.messages(deserialize=True) if m.topic == T.IMU_DATA]
    assert len(imu) == 6 * 134
    # Same seed: the other error sources are unchanged, the difference is the vibration.
    difference = _imu_values(imu) - _without_vibration()
    speed = float(np.linalg.norm(Simulation(CONFIG).vehicle.imu(np.array([3.0])).vel_ned_m_s))
    assert speed == pytest.approx(60 / 3.6, rel=0.01)
    expected = np.concatenate(vibration_sigma(CAR, speed))
    assert difference.std(axis=0) == pytest.approx(expected, rel=0.15)


def test_live_source_sees_the_same_vibration_as_the_bag():
    simulation = Simulation(CONFIG)
    live = LiveImu(simulation, start_s=0.0, offset_s=0.0)
    t = np.arange(134 * 2) / 134.0
    samples = [live(float(device_s)) for device_s in t]
    live_values = np.array([np.concatenate(sample) for sample in samples])
    bag = Simulation(CONFIG)
    truth = bag.vehicle.imu(t)
    speed = np.linalg.norm(truth.vel_ned_m_s, axis=1)
    rate, force = bag.vibration.sample(t, speed)
    expected = bag.imu_model.apply(
        t, truth.rate_flu_rad_s + rate, truth.specific_force_flu_m_s2 + force
    )
    assert live_values == pytest.approx(np.hstack(expected), abs=1e-9)
    quiet = Simulation(dataclasses.replace(CONFIG, vibration="none")).imu_model
    without = quiet.apply(t, truth.rate_flu_rad_s, truth.specific_force_flu_m_s2)
    vibrating = np.std(live_values - np.hstack(without), axis=0)
    assert np.all(vibrating > 0.5 * np.concatenate(vibration_sigma(CAR, 60 / 3.6)))


def test_live_source_offset_is_measured_on_the_first_sample_of_a_late_batch():
    """A late emulator thread asks for 20 samples, then writes them: the offset measured on the
    first packet is its own (sample time - device time); the next sample time comes after the
    last one (an offset measured against the batch's last sample went back by the batch)."""
    live = LiveImu(Simulation(CONFIG), start_s=1000.0, offset_s=0.0)
    device_s = 5.0 + np.arange(21) / 134.0
    for d in device_s[:20]:
        live(float(d))
    live.on_packet(SentPacket(0, 1000.0 + 0.01 + device_s[0], 1000.2))
    assert live.offset_s == pytest.approx(0.01, abs=1e-9)
    live(float(device_s[20]))  # sample time 0.01 s later than asked: still increasing
