"""A bag's sensor topics and reference topics, read once into memory for the engine runs.

The inputs keep the bag's receive (log-time) order, which is what ins_fusion_node sees: every
GNSS/attitude measurement records how many IMU samples were received before it. Messages are
read through ins_fusion.tools.bag_io and converted by ins_fusion.messages_in, as the node does
(IMU and reference messages straight from their bytes by ins_fusion.cdr_fields, for
speed).

Reference topics (``PREFIX/fix``, ``PREFIX/attitude``, optional ``PREFIX/vel``): the true
position (NavSatFix, WGS-84, ellipsoidal height), orientation (sensor_msgs/Imu, FLU in ENU) and
ENU velocity (TwistWithCovarianceStamped) of the frame the fix's ``header.frame_id`` names:
base_link for the simulator, imu_link for a pose of the IMU (comma2k19). The IMU messages'
frame_id is kept too, to recognise a reference of the IMU.
"""

from __future__ import annotations

import struct
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.highlevel import AnyReaderError
from rosbags.rosbag2 import ReaderError
from rosbags.serde import SerdeError

from gnss_ins_common.types import FloatArray
from ins_fusion import cdr_fields, messages_in
from ins_fusion.cdr_fields import CdrError
from ins_fusion.core.measurements import (
    AttitudeMeasurement,
    GnssFixMeasurement,
    GnssVelocityMeasurement,
)
from ins_fusion.messages_in import ImuSample
from ins_fusion.replay.topics import (
    DEFAULT_REFERENCE,
    DEFAULT_TOPICS,
    REFERENCE_TYPES,
    SENSOR_TYPES,
    TopicMap,
)
from ins_fusion.tools.bag_io import BagError, BagReader

Measurement = GnssFixMeasurement | GnssVelocityMeasurement | AttitudeMeasurement


class InputError(Exception):
    """The bag or the topic selection cannot be replayed (message says why)."""


@dataclass(frozen=True)
class Series:
    """Samples of a reference: stamps [s] (n,) and values (n, k)."""

    t_s: FloatArray
    values: FloatArray


@dataclass(frozen=True)
class Reference:
    """The true pose of frame ``frame_id`` (the first reference fix's header.frame_id; "" when
    not given): position (lat_deg, lon_deg, height_m), orientation (x, y, z, w of its FLU axes in
    ENU) and, when the bag has it, ENU velocity [m/s]."""

    position: Series
    attitude: Series | None
    velocity: Series | None
    frame_id: str = ""


@dataclass(frozen=True)
class ReplayInputs:
    """What one engine run consumes: IMU samples and measurements in receive order, the
    reference (None: no evaluation) and where they came from.

    ``measurements`` holds (k, topic role, measurement): the measurement arrived after the
    first k IMU samples. ``read_time_s``: wall time spent reading and converting [s].
    """

    bag: str
    topics: TopicMap
    imu: list[ImuSample]
    measurements: list[tuple[int, str, Measurement]]
    reference: Reference | None
    read_time_s: float
    imu_frame: str = ""

    @property
    def t0_s(self) -> float:
        """First IMU stamp [s]: time 0 of outage windows and of the report's times."""
        return self.imu[0].t_s

    @property
    def duration_s(self) -> float:
        """Last minus first IMU stamp [s]."""
        return self.imu[-1].t_s - self.imu[0].t_s


def _check_types(available: dict[str, str], wanted: dict[str, tuple[str, str]], path: Path) -> None:
    """Each wanted topic present in the bag must have its expected type."""
    for topic, (role, expected) in wanted.items():
        actual = available.get(topic)
        if actual is not None and actual != expected:
            raise InputError(f"{path}: {role} topic {topic} is {actual}, expected {expected}")


