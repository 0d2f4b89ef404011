"""What the serial driver nodes share on the ROS side: the link on the node's clock and logger,
the raw record of the port (gnss_ins_msgs/SerialChunk, its reads gathered)."""

from __future__ import annotations

import array
import threading
from collections.abc import Callable

import serial
from gnss_ins_msgs.msg import SerialChunk
from rclpy.node import Node
from rclpy.qos import QoSProfile

from gnss_ins_common.message_fields import set_header
from gnss_ins_common.ros_diagnostics import callback_errors
from gnss_ins_common.ros_endpoints import Endpoints
from gnss_ins_common.serial_link import LinkSettings, SerialLink
from gnss_ins_common.serial_reads import ReadBatch


def node_time_s(node: Node) -> float:
    """The node's ROS clock now [s] (wall time, or /clock with use_sim_time)."""
    return node.get_clock().now().nanoseconds * 1e-9


def start_serial_link(
    node: Node,
    settings: LinkSettings,
    on_open: Callable[[serial.Serial], None],
    on_data: Callable[[bytes, float], None],
) -> SerialLink:
    """A started SerialLink that stamps reads on the node's clock and logs through its logger;
    exceptions of ``on_data`` are the node's callback errors (ros_diagnostics)."""
    logger = node.get_logger()
    errors = callback_errors(node)

    def guarded_on_data(chunk: bytes, received_s: float) -> None:
        try:
            on_data(chunk, received_s)
        except Exception as exc:  # a decoding bug must not take the link down
            if not node.context.ok():
                # Ctrl-C/SIGTERM shut ROS down before the node closes this link: publishing
                # fails until then, which is no error of the data.
                return
            errors.record(exc, getattr(on_data, "__name__", "on_data"))

    link = SerialLink(
        settings,
        on_open=on_open,
        on_data=guarded_on_data,
        now=lambda: node_time_s(node),
        log=logger.warning,
        info=logger.info,
    )
    link.start()
    return link


#: Longest time a read waits to be published [s], and most reads in one message: 0.1 s is ~13
#: reads of the IMU at 134 Hz (one message instead of 13 for the node and the recorder).
RAW_PERIOD_S, RAW_MAX_READS = 0.1, 64


class RawPublisher:
    """A port's reads and (re)opens as gnss_ins_msgs/SerialChunk messages on ``topic``: the reads
    gathered (gnss_ins_common.serial_reads) into one message at most every ``period_s``, each with
    the time fed to the driver core; a port event (``event``) after the reads before it. ``data``
    runs on the link's thread, ``flush`` also on the executor's (a timer: the last reads before a
    silence), hence the lock."""

    def __init__(
        self,
        endpoints: Endpoints,
        topic: str,
        frame_id: str,
        qos: QoSProfile | int,
        period_s: float = RAW_PERIOD_S,
        max_reads: int = RAW_MAX_READS,
    ) -> None:
        """The publisher of ``topic``; ``frame_id``: the node's."""
        self._publisher = endpoints.publisher(SerialChunk, topic, qos)
        self._frame_id = frame_id
        self._batch = ReadBatch(period_ns=round(period_s * 1e9), max_reads=max_reads)
        self._lock = threading.Lock()

    def data(self, chunk: bytes, time_ns: int) -> None:
        """The bytes of one read at host time ``time_ns`` [ns]; published with the batch."""
        with self._lock:
            if self._batch.add(chunk, time_ns):
                self._publish_batch()

    def flush(self, now_ns: int | None = None) -> None:
        """Publish the reads held (all of them, or only a batch due at ``now_ns`` [ns])."""
        with self._lock:
            if now_ns is None or self._batch.due(now_ns):
                self._publish_batch()

    def event(self, first_open: bool, time_ns: int) -> None:
        """The port was opened and the device set up at ``time_ns`` [ns]: for the node's first
        time (``STARTED``, a new driver) or again (``OPENED``, the driver reset)."""
        msg = SerialChunk(event=SerialChunk.STARTED if first_open else SerialChunk.OPENED)
        set_header(msg, time_ns, self._frame_id)
        with self._lock:
            self._publish_batch()
            self._publisher.publish(msg)

    def _publish_batch(self) -> None:
        record = self._batch.take()
        if record is None:
            return
        msg = SerialChunk(event=SerialChunk.DATA)
        # Arrays of typecodes 'B', 'I', 'q' are taken whole; lists are checked item by item.
        msg.data = array.array("B", record.data)
        msg.read_ends = array.array("I", record.read_ends)
        msg.read_times_ns = array.array("q", record.read_times_ns)
        set_header(msg, record.read_times_ns[0], self._frame_id)
        self._publisher.publish(msg)
