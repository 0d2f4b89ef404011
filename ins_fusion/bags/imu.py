"""The IMU samples of one recording as arrays: the record type, its reader and its writer (no ROS).

``ImuRecord`` is what ``gnss_ins allan`` (ins_fusion.noise_id) and ``gnss_ins calibrate``
(ins_fusion.calibration_id) analyse; ``read_imu`` makes it from a bag, ``write_imu_bag`` writes
one as imu400cc_node publishes it (simulated records for the tests, benchmarks and procedures).

Time base: sample times are the messages' ``header.stamp`` (ARCHITECTURE.md "The shared
clock"), not the bag's receive (log) times. ``t_s`` and ``temperature_t_s`` count seconds from
the record's ``start_ns`` [ns since the Unix epoch]: with ``start_ns`` 0 they are seconds since
the epoch (``sec + nanosec·1e-9``, as ins_fusion_node reads stamps); ``read_imu(relative=True)``
puts ``start_ns`` at the first sample and takes exact integer-ns differences. Axes and units are
those of imu/data_raw (REP-145, imu_link FLU): rates [rad/s], specific force [m/s²] (a level
resting unit reads about (0, 0, +9.81)); temperatures [°C].
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from rosbags.highlevel import AnyReaderError
from rosbags.rosbag2 import ReaderError
from rosbags.serde import SerdeError

from gnss_ins_common.message_fields import fill_imu, fill_temperature, stamp_ns
from gnss_ins_common.types import FloatArray, IntArray
from ins_fusion.adapters.cdr_fields import CdrError, imu_columns
from ins_fusion.bags.bag_io import BagError, BagReader, BagWriter
from ins_fusion.bags.columns import read_topics
from ins_fusion.bags.messages import new_message
from ins_fusion.bags.topics import (
    IMU_DATA,
    IMU_FRAME,
    IMU_TEMPERATURE,
    IMU_TYPE,
    TEMPERATURE_TYPE,
)


def _no_samples() -> FloatArray:
    return np.zeros(0)


@dataclass(frozen=True)
class ImuRecord:
    """Samples of one IMU recording (time base, axes and units: see the module docstring).

    - ``t_s`` (n,): sample times [s after ``start_ns``], strictly increasing;
    - ``rate_flu_rad_s``, ``force_flu_m_s2`` (n, 3): angular rate [rad/s] and specific force
      [m/s²] in imu_link FLU;
    - ``temperature_t_s``, ``temperature_c`` (m,): imu/temperature stamps [s after
      ``start_ns``] and values [°C], possibly empty;
    - ``start_ns``: origin of the times [ns since the Unix epoch] (0: times since the epoch);
    - ``name``: where it came from (a bag's directory name).
    """

    t_s: FloatArray
    rate_flu_rad_s: FloatArray
    force_flu_m_s2: FloatArray
    temperature_t_s: FloatArray = field(default_factory=_no_samples)
    temperature_c: FloatArray = field(default_factory=_no_samples)
    start_ns: int = 0
    name: str = ""

    def __post_init__(self) -> None:
        n = len(self.t_s)
        if self.rate_flu_rad_s.shape != (n, 3) or self.force_flu_m_s2.shape != (n, 3):
            raise ValueError("rate and force need shape (n, 3) for n stamps")
        if n and np.any(np.diff(self.t_s) <= 0.0):
            raise ValueError("IMU stamps must increase")
        if self.temperature_t_s.shape != self.temperature_c.shape:
            raise ValueError("temperature stamps and values differ in length")

    @property
    def rate_hz(self) -> float:
        """Median sample rate [Hz]."""
        return float(1.0 / np.median(np.diff(self.t_s)))

    @property
    def duration_s(self) -> float:
        """Time from the first to the last sample [s]."""
        return float(self.t_s[-1] - self.t_s[0]) if len(self.t_s) else 0.0

    def temperature_range(self, t_start_s: float, t_end_s: float) -> tuple[float, float] | None:
        """Lowest and highest temperature [°C] stamped in [t_start_s, t_end_s] (None: none)."""
        inside = (self.temperature_t_s >= t_start_s) & (self.temperature_t_s <= t_end_s)
        if not np.any(inside):
            return None
        values = self.temperature_c[inside]
        return float(values.min()), float(values.max())


def _check_topic(reader: BagReader, topic: str, msgtype: str) -> None:
    info = reader.topics.get(topic)
    if info is None:
        same_type = sorted(t for t, i in reader.topics.items() if i.msgtype == msgtype)
        kind = msgtype.rsplit("/", 1)[-1]
        raise BagError(
            f"{reader.path}: no topic {topic} ({kind} topics: {', '.join(same_type) or 'none'})"
        )
    if info.msgtype != msgtype:
        raise BagError(f"{reader.path}: {topic} is {info.msgtype}, not {msgtype}")


def read_imu(
    path: Path | str,
    topic: str = IMU_DATA,
    temperature_topic: str | None = IMU_TEMPERATURE,
    progress: Callable[[int, int], None] | None = None,
    *,
    relative: bool = False,
) -> ImuRecord:
    """The record of the sensor_msgs/Imu ``topic`` of a bag, in stamp order (whatever order the
    recorder logged the messages in; of samples with the same time the first is kept), with the
    sensor_msgs/Temperature ``temperature_topic`` when the bag has it (None: not read). Times
    since the epoch, or with ``relative`` since the first IMU stamp (see the module docstring).

    ``progress(done, total)`` is called after every chunk read and at the end. BagError
    for an unreadable bag, a missing IMU topic, a topic of another type or fewer than two
    distinct stamps.
    """
    try:
        with BagReader(path) as reader:
            _check_topic(reader, topic, IMU_TYPE)
            topics = [topic]
            if temperature_topic is not None and temperature_topic in reader.topics:
                _check_topic(reader, temperature_topic, TEMPERATURE_TYPE)
                topics.append(temperature_topic)
            total = sum(reader.topics[t].count for t in topics)
            columns = read_topics(
                reader, topics, None if progress is None else lambda done: progress(done, total)
            )
            imu = imu_columns(columns[topic].payloads)
            messages = [  # a few: through rosbags
                reader.deserialize(data, TEMPERATURE_TYPE)
                for t in topics[1:]
                for data in columns[t].payloads
            ]
            temperatures = [
                (m.header.stamp.sec, m.header.stamp.nanosec, m.temperature) for m in messages
            ]
            if progress is not None:
                progress(total, total)
    except (AnyReaderError, ReaderError, SerdeError, CdrError, OSError) as exc:
        raise BagError(f"{path}: {exc}") from None
    sec_ns = np.column_stack(np.divmod(imu.stamp_ns, 1_000_000_000)).reshape(-1, 2)
    start_ns = int(imu.stamp_ns.min()) if relative and len(sec_ns) else 0
    t_s = _seconds(sec_ns, start_ns)
    order = np.argsort(t_s, kind="stable")
    order = order[np.concatenate(([True], np.diff(t_s[order]) > 0.0))[: len(order)]]
    if len(order) < 2:
        distinct = (
            f" ({len(order)} distinct stamp(s): are the header stamps set?)" if len(sec_ns) else ""
        )
        raise BagError(f"{path}: {topic} has {len(sec_ns)} message(s){distinct}")
    data = np.column_stack([imu.rate, imu.force])[order]
    temp_sec_ns = np.array([(s, n) for s, n, _ in temperatures], dtype=np.int64).reshape(-1, 2)
    temp_t_s = _seconds(temp_sec_ns, start_ns)
    temp_order = np.argsort(temp_t_s, kind="stable")
    temp_c = np.array([c for _, _, c in temperatures], dtype=np.float64)
    return ImuRecord(
        t_s[order],
        data[:, :3],
        data[:, 3:],
        temp_t_s[temp_order],
        temp_c[temp_order],
        start_ns,
        Path(path).name,
    )


def _seconds(sec_ns: IntArray, start_ns: int) -> FloatArray:
    """Stamps (sec, nanosec) (n, 2) as seconds after ``start_ns``: ``sec + nanosec·1e-9`` for
    0 (as messages_in.stamp_s), else the integer-ns difference divided by 1e9."""
    if start_ns == 0:
        return sec_ns[:, 0].astype(np.float64) + sec_ns[:, 1].astype(np.float64) * 1e-9
    return (sec_ns[:, 0] * 1_000_000_000 + sec_ns[:, 1] - start_ns) / 1e9


def write_imu_bag(
    path: Path | str,
    record: ImuRecord,
    *,
    topic: str = IMU_DATA,
    delay_ns: int = 0,
    storage: str = "mcap",
    stamps_ns: IntArray | None = None,
) -> None:
    """A new bag with the record as imu400cc_node publishes it: sensor_msgs/Imu on ``topic``
    (frame imu_link, covariances zero = unknown) and, when the record has temperatures,
    sensor_msgs/Temperature on /imu/temperature. Stamps are the record's ``start_ns`` + its times
    [ns] (IMU stamps: ``stamps_ns`` when given); each message is logged ``delay_ns`` after its
    stamp."""
    if stamps_ns is None:
        imu_stamps = [record.start_ns + stamp_ns(t) for t in record.t_s.tolist()]
    else:
        imu_stamps = [int(stamp) for stamp in stamps_ns]
    with BagWriter(path, storage=storage) as writer:
        payloads = _imu_payloads(writer, imu_stamps, record.rate_flu_rad_s, record.force_flu_m_s2)
        events: list[tuple[int, str, object]] = list(
            zip(imu_stamps, [topic] * len(imu_stamps), payloads, strict=True)
        )
        temperature_stamps = [
            record.start_ns + stamp_ns(t) for t in record.temperature_t_s.tolist()
        ]
        events += [
            (
                stamp,
                IMU_TEMPERATURE,
                fill_temperature(new_message(TEMPERATURE_TYPE), stamp, IMU_FRAME, c, 0.0),
            )
            for stamp, c in zip(temperature_stamps, record.temperature_c.tolist(), strict=True)
        ]
        writer.add_topic(topic, IMU_TYPE)
        if len(record.temperature_t_s):
            writer.add_topic(IMU_TEMPERATURE, TEMPERATURE_TYPE)
        for stamp, name, message in sorted(events, key=lambda e: e[0]):
            writer.write(name, stamp + delay_ns, message)


def _imu_payloads(
    writer: BagWriter, stamps_ns: list[int], rate_rad_s: FloatArray, force_m_s2: FloatArray
) -> list[bytes]:
    """The CDR bytes of the sensor_msgs/Imu that ``fill_imu`` makes of each sample (zero
    covariances), all at once: one message serialized by rosbags is the template, and numpy
    writes each sample's stamp, rate and force at their fixed offsets (layout: the module
    docstring of ins_fusion.adapters.cdr_fields), ~40 times faster than one rosbags message
    object serialized per sample (a 40 min record: 321 600 messages)."""
    zero = (0.0, 0.0, 0.0)
    message = fill_imu(new_message(IMU_TYPE), 0, IMU_FRAME, zero, zero, zero, zero)
    template = np.frombuffer(writer.typestore.serialize_cdr(message, IMU_TYPE), np.uint8)
    if template[1] != 1:
        raise BagError("the typestore does not serialize little-endian CDR")
    stamp_at = 4  # after the encapsulation header: sec (int32), nanosec (uint32), frame_id
    body = stamp_at + ((8 + 4 + len(IMU_FRAME) + 1 + 7) & ~7)  # aligned to 8 after it
    rate_at = body + 8 * (4 + 9)  # after the orientation and its covariance
    force_at = rate_at + 8 * (3 + 9)  # after the rate and its covariance
    n = len(stamps_ns)
    sec, nanosec = np.divmod(np.array(stamps_ns, dtype=np.int64), 1_000_000_000)
    raw = np.empty((n, len(template)), np.uint8)
    raw[:] = template
    for at, values in (
        (stamp_at, sec.astype("<i4")),
        (stamp_at + 4, nanosec.astype("<u4")),
        (rate_at, np.asarray(rate_rad_s, dtype="<f8")),
        (force_at, np.asarray(force_m_s2, dtype="<f8")),
    ):
        columns = np.ascontiguousarray(values).view(np.uint8).reshape(n, -1)
        raw[:, at : at + columns.shape[1]] = columns
    data, size = raw.tobytes(), len(template)
    return [data[k * size : (k + 1) * size] for k in range(n)]
