"""A small progress bar on stderr for the tools that run longer than a few seconds.

Draws only when the stream is a terminal (pipes and test captures stay clean) and at most
every ``min_interval_s``; no dependency beyond the standard library.
"""

from __future__ import annotations

import sys
import time
from types import TracebackType
from typing import TextIO

BAR_WIDTH = 30


def _clock(seconds: float) -> str:
    minutes, sec = divmod(int(seconds), 60)
    hours, minutes = divmod(minutes, 60)
    return f"{hours:d}:{minutes:02d}:{sec:02d}" if hours else f"{minutes:02d}:{sec:02d}"


class Progress:
    """``label [####....]  42%  420/1000 unit  00:12 < 00:17`` on one refreshed stderr line.

    ``total=None`` shows a running count instead of a bar (e.g. a recorder with no end).
    """

    def __init__(
        self,
        label: str,
        total: float | None = None,
        unit: str = "",
        stream: TextIO | None = None,
        min_interval_s: float = 0.2,
    ) -> None:
        self.label = label
        self.total = total
        self.unit = unit
        self.stream = stream if stream is not None else sys.stderr
        self.min_interval_s = min_interval_s
        self.enabled = self.stream.isatty()
        self._start = time.monotonic()
        self._last_draw = -float("inf")
        self._done = 0.0
        self._extra = ""

    def update(self, done: float, extra: str = "") -> None:
        """Set the absolute amount done (same unit as ``total``); redraws if due."""
        self._done = done
        self._extra = extra
        now = time.monotonic()
        if self.enabled and now - self._last_draw >= self.min_interval_s:
            self._last_draw = now
            self._draw(now)

    def update_with_total(self, done: float, total: float) -> None:
        """``update`` with the total too: a ``progress(done, total)`` callback of the readers."""
        self.total = total
        self.update(done)

    def message(self, text: str) -> None:
        """A line of its own on the stream above the bar (the bar drawn again below it)."""
        if self.enabled:
            self.stream.write("\r\x1b[K")
        self.stream.write(text + "\n")
        self.stream.flush()
        if self.enabled:
            self._draw(time.monotonic())

    def close(self) -> None:
        """Draw the final state and end the line."""
        if self.enabled:
            self._draw(time.monotonic())
            self.stream.write("\n")
            self.stream.flush()

    def _draw(self, now: float) -> None:
        elapsed = now - self._start
        unit = f" {self.unit}" if self.unit else ""
        if self.total:
            fraction = min(max(self._done / self.total, 0.0), 1.0)
            filled = round(fraction * BAR_WIDTH)
            remaining = elapsed * (1.0 - fraction) / fraction if fraction > 0 else 0.0
            text = (
                f"{self.label} [{'#' * filled}{'.' * (BAR_WIDTH - filled)}] {fraction:4.0%} "
                f"{self._done:.0f}/{self.total:.0f}{unit}  {_clock(elapsed)} < {_clock(remaining)}"
            )
        else:
            text = f"{self.label} {self._done:.0f}{unit}  {_clock(elapsed)}"
        if self._extra:
            text += f"  {self._extra}"
        self.stream.write("\r" + text + "\x1b[K")
        self.stream.flush()

    def __enter__(self) -> Progress:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
