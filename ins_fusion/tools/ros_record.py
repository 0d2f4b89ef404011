"""The rclpy half of ``gnss_ins record`` (ins_fusion/tools/record.py): a node that subscribes
with ``raw=True`` (serialized CDR, no deserialization) to each requested topic as soon as a
publisher of it appears in the graph, with the QoS its publishers offer (reliable only if all
are, transient-local only if all are — rosbag2's rule). Callbacks only queue (topic, receive time,
bytes); a writer thread hands them to ``BagWriter``. The receive time is the middleware's
reception time (system clock, ns since the epoch). The writer thread flushes the bag every
FLUSH_PERIOD_S while messages come, so a process killed otherwise (SIGKILL, power cut) leaves all
but its last FLUSH_PERIOD_S on disk for ``gnss_ins recover``.
"""

from __future__ import annotations

import importlib
import queue
import signal
import sys
import threading
import time
from collections import Counter
from functools import partial
from typing import Any, NamedTuple

import rclpy
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rosbags.interfaces import (
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)

from ins_fusion.bags.bag_io import BagWriter
from ins_fusion.runtime.progress import Progress

#: How often the graph is searched for new topics (s).
DISCOVERY_PERIOD_S = 0.2
#: Subscription history depth: messages the middleware keeps while the executor is busy.
SUBSCRIPTION_DEPTH = 1000
#: Executor wake-up period, the latency of reacting to Ctrl-C (s).
SPIN_PERIOD_S = 0.1
#: Longest time a written message waits before it is flushed to disk (s): what a kill loses.
FLUSH_PERIOD_S = 0.5


def message_class(msgtype: str) -> Any:
    """The rclpy (rosidl Python) class of ``pkg/msg/Name``; ImportError/AttributeError if the
    package is not installed."""
    package, kind, name = msgtype.split("/")
    return getattr(importlib.import_module(f"{package}.{kind}"), name)


def qos_to_rosbags(profile: QoSProfile) -> Qos:
    """An rclpy QoS profile (e.g. a publisher's, from the graph) as rosbags metadata."""

    def duration(value: Any) -> QosTime:
        return QosTime(*divmod(int(value.nanoseconds), 1_000_000_000))

    return Qos(
        QosHistory(int(profile.history)),
        int(profile.depth),
        QosReliability(int(profile.reliability)),
        QosDurability(int(profile.durability)),
        duration(profile.deadline),
        duration(profile.lifespan),
        QosLiveliness(int(profile.liveliness)),
        duration(profile.liveliness_lease_duration),
        bool(profile.avoid_ros_namespace_conventions),
    )


def subscription_qos(offered: list[QoSProfile]) -> QoSProfile:
    """A profile compatible with every offered one (reliable / transient-local only if all
    publishers are), keeping SUBSCRIPTION_DEPTH messages."""
    reliable = all(p.reliability == ReliabilityPolicy.RELIABLE for p in offered)
    latched = all(p.durability == DurabilityPolicy.TRANSIENT_LOCAL for p in offered)
    return QoSProfile(
        depth=SUBSCRIPTION_DEPTH,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE,
    )


class _Declare(NamedTuple):
    topic: str
    msgtype: str
    qos: list[Qos]


class _Message(NamedTuple):
    topic: str
    receive_ns: int
    data: bytes


