"""Summary of a bag: messages per topic, rates, time span, the largest gaps; fed one message time
at a time by the writer, the reader, the recorder and the importers."""

from __future__ import annotations

import heapq
from dataclasses import dataclass, field
from datetime import UTC, datetime
from typing import NamedTuple

#: Largest gaps kept per topic for the summary.
GAPS_KEPT = 3
#: A gap is listed in the summary when it lasts this many mean periods of its topic or more.
GAP_REPORT_PERIODS = 1.5


def utc_text(time_ns: int) -> str:
    """``2013-08-26T10:00:00.000Z`` for a time in ns since the Unix epoch."""
    stamp = datetime.fromtimestamp(time_ns / 1e9, tz=UTC)
    return stamp.strftime("%Y-%m-%dT%H:%M:%S.") + f"{stamp.microsecond // 1000:03d}Z"


class Gap(NamedTuple):
    """A gap between two consecutive messages of one topic."""

    topic: str
    start_ns: int
    length_ns: int
    periods: float  #: length in mean periods of the topic (1.0 = on time)


@dataclass
class TopicStats:
    """Count, time span and largest gaps of one topic (times in ns)."""

    msgtype: str
    count: int = 0
    first_ns: int = 0
    last_ns: int = 0
    #: min-heap of (length_ns, start_ns) holding the GAPS_KEPT largest gaps
    gaps: list[tuple[int, int]] = field(default_factory=list)

    @property
    def rate_hz(self) -> float:
        """Mean message rate over the topic's own span (0 with fewer than two messages)."""
        span = self.last_ns - self.first_ns
        return (self.count - 1) * 1e9 / span if span > 0 else 0.0

    @property
    def max_gap_ns(self) -> int:
        """Largest interval between consecutive messages (0 with fewer than two messages)."""
        return max(self.gaps)[0] if self.gaps else 0


@dataclass
class BagSummary:
    """Messages per topic, time span and largest gaps; fed one message time at a time."""

    topics: dict[str, TopicStats] = field(default_factory=dict)

    def add(self, topic: str, msgtype: str, log_time_ns: int) -> None:
        """Account one message. A time earlier than the topic's last (a loop) opens no gap."""
        stats = self.topics.get(topic)
        if stats is None:
            self.topics[topic] = TopicStats(msgtype, 1, log_time_ns, log_time_ns)
            return
        gap = log_time_ns - stats.last_ns
        if gap > 0:
            item = (gap, stats.last_ns)
            if len(stats.gaps) < GAPS_KEPT:
                heapq.heappush(stats.gaps, item)
            elif item > stats.gaps[0]:
                heapq.heapreplace(stats.gaps, item)
        stats.count += 1
        stats.first_ns = min(stats.first_ns, log_time_ns)
        stats.last_ns = max(stats.last_ns, log_time_ns)

    @property
    def count(self) -> int:
        """Messages of all topics."""
        return sum(s.count for s in self.topics.values())

    @property
    def start_ns(self) -> int:
        """Time of the earliest message (0 when empty)."""
        return min((s.first_ns for s in self.topics.values()), default=0)

    @property
    def end_ns(self) -> int:
        """Time of the latest message (0 when empty)."""
        return max((s.last_ns for s in self.topics.values()), default=0)

    def largest_gaps(self, n: int = 5) -> list[Gap]:
        """Up to ``n`` gaps of GAP_REPORT_PERIODS mean periods or more, longest (relative to
        their topic's mean period) first."""
        gaps = [
            Gap(topic, start, length, length * s.rate_hz / 1e9)
            for topic, s in self.topics.items()
            for length, start in s.gaps
            if length * s.rate_hz / 1e9 >= GAP_REPORT_PERIODS
        ]
        return sorted(gaps, key=lambda g: g.periods, reverse=True)[:n]

    def format(self, title: str = "") -> str:
        """Human-readable table (counts, rates, max gaps) and the largest gaps."""
        lines = [title] if title else []
        if not self.topics:
            return "\n".join([*lines, "no messages"])
        span_s = (self.end_ns - self.start_ns) / 1e9
        lines.append(
            f"{self.count} messages, {utc_text(self.start_ns)} .. {utc_text(self.end_ns)}"
            f" ({span_s:.3f} s)"
        )
        width = max(len("topic"), *(len(t) for t in self.topics))
        type_width = max(len("type"), *(len(s.msgtype) for s in self.topics.values()))
        lines.append(
            f"  {'topic':<{width}}  {'type':<{type_width}}  {'count':>8}  {'rate Hz':>9}"
            f"  {'max gap s':>9}"
        )
        for topic in sorted(self.topics):
            s = self.topics[topic]
            lines.append(
                f"  {topic:<{width}}  {s.msgtype:<{type_width}}  {s.count:>8}  {s.rate_hz:>9.3f}"
                f"  {s.max_gap_ns / 1e9:>9.4f}"
            )
        gaps = self.largest_gaps()
        if not gaps:
            lines.append(f"  largest gaps: none of {GAP_REPORT_PERIODS} mean periods or more")
        else:
            lines.append("  largest gaps:")
            lines.extend(
                f"    {g.topic}: {g.length_ns / 1e9:.4f} s at"
                f" +{(g.start_ns - self.start_ns) / 1e9:.3f} s ({g.periods:.1f} mean periods)"
                for g in gaps
            )
        return "\n".join(lines)
