"""A bag's sensor topics and reference topics, read once into memory for the engine runs.

The inputs keep the bag's receive (log-time) order, which is what ins_fusion_node sees: every
GNSS/attitude measurement records how many IMU samples were received before it. Messages are
read through ins_fusion.bags.bag_io and converted by ins_fusion.adapters.messages_in, as the node
does (IMU and reference messages straight from their bytes by ins_fusion.adapters.cdr_fields, for
speed).

Reference topics (``PREFIX/fix``, ``PREFIX/attitude``, optional ``PREFIX/vel``): the true
position (NavSatFix, WGS-84, ellipsoidal height), orientation (sensor_msgs/Imu, FLU in ENU) and
ENU velocity (TwistWithCovarianceStamped) of the frame the fix's ``header.frame_id`` names:
base_link for the simulator, imu_link for a pose of the IMU (comma2k19). The IMU messages'
frame_id is kept too, to recognise a reference of the IMU.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.highlevel import AnyReaderError
from rosbags.rosbag2 import ReaderError
from rosbags.serde import SerdeError

from gnss_ins_common.types import FloatArray
from ins_fusion.adapters import cdr_fields, messages_in
from ins_fusion.adapters.cdr_fields import CdrError
from ins_fusion.adapters.messages_in import ImuSample
from ins_fusion.bags.bag_io import BagError, BagReader
from ins_fusion.bags.columns import read_topics
from ins_fusion.core.filter.records import (
    AttitudeMeasurement,
    GnssFixMeasurement,
    GnssVelocityMeasurement,
    VehicleSpeedMeasurement,
)
from ins_fusion.replay.topics import (
    ALSO_TYPES,
    DEFAULT_REFERENCE,
    DEFAULT_TOPICS,
    OPTIONAL_ROLES,
    REFERENCE_TYPES,
    SENSOR_TYPES,
    TopicChoiceError,
    TopicMap,
    choose_reference,
    choose_topics,
)

Measurement = (
    GnssFixMeasurement | GnssVelocityMeasurement | AttitudeMeasurement | VehicleSpeedMeasurement
)


class InputError(Exception):
    """The bag or the topic selection cannot be replayed (message says why)."""


@dataclass(frozen=True)
class Series:
    """Samples of a reference: stamps [s] (n,) and values (n, k)."""

    t_s: FloatArray
    values: FloatArray


@dataclass(frozen=True)
class ImuSeries:
    """IMU samples in receive order: stamps [s] (n,), rate [rad/s] and specific force [m/s²]
    (n, 3) in imu_link FLU (REP-145), as ins_fusion.adapters.messages_in.ImuSample has them."""

    t_s: FloatArray
    rate_flu_rad_s: FloatArray
    force_flu_m_s2: FloatArray

    @classmethod
    def from_samples(cls, samples: Sequence[ImuSample]) -> ImuSeries:
        """The series of a sequence of samples."""
        return cls(
            np.array([s.t_s for s in samples], dtype=np.float64),
            np.array([s.rate_flu_rad_s for s in samples], dtype=np.float64).reshape(-1, 3),
            np.array([s.force_flu_m_s2 for s in samples], dtype=np.float64).reshape(-1, 3),
        )

    def __len__(self) -> int:
        return len(self.t_s)

    def samples(self) -> Iterator[tuple[float, list[float], list[float]]]:
        """(stamp, rate, force) per sample in plain floats, for InsEngine.add_imu."""
        return zip(
            self.t_s.tolist(),
            self.rate_flu_rad_s.tolist(),
            self.force_flu_m_s2.tolist(),
            strict=True,
        )


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
    imu: ImuSeries
    measurements: list[tuple[int, str, Measurement]]
    reference: Reference | None
    read_time_s: float
    imu_frame: str = ""
    #: What the replay chose for a default topic that is absent (choose_topics, choose_reference).
    notes: tuple[str, ...] = ()
    #: The reference topics' prefix (the one chosen when the default is absent).
    reference_prefix: str = DEFAULT_REFERENCE

    @property
    def t0_s(self) -> float:
        """First IMU stamp [s]: time 0 of outage windows and of the report's times."""
        return float(self.imu.t_s[0])

    def roles_read(self) -> dict[str, str]:
        """{role: topic} of the inputs: every role but an optional one (the vehicle speed)
        whose topic gave nothing."""
        given = {role for _, role, _ in self.measurements}
        return {
            role: topic
            for role, topic in self.topics.by_role().items()
            if role not in OPTIONAL_ROLES or role in given
        }

    @property
    def has_speed(self) -> bool:
        """Whether the inputs hold vehicle speed readings (the engine then uses them)."""
        return any(role == "speed" for _, role, _ in self.measurements)

    def without_speed(self) -> ReplayInputs:
        """The same inputs without the vehicle speed readings."""
        kept = [item for item in self.measurements if item[1] != "speed"]
        return replace(self, measurements=kept)

    @property
    def duration_s(self) -> float:
        """Last minus first IMU stamp [s]."""
        return float(self.imu.t_s[-1] - self.imu.t_s[0])


