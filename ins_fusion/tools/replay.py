"""`gnss_ins replay`: a bag through the fusion core offline, as fast as the CPU allows.

Reads the node's input topics (imu/data_raw, gnss/fix, gnss/vel, gnss/attitude; ``--topics``
renames them) and runs ins_fusion.core's engine over them in the bag's receive order, with the
parameters of ins_fusion_node (``--params`` YAML, ``--set`` overrides, validated with the node's
specs). ``--outage START:DURATION`` drops the GNSS messages stamped in the window (START in
seconds after the first IMU stamp). With reference topics (``PREFIX/fix``, ``PREFIX/attitude``,
``PREFIX/vel``, default prefix /ground_truth) the fused solution is evaluated at the reference
stamps, in the reference's frame (base_link, or the IMU when its frame_id is the IMU's); with or
without them, each outage is scored against the GNSS fixes it withheld (the fused antenna at
each fix stamp). Prints a short table; ``--report`` writes the JSON report, ``--plot`` the
figure, ``--output`` the fused /ins/odometry and /ins/fix as a bag. ``--free-inertial START``
withholds every GNSS message from START on and turns the pseudo-measurements off, the Aalborg
report's unaided evaluation (ins_fusion.replay.free_inertial). ``--smooth`` runs the RTS smoother
after the forward pass (report section ``smoothed``, both in the plot, its own topics in the
fused bag); ``--export FILE`` writes the forward or smoothed solution as CSV, GPX or NMEA
(ins_fusion.replay.export). ``--sweep NAME=V1,V2,...``
(repeatable: the grid of all combinations) replays every setting and ranks them by
``--rank-by``, one task per setting on a Dask cluster (a local one of ``--workers`` processes,
or ``--scheduler``'s, docs/fleet.md). docs/replay.md describes the report. Exit status 2 on bad
input.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from ins_fusion.replay.outages import parse_outage
from ins_fusion.replay.ranking import DEFAULT_RANK_BY, RANK_METRICS
from ins_fusion.replay.settings import parse_setting, parse_sweep
from ins_fusion.replay.topics import DEFAULT_REFERENCE, DEFAULT_TOPICS, TopicMap
from ins_fusion.tools.cli import argument_type


def _start(text: str) -> float:
    value = float(text)
    if not (value >= 0.0 and value < float("inf")):
        raise ValueError(f"START must be a finite number >= 0, got {text!r}")
    return value


def add_replay_options(parser: argparse.ArgumentParser) -> list[str]:
    """The options of one replay that ``gnss_ins batch`` shares; their destination names."""
    actions = [
        parser.add_argument(
            "--params",
            type=Path,
            metavar="YAML",
            help="ROS parameter file (ins_fusion_node section)",
        ),
        parser.add_argument(
            "--set",
            dest="settings",
            type=argument_type(parse_setting),
            action="append",
            default=[],
            metavar="NAME=VALUE",
            help="override one parameter, value as in the YAML file (repeatable)",
        ),
        parser.add_argument(
            "--outage",
            type=argument_type(parse_outage),
            action="append",
            default=[],
            metavar="START:DURATION",
            help="drop GNSS fix/velocity/attitude stamped in this window [s after the first IMU "
            "stamp] and score the fused antenna against the withheld fixes (repeatable)",
        ),
        parser.add_argument(
            "--free-inertial",
            type=argument_type(_start),
            metavar="START",
            help="the Aalborg report's evaluation: withhold all GNSS from START [s after the "
            "first IMU stamp] on, no ZUPT/ZARU/NHC, and print the drift against the withheld "
            "fixes 5...180 s after START",
        ),
        parser.add_argument(
            "--reference",
            metavar="PREFIX",
            help=f"reference topics PREFIX/fix, PREFIX/attitude, PREFIX/vel (default "
            f"{DEFAULT_REFERENCE}, used when present; a given PREFIX must exist)",
        ),
        parser.add_argument(
            "--smooth",
            action="store_true",
            help="also run the Rauch-Tung-Striebel smoother over the forward pass "
            "(post-processing: report, plot and fused bag get the smoothed solution too)",
        ),
        parser.add_argument(
            "--export-solution",
            choices=("forward", "smoothed"),
            help="which solution --export writes (default: smoothed with --smooth, else forward)",
        ),
        parser.add_argument(
            "--topics",
            type=argument_type(TopicMap.parse),
            default=DEFAULT_TOPICS,
            metavar="ROLE=TOPIC,...",
            help="input topics (defaults "
            + ",".join(f"{role}={topic}" for role, topic in DEFAULT_TOPICS.by_role().items())
            + ")",
        ),
    ]
    return [action.dest for action in actions]


def add_cluster_options(parser: argparse.ArgumentParser, tasks: str) -> None:
    """``--scheduler`` and ``--workers``: where the tasks (``tasks``, e.g. "bags") run."""
    parser.add_argument(
        "--scheduler",
        metavar="tcp://HOST:PORT",
        help=f"run the {tasks} on this Dask scheduler's workers (docs/fleet.md; default: a "
        "local cluster)",
    )
    parser.add_argument(
        "--workers",
        type=int,
        metavar="N",
        help=f"processes of the local cluster running the {tasks} (default: one per core)",
    )


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``gnss_ins replay``."""
    parser.add_argument("bag", type=Path, help="rosbag2 bag (directory or storage file)")
    add_replay_options(parser)
    parser.add_argument("--report", type=Path, metavar="FILE.json", help="write the JSON report")
    parser.add_argument("--plot", type=Path, metavar="FILE.png", help="write the figure")
    parser.add_argument(
        "--output", type=Path, metavar="FUSED", help="write /ins/odometry and /ins/fix to this bag"
    )
    parser.add_argument(
        "--export",
        type=Path,
        action="append",
        default=[],
        metavar="FILE",
        help="write the solution past alignment as .csv, .gpx or .nmea (by suffix; repeatable)",
    )
    parser.add_argument(
        "--sweep",
        type=argument_type(parse_sweep),
        action="append",
        default=[],
        metavar="NAME=V1,V2,...",
        help="replay every value (repeatable: every combination) and rank the settings",
    )
    parser.add_argument(
        "--rank-by",
        choices=sorted(RANK_METRICS),
        metavar="METRIC",
        help=f"sweep ranking metric, lower is better: {', '.join(sorted(RANK_METRICS))}"
        f" (default {DEFAULT_RANK_BY})",
    )
    add_cluster_options(parser, "sweep's settings")


def run(args: argparse.Namespace) -> int:
    """Replay (or sweep); 0 done, 1 no fused solution, 2 bad input."""
    # The engine, rosbags and matplotlib load here, not when `gnss_ins` builds its parser.
    from ins_fusion.replay.command import execute

    return execute(args)
