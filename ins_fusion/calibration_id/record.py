"""A bag's IMU data as arrays: imu/data_raw and imu/temperature (no ROS).

``read_bag`` takes the header stamps (the sample times, shared/ARCHITECTURE.md "The shared
clock"), sorted; ``write_bag`` writes what imu400cc_node publishes, for simulated procedures.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from rosbags.highlevel import AnyReaderError
from rosbags.rosbag2 import ReaderError
from rosbags.serde import SerdeError

from gnss_ins_common.message_fields import stamp_ns
from gnss_ins_common.types import FloatArray
from ins_fusion.messages_in import imu_sample, stamp_s
from ins_fusion.sim.messages import fill_imu, fill_temperature, new_message
from ins_fusion.tools.bag_io import BagError, BagReader, BagWriter

IMU_TOPIC = "/imu/data_raw"
TEMPERATURE_TOPIC = "/imu/temperature"
IMU_TYPE = "sensor_msgs/msg/Imu"
TEMPERATURE_TYPE = "sensor_msgs/msg/Temperature"
#: Frame of imu400cc_node's messages (ARCHITECTURE.md).
IMU_FRAME = "imu_link"


class RecordError(Exception):
    """A bag cannot give an IMU record (missing topic, wrong type, no samples)."""


@dataclass(frozen=True)
class ImuRecord:
    """One recording: sample stamps t_s [s since the epoch] (n,), increasing; rate_flu_rad_s
    and force_flu_m_s2 (n, 3) in imu_link FLU (REP-145); temperature stamps [s] and values [°C]
    (m,), possibly empty; name (the bag it came from)."""

    name: str
    t_s: FloatArray
    rate_flu_rad_s: FloatArray
    force_flu_m_s2: FloatArray
    temperature_t_s: FloatArray
    temperature_c: FloatArray

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

    def temperature_range(self, t_start_s: float, t_end_s: float) -> tuple[float, float] | None:
        """Lowest and highest temperature [°C] stamped in [t_start_s, t_end_s] (None: none)."""
        inside = (self.temperature_t_s >= t_start_s) & (self.temperature_t_s <= t_end_s)
        if not np.any(inside):
            return None
        values = self.temperature_c[inside]
        return float(values.min()), float(values.max())


def read_bag(
    path: Path, imu_topic: str = IMU_TOPIC, temperature_topic: str = TEMPERATURE_TOPIC
) -> ImuRecord:
    """The IMU record of a bag; the temperature topic is optional. RecordError on bad input."""
    try:
        with BagReader(path) as reader:
            _check_topic(reader, path, imu_topic, IMU_TYPE)
            topics = [imu_topic]
            if temperature_topic in reader.topics:
                _check_topic(reader, path, temperature_topic, TEMPERATURE_TYPE)
                topics.append(temperature_topic)
            samples: list[tuple[float, ...]] = []
            temperatures: list[tuple[float, float]] = []
            for msg in reader.messages(topics, deserialize=True):
                if msg.topic == imu_topic:
                    s = imu_sample(msg.message)
                    samples.append((s.t_s, *s.rate_flu_rad_s, *s.force_flu_m_s2))
                else:
                    temperatures.append((stamp_s(msg.message), float(msg.message.temperature)))
    except (BagError, AnyReaderError, ReaderError, SerdeError, OSError) as exc:
        raise RecordError(f"{path}: {exc}") from None
    if len(samples) < 2:
        raise RecordError(f"{path}: {imu_topic} has {len(samples)} message(s)")
    data = np.array(samples)
    data = data[np.argsort(data[:, 0], kind="stable")]
    data = data[np.concatenate(([True], np.diff(data[:, 0]) > 0.0))]  # repeated stamps
    temp = np.array(temperatures).reshape(-1, 2)
    temp = temp[np.argsort(temp[:, 0], kind="stable")]
    return ImuRecord(
        Path(path).name, data[:, 0], data[:, 1:4], data[:, 4:7], temp[:, 0], temp[:, 1]
    )


def _check_topic(reader: BagReader, path: Path, topic: str, msgtype: str) -> None:
    if topic not in reader.topics:
        available = ", ".join(sorted(reader.topics)) or "none"
        raise RecordError(f"{path}: no topic {topic} (topics: {available})")
    if reader.topics[topic].msgtype != msgtype:
        raise RecordError(f"{path}: {topic} is {reader.topics[topic].msgtype}, not {msgtype}")


def write_bag(path: Path, record: ImuRecord) -> None:
    """Write a record as imu400cc_node publishes it (simulated procedures): imu/data_raw and
    imu/temperature, each received at its stamp; covariances zero (unknown)."""
    zero = (0.0, 0.0, 0.0)
    imu = [
        (
            stamp_ns(t),
            IMU_TOPIC,
            fill_imu(new_message(IMU_TYPE), stamp_ns(t), IMU_FRAME, w, f, zero, zero),
        )
        for t, w, f in zip(
            record.t_s.tolist(),
            record.rate_flu_rad_s.tolist(),
            record.force_flu_m_s2.tolist(),
            strict=True,
        )
    ]
    temperature = [
        (
            stamp_ns(t),
            TEMPERATURE_TOPIC,
            fill_temperature(new_message(TEMPERATURE_TYPE), stamp_ns(t), IMU_FRAME, c, 0.0),
        )
        for t, c in zip(record.temperature_t_s.tolist(), record.temperature_c.tolist(), strict=True)
    ]
    with BagWriter(path) as writer:
        writer.add_topic(IMU_TOPIC, IMU_TYPE)
        writer.add_topic(TEMPERATURE_TOPIC, TEMPERATURE_TYPE)
        for time_ns, topic, message in sorted(imu + temperature, key=lambda e: e[0]):
            writer.write(topic, time_ns, message)
