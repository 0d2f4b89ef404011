"""The fused solution of a replay as the bag ins_fusion_node would have recorded.

``/ins/odometry`` (nav_msgs/Odometry: pose in the map frame = ENU tangent plane at the datum,
child base_link, twist in base_link; numbers from ins_fusion.adapters.solution_out, as the node) and
``/ins/fix`` (NavSatFix of base_link, ENU covariance, COVARIANCE_TYPE_KNOWN, status NO_FIX while
the engine is aligning), one message of each per recorded solution, stamped and logged at the
solution's IMU stamp.
"""

from __future__ import annotations

from pathlib import Path

from gnss_ins_common.message_fields import stamp_ns
from ins_fusion.adapters.solution_out import fill_fused_fix, fill_odometry, publishable
from ins_fusion.bags.bag_io import BagSummary, BagWriter
from ins_fusion.bags.messages import new_message
from ins_fusion.bags.topics import FIX_TYPE, INS_FIX, INS_ODOMETRY, ODOMETRY_TYPE
from ins_fusion.core.engine import InsSolution


def write_fused_bag(
    path: Path | str,
    solutions: tuple[InsSolution, ...],
    map_frame: str,
    base_frame: str,
    rate_variance_rad2_s2: float,
) -> BagSummary:
    """Write /ins/odometry and /ins/fix of every publishable solution to a new bag at ``path``
    (MCAP)."""
    with BagWriter(path) as writer:
        writer.add_topic(INS_ODOMETRY, ODOMETRY_TYPE)
        writer.add_topic(INS_FIX, FIX_TYPE)
        for solution in filter(publishable, solutions):
            time_ns = stamp_ns(solution.t_s)
            odometry = fill_odometry(
                new_message(ODOMETRY_TYPE), solution, map_frame, base_frame, rate_variance_rad2_s2
            )
            fix = fill_fused_fix(new_message(FIX_TYPE), solution, base_frame)
            writer.write(INS_ODOMETRY, time_ns, odometry)
            writer.write(INS_FIX, time_ns, fix)
    return writer.summary
