"""``gnss_ins play``: publish a bag's messages on their topics with the recorded timing.

Messages are published as the raw CDR bytes stored in the bag (no deserialization), at the
wall time ``start + (log_time − bag_start) / rate``. With ``--clock`` the bag time is published
on ``/clock`` (rosgraph_msgs/Clock) at HZ so nodes with ``use_sim_time`` follow the bag; a last
tick carries the time of the last message. Publishers are reliable (they match reliable and
best-effort subscribers) and transient-local when the recording publisher was. Reads MCAP and
sqlite3 bags, split or not.

rclpy is imported inside the functions that need it (this module is loaded by ``gnss_ins --help``).
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
import time
from collections.abc import Collection
from pathlib import Path
from typing import TYPE_CHECKING

from rosbags.interfaces import Qos, QosDurability

from ins_fusion.bags.bag_io import BagError, BagReader, BagSummary
from ins_fusion.runtime.progress import Progress
from ins_fusion.tools.record import message_class

if TYPE_CHECKING:
    from rclpy.node import Node
    from rclpy.qos import QoSProfile

#: ``--clock`` without a value: ticks per second (rosbag2's default).
DEFAULT_CLOCK_HZ = 40.0
#: Publisher history depth.
PUBLISHER_DEPTH = 100
#: At the end, how long at most to wait for reliable subscribers to acknowledge the last
#: messages, so lost ones can still be resent (s). Fast DDS often acknowledges only with its
#: next periodic heartbeat, so this is usually a short linger rather than a confirmation.
ACK_TIMEOUT_S = 0.5
#: Poll period while waiting for subscribers (s).
WAIT_PERIOD_S = 0.05


def _positive(text: str) -> float:
    value = float(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {text}")
    return value


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Command-line options of ``gnss_ins play``."""
    parser.add_argument("bag", type=Path, help="bag directory (or one .mcap/.db3 file)")
    parser.add_argument(
        "--rate", type=_positive, default=1.0, help="time scale (2 = twice as fast)"
    )
    parser.add_argument("--loop", action="store_true", help="start over at the end until Ctrl-C")
    parser.add_argument("--topics", nargs="+", help="play only these topics")
    parser.add_argument(
        "--clock",
        type=_positive,
        nargs="?",
        const=DEFAULT_CLOCK_HZ,
        metavar="HZ",
        help=f"publish /clock at HZ (default {DEFAULT_CLOCK_HZ:g})",
    )
    parser.add_argument(
        "--start-offset", type=float, default=0.0, metavar="S", help="skip the first S seconds"
    )
    parser.add_argument(
        "--wait-for-subscribers",
        action="store_true",
        help="start only when every played topic has a subscriber",
    )


def publisher_qos(offered: Collection[Qos]) -> QoSProfile:
    """Reliable, PUBLISHER_DEPTH deep, transient-local if a recorded publisher was."""
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    latched = any(q.durability == QosDurability.TRANSIENT_LOCAL for q in offered)
    return QoSProfile(
        depth=PUBLISHER_DEPTH,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE,
    )


