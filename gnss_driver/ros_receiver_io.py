"""gnss_node's raw traffic with the receiver on ROS topics (relative names, root namespace).

- ``rtcm`` (rtcm_msgs/Message, subscribed, reliable, depth 100): RTCM 3 corrections for the
  receiver from any publisher (an NTRIP client, a base station); each message must hold whole
  frames. Only frames with a valid CRC are written, each whole in one write, in order, never
  older than ``corrections_max_age`` (gnss_driver/corrections.py).
- ``nmea`` (nmea_msgs/Sentence): every line read from the receiver, as received and in order,
  the rejected ones (bad or missing checksum, unknown type, cut off) included; stamped with the
  host receive time of the chunk that held the line's end; latched (the last 500 lines).
- ``port_events`` (gnss_ins_msgs/SerialChunk, no data): each open of the port, just after the
  driver was reset and before the set-up (``STARTED`` the node's first, ``OPENED`` a later one),
  where ``gnss_ins redecode`` starts the driver anew; published with ``nmea``, latched (the last
  10).
- ``to_device/rtcm`` (rtcm_msgs/Message, one frame each) and ``to_device/nmea``
  (nmea_msgs/Sentence, one set-up command each, latched: the last 500): what the node wrote to the
  receiver, stamped with the host time of the write.

Like the measurements, ``nmea`` is published only while the node is active (``port_events`` in
every state); corrections are
written whenever the port is open and the receiver set up (configured, active or not), and
``to_device/*`` record every write, so they are published in every state.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from nmea_msgs.msg import Sentence
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rtcm_msgs.msg import Message

from gnss_driver.corrections import CorrectionQueue, CorrectionWriter
from gnss_ins_common.message_fields import set_header, stamp_ns
from gnss_ins_common.ros_diagnostics import guarded
from gnss_ins_common.ros_endpoints import Endpoints
from gnss_ins_common.ros_lifecycle import ManagedSerialDriver
from gnss_ins_common.ros_serial import RawPublisher, node_time_s

#: nmea, to_device/nmea and port_events are latched: a recorder that subscribes late, or matches
#: a restarted node only after its first lines, still gets the last 500 lines (50-100 s of a
#: receiver) and 10 opens.
RAW_QOS = QoSProfile(
    depth=500, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
)
EVENTS_QOS = QoSProfile(
    depth=10, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
)
#: Queue depth of the rtcm subscription: a burst of a network's epoch (~10 messages) many times.
RTCM_DEPTH = 100


class ReceiverTraffic:
    """The topics of the module docstring for one node; ``write`` writes to the receiver."""

    def __init__(
        self,
        node: ManagedSerialDriver,
        endpoints: Endpoints,
        frame_id: str,
        *,
        corrections: CorrectionQueue | None,
        nmea_output: bool,
        write: Callable[[bytes], bool],
    ) -> None:
        """``corrections``: the queue of the rtcm subscription (None: no subscription);
        ``nmea_output``: publish ``nmea``."""
        self._node = node
        self._frame_id = frame_id
        qos = QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE)
        self._nmea_pub = endpoints.publisher(Sentence, "nmea", RAW_QOS) if nmea_output else None
        self._events = (
            RawPublisher(endpoints, "port_events", frame_id, EVENTS_QOS) if nmea_output else None
        )
        self._opened = False
        self._commands_pub = endpoints.publisher(Sentence, "to_device/nmea", RAW_QOS)
        self.queue = corrections
        self._writer: CorrectionWriter | None = None
        if corrections is not None:
            self._rtcm_pub = endpoints.publisher(Message, "to_device/rtcm", qos)
            endpoints.subscription(
                Message,
                "rtcm",
                self._on_rtcm,
                QoSProfile(depth=RTCM_DEPTH, reliability=ReliabilityPolicy.RELIABLE),
            )
            self._writer = CorrectionWriter(
                corrections,
                write=write,
                ready=lambda: node.port_open,
                now=lambda: node_time_s(node),
                on_written=guarded(node, self._publish_written),
            )
            self._writer.start()

    def stop(self) -> None:
        """Stop writing corrections."""
        if self._writer is not None:
            self._writer.stop()

    def publish_opened(self, time_ns: int) -> None:
        """The port was opened at host time ``time_ns`` [ns] and the driver reset."""
        if self._events is not None:
            self._events.event(not self._opened, time_ns)
        self._opened = True

    def publish_lines(self, lines: list[bytes], time_ns: int) -> None:
        """The lines read from the receiver in a chunk received at host time ``time_ns`` [ns]."""
        if self._nmea_pub is None or not lines or not self._node.publishing(held=0):
            return
        for line in lines:
            msg = Sentence(sentence=line.decode("ascii", "backslashreplace"))
            set_header(msg, time_ns, self._frame_id)
            self._nmea_pub.publish(msg)

    def publish_command(self, command: str, sent_s: float) -> None:
        """A set-up command sent at host time ``sent_s`` [s] (without CR LF)."""
        msg = Sentence(sentence=command)
        set_header(msg, stamp_ns(sent_s), self._frame_id)
        self._commands_pub.publish(msg)

    def diagnostics(self, now_s: float) -> dict[str, object]:
        """The corrections' status values at host time ``now_s`` [s] (none without input)."""
        if self.queue is None:
            return {}
        stats = self.queue.stats
        age_s = now_s - stats.last_written_s
        return {
            "rtcm_messages": stats.messages_in,
            "rtcm_frames": stats.frames_in,
            "rtcm_frames_written": stats.frames_written,
            "rtcm_bytes_written": stats.bytes_written,
            "rtcm_invalid_bytes": stats.invalid_bytes,
            "rtcm_crc_failures": stats.crc_failures,
            "rtcm_dropped_stale": stats.dropped_stale,
            "rtcm_dropped_overflow": stats.dropped_overflow,
            "rtcm_write_failures": stats.write_failures,
            "rtcm_age_s": "-" if math.isnan(age_s) else age_s,
            "rtcm_message_numbers": " ".join(
                f"{number}:{n}" for number, n in sorted(stats.written_by_number.items())
            )
            or "-",
        }

    def _on_rtcm(self, msg: Message) -> None:
        assert self.queue is not None
        self.queue.accept(bytes(msg.message), node_time_s(self._node))

    def _publish_written(self, frame: bytes, written_s: float) -> None:
        msg = Message(message=frame)
        set_header(msg, stamp_ns(written_s), self._frame_id)
        self._rtcm_pub.publish(msg)