class Recorder:
    """Subscribes to topics as they appear and writes what they carry on a writer thread.

    ``topics`` None records every topic. Counters (``received``, ``lost``) are updated on the
    executor thread; the writer thread owns ``writer`` and closes it. ``stop`` is set by the
    owner to end the recording, or by the writer thread when writing fails.
    """

    def __init__(self, node: Node, writer: BagWriter, topics: list[str] | None) -> None:
        self.node = node
        self.writer = writer
        self.wanted = None if topics is None else {node.resolve_topic_name(t) for t in topics}
        self.received = 0
        self.lost: Counter[str] = Counter()
        self.error: BaseException | None = None
        self.stop = threading.Event()
        self._subscriptions: dict[str, Any] = {}
        self._ignored: set[str] = set()
        self._queue: queue.SimpleQueue[_Declare | _Message | None] = queue.SimpleQueue()
        self._thread = threading.Thread(target=self._write_loop, name="bag-writer", daemon=True)
        self._thread.start()
        self._discover()
        self._timer = node.create_timer(DISCOVERY_PERIOD_S, self._discover)

    @property
    def waiting_for(self) -> list[str]:
        """Requested topics with no subscription yet."""
        return sorted((self.wanted or set()) - set(self._subscriptions))

    @property
    def backlog(self) -> int:
        """Messages queued for the writer thread."""
        return self._queue.qsize()

    def _discover(self) -> None:
        for topic, types in self.node.get_topic_names_and_types():
            if topic in self._subscriptions or topic in self._ignored:
                continue
            if self.wanted is not None and topic not in self.wanted:
                continue
            publishers = self.node.get_publishers_info_by_topic(topic)
            if not publishers:
                continue  # known only from subscribers so far: no type or QoS to trust yet
            msgtype = types[0]
            if len(types) > 1:
                print(f"warning: {topic} has types {types}; recording {msgtype}", file=sys.stderr)
            try:
                msg_class = message_class(msgtype)
            except (ImportError, AttributeError, ValueError):
                msg_class = None
            if msg_class is None or msgtype not in self.writer.typestore.fielddefs:
                print(
                    f"warning: {topic}: type {msgtype} unknown here, not recorded", file=sys.stderr
                )
                self._ignored.add(topic)
                continue
            offered = [p.qos_profile for p in publishers]
            self._queue.put(_Declare(topic, msgtype, [qos_to_rosbags(p) for p in offered]))
            self._subscriptions[topic] = self.node.create_subscription(
                msg_class,
                topic,
                partial(self._on_message, topic),
                subscription_qos(offered),
                raw=True,
                event_callbacks=SubscriptionEventCallbacks(
                    message_lost=partial(self._on_lost, topic)
                ),
            )
            print(f"recording {topic} [{msgtype}]", file=sys.stderr)

    def _on_message(self, topic: str, data: bytes, info: dict[str, Any]) -> None:
        receive_ns = info.get("received_timestamp") or self.node.get_clock().now().nanoseconds
        self._queue.put(_Message(topic, receive_ns, data))
        self.received += 1

    def _on_lost(self, topic: str, status: Any) -> None:
        self.lost[topic] += int(status.total_count_change)

    def _write_loop(self) -> None:
        """Write queued items until the None sentinel, then close the bag — all on this thread
        (the storage, e.g. a sqlite3 connection, belongs to the thread that opened it). Items
        written are flushed at most FLUSH_PERIOD_S later."""
        flush_due: float | None = None  # monotonic time the oldest unflushed item must be out
        try:
            while True:
                timeout = None if flush_due is None else max(0.0, flush_due - time.monotonic())
                try:
                    item = self._queue.get(timeout=timeout)
                except queue.Empty:  # nothing came for a while: out with what is pending
                    self.writer.flush()
                    flush_due = None
                    continue
                if item is None:
                    break
                if isinstance(item, _Declare):
                    self.writer.add_topic(item.topic, item.msgtype, item.qos)
                else:
                    self.writer.write(item.topic, item.receive_ns, item.data)
                if flush_due is None:
                    flush_due = time.monotonic() + FLUSH_PERIOD_S
                elif time.monotonic() >= flush_due:
                    self.writer.flush()
                    flush_due = None
        except BaseException as exc:  # re-raised by close()
            self.error = exc
            self.stop.set()
        finally:
            try:
                self.writer.close()
            except BaseException as exc:
                self.error = self.error or exc

    def spin(self, executor: Any, progress: Progress) -> None:
        """Spin until ``stop``, then take every message the middleware already received."""
        while not self.stop.is_set():
            executor.spin_once(timeout_sec=SPIN_PERIOD_S)
            progress.update(self.received, f"backlog {self.backlog}")
        self._timer.cancel()
        before = -1
        while before != self.received:  # one pass per ready message; ends when none is ready
            before = self.received
            executor.spin_once(timeout_sec=0.0)
        progress.update(self.received)

    def close(self) -> None:
        """Write what is queued, close the bag; re-raises a writer-thread error."""
        self._queue.put(None)
        self._thread.join()
        if self.error is not None:
            raise self.error


def record(writer: BagWriter, topics: list[str] | None) -> tuple[Counter[str], Exception | None]:
    """Record into ``writer`` until Ctrl-C/SIGTERM (``topics`` None: every topic) and close it;
    returns the messages lost in transport per topic and the error of the writer thread (disk
    full, ...) if writing failed."""
    # Own signal handlers (not rclpy's, which shut the context down at once) so that messages
    # already received are still taken and written after Ctrl-C.
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("gnss_ins_record")
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    recorder = Recorder(node, writer, topics)
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: recorder.stop.set())
    if recorder.waiting_for:
        print(f"waiting for {', '.join(recorder.waiting_for)}", file=sys.stderr)
    failure: Exception | None = None
    try:
        with Progress("recorded", unit="msgs") as progress:
            recorder.spin(executor, progress)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
        try:
            recorder.close()
        except Exception as exc:  # raised on the writer thread
            failure = exc
    return recorder.lost, failure
