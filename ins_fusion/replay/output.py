"""The fused solution of a replay as the bag ins_fusion_node would have recorded.

``/ins/odometry`` (nav_msgs/Odometry: pose in the map frame = ENU tangent plane at the datum,
child base_link, twist in base_link; numbers from ins_fusion.adapters.solution_out, as the node) and
``/ins/fix`` (NavSatFix of base_link, ENU covariance, COVARIANCE_TYPE_KNOWN, status NO_FIX while
the engine is aligning), one message of each per recorded solution, stamped and logged at the
solution's IMU stamp; the RTS-smoothed solution, when given, the same way on
``/ins/smoothed/odometry`` and ``/ins/smoothed/fix``.
"""

from __future__ import annotations

import heapq
from collections.abc import Iterator, Sequence
from pathlib import Path

from gnss_ins_common.message_fields import stamp_ns
from ins_fusion.adapters.solution_out import fill_fused_fix, fill_odometry, publishable
from ins_fusion.bags.bag_io import BagWriter
from ins_fusion.bags.messages import new_message
from ins_fusion.bags.summary import BagSummary
from ins_fusion.bags.topics import FIX_TYPE, INS_FIX, INS_ODOMETRY, ODOMETRY_TYPE
from ins_fusion.core.engine.engine import InsSolution

SMOOTHED_ODOMETRY_TOPIC, SMOOTHED_FIX_TOPIC = "/ins/smoothed/odometry", "/ins/smoothed/fix"


def _stamped(k: int, solutions: Sequence[InsSolution]) -> Iterator[tuple[float, int, InsSolution]]:
    return ((s.t_s, k, s) for s in filter(publishable, solutions))


def write_fused_bag(
    path: Path | str,
    solutions: Sequence[InsSolution],
    map_frame: str,
    base_frame: str,
    rate_variance_rad2_s2: float,
    smoothed: Sequence[InsSolution] | None = None,
) -> BagSummary:
    """Write /ins/odometry and /ins/fix of every publishable solution (and the smoothed ones
    on their topics) to a new bag at ``path`` (MCAP)."""
    tracks = [(INS_ODOMETRY, INS_FIX, solutions)]
    if smoothed is not None:
        tracks.append((SMOOTHED_ODOMETRY_TOPIC, SMOOTHED_FIX_TOPIC, smoothed))
    # Both tracks in one time order (log time = stamp), as a recording would have them.
    merged = heapq.merge(
        *(_stamped(k, track) for k, (*_, track) in enumerate(tracks)),
        key=lambda item: (item[0], item[1]),
    )
    with BagWriter(path) as writer:
        for odometry_topic, fix_topic, _ in tracks:
            writer.add_topic(odometry_topic, ODOMETRY_TYPE)
            writer.add_topic(fix_topic, FIX_TYPE)
        for _, k, solution in merged:
            odometry_topic, fix_topic, _ = tracks[k]
            time_ns = stamp_ns(solution.t_s)
            odometry = fill_odometry(
                new_message(ODOMETRY_TYPE), solution, map_frame, base_frame, rate_variance_rad2_s2
            )
            fix = fill_fused_fix(new_message(FIX_TYPE), solution, base_frame)
            writer.write(odometry_topic, time_ns, odometry)
            writer.write(fix_topic, time_ns, fix)
    return writer.summary