def load_bag(
    path: Path | str,
    topics: TopicMap = DEFAULT_TOPICS,
    reference_prefix: str = DEFAULT_REFERENCE,
    *,
    reference_required: bool = False,
    progress: Callable[[int, int], None] | None = None,
) -> ReplayInputs:
    """Read the sensor and reference topics of a bag.

    Raises InputError when the bag is missing or unreadable, has no IMU messages on
    ``topics.imu``, a topic named by the user (``topics.named``) is absent or a selected topic
    has the wrong type; also when ``reference_required``
    and ``PREFIX/fix`` is missing. Missing GNSS topics are allowed (the node treats them as
    optional). ``progress(done, total)`` is called every few thousand messages.
    """
    path = Path(path)
    start = time.perf_counter()
    try:
        with BagReader(path) as reader:
            available = {name: info.msgtype for name, info in reader.topics.items()}
            roles = {topic: role for role, topic in topics.by_role().items()}
            prefix = reference_prefix.rstrip("/")
            ref_topics = {f"{prefix}/{s}": s for s in REFERENCE_TYPES}
            _check_types(
                available,
                {t: (f"{r!r}", SENSOR_TYPES[r]) for t, r in roles.items()},
                path,
            )
            _check_types(
                available,
                {t: (f"reference {s!r}", REFERENCE_TYPES[s]) for t, s in ref_topics.items()},
                path,
            )
            if topics.imu not in available or reader.topics[topics.imu].count == 0:
                listing = ", ".join(f"{t} ({m})" for t, m in sorted(available.items()))
                raise InputError(
                    f"{path}: no IMU messages on {topics.imu} (topics: {listing or 'none'});"
                    " choose the IMU topic with --topics imu=TOPIC"
                )
            named = [(r, t) for t, r in roles.items() if r in topics.named]
            if absent := [f"{r}={t}" for r, t in named if t not in available]:
                listing = ", ".join(sorted(available)) or "none"
                raise InputError(
                    f"{path}: --topics names {', '.join(absent)}, not in the bag"
                    f" (topics: {listing})"
                )
            if shared := sorted(set(ref_topics) & {*roles, topics.imu}):
                raise InputError(
                    f"{path}: reference topic(s) {', '.join(shared)} are also sensor topics;"
                    " choose another --reference prefix"
                )
            if f"{prefix}/fix" not in available:
                if reference_required:
                    raise InputError(f"{path}: no reference topic {prefix}/fix")
                ref_topics = {}
            selected = [t for t in (*roles, *ref_topics) if t in available]
            total = sum(reader.topics[t].count for t in selected)
            imu, measurements, reference, imu_frame = _read(
                reader, selected, topics.imu, roles, ref_topics, total, progress
            )
    except (BagError, AnyReaderError, ReaderError, SerdeError, CdrError, OSError) as exc:
        raise InputError(f"cannot read bag {path}: {exc}") from exc
    return ReplayInputs(
        str(path), topics, imu, measurements, reference, time.perf_counter() - start, imu_frame
    )


_CONVERTERS: dict[str, Callable[[Any], Measurement]] = {
    "fix": messages_in.fix_measurement,
    "vel": messages_in.velocity_measurement,
    "attitude": messages_in.attitude_measurement,
}

#: Reference values from the serialized message: position (lat_deg, lon_deg, height_m),
#: orientation (x, y, z, w of FLU in ENU), ENU velocity [m/s].
_REFERENCE_DECODERS: dict[str, Callable[[bytes], tuple[float, tuple[float, ...]]]] = {
    "fix": cdr_fields.position,
    "attitude": cdr_fields.orientation,
    "vel": cdr_fields.linear_velocity,
}


_Read = tuple[list[ImuSample], list[tuple[int, str, Measurement]], Reference | None, str]


def frame_id(data: bytes) -> str:
    """header.frame_id of a serialized (CDR) message that starts with a std_msgs/Header: after
    the 4-byte encapsulation and the stamp, a uint32 length (with the NUL) and the characters
    (ins_fusion.cdr_fields); "" when the bytes are too short to hold it."""
    if len(data) < 16:
        return ""
    (length,) = struct.unpack_from("<I" if data[1] == 1 else ">I", data, 12)
    return bytes(data[16 : 16 + max(length - 1, 0)]).decode("utf-8", "replace")


def _read(
    reader: BagReader,
    selected: list[str],
    imu_topic: str,
    roles: dict[str, str],
    ref_topics: dict[str, str],
    total: int,
    progress: Callable[[int, int], None] | None,
) -> _Read:
    imu: list[ImuSample] = []
    measurements: list[tuple[int, str, Measurement]] = []
    ref: dict[str, list[tuple[float, tuple[float, ...]]]] = {s: [] for s in REFERENCE_TYPES}
    frames: dict[str, str] = {}  # first frame_id of the IMU ("imu") and the reference fix
    raw = {imu_topic, *ref_topics}
    for done, msg in enumerate(reader.messages(selected, deserialize=True, raw_topics=raw), 1):
        if progress is not None and done % 4096 == 0:
            progress(done, total)
        if msg.topic == imu_topic:
            imu.append(cdr_fields.imu_sample(msg.message))
            if len(imu) == 1:
                frames["imu"] = frame_id(msg.message)
            continue
        role = roles.get(msg.topic)
        if role is not None:
            measurements.append((len(imu), role, _CONVERTERS[role](msg.message)))
        suffix = ref_topics.get(msg.topic)
        if suffix is not None:
            ref[suffix].append(_REFERENCE_DECODERS[suffix](msg.message))
            if suffix == "fix" and len(ref["fix"]) == 1:
                frames["fix"] = frame_id(msg.message)
    if progress is not None:
        progress(total, total)
    return imu, measurements, _reference(ref, frames.get("fix", "")), frames.get("imu", "")


def _series(samples: list[tuple[float, tuple[float, ...]]]) -> Series | None:
    """Samples sorted by stamp (a bag is in receive order), None when there are none."""
    if not samples:
        return None
    samples.sort(key=lambda item: item[0])
    return Series(
        np.array([t for t, _ in samples], dtype=np.float64),
        np.array([v for _, v in samples], dtype=np.float64),
    )


def _reference(
    ref: dict[str, list[tuple[float, tuple[float, ...]]]], frame: str
) -> Reference | None:
    position = _series(ref["fix"])
    if position is None:
        return None
    return Reference(position, _series(ref["attitude"]), _series(ref["vel"]), frame)
