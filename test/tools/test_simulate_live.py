"""`gnss_ins simulate --live`: emulated IMU400CC and GNSS receivers on pseudo-terminals, driven in
real time by the simulation, read with pyserial as the drivers read them; the truth bag lines up
with what the receivers send."""

from __future__ import annotations

import math
import subprocess
import sys
import time

import numpy as np
import pynmea2
import pytest
import serial
from support.live_ports import port_lines
from support.pacing import pause

from gnss_driver.reader import NmeaReader
from gnss_driver.sentences import ASHRPAT, lat_lon_deg
from gnss_ins_common.axes import AxisMap
from imu400cc_driver.axes import DEFAULT_AXIS_SPEC, PacketConverter
from imu400cc_driver.framer import PacketFramer
from imu400cc_driver.protocol import Scaling
from ins_fusion.bags.bag_io import BagReader

DURATION_S = 6.0


def _read(port: serial.Serial, enough: int, timeout_s: float) -> bytes:
    data = bytearray()
    deadline = time.monotonic() + timeout_s
    while len(data) < enough and time.monotonic() < deadline:
        data += port.read(max(1, port.in_waiting))
    return bytes(data)


@pytest.fixture(scope="module")
def live(tmp_path_factory: pytest.TempPathFactory):
    truth = tmp_path_factory.mktemp("live") / "truth"
    command = [sys.executable, "-m", "ins_fusion.tools.cli", "simulate", "--live"]
    command += ["--scenario=aalborg_turn", f"--duration={DURATION_S}", f"--truth-output={truth}"]
    proc = subprocess.Popen(command, stdout=subprocess.PIPE, text=True)
    try:
        ports = port_lines(proc, {"imu", "gnss", "adu5", "truth"})
        with (
            serial.Serial(ports["imu"], 38400, timeout=0.1) as imu,
            serial.Serial(ports["gnss"], 9600, timeout=0.1) as gnss,
            serial.Serial(ports["adu5"], 115200, timeout=0.1) as adu5,
        ):
            imu.write(b"C")  # continuous mode: the unit powers up polled and silent
            imu_bytes = _read(imu, 18 * 200, 8.0)
            gnss_bytes = _read(gnss, 600, 5.0)
            adu5_bytes = _read(adu5, 600, 5.0)
        tail, _ = proc.communicate(timeout=DURATION_S + 20.0)
    finally:
        proc.kill()
    assert proc.returncode == 0
    return imu_bytes, gnss_bytes, adu5_bytes, truth, tail


def test_imu_port_streams_valid_packets_of_the_simulated_drive(live):
    imu_bytes, *_ = live
    framer = PacketFramer(confirm_with_next_packet=True)
    packets = framer.feed(imu_bytes)
    assert len(packets) >= 150 and framer.stats.bad_checksums == 0
    convert = PacketConverter(Scaling(), AxisMap.from_spec(list(DEFAULT_AXIS_SPEC)), -1.0)
    measurements = [convert(p) for p in packets]
    force = np.array([m.specific_force_flu_m_s2 for m in measurements])
    assert force[:, 2].mean() == pytest.approx(9.82, abs=0.3)  # REP-145 after the driver's axes
    assert all(20.0 < m.temperature_c < 36.0 for m in measurements)
    timers = np.array([p.timer for p in packets], dtype=np.int64)
    steps = np.mod(timers[:-1] - timers[1:], 65536)
    assert np.median(steps) == pytest.approx(9411.75, abs=2)  # 134 Hz on the device timer


def test_gnss_ports_send_nmea_that_matches_the_truth_bag(live):
    _, gnss_bytes, adu5_bytes, truth, tail = live
    sentences = [r.sentence for r in NmeaReader().feed(gnss_bytes)]
    ggas = [s for s in sentences if isinstance(s, pynmea2.GGA)]
    assert ggas and all(int(s.gps_qual) == 4 for s in ggas)  # RTK fixed
    assert any(isinstance(s, pynmea2.VTG) for s in sentences)
    pats = [s for s in NmeaReader().feed(adu5_bytes) if isinstance(s.sentence, ASHRPAT)]
    assert len(pats) >= 2
    with BagReader(truth) as reader:
        assert set(reader.topics) == {
            "/ground_truth/fix",
            "/ground_truth/vel",
            "/ground_truth/attitude",
        }
        fixes = [m.message for m in reader.messages(["/ground_truth/fix"], deserialize=True)]
    stamps = np.array([f.header.stamp.sec + f.header.stamp.nanosec * 1e-9 for f in fixes])
    assert len(fixes) == pytest.approx(DURATION_S * 50, abs=2)
    assert np.diff(stamps) == pytest.approx(0.02, abs=1e-6)
    # The GGA position at its UTC second against the truth then (base_link, under the antenna):
    # same clock, same start time for emulators and truth.
    gga = ggas[-1]
    day = stamps[0] - stamps[0] % 86400.0
    ts = gga.timestamp
    utc = day + ts.hour * 3600 + ts.minute * 60 + ts.second + ts.microsecond * 1e-6
    lat, lon = lat_lon_deg(gga)
    lat_truth = np.interp(utc, stamps, [f.latitude for f in fixes])
    lon_truth = np.interp(utc, stamps, [f.longitude for f in fixes])
    north = math.radians(lat - lat_truth) * 6.36e6
    east = math.radians(lon - lon_truth) * 6.39e6 * math.cos(math.radians(lat))
    assert math.hypot(north, east) < 0.3  # RTK noise, roll in the turn; a 10 ms slip is 0.17 m
    assert "sent: imu" in tail and "truth bag" in tail


def test_hold_keeps_the_devices_open_after_the_drive_until_sigterm():
    command = [sys.executable, "-m", "ins_fusion.tools.cli", "simulate", "--live", "--hold"]
    command += ["--scenario=aalborg_turn", "--duration=2", "--no-adu5", "--gnss=none"]
    proc = subprocess.Popen(command, stdout=subprocess.PIPE, text=True)
    try:
        imu_port = port_lines(proc, {"imu"})["imu"]
        assert proc.stdout is not None
        assert proc.stdout.readline() == "drive ended\n"
        pause(1.0)  # past the drive: the process and its device are still there
        assert proc.poll() is None
        with serial.Serial(imu_port, 38400, timeout=0.1) as imu:
            imu.write(b"C")
            framer = PacketFramer(confirm_with_next_packet=True)
            packets = list(framer.feed(_read(imu, 18 * 40, 5.0)))
        assert len(packets) >= 20
        proc.terminate()
        proc.communicate(timeout=20.0)
    finally:
        proc.kill()
    assert proc.returncode == 0
