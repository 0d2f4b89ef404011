"""The emulator's sentences read back through the driver core, and its corrections input (no
ROS)."""

from __future__ import annotations

import math

import pymap3d
import pytest
import serial
from scipy.spatial.transform import Rotation
from support.waiting import wait_for

from gnss_driver.attitude import R_BRF_FLU, brf_rotation
from gnss_driver.driver import DriverConfig, GnssDriver
from gnss_driver.emulated_rtk import RTK_FLOAT, STANDALONE, RoverCorrections
from gnss_driver.emulator import (
    EmulatorConfig,
    GnssEmulator,
    Truth,
    adu5_sentences,
    constant_velocity,
    leica_sentences,
)
from gnss_driver.fix_type import FixType
from gnss_driver.profiles import Receiver
from gnss_driver.reader import frame_sentence
from gnss_ins_common.rtcm import make_frame

UTC = 1_735_689_599.0  # 2024-12-31T23:59:59Z
SOUTH_WEST = Truth(-33.85, -70.675, 520.25, (-2.0, 1.0, 0.0), 296.565, 1.5, -2.25)


def _read(bodies: list[str], baud: int = 9600):
    driver = GnssDriver(DriverConfig(baud=baud))
    driver.feed(b"".join(frame_sentence(b) for b in bodies), UTC + 0.5)
    (out,) = driver.flush_idle(UTC + 2.0)
    return out, driver


def _horizontal_error_m(fix, truth: Truth) -> float:
    east, north, _ = pymap3d.geodetic2enu(
        fix.lat_deg, fix.lon_deg, truth.alt_m, truth.lat_deg, truth.lon_deg, truth.alt_m
    )
    return math.hypot(east, north)


def test_leica_epoch_round_trip_in_the_southern_western_hemispheres():
    config = EmulatorConfig(leica_extra=("GST", "RMC", "ZDA"))
    bodies = leica_sentences(UTC, SOUTH_WEST, config, fix=True)
    assert [b[2:5] for b in bodies] == ["VTG", "GGA", "LLQ", "GST", "RMC", "ZDA"]
    out, driver = _read(bodies)
    assert out.utc.utc_s == UTC
    assert out.fix.fix_type is FixType.RTK_FIXED
    assert _horizontal_error_m(out.fix, SOUTH_WEST) < 1e-3
    assert out.fix.alt_m == pytest.approx(520.25, abs=1e-3)
    assert out.fix.accuracy_source == "GST"
    assert out.velocity.vel_enu_m_s == pytest.approx((-2.0, 1.0, 0.0), abs=0.01)
    assert driver.reader.stats.sentences == 6 and not any(driver.reader.stats.rejected().values())
    assert driver.solver.fields.empty_fields == driver.solver.fields.bad_fields == 0


def test_leica_without_fix():
    out, _ = _read(leica_sentences(UTC, SOUTH_WEST, EmulatorConfig(), fix=False))
    assert out.fix.fix_type is FixType.NO_FIX and out.velocity is None
    assert out.utc.utc_s == UTC  # LLQ still dates the epoch


def test_adu5_epoch_round_trip_with_att_and_offsets():
    config = EmulatorConfig(
        receiver=Receiver.ADU5, adu5_att=True, mount_offsets_deg=(0.5, 1.0, -1.5)
    )
    bodies = adu5_sentences(UTC, SOUTH_WEST, config, (0.5, 1.0, -1.5), 0, 0.002)
    assert [b[:9] for b in bodies] == ["PASHR,PAT", "PASHR,ATT"]
    out, driver = _read(bodies, baud=115200)
    assert driver.assembler.stats.duplicate_sentences == 0  # ATT's GPS time matched PAT's UTC
    assert _horizontal_error_m(out.fix, SOUTH_WEST) < 0.2  # PAT's 4-decimal minutes
    assert out.attitude.source == "PASHR,PAT"
    # The receiver removed the mounting offsets it was told: the vehicle's own angles.
    got = Rotation.from_quat(out.attitude.orientation.quat_enu_flu_xyzw)
    want = brf_rotation(SOUTH_WEST.heading_deg, SOUTH_WEST.pitch_deg, SOUTH_WEST.roll_deg)
    assert (got * (want * R_BRF_FLU).inv()).magnitude() < math.radians(0.01)
    assert out.attitude.orientation.scale == 1.0
    no_fix = adu5_sentences(UTC, SOUTH_WEST, config, (0.0, 0.0, 0.0), 0, 0.002, fix=False)
    out, driver = _read(no_fix, baud=115200)
    assert out.fix.fix_type is FixType.NO_FIX and out.attitude is None
    assert driver.solver.stats.attitude_resets == 1


