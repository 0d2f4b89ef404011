"""Topics the replay reads: the node's input roles and the reference topics, with their types.

Kept free of the engine and of rosbags so that the command line can parse ``--topics`` without
loading them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ins_fusion.bags.topics import (
    ATTITUDE_TYPE,
    FIX_TYPE,
    GNSS_ATTITUDE,
    GNSS_FIX,
    GNSS_VEL,
    IMU_DATA,
    IMU_TYPE,
    INS_FIX,
    ODOMETRY_TYPE,
    TRUTH_PREFIX,
    VEHICLE_SPEED,
    VELOCITY_TYPE,
)

#: Default reference prefix (the simulator's truth topics).
DEFAULT_REFERENCE = TRUTH_PREFIX
#: Topic roles of the fusion node -> expected message type.
SENSOR_TYPES: dict[str, str] = {
    "imu": IMU_TYPE,
    "fix": FIX_TYPE,
    "vel": VELOCITY_TYPE,
    "attitude": ATTITUDE_TYPE,
    "speed": VELOCITY_TYPE,
}
#: Other message types a role takes: wheel odometry's twist as the vehicle speed.
ALSO_TYPES: dict[str, tuple[str, ...]] = {"speed": (ODOMETRY_TYPE,)}
#: Roles used only when their topic is in the bag or named: never chosen among the bag's
#: topics of their type, and no note when absent (a bag without a speed is the usual case).
OPTIONAL_ROLES = frozenset({"speed"})
#: Reference topic suffixes -> expected message type.
REFERENCE_TYPES: dict[str, str] = {
    "fix": FIX_TYPE,
    "attitude": ATTITUDE_TYPE,
    "vel": VELOCITY_TYPE,
}


def _absolute(topic: str) -> str:
    return topic if topic.startswith("/") else f"/{topic}"


@dataclass(frozen=True)
class TopicMap:
    """Bag topics of the node's inputs (the node's names, absolute)."""

    imu: str = IMU_DATA
    fix: str = GNSS_FIX
    vel: str = GNSS_VEL
    attitude: str = GNSS_ATTITUDE
    speed: str = VEHICLE_SPEED
    #: Roles the user named (``parse``): their topics must be in the bag.
    named: tuple[str, ...] = field(default=(), compare=False)

    def __post_init__(self) -> None:
        topics = list(self.by_role().values())
        for topic in topics:
            if topics.count(topic) > 1:
                raise ValueError(f"topic {topic} is given for more than one role")

    @classmethod
    def parse(cls, text: str) -> TopicMap:
        """``imu=/a,fix=/b,...`` (any subset; relative names get a leading '/')."""
        values: dict[str, str] = {}
        for item in filter(None, (part.strip() for part in text.split(","))):
            role, sep, topic = item.partition("=")
            if not sep or role not in SENSOR_TYPES or not topic:
                raise ValueError(
                    f"topic mapping {item!r} is not ROLE=TOPIC with ROLE one of"
                    f" {', '.join(SENSOR_TYPES)}"
                )
            values[role] = _absolute(topic)
        return cls(**values, named=tuple(values))

    def by_role(self) -> dict[str, str]:
        """{role: topic} for the roles of SENSOR_TYPES."""
        return {role: getattr(self, role) for role in SENSOR_TYPES}


#: The node's default topic names.
DEFAULT_TOPICS = TopicMap()


class TopicChoiceError(ValueError):
    """A default topic is absent and the bag offers several of its type (message lists them)."""


#: The fusion node's own outputs (``/ins/...``): never an input nor a reference.
_OUTPUT_PREFIX = INS_FIX.rsplit("/", 1)[0] + "/"


def _listing(topics: list[str]) -> str:
    return ", ".join(topics)


def choose_topics(
    topics: TopicMap, available: dict[str, str], reference_prefix: str
) -> tuple[TopicMap, list[str]]:
    """The input topics of a bag whose topics and types are ``available``: a role the user did
    not name and whose default topic is absent takes the bag's only topic of the role's type
    (not the reference's, not the node's ``/ins`` output, not another role's); several such
    topics raise TopicChoiceError listing them. Returns the map and one note per role whose
    topic was chosen or is missing."""
    taken = {t for r, t in topics.by_role().items() if r in topics.named or t in available}
    reference = reference_prefix.rstrip("/") + "/"
    chosen: dict[str, str] = {}
    notes: list[str] = []
    for role, default in topics.by_role().items():
        if role in topics.named or default in available or role in OPTIONAL_ROLES:
            continue
        wanted = SENSOR_TYPES[role]
        candidates = sorted(
            t
            for t, msgtype in available.items()
            if msgtype == wanted
            and t not in taken
            and not t.startswith((reference, _OUTPUT_PREFIX))
        )
        if len(candidates) > 1:
            raise TopicChoiceError(
                f"no {default}; the bag's {wanted} topics {_listing(candidates)} could each be"
                f" the {role!r} input: choose one with --topics {role}=TOPIC"
            )
        if candidates:
            chosen[role] = candidates[0]
            taken.add(candidates[0])
            notes.append(f"no {default}: {role} from {candidates[0]}, the bag's only {wanted}")
        else:
            notes.append(f"no {default} and no other {wanted} topic: replaying without {role}")
    roles = {**topics.by_role(), **chosen}
    return TopicMap(**roles, named=topics.named), notes


def choose_reference(
    prefix: str, available: dict[str, str], sensor_topics: list[str]
) -> tuple[str, str | None]:
    """The reference prefix: ``prefix`` when ``PREFIX/fix`` is in the bag, else the only other
    ``P/fix`` of the reference type (none of ``P/*`` a sensor topic: a receiver's own fix beside
    its attitude is no reference; not the node's output), with a note
    saying so; several raise TopicChoiceError listing them; none keeps ``prefix`` (no
    reference)."""
    prefix = prefix.rstrip("/")
    wanted = REFERENCE_TYPES["fix"]
    if f"{prefix}/fix" in available:
        return prefix, None
    candidates = sorted(
        t
        for t, msgtype in available.items()
        if msgtype == wanted
        and t.endswith("/fix")
        and not t.startswith(_OUTPUT_PREFIX)
        and not _shares_a_sensor_topic(t.removesuffix("/fix"), sensor_topics)
    )
    if len(candidates) > 1:
        raise TopicChoiceError(
            f"no {prefix}/fix; the bag's other {wanted} topics {_listing(candidates)} could each"
            " be the reference: choose one with --reference PREFIX (the topic without /fix)"
        )
    if not candidates:
        return prefix, None
    found = candidates[0].removesuffix("/fix")
    return found, f"no {prefix}/fix: reference {found}/*, the bag's only other {wanted} /fix"


def _shares_a_sensor_topic(prefix: str, sensor_topics: list[str]) -> bool:
    """True if a reference topic under ``prefix`` would be one the replay reads as a sensor."""
    return any(f"{prefix}/{name}" in sensor_topics for name in REFERENCE_TYPES)
