"""`gnss_ins emulate-imu`: an emulated IMU400CC on a pseudo-terminal until Ctrl-C.

``--send-log FILE`` writes one record per packet written to the port (SEND_LOG_DTYPE, raw
little-endian, 20 bytes): the sample's true time and the write's time, both host wall clock in
integer ns, and the packet's timer field; for latency measurements (bench/bench_latency.py).
The file is complete once the emulator has stopped (SIGINT or SIGTERM).
"""

from __future__ import annotations

import argparse
import contextlib
import signal
import struct
import threading
from collections.abc import Callable
from pathlib import Path
from typing import BinaryIO

import numpy as np

from imu400cc_driver.emulator import EmulatorConfig, Imu400ccEmulator, SentPacket, resting_source

#: One record of ``--send-log``: the sample's true time [ns, host wall clock], the time the
#: packet was written to the port [ns, same clock] and its 16-bit timer field.
SEND_LOG_DTYPE = np.dtype([("sample_ns", "<i8"), ("written_ns", "<i8"), ("timer", "<u4")])
_SEND_LOG_RECORD = struct.Struct("<qqI")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of the emulated device."""
    parser.add_argument("--link", help="stable path for the port (default: a temporary symlink)")
    parser.add_argument(
        "--drift-ppm",
        type=float,
        default=0.0,
        help="device clock rate error [ppm], positive = slow",
    )
    parser.add_argument("--temperature", type=float, default=25.0, help="reported temp [degC]")
    parser.add_argument("--seed", type=int, default=0, help="seed of the sensor noise")
    parser.add_argument("--no-noise", action="store_true", help="noise-free level unit at rest")
    parser.add_argument(
        "--send-log",
        type=Path,
        metavar="FILE",
        help="write each packet's sample time, write time (host ns) and timer to FILE "
        "(20-byte binary records, ins_fusion.tools.emulate_imu.SEND_LOG_DTYPE)",
    )


def read_send_log(path: Path) -> np.ndarray:
    """The records of a ``--send-log`` file (SEND_LOG_DTYPE), in the order written."""
    return np.fromfile(path, dtype=SEND_LOG_DTYPE)


def _send_logger(log: BinaryIO) -> Callable[[SentPacket], None]:
    """``on_packet`` of the emulator for ``--send-log``: one record per packet, written after
    the packet (its write time is taken before)."""

    def on_packet(sent: SentPacket) -> None:
        sample_ns, written_ns = round(sent.sample_wall_s * 1e9), round(sent.written_wall_s * 1e9)
        log.write(_SEND_LOG_RECORD.pack(sample_ns, written_ns, sent.timer))

    return on_packet


def run(args: argparse.Namespace) -> int:
    """Run the device until SIGINT/SIGTERM; prints the port path first."""
    config = EmulatorConfig(clock_drift_ppm=args.drift_ppm, temperature_c=args.temperature)
    source = resting_source(seed=args.seed, noise=not args.no_noise)
    done = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: done.set())
    with contextlib.ExitStack() as stack:
        log = None if args.send_log is None else stack.enter_context(args.send_log.open("wb"))
        on_packet = None if log is None else _send_logger(log)
        device = stack.enter_context(
            Imu400ccEmulator(source, config, link_path=args.link, on_packet=on_packet)
        )
        print(f"IMU400CC emulator on {device.path} (38400 8N1). Ctrl-C to stop.", flush=True)
        with contextlib.suppress(KeyboardInterrupt):
            done.wait()
        print(f"sent {device.packets_sent} packets; commands: {dict(device.commands)}")
    return 0
