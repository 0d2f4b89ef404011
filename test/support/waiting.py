"""Waiting for a condition: polled, with a deadline (never a fixed sleep)."""

from __future__ import annotations

import time
from collections.abc import Callable


def wait_for(predicate: Callable[[], bool], timeout_s: float, poll_s: float = 0.02) -> bool:
    """Poll ``predicate`` until it is true or the time-out expires; returns its last value."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(poll_s)
    return predicate()


def wait_until_steady(value: Callable[[], int], quiet_s: float, timeout_s: float) -> int:
    """Poll ``value`` until it has not changed for ``quiet_s`` (a node done with its input:
    nothing tells when it has read the last byte); returns it. Fails after ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    last, since = value(), time.monotonic()
    while time.monotonic() - since < quiet_s:
        assert time.monotonic() < deadline, f"still changing after {timeout_s} s"
        time.sleep(0.02)
        if (now := value()) != last:
            last, since = now, time.monotonic()
    return last
