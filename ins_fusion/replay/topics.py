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
    TRUTH_PREFIX,
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
}
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
