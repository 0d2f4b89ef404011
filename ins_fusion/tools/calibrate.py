"""`gnss_ins calibrate METHOD BAG...`: laboratory calibration of the IMU from recorded bags.

Methods of the Aalborg report (shared/reference/imu400cc-aalborg-notes.md §4): ``six-position``
(S2), ``salychev`` (S2 as the report executed it), ``known-attitude`` (S3), ``unknown-attitude``
(S4), ``rate-table`` (D1), ``known-angle`` (D2); ``axes`` checks the driver's axis_map and
accel_sign on a six-position record. Segments are detected (static or steady rotation) or given
with ``--segments``. Writes the calibration YAML the fusion node reads (``-o``), a markdown report
(``--report``) and a figure of the segments (``--plot``). docs/calibration.md has the procedures.
Exit status 2 on bad input; ``axes`` exits 1 when the driver's mapping is wrong.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from ins_fusion.bags.topics import IMU_DATA, IMU_TEMPERATURE
from ins_fusion.tools.cli import argument_type


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``gnss_ins calibrate``."""
    # The estimators (numpy, scipy, rosbags) load here, only for this sub-command.
    from ins_fusion.calibration_id import command

    parser.add_argument(
        "method",
        choices=command.METHODS,
        metavar="METHOD",
        help="six-position (S2), salychev, known-attitude (S3), unknown-attitude (S4),"
        " rate-table (D1), known-angle (D2), axes",
    )
    parser.add_argument("bags", nargs="+", type=Path, metavar="BAG", help="rosbag2 bag(s)")
    out = parser.add_argument_group("output")
    out.add_argument("-o", "--output", type=Path, metavar="YAML", help="calibration file to write")
    out.add_argument("--report", type=Path, metavar="FILE.md", help="markdown report to write")
    out.add_argument("--plot", type=Path, metavar="FILE.png", help="figure of the segments")
    out.add_argument(
        "--base",
        type=Path,
        metavar="YAML",
        help="start from this calibration file: the method's terms replace its values",
    )
    out.add_argument("--sensor", help="sensor name for the file (e.g. the serial number)")
    seg = parser.add_argument_group("segments")
    seg.add_argument(
        "--segments",
        type=argument_type(command.parse_windows),
        metavar="[BAG@]T0:T1,...",
        help="use these windows [s after the bag's first IMU stamp; BAG counts from 1]",
    )
    seg.add_argument("--window", type=float, default=1.0, help="detection window [s]")
    seg.add_argument(
        "--accel-std-max", type=float, default=0.05, help="static: accel std per axis [m/s²]"
    )
    seg.add_argument(
        "--gyro-std-max", type=float, default=1.0, help="static: gyro std per axis [deg/s]"
    )
    seg.add_argument(
        "--static-rate-max",
        type=float,
        default=1.0,
        help="largest |mean rate| of a static segment [deg/s]",
    )
    seg.add_argument("--min-duration", type=float, default=10.0, help="shortest segment [s]")
    seg.add_argument("--trim", type=float, default=1.0, help="cut from each end [s]")
    seg.add_argument("--imu-topic", default=IMU_DATA, help="sensor_msgs/Imu topic")
    seg.add_argument(
        "--temperature-topic", default=IMU_TEMPERATURE, help="sensor_msgs/Temperature topic"
    )
    site = parser.add_argument_group("static methods")
    site.add_argument("--latitude", type=float, metavar="DEG", help="laboratory latitude [deg]")
    site.add_argument("--height", type=float, default=0.0, help="ellipsoidal height [m]")
    site.add_argument(
        "--gravity", type=float, metavar="M_S2", help="local gravity (default: normal gravity)"
    )
    site.add_argument(
        "--level-sigma",
        type=float,
        default=0.1,
        metavar="DEG",
        help="attitude (levelling) σ of each position [deg]",
    )
    site.add_argument(
        "--accel-scale",
        choices=("asymmetric", "symmetric"),
        help="accelerometer scale model (six-position, known-attitude: asymmetric; salychev:"
        " symmetric)",
    )
    site.add_argument(
        "--scale-ranges",
        type=float,
        metavar="G",
        help="two-range accelerometer scale (Aalborg report §9.1.1): inputs of at least G [g]"
        " get the large-range scale (scale_large_*), smaller ones the usual one; six-position"
        " positions (±1 g) give the large range only, tilted known-attitude positions the small",
    )
    site.add_argument(
        "--positions",
        type=argument_type(command.parse_positions),
        metavar="+z,-z,...",
        help="imu_link axis up in each static segment, in order (axes: default"
        " +z,-z,+x,-x,+y,-y; six-position/salychev: checked if given)",
    )
    site.add_argument(
        "--attitudes",
        type=argument_type(command.parse_attitudes),
        metavar="R:P:Y,...",
        help="known-attitude: roll:pitch:yaw of imu_link in ENU per static segment [deg]",
    )
    site.add_argument(
        "--noise",
        type=Path,
        metavar="YAML",
        help="ins_fusion_node parameter file: its imu_noise bias instability enters the σ",
    )
    # σ defaults of the turn table: Aalborg notes §4.4 (Fig. 5-6): rate 0.015 deg/s, angle 0.1°,
    # gyro axis against the spin axis 0.5°.
    table = parser.add_argument_group("rotation methods")
    table.add_argument("--rate", type=float, metavar="DEG_S", help="rate-table: table rate")
    table.add_argument("--rate-sigma", type=float, default=0.015, help="its σ [deg/s]")
    table.add_argument("--angle", type=float, metavar="DEG", help="known-angle: rotation angle")
    table.add_argument("--angle-sigma", type=float, default=0.1, help="its σ [deg]")
    table.add_argument(
        "--mount-sigma",
        type=float,
        default=0.5,
        help="σ of the unit's axis against the table axis [deg]",
    )
    axes = parser.add_argument_group("axes")
    axes.add_argument(
        "--driver-params",
        type=Path,
        metavar="YAML",
        help="imu400cc_node parameter file with the axis_map/accel_sign the bag was recorded"
        " with (default: the driver's defaults)",
    )


def run(args: argparse.Namespace) -> int:
    """Calibrate; 0 done, 1 the driver's axis mapping disagrees (axes), 2 bad input."""
    from ins_fusion.calibration_id.command import execute

    return execute(args)