class Player:
    """Publishes the messages of ``topics`` of an open bag, paced by the monotonic clock.

    ``stop`` ends playing at the next message or clock tick.
    """

    def __init__(
        self,
        node: Node,
        reader: BagReader,
        topics: list[str],
        rate: float,
        clock_hz: float | None,
    ) -> None:
        from rosgraph_msgs.msg import Clock

        self.reader = reader
        self.topics = topics
        self.rate = rate
        self.clock_period_s = 1.0 / clock_hz if clock_hz else None
        self.stop = threading.Event()
        self.summary = BagSummary()
        self.publishers = {
            topic: node.create_publisher(
                message_class(reader.topics[topic].msgtype),
                topic,
                publisher_qos(reader.topics[topic].qos),
            )
            for topic in topics
        }
        self._clock = node.create_publisher(Clock, "/clock", 10) if clock_hz else None

    def wait_for_subscribers(self) -> None:
        """Block until every publisher has a subscriber, or ``stop``."""
        while any(p.get_subscription_count() == 0 for p in self.publishers.values()):
            if self.stop.wait(WAIT_PERIOD_S):
                return

    def publish_clock(self, bag_ns: int) -> None:
        """One /clock message at bag time ``bag_ns`` (if --clock)."""
        from builtin_interfaces.msg import Time
        from rosgraph_msgs.msg import Clock

        if self._clock is not None:
            sec, nanosec = divmod(bag_ns, 1_000_000_000)
            self._clock.publish(Clock(clock=Time(sec=sec, nanosec=nanosec)))

    def play(self, start_ns: int, progress: Progress) -> bool:
        """One pass from bag time ``start_ns`` to the end; False if stopped."""
        wall_start = time.monotonic()
        next_tick = wall_start
        last_ns = start_ns

        def bag_time(wall: float) -> int:
            return start_ns + round((wall - wall_start) * self.rate * 1e9)

        for msg in self.reader.messages(self.topics, start_ns=start_ns):
            if self.stop.is_set():
                return False
            due = wall_start + (msg.log_time_ns - start_ns) / self.rate / 1e9
            while True:
                now = time.monotonic()
                if self.clock_period_s is not None and next_tick <= min(due, now):
                    self.publish_clock(bag_time(now))
                    next_tick += self.clock_period_s
                    if next_tick <= now:  # late (a slow machine): one period from now
                        next_tick = now + self.clock_period_s
                    continue
                wake = due if self.clock_period_s is None else min(due, next_tick)
                if wake <= now:
                    break
                if self.stop.wait(wake - now):
                    return False
            self.publishers[msg.topic].publish(msg.message)
            self.summary.add(msg.topic, msg.msgtype, msg.log_time_ns)
            last_ns = msg.log_time_ns
            progress.update((last_ns - start_ns) / 1e9)
        self.publish_clock(last_ns)
        return True

    def flush(self) -> None:
        """Wait (ACK_TIMEOUT_S at most) until reliable subscribers acknowledged everything."""
        from rclpy.duration import Duration

        deadline = time.monotonic() + ACK_TIMEOUT_S
        clock = [] if self._clock is None else [self._clock]
        for publisher in [*self.publishers.values(), *clock]:
            remaining = max(deadline - time.monotonic(), 0.0)
            publisher.wait_for_all_acked(Duration(nanoseconds=round(remaining * 1e9)))


def run(args: argparse.Namespace) -> int:
    """Play until the end (or forever with --loop) or Ctrl-C; prints what was published."""
    try:
        reader = BagReader(args.bag)
    except BagError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    with reader:
        if not reader.topics:
            print(f"error: {args.bag} has no messages", file=sys.stderr)
            return 1
        topics = sorted(reader.topics) if args.topics is None else list(args.topics)
        if unknown := sorted(set(topics) - set(reader.topics)):
            print(f"error: {args.bag} has no topic {', '.join(unknown)}", file=sys.stderr)
            return 2
        playable = [t for t in topics if _importable(reader.topics[t].msgtype)]
        for topic in sorted(set(topics) - set(playable)):
            msgtype = reader.topics[topic].msgtype
            print(f"warning: {topic}: type {msgtype} not installed, not played", file=sys.stderr)
        if not playable:
            return 1
        return _play(args, reader, playable)


def _importable(msgtype: str) -> bool:
    try:
        message_class(msgtype)
    except (ImportError, AttributeError, ValueError):
        return False
    return True


def _play(args: argparse.Namespace, reader: BagReader, topics: list[str]) -> int:
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("gnss_ins_play")
    try:
        player = Player(node, reader, topics, args.rate, args.clock)
        for signum in (signal.SIGINT, signal.SIGTERM):
            signal.signal(signum, lambda *_: player.stop.set())
        start_ns = reader.start_ns + round(args.start_offset * 1e9)
        if args.wait_for_subscribers:
            print(f"waiting for subscribers on {', '.join(topics)}", file=sys.stderr)
            player.wait_for_subscribers()
        wall_start = time.monotonic()
        span_s = max(reader.end_ns - start_ns, 0) / 1e9
        passes = 1
        with Progress("play", total=span_s, unit="s") as progress:
            while player.play(start_ns, progress) and args.loop:
                passes += 1
        player.flush()
        wall_s = time.monotonic() - wall_start
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    title = f"played {args.bag} at rate {args.rate:g}, {passes} pass(es) in {wall_s:.2f} s"
    print(player.summary.format(title))
    return 0
