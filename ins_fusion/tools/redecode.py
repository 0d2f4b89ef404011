"""``gnss_ins redecode``: a recording decoded again from the devices' own bytes.

The raw topics (``/imu/raw``, ``/leica/nmea``, ``/adu5/nmea`` and the receivers'
``port_events``) go through today's driver cores with the given parameters; the rebuilt IMU and
GNSS topics replace the recorded ones in a new bag, every other topic is copied unchanged
(ins_fusion/redecode/, docs/redecode.md).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ins_fusion.redecode.run import RedecodeError, redecode


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Command-line options of ``gnss_ins redecode``."""
    parser.add_argument("bag", type=Path, help="the recording (a bag directory)")
    parser.add_argument(
        "-o",
        "--output",
        type=Path,
        required=True,
        help="bag directory to create (never overwritten)",
    )
    parser.add_argument(
        "--config",
        type=Path,
        metavar="DIR",
        help="the nodes' parameter files, as `gnss_ins launch --config DIR` reads them"
        " (default: the installed config/); a recording does not hold them",
    )
    parser.add_argument(
        "--params",
        type=Path,
        action="append",
        default=[],
        metavar="FILE",
        help="a ROS parameter file whose sections named after a node (imu400cc_node,"
        " leica_gnss, adu5_gnss, or /**) override its values; repeatable",
    )


def run(args: argparse.Namespace) -> int:
    """Decode again and print what was rebuilt; 2 when nothing can be decoded or written."""
    try:
        result = redecode(args.bag, args.output, args.config, args.params)
    except (RedecodeError, OSError) as exc:
        print(f"gnss_ins redecode: error: {exc}", file=sys.stderr)
        return 2
    print(result.format())
    print(f"written: {args.output} ({result.summary.count} messages)")
    return 0
