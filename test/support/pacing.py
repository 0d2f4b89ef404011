"""Time a test lets pass on purpose."""

from __future__ import annotations

import time


def pause(seconds: float) -> None:
    """Let ``seconds`` pass on purpose: the pace of what a test sends, a gap it makes in a
    stream, a device it leaves unplugged for a while. Never a wait for a state: poll for that
    with a deadline (``support.ros_harness.wait_for``)."""
    time.sleep(seconds)
