"""The driver cores fed from a recording's raw topics, as the nodes fed them live (no ROS).

- ``ImuDecoder``: each ``imu/raw`` message (gnss_ins_msgs/SerialChunk) in order: ``STARTED`` a
  new ``ImuDriver`` (the node started), ``OPENED`` ``reset()`` (the port reopened), ``DATA``
  each of its reads (gnss_ins_common.serial_reads) as ``feed(read, seconds_of_ns(read time))``:
  the node fed the driver those very bytes and that very float.
- ``GnssDecoder``: each line of ``nmea`` as ``feed(line + CR LF, seconds_of_ns(stamp))``, one
  call per line (the node fed the chunk holding the lines' ends at that stamp: the same
  sentences at the same time), ``port_events`` as the IMU's events. The node closes an epoch
  the line left idle from a timer (``flush_idle`` at its clock every ``epoch_idle_timeout``/2);
  here ``flush_idle`` runs at each message's stamp before it is taken and at the end: the same
  epochs with the same stamps (an epoch's stamp comes from its sentences, never from the flush
  time) unless a gap between lines lay between one and 1.5 ``epoch_idle_timeout``, where the
  node's timer may have missed it (docs/redecode.md, "Limits").

The messages are built by the nodes' own code (``imu400cc_driver.messages``,
``gnss_driver.messages``) on rosbags classes.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from gnss_driver.driver import EpochOutput, GnssDriver
from gnss_driver.messages import MessageClasses, epoch_messages
from gnss_driver.parameters import driver_config as gnss_config
from gnss_driver.profiles import Receiver
from gnss_ins_common.message_fields import seconds_of_ns
from gnss_ins_common.serial_reads import split_reads
from imu400cc_driver.driver import ImuDriver
from imu400cc_driver.messages import sample_messages
from imu400cc_driver.parameters import driver_config as imu_config
from ins_fusion.bags.messages import new_message
from ins_fusion.bags.topics import (
    ATTITUDE_TYPE,
    FIX_TYPE,
    IMU_TYPE,
    TEMPERATURE_TYPE,
    TIME_REFERENCE_TYPE,
    VELOCITY_TYPE,
)

#: SerialChunk.event values (ros_interfaces/gnss_ins_msgs/msg/SerialChunk.msg).
DATA, OPENED, STARTED = 0, 1, 2
#: Message types of what the decoders rebuild, by topic relative to the node's namespace.
IMU_TOPICS = {"imu/data_raw": IMU_TYPE, "imu/temperature": TEMPERATURE_TYPE}
GNSS_TOPICS = {
    "gnss/fix": FIX_TYPE,
    "gnss/vel": VELOCITY_TYPE,
    "gnss/attitude": ATTITUDE_TYPE,
    "gnss/time_reference": TIME_REFERENCE_TYPE,
}
#: rosbags message makers of the GNSS topics (gnss_driver.messages).
GNSS_CLASSES = MessageClasses(
    *(lambda kind=kind: new_message(kind) for kind in GNSS_TOPICS.values())
)
#: What gnss_node's publishing survives of a bad epoch (it counts them as publish errors).
_PUBLISH_ERRORS = (AssertionError, ValueError, OverflowError)

Rebuilt = Iterator[tuple[str, Any]]


def header_ns(msg: Any) -> int:
    """header.stamp of a rosbags message [ns]."""
    stamp = msg.header.stamp
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


class ImuDecoder:
    """imu400cc_node's decoding of ``imu/raw`` (module docstring)."""

    def __init__(self, params: dict[str, Any]) -> None:
        """``params``: the node's validated parameters."""
        self._config = imu_config(params)
        self._frame_id: str = params["frame_id"]
        self.driver = ImuDriver(self._config)

    def take(self, chunk: Any) -> Rebuilt:
        """(relative topic, message) of what one SerialChunk completes."""
        if chunk.event == STARTED:
            self.driver = ImuDriver(self._config)
        elif chunk.event == OPENED:
            self.driver.reset()
        elif chunk.event == DATA:
            driver = self.driver
            reads = split_reads(
                bytes(chunk.data), chunk.read_ends, chunk.read_times_ns, header_ns(chunk)
            )
            for data, time_ns in reads:
                for sample in driver.feed(data, seconds_of_ns(time_ns)):
                    imu, temperature = sample_messages(
                        sample,
                        driver,
                        self._frame_id,
                        lambda: new_message(IMU_TYPE),
                        lambda: new_message(TEMPERATURE_TYPE),
                    )
                    yield "imu/data_raw", imu
                    if temperature is not None:
                        yield "imu/temperature", temperature


class GnssDecoder:
    """gnss_node's decoding of ``nmea`` and ``port_events`` (module docstring)."""

    def __init__(self, params: dict[str, Any]) -> None:
        """``params``: the node's validated parameters."""
        self._config = gnss_config(params)
        self._frame_id: str = params["frame_id"]
        self._source = Receiver(params["receiver"]).value
        self.driver = GnssDriver(self._config)

    def event(self, chunk: Any) -> Rebuilt:
        """A ``port_events`` message: an idle epoch closed, then the driver new or reset."""
        yield from self.idle(header_ns(chunk))
        if chunk.event == STARTED:
            self.driver = GnssDriver(self._config)
        elif chunk.event == OPENED:
            self.driver.reset()

    def line(self, sentence: Any) -> Rebuilt:
        """An ``nmea`` message: an idle epoch closed, then the line read."""
        time_ns = header_ns(sentence)
        yield from self.idle(time_ns)
        line = sentence.sentence.encode("ascii", "backslashreplace") + b"\r\n"
        yield from self._messages(self.driver.feed(line, seconds_of_ns(time_ns)))

    def idle(self, time_ns: int) -> Rebuilt:
        """The epoch the line left idle up to ``time_ns`` [ns], if any."""
        return self._messages(self.driver.flush_idle(seconds_of_ns(time_ns)))

    def _messages(self, outputs: list[EpochOutput]) -> Rebuilt:
        for out in outputs:
            messages = epoch_messages(out, self._frame_id, self._source, GNSS_CLASSES)
            try:
                yield from messages
            except _PUBLISH_ERRORS:  # as the node: the rest of that epoch is lost
                continue