def test_constant_velocity_truth():
    truth = constant_velocity((3.0, 4.0, 0.0), start_utc_s=UTC)
    start, later = truth(UTC), truth(UTC + 10.0)
    east, north, up = pymap3d.geodetic2enu(
        later.lat_deg, later.lon_deg, later.alt_m, start.lat_deg, start.lon_deg, start.alt_m
    )
    assert (east, north, up) == pytest.approx((30.0, 40.0, 0.0), abs=1e-6)
    assert later.heading_deg == pytest.approx(math.degrees(math.atan2(3.0, 4.0)))


def test_rover_solution_follows_the_corrections():
    frames = [make_frame(bytes((0x3E, 0xD0)) + bytes(range(n))) for n in (3, 40)]  # 1005
    rover = RoverCorrections(rtk_hold_s=2.0, float_hold_s=10.0, seed=3)
    assert rover.solution(50.0, 1.0)[0] is STANDALONE  # no corrections yet
    other = rover.take(b"$PXXX,1\r\n" + frames[0] + b"noise" + frames[1][:9], 100.0)
    assert other == b"$PXXX,1\r\nnoise"
    assert rover.take(frames[1][9:], 100.5) == b""  # the rest of a frame split over two writes
    assert rover.received == b"".join(frames) and rover.frames == 2
    assert rover.solution(102.5, 1.0) == (None, (0.0, 0.0, 0.0))  # RTK fixed: the truth
    kind, error_enu_m = rover.solution(103.0, 1.0)
    assert kind is RTK_FLOAT and 0.0 < math.hypot(*error_enu_m[:2]) < 5 * RTK_FLOAT.sigma_m
    assert rover.solution(112.5, 1.0)[0] is RTK_FLOAT
    assert rover.solution(112.6, 1.0)[0] is STANDALONE


@pytest.mark.parametrize(
    ("quality", "fix_type"),
    [(4, FixType.RTK_FIXED), (5, FixType.RTK_FLOAT), (1, FixType.SPS)],
)
def test_leica_mode_letters_follow_the_quality(quality, fix_type):
    config = EmulatorConfig(leica_extra=("RMC",), fix_quality=quality)
    bodies = leica_sentences(UTC, SOUTH_WEST, config, fix=True)
    rmc_mode, vtg_mode = {4: "R", 5: "F", 1: "A"}[quality], "A" if quality == 1 else "D"
    assert bodies[-1].endswith(f",{rmc_mode}") and bodies[0].endswith(f",{vtg_mode}")
    out, _ = _read(bodies)
    assert out.fix.fix_type is fix_type


def test_emulated_rover_takes_frames_and_commands_from_its_port():
    frames = [make_frame(bytes((0x43, 0xD0)) + bytes(n)) for n in (5, 200)]  # 1085
    config = EmulatorConfig(rtk_from_corrections=True, output_latency_s=0.0)
    with GnssEmulator(config=config) as device, serial.Serial(device.path, 115200) as port:
        port.write(frames[0] + b"$PLEIC,1\r\n" + frames[1])
        assert wait_for(lambda: device.rtcm_frames == 2, 10.0)
        assert wait_for(lambda: device.commands == ["$PLEIC,1"], 10.0)
    assert device.rtcm_received == frames[0] + frames[1]
