"""`gnss_ins emulate`: the vehicle's three devices on pseudo-terminals, driving one simulated drive
together, for `gnss_ins launch` without hardware.

The emulated IMU400CC, Leica RTK rover and ADU5 take their samples from one simulated drive
(ins_fusion/sim/live.py, as ``gnss_ins simulate --live``) at fixed link paths, so that
``gnss_ins launch --imu-port /tmp/imu0 --leica-port /tmp/leica0 --adu5-port /tmp/adu50`` reads
them; ``--only`` runs some of them. The drive lasts ``--duration`` (an hour by default); then the
car stays parked where it stopped and the receivers report no fix until Ctrl-C / SIGTERM.
``--write-config DIR`` first writes the parameter files of the simulated car (its lever arms)
and receivers (their output latency) into DIR, for ``gnss_ins launch --config DIR``
(ins_fusion/sim/launch_config.py).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ins_fusion.sim.drive import SimulationConfig
from ins_fusion.sim.launch_config import write_launch_config
from ins_fusion.sim.live import LiveOptions, run_live
from ins_fusion.tools.simulate import add_drive_arguments

#: The devices as the options name them -> the live drive's names (ins_fusion.sim.live.DEVICES).
DEVICES = {"imu": "imu", "leica": "gnss", "adu5": "adu5"}
#: Default link path of each device (what `gnss_ins launch --DEVICE-port` is given).
LINKS = {"imu": "/tmp/imu0", "leica": "/tmp/leica0", "adu5": "/tmp/adu50"}
_NAMES = {"imu": "IMU400CC", "leica": "Leica rover", "adu5": "ADU5"}
#: Default length of the drive [s]: the test pattern's 60 s standstill, then its 180 s of urban
#: driving again and again, for an hour.
DEFAULT_DURATION_S = 3600.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Command-line options of ``gnss_ins emulate``."""
    add_drive_arguments(
        parser,
        DEFAULT_DURATION_S,
        "seconds of driving; then the car stays parked, the receivers without a fix, until Ctrl-C",
    )
    for device, link in LINKS.items():
        parser.add_argument(
            f"--{device}-link",
            default=link,
            metavar="PATH",
            help=f"path of the {_NAMES[device]}'s port (launch's --{device}-port)",
        )
    parser.add_argument(
        "--only",
        nargs="+",
        choices=list(DEVICES),
        metavar="DEVICE",
        help=f"run only these devices ({', '.join(DEVICES)}); the others are left out, the drive"
        " is the same",
    )
    parser.add_argument(
        "--write-config",
        type=Path,
        metavar="DIR",
        help="first write the nodes' parameter files for the simulated car and receivers (lever"
        " arms, output latency) into DIR, for `gnss_ins launch --config DIR`",
    )


def run(args: argparse.Namespace) -> int:
    """Write the parameter files if asked, then play the drive until Ctrl-C/SIGTERM; 2 when the
    files cannot be written."""
    chosen = args.only or list(DEVICES)
    if args.write_config is not None:
        try:
            write_launch_config(args.write_config)
        except (OSError, ValueError) as exc:
            print(f"gnss_ins emulate: error: --write-config: {exc}", file=sys.stderr)
            return 2
        print(
            f"parameter files of the simulated vehicle written to {args.write_config}/"
            f" (gnss_ins launch --config {args.write_config})",
            flush=True,
        )
    print(
        f"gnss_ins emulate: {args.scenario}, {args.duration:g} s, seed {args.seed}:"
        f" {', '.join(chosen)} (Ctrl-C to stop)",
        flush=True,
    )
    options = LiveOptions(
        devices=frozenset(DEVICES[d] for d in chosen),
        links={DEVICES[d]: getattr(args, f"{d}_link") for d in chosen},
        hold=True,
        progress=False,
    )
    config = SimulationConfig(scenario=args.scenario, duration_s=args.duration, seed=args.seed)
    return run_live(config, options)
