"""`gnss_ins emulate-imu`: an emulated IMU400CC on a pseudo-terminal until Ctrl-C."""

from __future__ import annotations

import argparse
import contextlib
import signal
import threading

from imu400cc_driver.emulator import EmulatorConfig, Imu400ccEmulator, resting_source


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


def run(args: argparse.Namespace) -> int:
    """Run the device until SIGINT/SIGTERM; prints the port path first."""
    config = EmulatorConfig(clock_drift_ppm=args.drift_ppm, temperature_c=args.temperature)
    source = resting_source(seed=args.seed, noise=not args.no_noise)
    done = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: done.set())
    with Imu400ccEmulator(source, config, link_path=args.link) as device:
        print(f"IMU400CC emulator on {device.path} (38400 8N1). Ctrl-C to stop.", flush=True)
        with contextlib.suppress(KeyboardInterrupt):
            done.wait()
        print(f"sent {device.packets_sent} packets; commands: {dict(device.commands)}")
    return 0
