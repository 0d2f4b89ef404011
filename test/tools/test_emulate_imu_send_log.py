"""`gnss_ins emulate-imu --send-log`: one record per packet written to the port, in order."""

from __future__ import annotations

import signal
import subprocess

import serial
from support.waiting import wait_for

from imu400cc_driver.device_clock import PACKET_TRANSMISSION_S
from imu400cc_driver.protocol import PACKET_LENGTH, decode_packet
from ins_fusion.runtime.processes import gnss_ins_command
from ins_fusion.tools.emulate_imu import read_send_log

PACKETS = 20


def test_the_send_log_holds_each_packet_written_with_its_times(tmp_path):
    port, log = tmp_path / "imu", tmp_path / "sent.bin"
    emulator = subprocess.Popen(
        gnss_ins_command("emulate-imu", "--link", str(port), "--send-log", str(log)),
        stdout=subprocess.DEVNULL,
    )
    try:
        assert wait_for(port.exists, 30.0)
        received = bytearray()
        with serial.Serial(str(port), 38400, timeout=0.05) as link:

            def enough() -> bool:
                received.extend(link.read(4096))
                return len(received) >= PACKETS * PACKET_LENGTH

            link.write(b"C")  # continuous mode
            assert wait_for(enough, 10.0)
    finally:
        emulator.send_signal(signal.SIGTERM)
        assert emulator.wait(timeout=30) == 0
    timers = [
        decode_packet(received[i : i + PACKET_LENGTH]).timer
        for i in range(0, len(received) - PACKET_LENGTH + 1, PACKET_LENGTH)
    ]
    records = read_send_log(log)
    assert len(records) >= len(timers) >= PACKETS
    assert records["timer"][: len(timers)].tolist() == timers
    # Written when its last byte would have left the wire, or later (a late wake-up), in ns.
    after_sample_s = (records["written_ns"] - records["sample_ns"]) / 1e9
    assert (after_sample_s > PACKET_TRANSMISSION_S - 1e-4).all()
    assert (after_sample_s < 1.0).all()
