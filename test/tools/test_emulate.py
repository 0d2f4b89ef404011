"""`gnss_ins emulate`: the IMU400CC, Leica and ADU5 emulated on pseudo-terminals at fixed link
paths play one simulated drive together, read with pyserial as the drivers read them; ``--only``
runs some of them; ``--write-config`` writes the parameter files before the ports appear."""

from __future__ import annotations

import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pynmea2
import pytest
import serial
from support.live_ports import port_lines
from support.waiting import wait_for

from gnss_driver.reader import NmeaReader
from gnss_driver.sentences import ASHRPAT
from gnss_ins_common.axes import AxisMap
from imu400cc_driver.axes import DEFAULT_AXIS_SPEC, PacketConverter
from imu400cc_driver.framer import PacketFramer
from imu400cc_driver.protocol import Scaling
from ins_fusion.runtime.vehicle_nodes import VEHICLE

pytestmark = pytest.mark.slow

#: The figure-eight of 120 s (ins_fusion.sim.scenarios): 10 s standing, 10 s accelerating to
#: 10 m/s, then a left circle of 40 m radius whose yaw rate ramps in over 1.5 s from 20 s on [s].
STANDING_S = (1.0, 9.0)
TURN_IN_S = (16.0, 26.0)
CIRCLE_S = (22.0, 26.0)
BAUD = {"imu": 38400, "leica": 9600, "adu5": 115200}
IMU_RATE_HZ = 134.0


def _emulate(*args: str) -> subprocess.Popen[str]:
    command = [sys.executable, "-m", "ins_fusion.tools.cli", "emulate", *args]
    return subprocess.Popen(command, stdout=subprocess.PIPE, text=True)


def _stop(proc: subprocess.Popen[str]) -> str:
    """SIGTERM, as a user's kill: the run ends with status 0 and says what it sent."""
    proc.terminate()
    tail, _ = proc.communicate(timeout=30.0)
    assert proc.returncode == 0
    return tail


class Port:
    """A device read as its driver reads it, on a thread: every chunk with its host time."""

    def __init__(self, path: str, baud: int) -> None:
        self.serial = serial.Serial(path, baud, timeout=0.05)
        self.chunks: list[tuple[float, bytes]] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self) -> None:
        while not self._stop.is_set():
            data = self.serial.read(max(1, self.serial.in_waiting))
            if data:
                self.chunks.append((time.time(), data))

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5.0)
        self.serial.close()

    def data(self) -> bytes:
        return b"".join(chunk for _, chunk in list(self.chunks))


def _utc_s(sentence: pynmea2.NMEASentence, near_s: float) -> float:
    """The sentence's UTC time of day on the day of host time ``near_s`` [s since 1970]."""
    ts = sentence.timestamp
    of_day = ts.hour * 3600 + ts.minute * 60 + ts.second + ts.microsecond * 1e-6
    day = near_s - near_s % 86400.0
    return day + of_day + 86400.0 * round((near_s - day - of_day) / 86400.0)


def _imu(port: Port) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Host receive times [s], angular rates and specific forces (FLU, SI) of the packets."""
    framer = PacketFramer(confirm_with_next_packet=True)
    convert = PacketConverter(Scaling(), AxisMap.from_spec(list(DEFAULT_AXIS_SPEC)), -1.0)
    times, rates, forces = [], [], []
    for received_s, chunk in list(port.chunks):
        for packet in framer.feed(chunk):
            m = convert(packet)
            times.append(received_s)
            rates.append(m.rate_flu_rad_s)
            forces.append(m.specific_force_flu_m_s2)
    assert framer.stats.bad_checksums == 0
    return np.array(times), np.array(rates), np.array(forces)


def _pat_headings(port: Port, near_s: float) -> tuple[np.ndarray, np.ndarray]:
    """UTC times [s] and unwrapped headings [rad] of the ADU5's PAT sentences."""
    pats = [r.sentence for r in NmeaReader().feed(port.data()) if isinstance(r.sentence, ASHRPAT)]
    utc = np.array([_utc_s(p, near_s) for p in pats])
    return utc, np.unwrap(np.radians([float(p.heading) for p in pats]))


def _leica_speeds(port: Port) -> tuple[np.ndarray, np.ndarray]:
    """Host receive times [s] and VTG ground speeds [m/s] of the Leica's epochs."""
    reader, times, speeds = NmeaReader(), [], []
    for received_s, chunk in list(port.chunks):
        for read in reader.feed(chunk):
            if isinstance(read.sentence, pynmea2.VTG):
                times.append(received_s)
                speeds.append(float(read.sentence.spd_over_grnd_kmph) / 3.6)
    return np.array(times), np.array(speeds)


