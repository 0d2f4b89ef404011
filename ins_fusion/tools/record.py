"""``gnss_ins record``: record ROS 2 topics into a rosbag2 bag (MCAP by default).

The recording node (ins_fusion/tools/ros_record.py) subscribes with ``raw=True`` to each
requested topic as soon as a publisher of it appears, with the QoS its publishers offer, and
writes what it receives on a writer thread, flushed every 0.5 s (what a SIGKILL or power cut
loses; ``gnss_ins recover`` reads the rest). Ctrl-C or SIGTERM stops the subscriptions, takes
every message already received, and closes the bag cleanly.

rclpy is imported only when recording starts (this module is loaded by ``gnss_ins --help``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ins_fusion.bags.bag_io import STORAGES, BagError, BagWriter


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Command-line options of ``gnss_ins record``."""
    parser.add_argument("topics", nargs="*", help="topics to record (relative names resolved)")
    parser.add_argument("-o", "--output", type=Path, required=True, help="bag directory to create")
    parser.add_argument("-a", "--all", action="store_true", help="record every topic that appears")
    parser.add_argument(
        "--storage", choices=sorted(STORAGES), default="mcap", help="rosbag2 storage plugin"
    )
    parser.add_argument(
        "--max-bag-size",
        type=int,
        default=0,
        metavar="BYTES",
        help="start a new file when a file's message bytes would exceed BYTES (0: never)",
    )
    parser.add_argument(
        "--max-bag-duration",
        type=float,
        default=0.0,
        metavar="S",
        help="start a new file after S seconds of recorded time (0: never)",
    )


def run(args: argparse.Namespace) -> int:
    """Record until Ctrl-C/SIGTERM; prints the summary. 2 on bad arguments, 1 if writing
    failed."""
    if not args.topics and not args.all:
        print("gnss_ins record: error: name topics to record or use --all", file=sys.stderr)
        return 2
    try:
        writer = BagWriter(
            args.output,
            storage=args.storage,
            max_file_bytes=args.max_bag_size,
            max_file_duration_s=args.max_bag_duration,
        )
    except BagError as exc:
        print(f"gnss_ins record: error: {exc}", file=sys.stderr)
        return 2
    from ins_fusion.tools.ros_record import record

    lost, failure = record(writer, None if args.all else list(args.topics))
    if failure is not None:
        print(f"gnss_ins record: error: writing {args.output} failed: {failure!r}", file=sys.stderr)
        return 1
    print(writer.summary.format(f"bag {args.output} ({args.storage}, files: {len(writer.files)})"))
    lost_text = ", ".join(f"{t} {n}" for t, n in sorted(lost.items()) if n) or "none"
    print(f"  lost in transport (reported by the middleware): {lost_text}")
    return 0
