"""The rclpy half of ``gnss_ins play`` (ins_fusion/tools/play.py): publishers of a bag's raw CDR
messages at the wall time ``start + (log_time − bag_start) / rate``, and ``/clock``
(rosgraph_msgs/Clock) at HZ when asked, with a last tick at the time of the last message.
Publishers are reliable (they match reliable and best-effort subscribers) and transient-local
when the recording publisher was.
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
import time
from collections.abc import Collection

import rclpy
from builtin_interfaces.msg import Time
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rosbags.interfaces import Qos, QosDurability
from rosgraph_msgs.msg import Clock

from ins_fusion.bags.bag_io import BagReader
from ins_fusion.bags.summary import BagSummary
from ins_fusion.runtime.progress import Progress
from ins_fusion.tools.ros_record import message_class

#: Publisher history depth.
PUBLISHER_DEPTH = 100
#: At the end, how long at most to wait for reliable subscribers to acknowledge the last
#: messages, so lost ones can still be resent (s). Fast DDS often acknowledges only with its
#: next periodic heartbeat, so this is usually a short linger rather than a confirmation.
ACK_TIMEOUT_S = 0.5
#: Poll period while waiting for subscribers (s).
WAIT_PERIOD_S = 0.05


def publisher_qos(offered: Collection[Qos]) -> QoSProfile:
    """Reliable, PUBLISHER_DEPTH deep, transient-local if a recorded publisher was."""
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
                    # Never past the message not yet published (a late, loaded machine): /clock
                    # stays monotonic up to the final tick at the last message's time.
                    self.publish_clock(min(bag_time(now), msg.log_time_ns))
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
        deadline = time.monotonic() + ACK_TIMEOUT_S
        clock = [] if self._clock is None else [self._clock]
        for publisher in [*self.publishers.values(), *clock]:
            remaining = max(deadline - time.monotonic(), 0.0)
            publisher.wait_for_all_acked(Duration(nanoseconds=round(remaining * 1e9)))


def importable(msgtype: str) -> bool:
    """True if the message class of ``msgtype`` is installed here."""
    try:
        message_class(msgtype)
    except (ImportError, AttributeError, ValueError):
        return False
    return True


def play(args: argparse.Namespace, reader: BagReader, topics: list[str]) -> int:
    """Play ``topics`` of the open bag as ``args`` say (rate, clock, start offset, loop, waiting
    for subscribers) until the end or Ctrl-C; prints what was published."""
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
        passes = 0  # complete passes
        with Progress("play", total=span_s, unit="s") as progress:
            while not player.stop.is_set() and player.play(start_ns, progress):
                passes += 1
                if not args.loop:
                    break
        player.flush()
        wall_s = time.monotonic() - wall_start
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    interrupted = player.stop.is_set()
    if interrupted and player.summary.count == 0:
        waited = " while waiting for subscribers" if args.wait_for_subscribers else ""
        print(f"played {args.bag}: interrupted{waited}, nothing published")
        return 0
    done = f"interrupted after {passes} complete pass(es)" if interrupted else f"{passes} pass(es)"
    title = f"played {args.bag} at rate {args.rate:g}, {done} in {wall_s:.2f} s"
    print(player.summary.format(title))
    return 0
