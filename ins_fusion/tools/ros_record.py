"""The rclpy half of ``gnss_ins record`` (ins_fusion/tools/record.py): a node that subscribes
with ``raw=True`` (serialized CDR, no deserialization) to each requested topic as soon as a
publisher of it appears in the graph, with the QoS its publishers offer (reliable only if all
are, transient-local only if all are — rosbag2's rule). The node spins the nodes' executor
(gnss_ins_common/ros_node_main.py: rclpy's EventsExecutor, which takes each message in C++;
SingleThreadedExecutor rebuilt its wait set of every subscription and its message-lost event in
Python for every message, about two thirds of the recorder's CPU). Callbacks only queue (topic,
receive time, bytes); a writer thread takes the queue every WRITE_PERIOD_S (not once per
message) and hands it to ``BagWriter``. The receive time is the system clock (ns since the epoch)
when the callback takes the message, as rosbag2's recorder stamps it (rclpy 7.1's EventsExecutor
fails on callbacks that ask for the message info with the middleware's reception time:
"SystemError: null argument to internal routine"). The writer thread runs a
``RecordingWriter`` (ins_fusion/bags/recording.py): messages held a moment and written in
log-time order, flushed on a bounded interval, the disk's free space guarded; a process killed
otherwise (SIGKILL, power cut) leaves all but its last fraction of a second on disk.

The node also watches its topics (a streaming topic silent for ``silence_s`` while it has a
publisher, a topic whose publishers all left: a warning in its log, which ``gnss_ins launch``
shows, and a WARN status; a topic with a publisher but without a first message for
FIRST_MESSAGE_FACTOR times ``silence_s``: said once in the log) and publishes its state on
/diagnostics every DIAGNOSTICS_PERIOD_S. A topic that carries messages on events only (a port
opened, set-up commands written) is never silent: a topic streams once it has carried messages
for ``silence_s`` at least two per ``silence_s``.
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
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.duration import Duration
from rclpy.event_handler import SubscriptionEventCallbacks
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

from gnss_ins_common.ros_diagnostics import ERROR, OK, WARN, make_status
from gnss_ins_common.ros_node_main import SpinSlices, make_executor
from ins_fusion.bags.recording import RecordingWriter
from ins_fusion.runtime.progress import Progress

#: How often the graph is searched for new topics (s).
DISCOVERY_PERIOD_S = 0.2
#: Subscription history depth: messages the middleware keeps while the executor is busy.
SUBSCRIPTION_DEPTH = 1000
#: Longest spin between two looks at the stop request and the progress line [s]; a stop ends
#: the spin at once (each return costs a Python round: 0.1 s slices cost ~0.15 % of a core).
SPIN_PERIOD_S = 1.0
#: How often the writer thread takes the queued messages (s): one wake-up for all of them.
WRITE_PERIOD_S = 0.05
#: How many times ``silence_s`` a subscribed topic may go without its first message before the
#: log says so: 60 s by default (the fusion's outputs start when it has aligned, 15-40 s on a
#: vehicle at rest).
FIRST_MESSAGE_FACTOR = 12
#: Spins in a row that take no message before the recorder stops taking them after a stop.
DRAIN_IDLE_SPINS = 3
#: Longest wait for the subscribers of /diagnostics to take the ERROR status of a recorder
#: that stops on its own (full disk, writing failed) [s].
FINAL_STATUS_WAIT_S = 1.0
#: Period of the recorder's /diagnostics status and of its topic watch (s).
DIAGNOSTICS_PERIOD_S = 1.0


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


class _Watch:
    """What the recorder saw of one topic: messages, first and last arrival (monotonic s),
    warnings."""

    def __init__(self) -> None:
        self.count = 0
        self.first: float | None = None
        self.last = time.monotonic()
        self.silent_warned = False
        self.had_publishers = True

    def streams(self, silence_s: float) -> bool:
        """Its messages came for ``silence_s`` at least, on average two per ``silence_s``: a
        stream, not a burst of set-up commands or a port event now and then."""
        if self.first is None or self.count < 3:
            return False
        span_s = self.last - self.first
        return span_s >= silence_s and span_s / (self.count - 1) <= silence_s / 2.0


class Recorder:
    """Subscribes to topics as they appear and writes what they carry on a writer thread.

    ``topics`` None records every topic. Counters (``received``, ``lost``) are updated on the
    executor thread; the writer thread owns ``recording`` (and its bag) and closes it. ``stop`` is
    set by the owner to end the recording, or by the writer thread when writing fails or the
    disk guard stopped the recording.
    """

    def __init__(
        self, node: Node, recording: RecordingWriter, topics: list[str] | None, silence_s: float
    ) -> None:
        self.node = node
        self.recording = recording
        self.writer = recording.writer
        self.wanted = None if topics is None else {node.resolve_topic_name(t) for t in topics}
        self.silence_s = silence_s
        self.received = 0
        self.lost: Counter[str] = Counter()
        self.error: BaseException | None = None
        #: topic -> when it was subscribed [s after the start]
        self.subscribed_s: dict[str, float] = {}
        self._started = time.monotonic()
        self.stop = threading.Event()
        self._subscriptions: dict[str, Any] = {}
        self._watch: dict[str, _Watch] = {}
        self._ignored: set[str] = set()
        self._queue: queue.SimpleQueue[_Declare | _Message | None] = queue.SimpleQueue()
        self._closing = threading.Event()  # wakes the writer thread for the None sentinel
        self._thread = threading.Thread(target=self._write_loop, name="bag-writer", daemon=True)
        self._thread.start()
        self._diagnostics = node.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self._discover()
        self._timer = node.create_timer(DISCOVERY_PERIOD_S, self._discover)
        self._status_timer = node.create_timer(DIAGNOSTICS_PERIOD_S, self._watch_and_report)
        self._slices = SpinSlices(node, SPIN_PERIOD_S)

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
            self._watch[topic] = _Watch()
            self.subscribed_s[topic] = time.monotonic() - self._started
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

    def _on_message(self, topic: str, data: bytes) -> None:
        self._queue.put(_Message(topic, time.time_ns(), data))
        self.received += 1
        watch = self._watch[topic]
        watch.count += 1
        if watch.first is None:
            watch.first = time.monotonic()
        if watch.silent_warned:
            silent = time.monotonic() - watch.last
            self.node.get_logger().info(
                f"{topic} recorded again after {silent:.1f} s of silence"
                if watch.count > 1
                else f"{topic}: its first message, {silent:.0f} s after its subscription"
            )
            watch.silent_warned = False
        watch.last = time.monotonic()

    def _on_lost(self, topic: str, status: Any) -> None:
        self.lost[topic] += int(status.total_count_change)

    def _watch_and_report(self) -> None:
        """Warn about silent topics and topics that lost their publishers; publish the status."""
        now = time.monotonic()
        logger = self.node.get_logger()
        silent = []
        for topic, watch in self._watch.items():
            publishers = self.node.count_publishers(topic)
            if publishers == 0 and watch.had_publishers:
                logger.warning(f"{topic}: no publisher any more (its node stopped?)")
            watch.had_publishers = publishers > 0
            if not publishers:
                continue
            if watch.streams(self.silence_s) and now - watch.last > self.silence_s:
                silent.append(topic)
                if not watch.silent_warned:
                    watch.silent_warned = True
                    logger.warning(
                        f"{topic} silent for {now - watch.last:.1f} s although it has a publisher"
                    )
            elif (
                not watch.count
                and not watch.silent_warned
                and now - watch.last > self.silence_s * FIRST_MESSAGE_FACTOR
            ):
                # Said once, not a warning: an output that starts late by design (the fusion's
                # while it aligns) or a topic of events that have not happened (no set-up
                # commands for this receiver) is not a fault; its node's own status says more.
                watch.silent_warned = True
                logger.info(
                    f"{topic}: no message yet, {now - watch.last:.0f} s after its subscription"
                )
        self._diagnostics.publish(self._status(now, silent))

    def _status(self, now: float, silent: list[str]) -> DiagnosticArray:
        recording = self.recording
        values: dict[str, object] = {
            "bag": self.writer.path,
            "files": len(self.writer.files) + 1,
            "messages": self.received,
            "late_messages": recording.late,
            "deleted_files": len(recording.deleted),
        }
        if recording.free is not None:
            values["free_bytes"] = recording.free.free_bytes
            values["min_free_bytes"] = recording.min_free.limit(recording.free.total_bytes)
        for topic, watch in sorted(self._watch.items()):
            values[f"{topic} count"] = watch.count
            values[f"{topic} age_s"] = round(now - watch.last, 3)
        if self.error is not None or recording.stopped is not None:
            level, message = ERROR, recording.stopped or f"writing failed: {self.error!r}"
        elif recording.low_disk:
            level, message = WARN, "disk space low"
        elif silent:
            level, message = WARN, f"silent: {', '.join(silent)}"
        else:  # a requested topic nobody publishes (corrections without --ntrip) is no fault
            level, message = OK, "recording"
            if self.waiting_for:
                message += f"; no publisher yet: {', '.join(self.waiting_for)}"
        status = make_status(
            f"{self.node.get_name()}: recording", str(self.writer.path), level, message, values
        )
        array = DiagnosticArray(status=[status])
        array.header.stamp = self.node.get_clock().now().to_msg()
        return array

    def _take_queue(self) -> bool:
        """Hand every queued item to the recording; False at the None sentinel."""
        while True:
            try:
                item = self._queue.get_nowait()
            except queue.Empty:
                return True
            if item is None:
                return False
            if isinstance(item, _Declare):
                self.recording.declare(item.topic, item.msgtype, item.qos)
            else:
                self.recording.receive(item.topic, item.receive_ns, item.data)

    def _write_loop(self) -> None:
        """Every WRITE_PERIOD_S hand the queued items to the recording and let it write, flush
        and check the disk when due, until the None sentinel; then close it — all on this
        thread (the storage, e.g. a sqlite3 connection, belongs to the thread that opened it)."""
        try:
            self.recording.service()
            while True:
                # Never longer: a message that came after a silence must not wait for the
                # recording's next deadline (a disk check, 1 s) before its hold even starts.
                self._closing.wait(WRITE_PERIOD_S)
                going_on = self._take_queue()
                self.recording.service()
                if self.recording.stopped is not None:
                    self.request_stop()
                if not going_on:
                    break
        except BaseException as exc:  # re-raised by close()
            self.error = exc
            self.request_stop()
        finally:
            try:
                self.recording.close()  # nothing left to do when the disk guard closed it
            except BaseException as exc:
                self.error = self.error or exc

    def request_stop(self) -> None:
        """End the recording (Ctrl-C, SIGTERM, the writer thread): the spin returns at once."""
        self.stop.set()
        self._slices.wake()

    def spin(self, executor: Any, progress: Progress) -> None:
        """Spin until ``stop``, then take every message the middleware already received."""
        while not self.stop.is_set():
            self._slices.spin(executor, SPIN_PERIOD_S)
            progress.update(self.received, f"backlog {self.backlog}")
        for timer in (self._timer, self._status_timer, self._slices):
            timer.cancel()
        if self.error is not None or self.recording.stopped is not None:
            # The reason on /diagnostics before the process ends (gnss_ins status shows it).
            self._diagnostics.publish(self._status(time.monotonic(), []))
            self._diagnostics.wait_for_all_acked(Duration(seconds=FINAL_STATUS_WAIT_S))
        idle = 0
        while idle < DRAIN_IDLE_SPINS:  # one event per spin; ends when none is left
            before = self.received
            executor.spin_once(timeout_sec=0.0)
            idle = idle + 1 if self.received == before else 0
        progress.update(self.received)

    def close(self) -> None:
        """Write what is queued, close the bag; re-raises a writer-thread error."""
        self._queue.put(None)
        self._closing.set()
        self._thread.join()
        if self.error is not None:
            raise self.error


class Recorded(NamedTuple):
    """What ``record`` reports: messages lost in transport per topic, the writer thread's error
    (None: written), and when each topic was subscribed [s after the recorder started]."""

    lost: Counter[str]
    failure: Exception | None
    subscribed_s: dict[str, float]


def record(
    recording: RecordingWriter, topics: list[str] | None, silence_s: float, name: str
) -> Recorded:
    """Record into ``recording`` until Ctrl-C/SIGTERM or until its disk guard stops it (``topics``
    None: every topic) and close it (see ``Recorded``)."""
    # Own signal handlers (not rclpy's, which shut the context down at once) so that messages
    # already received are still taken and written after Ctrl-C.
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node(name)
    executor = make_executor()
    executor.add_node(node)
    recorder = Recorder(node, recording, topics, silence_s)
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: recorder.request_stop())
    if recorder.waiting_for:
        print(f"waiting for {', '.join(recorder.waiting_for)}", file=sys.stderr)
    failure: Exception | None = None
    try:
        with Progress("recorded", unit="msgs") as progress:
            recorder.spin(executor, progress)
    finally:
        executor.shutdown(timeout_sec=2.0)  # its callbacks off the node's endpoints before they go
        node.destroy_node()
        rclpy.try_shutdown()
        try:
            recorder.close()
        except Exception as exc:  # raised on the writer thread
            failure = exc
    return Recorded(recorder.lost, failure, recorder.subscribed_s)
