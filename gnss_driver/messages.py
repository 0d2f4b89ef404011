"""The messages of one epoch's results, for gnss_node and ``gnss_ins redecode`` alike (no ROS).

``MessageClasses`` makes empty messages: rclpy's classes in the node, rosbags'
(``ins_fusion.bags.messages.new_message``) offline; the fields are set by
``gnss_ins_common.message_fields`` and ``solution.fill_gnss_fix`` either way, so a redecoded
message is the node's.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any, NamedTuple

from gnss_driver.driver import EpochOutput
from gnss_driver.solution import fill_gnss_fix
from gnss_ins_common.message_fields import (
    fill_orientation,
    fill_time_reference,
    fill_velocity,
    stamp_ns,
)

#: The topics of an epoch's messages, relative to the node's namespace.
FIX, VELOCITY, ATTITUDE, TIME_REFERENCE = (
    "gnss/fix",
    "gnss/vel",
    "gnss/attitude",
    "gnss/time_reference",
)
#: The topics in the order of ``MessageClasses``' fields.
TOPICS = (FIX, VELOCITY, ATTITUDE, TIME_REFERENCE)


class MessageClasses(NamedTuple):
    """Makers of empty NavSatFix, TwistWithCovarianceStamped, Imu and TimeReference messages."""

    fix: Callable[[], Any]
    velocity: Callable[[], Any]
    attitude: Callable[[], Any]
    time_reference: Callable[[], Any]


def epoch_messages(
    out: EpochOutput, frame_id: str, source: str, classes: MessageClasses
) -> Iterator[tuple[str, Any]]:
    """(topic, message) of each result of ``out`` in the order the node publishes them; the time
    reference (``source``: the receiver's name) only with the epoch's first publication. Each
    message is built when asked for, so a fill that raises stops the epoch there."""
    stamp = stamp_ns(out.stamp_s)
    if out.fix is not None:
        yield FIX, fill_gnss_fix(classes.fix(), stamp, frame_id, out.fix)
    if out.velocity is not None:
        vel = out.velocity
        yield (
            VELOCITY,
            fill_velocity(classes.velocity(), stamp, frame_id, vel.vel_enu_m_s, vel.cov_enu),
        )
    if out.attitude is not None:
        orientation = out.attitude.orientation
        yield (
            ATTITUDE,
            fill_orientation(
                classes.attitude(),
                stamp,
                frame_id,
                orientation.quat_enu_flu_xyzw,
                orientation.cov_rpy_rad2,
            ),
        )
    if out.utc is not None and not out.extends:
        time_ref = stamp_ns(out.utc.utc_s)
        yield (
            TIME_REFERENCE,
            fill_time_reference(
                classes.time_reference(), stamp_ns(out.host_s), frame_id, time_ref, source
            ),
        )
