"""``gnss_ins topics``: the topics on the ROS domain with their type and how many publishers and
subscribers each has, as ``ros2 topic list -v`` shows them, for a machine whose ROS 2 comes from
PyPI (no ``ros2`` command). rclpy is imported only when listening starts."""

from __future__ import annotations

import argparse
import sys

from ins_fusion.runtime.priority import run_as_a_look


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Command-line options of ``gnss_ins topics``."""
    parser.add_argument(
        "--wait",
        type=float,
        default=3.0,
        metavar="S",
        help="seconds to wait for the first topic to be discovered (then 1 s more for the rest)",
    )


def run(args: argparse.Namespace) -> int:
    """Print one line per topic; 1 when none is seen within --wait."""
    run_as_a_look()  # below the vehicle's nodes (runtime.priority)
    from ins_fusion.tools.ros_echo import topics

    if not args.wait >= 0.0:
        print("gnss_ins topics: --wait must be >= 0", file=sys.stderr)
        return 2
    found = [t for t in topics(args.wait) if t[2] or t[3]]
    if not found:
        print(f"gnss_ins topics: no topic seen within {args.wait:g} s", file=sys.stderr)
        return 1
    width = max(len(name) for name, *_ in found)
    print(f"{'topic':{width}s}  publishers  subscribers  type")
    for name, msgtype, publishers, subscribers in found:
        print(f"{name:{width}s}  {publishers:10d}  {subscribers:11d}  {msgtype}")
    return 0