def _check_types(
    available: dict[str, str], wanted: dict[str, tuple[str, tuple[str, ...]]], path: Path
) -> None:
    """Each wanted topic present in the bag must have one of its expected types."""
    for topic, (role, expected) in wanted.items():
        actual = available.get(topic)
        if actual is not None and actual not in expected:
            raise InputError(
                f"{path}: {role} topic {topic} is {actual}, expected {' or '.join(expected)}"
            )


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
            prefix = reference_prefix.rstrip("/")
            try:
                topics, notes = choose_topics(topics, available, prefix)
                if not reference_required:
                    prefix, note = choose_reference(prefix, available, [*topics.by_role().values()])
                    notes += [note] if note else []
            except TopicChoiceError as exc:
                raise InputError(f"{path}: {exc}") from None
            roles = {topic: role for role, topic in topics.by_role().items()}
            ref_topics = {f"{prefix}/{s}": s for s in REFERENCE_TYPES}
            _check_types(
                available,
                {
                    t: (f"{r!r}", (SENSOR_TYPES[r], *ALSO_TYPES.get(r, ())))
                    for t, r in roles.items()
                },
                path,
            )
            _check_types(
                available,
                {t: (f"reference {s!r}", (REFERENCE_TYPES[s],)) for t, s in ref_topics.items()},
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
        detail = str(exc).removeprefix(f"{path}: ")  # the bag's name once
        raise InputError(f"cannot read bag {path}: {detail}") from exc
    return ReplayInputs(
        str(path),
        topics,
        imu,
        measurements,
        reference,
        time.perf_counter() - start,
        imu_frame,
        tuple(notes),
        prefix,
    )


_CONVERTERS: dict[str, Callable[[Any], Measurement]] = {
    "fix": messages_in.fix_measurement,
    "vel": messages_in.velocity_measurement,
    "attitude": messages_in.attitude_measurement,
    "speed": messages_in.speed_measurement,
}


def _fixes(payloads: Sequence[bytes]) -> list[Measurement]:
    """The measurements of a whole NavSatFix topic from its serialized messages (the fields
    read as columns: cdr_fields.fix_columns), as ``messages_in.fix_measurement`` gives them."""
    t_s, status, lla, cov, cov_type = cdr_fields.fix_columns(payloads)
    return list(messages_in.fixes_from_fields(t_s, lla, status, cov_type, cov.reshape(-1, 3, 3)))


def _velocities(payloads: Sequence[bytes]) -> list[Measurement]:
    """``messages_in.velocity_measurement`` of a whole TwistWithCovarianceStamped topic."""
    t_s, linear, cov = cdr_fields.twist_columns(payloads)
    return [
        messages_in.velocity_from_fields(t, (x, y, z), row.reshape(6, 6))
        for t, (x, y, z), row in zip(t_s.tolist(), linear.tolist(), cov, strict=True)
    ]


def _speeds(payloads: Sequence[bytes]) -> list[Measurement]:
    """``messages_in.speed_measurement`` of a whole TwistWithCovarianceStamped topic."""
    t_s, linear, cov = cdr_fields.twist_columns(payloads)
    return [
        messages_in.speed_from_fields(t, row, cov_row)
        for t, row, cov_row in zip(t_s.tolist(), linear, cov, strict=True)
    ]


#: Roles whose whole topic is decoded from the bytes (rosbags deserializes ~60 µs a message),
#: for messages of the expected type; another type goes through rosbags and _CONVERTERS.
_FIELD_DECODERS: dict[str, Callable[[Sequence[bytes]], list[Measurement]]] = {
    "fix": _fixes,
    "vel": _velocities,
    "speed": _speeds,
}
_FIELD_TYPES = {
    "fix": "sensor_msgs/msg/NavSatFix",
    "vel": "geometry_msgs/msg/TwistWithCovarianceStamped",
    "speed": "geometry_msgs/msg/TwistWithCovarianceStamped",
}

#: Reference stamps and values of a whole topic from the serialized messages: position
#: (lat_deg, lon_deg, height_m), orientation (x, y, z, w of FLU in ENU), ENU velocity [m/s].
_REFERENCE_DECODERS: dict[str, Callable[[Sequence[bytes]], tuple[FloatArray, FloatArray]]] = {
    "fix": cdr_fields.positions,
    "attitude": cdr_fields.orientations,
    "vel": cdr_fields.linear_velocities,
}


_Read = tuple[ImuSeries, list[tuple[int, str, Measurement]], Reference | None, str]


def _read(
    reader: BagReader,
    selected: list[str],
    imu_topic: str,
    roles: dict[str, str],
    ref_topics: dict[str, str],
    total: int,
    progress: Callable[[int, int], None] | None,
) -> _Read:
    columns = read_topics(
        reader, selected, None if progress is None else lambda done: progress(done, total)
    )
    imu_column = columns[imu_topic]
    decoded = cdr_fields.imu_columns(imu_column.payloads)
    imu = ImuSeries(decoded.t_s, decoded.rate, decoded.force)
    arrivals: list[tuple[int, int, str, Measurement]] = []  # receive order, k, role, measurement
    for topic, role in roles.items():
        if role == "imu" or topic not in columns:
            continue
        column = columns[topic]
        # IMU messages received before each: the engine gets them first.
        before = np.searchsorted(imu_column.order, column.order).tolist()
        if role in _FIELD_DECODERS and column.msgtype == _FIELD_TYPES[role]:
            received = _FIELD_DECODERS[role](column.payloads)
        else:
            received = [
                _CONVERTERS[role](reader.deserialize(d, column.msgtype)) for d in column.payloads
            ]
        for rank, k, measurement in zip(column.order.tolist(), before, received, strict=True):
            arrivals.append((rank, k, role, measurement))
    arrivals.sort(key=lambda item: item[0])
    series = {
        suffix: _series(*_REFERENCE_DECODERS[suffix](columns[topic].payloads))
        for topic, suffix in ref_topics.items()
        if topic in columns
    }
    reference = None
    if (position := series.get("fix")) is not None:
        fix_topic = next(t for t, suffix in ref_topics.items() if suffix == "fix")
        fix_frame = cdr_fields.frame_id(columns[fix_topic].payloads[0])
        reference = Reference(position, series.get("attitude"), series.get("vel"), fix_frame)
    if progress is not None:
        progress(total, total)
    measurements = [(k, role, m) for _, k, role, m in arrivals]
    return (
        imu,
        measurements,
        reference,
        cdr_fields.frame_id(imu_column.payloads[0]) if len(imu) else "",
    )


def _series(t_s: FloatArray, values: FloatArray) -> Series | None:
    """Samples sorted by stamp (a bag is in receive order), None when there are none."""
    if not len(t_s):
        return None
    order = np.argsort(t_s, kind="stable")
    return Series(t_s[order], values[order])
