"""The CPU priority of the tools that look at a running vehicle (no ROS).

``gnss_ins status``, ``topics`` and ``echo`` start a Python process that imports rclpy and joins
the domain: about a second of CPU on a 2-core vehicle laptop, right beside the drivers and the
fusion. The largest odometry gap of the disturbed latency bench (41 ms, 0.3 s after a status had
started) was such a start. A look therefore runs below them: a niceness of LOOK_NICENESS gives it
about a tenth of a core's share against a node at the default priority (Linux CFS weights 110
against 1024), while an idle machine still serves it at once.
"""

from __future__ import annotations

import os

#: Niceness a look adds to its own process (0 = the nodes' default, 19 the lowest priority).
LOOK_NICENESS = 10


def run_as_a_look() -> int:
    """Lower this process's priority by LOOK_NICENESS; its niceness afterwards (unchanged where
    the system refuses, e.g. under a restrictive container)."""
    try:
        return os.nice(LOOK_NICENESS)
    except OSError:
        return os.nice(0)
