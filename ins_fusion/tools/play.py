"""``gnss_ins play``: publish a bag's messages on their topics with the recorded timing.

Messages are published as the raw CDR bytes stored in the bag (no deserialization), at the
wall time ``start + (log_time − bag_start) / rate``. With ``--clock`` the bag time is published
on ``/clock`` (rosgraph_msgs/Clock) at HZ so nodes with ``use_sim_time`` follow the bag; a last
tick carries the time of the last message. Publishers are reliable (they match reliable and
best-effort subscribers) and transient-local when the recording publisher was. Reads MCAP and
sqlite3 bags, split or not.

The publishing node is ins_fusion/tools/ros_play.py; rclpy is imported only when playing starts
(this module is loaded by ``gnss_ins --help``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ins_fusion.bags.bag_io import BagError, BagReader

#: ``--clock`` without a value: ticks per second (rosbag2's default).
DEFAULT_CLOCK_HZ = 40.0


def _positive(text: str) -> float:
    value = float(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {text}")
    return value


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Command-line options of ``gnss_ins play``."""
    parser.add_argument("bag", type=Path, help="bag directory (or one .mcap/.db3 file)")
    parser.add_argument(
        "--rate", type=_positive, default=1.0, help="time scale (2 = twice as fast)"
    )
    parser.add_argument("--loop", action="store_true", help="start over at the end until Ctrl-C")
    parser.add_argument("--topics", nargs="+", help="play only these topics")
    parser.add_argument(
        "--clock",
        type=_positive,
        nargs="?",
        const=DEFAULT_CLOCK_HZ,
        metavar="HZ",
        help=f"publish /clock at HZ (default {DEFAULT_CLOCK_HZ:g})",
    )
    parser.add_argument(
        "--start-offset", type=float, default=0.0, metavar="S", help="skip the first S seconds"
    )
    parser.add_argument(
        "--wait-for-subscribers",
        action="store_true",
        help="start only when every played topic has a subscriber",
    )


def run(args: argparse.Namespace) -> int:
    """Play until the end (or forever with --loop) or Ctrl-C; prints what was published."""
    try:
        reader = BagReader(args.bag)
    except BagError as exc:
        print(f"gnss_ins play: error: {exc}", file=sys.stderr)
        return 2
    with reader:
        if not reader.topics:
            print(f"gnss_ins play: error: {args.bag} has no messages", file=sys.stderr)
            return 1
        topics = sorted(reader.topics) if args.topics is None else list(args.topics)
        if unknown := sorted(set(topics) - set(reader.topics)):
            print(
                f"gnss_ins play: error: {args.bag} has no topic {', '.join(unknown)}",
                file=sys.stderr,
            )
            return 2
        from ins_fusion.tools.ros_play import importable, play

        playable = [t for t in topics if importable(reader.topics[t].msgtype)]
        for topic in sorted(set(topics) - set(playable)):
            msgtype = reader.topics[topic].msgtype
            print(f"warning: {topic}: type {msgtype} not installed, not played", file=sys.stderr)
        if not playable:
            return 1
        return play(args, reader, playable)