@pytest.fixture(scope="module")
def drive(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, object]]:
    """The three devices of a figure-eight read from its start until 2 s past TURN_IN_S."""
    tmp = tmp_path_factory.mktemp("emulate")
    links = {device: str(tmp / device) for device in BAUD}
    config = tmp / "config"
    proc = _emulate(
        "--scenario=figure_eight",
        "--duration=120",
        "--seed=3",
        f"--write-config={config}",
        *(f"--{device}-link={link}" for device, link in links.items()),
    )
    ports: dict[str, Port] = {}
    try:
        printed = port_lines(proc, {"imu", "gnss", "adu5"})
        start_s = time.time()  # the drive started a little earlier: the windows have margins
        config_files = sorted(p.name for p in config.iterdir())
        ports = {device: Port(link, BAUD[device]) for device, link in links.items()}
        ports["imu"].serial.write(b"C")  # continuous mode: the unit powers up polled and silent

        def past_the_turn_in() -> bool:  # the ADU5 has reported past it
            utc, _ = _pat_headings(ports["adu5"], start_s)
            return bool(len(utc)) and utc[-1] > start_s + TURN_IN_S[1] + 2.0

        wait_for(past_the_turn_in, 120.0, poll_s=0.5)
    finally:
        for port in ports.values():
            port.close()
        tail = _stop(proc)
    yield {
        "printed": printed,
        "links": links,
        "start_s": start_s,
        "ports": ports,
        "config_files": config_files,
        "tail": tail,
    }


def test_each_device_is_at_its_link_path_and_the_config_is_written_first(drive):
    assert drive["printed"] == {
        "imu": drive["links"]["imu"],
        "gnss": drive["links"]["leica"],
        "adu5": drive["links"]["adu5"],
    }
    assert drive["config_files"] == sorted(spec.config for spec in VEHICLE)
    assert "sent: imu" in drive["tail"] and "leica" in drive["tail"] and "adu5" in drive["tail"]


def test_the_imu_and_the_adu5_turn_together(drive):
    """Over a window that holds the start of the first circle, the heading the ADU5 reports
    turns by what the IMU's yaw rate integrates to: the devices play one drive, in step (a
    time offset of 0.2 s between them would leave 0.05 rad)."""
    start_s = drive["start_s"]
    times, rates, _ = _imu(drive["ports"]["imu"])
    standing = (times > start_s + STANDING_S[0]) & (times < start_s + STANDING_S[1])
    bias = rates[standing, 2].mean()  # gyro bias and earth rate
    window = (times > start_s + TURN_IN_S[0]) & (times < start_s + TURN_IN_S[1])
    assert window.sum() > 0.9 * IMU_RATE_HZ * (TURN_IN_S[1] - TURN_IN_S[0])
    turned_imu = float((rates[window, 2] - bias).sum()) / IMU_RATE_HZ
    utc, heading = _pat_headings(drive["ports"]["adu5"], start_s)
    edges = np.interp([times[window][0], times[window][-1]], utc, heading)
    turned_adu5 = -float(edges[1] - edges[0])  # heading is clockwise, the FLU yaw rate not
    assert turned_adu5 > 1.0  # the first circle turns left at 0.25 rad/s
    assert turned_imu == pytest.approx(turned_adu5, abs=0.05)


def test_the_imu_feels_the_turn_the_leica_drives(drive):
    """In the circle the IMU's lateral specific force is the Leica's speed times the IMU's yaw
    rate (centripetal acceleration), and before the start the Leica stands still."""
    start_s = drive["start_s"]
    times, rates, forces = _imu(drive["ports"]["imu"])
    circle = (times > start_s + CIRCLE_S[0]) & (times < start_s + CIRCLE_S[1])
    received, speeds = _leica_speeds(drive["ports"]["leica"])
    speed = speeds[(received > start_s + CIRCLE_S[0]) & (received < start_s + CIRCLE_S[1] + 1)]
    assert len(speed) >= 3 and speed.mean() > 8.0
    assert speeds[received < start_s + STANDING_S[1]].max() < 0.5
    centripetal = speed.mean() * rates[circle, 2].mean()
    assert centripetal > 2.0
    assert forces[circle, 1].mean() == pytest.approx(centripetal, rel=0.15)


def test_the_receivers_send_on_the_host_clock(drive):
    """Each epoch arrives just after its UTC time (latency and transmission), on every port."""
    start_s = drive["start_s"]
    for device in ("leica", "adu5"):
        port = drive["ports"][device]
        for received_s, chunk in list(port.chunks)[-20:]:
            for read in NmeaReader().feed(chunk):
                if isinstance(read.sentence, pynmea2.GGA | ASHRPAT):
                    late_s = received_s - _utc_s(read.sentence, start_s)
                    assert 0.0 < late_s < 1.0, device


@pytest.mark.parametrize("only", [("imu",), ("leica", "adu5")])
def test_only_runs_the_devices_named(tmp_path: Path, only: tuple[str, ...]):
    links = {device: tmp_path / device for device in BAUD}
    proc = _emulate(
        "--scenario=figure_eight",
        "--only",
        *only,
        *(f"--{device}-link={link}" for device, link in links.items()),
    )
    try:
        printed = port_lines(proc, {"gnss" if d == "leica" else d for d in only})
        assert sorted(device for device in BAUD if links[device].exists()) == sorted(only)
        for device in only:
            with serial.Serial(str(links[device]), BAUD[device], timeout=0.2) as port:
                if device == "imu":
                    port.write(b"C")
                received = bytearray()
                deadline = time.monotonic() + 10.0
                while len(received) < 100 and time.monotonic() < deadline:
                    received += port.read(max(1, port.in_waiting))
                assert len(received) >= 100, device
    finally:
        tail = _stop(proc)
    assert set(printed) == {"gnss" if d == "leica" else d for d in only}
    sent = tail.strip().splitlines()[-1]
    assert ("imu" in sent) == ("imu" in only) and ("adu5" in sent) == ("adu5" in only)
