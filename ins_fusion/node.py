"""ins_fusion_node entry point.

The fusion node (error-state filter over imu/data_raw + gnss/*) is issue 5 and not written yet;
until then the executable says so and exits with an error instead of pretending to navigate.
"""

from __future__ import annotations

import sys


def main(args: list[str] | None = None) -> int:
    """Console-script entry point (``ros2 run gnss_ins ins_fusion_node``)."""
    print("ins_fusion_node is not available yet (see issue 5).", file=sys.stderr)
    return 1
