"""`gnss_ins emulate-gnss`: an emulated Leica RTK rover or ADU5 on a pseudo-terminal."""

from __future__ import annotations

import argparse
import contextlib
import signal
import threading

from gnss_driver.emulator import AALBORG_LLH, EmulatorConfig, GnssEmulator, constant_velocity
from gnss_driver.profiles import Receiver


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of the emulated receiver."""
    parser.add_argument(
        "--receiver",
        choices=[Receiver.LEICA.value, Receiver.ADU5.value],
        default="leica",
        help="which receiver's sentences and baud rate",
    )
    parser.add_argument("--link", help="stable path for the port (default: a temporary symlink)")
    parser.add_argument(
        "--velocity",
        type=float,
        nargs=3,
        default=(0.0, 0.0, 0.0),
        metavar=("EAST", "NORTH", "UP"),
        help="constant velocity in ENU [m/s] (heading follows it)",
    )
    parser.add_argument(
        "--origin",
        type=float,
        nargs=3,
        default=AALBORG_LLH,
        metavar=("LAT", "LON", "HEIGHT"),
        help="start position [deg, deg, m above the ellipsoid]",
    )
    parser.add_argument(
        "--extra",
        nargs="*",
        choices=("GST", "RMC", "ZDA"),
        default=(),
        help="optional Leica sentences after VTG, GGA, LLQ",
    )
    parser.add_argument("--att", action="store_true", help="ADU5: also send PASHR,ATT")
    parser.add_argument(
        "--rtk-from-corrections",
        action="store_true",
        help="Leica: RTK fixed only while RTCM 3 frames are written to the port, then float,"
        " then standalone (default: always RTK fixed)",
    )


def run(args: argparse.Namespace) -> int:
    """Run the receiver until SIGINT/SIGTERM; prints the port path first."""
    config = EmulatorConfig(
        receiver=Receiver(args.receiver),
        leica_extra=tuple(args.extra),
        adu5_att=args.att,
        rtk_from_corrections=args.rtk_from_corrections,
    )
    truth = constant_velocity(tuple(args.velocity), tuple(args.origin))
    done = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: done.set())
    with GnssEmulator(truth, config, link_path=args.link) as device:
        print(
            f"{args.receiver} emulator on {device.path} ({device.baud} 8N1). Ctrl-C to stop.",
            flush=True,
        )
        with contextlib.suppress(KeyboardInterrupt):
            done.wait()
        print(f"sent {device.epochs_sent} epochs; commands: {device.commands}")
        if config.rtk_from_corrections:
            print(f"received {device.rtcm_frames} RTCM 3 frames")
    return 0
