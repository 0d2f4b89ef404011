"""The walk of one IMU sample through the fusion node, from its IMU callback to the published
odometry: how many stops, in how many files, and how often it comes back to a file it left.

The node (rclpy, no executor) is fed the synthetic drive of core.engine.warm_up through its own
callbacks until it navigates; then one callback of a sample with an output due is traced
(sys.setprofile): the sequence of the repository's files the interpreter is in (calls, returns
to the caller, a compiled kernel as one stop in its source file), repeats in a row collapsed.
Two samples: an ordinary one and one at a pseudo-measurement epoch (an NHC).

Usage: ROS_DOMAIN_ID=<free> [PYTHONPATH=<tree>] python bench/sample_walk.py   (a few seconds)
"""

from __future__ import annotations

import collections
import sys
from collections.abc import Callable
from pathlib import Path
from types import FrameType
from typing import Any

import rclpy
from rclpy.parameter import Parameter
from rclpy.serialization import serialize_message
from sensor_msgs.msg import Imu

import ins_fusion
from ins_fusion.core.engine.warm_up import synthetic_drive
from ins_fusion.core.filter.records import (
    AttitudeMeasurement,
    GnssFixMeasurement,
    GnssVelocityMeasurement,
)
from ins_fusion.node import InsFusionNode

#: The tree whose code is walked (PYTHONPATH=<tree> walks another).
REPO = Path(ins_fusion.__file__).resolve().parents[1]
#: The drive's stamps are moved by this [s] (a host clock's stamps are far from zero).
EPOCH_S = 1000.0
#: Samples traced only after this much of the drive [s]: the filter runs and the vehicle moves.
MOVING_AFTER_S = 6.0


def imu_message(t_s: float, rate: Any, force: Any) -> bytes:
    """A serialized sensor_msgs/Imu as the IMU driver publishes it."""
    msg = Imu()
    msg.header.stamp.sec = int(t_s)
    msg.header.stamp.nanosec = round((t_s - int(t_s)) * 1e9)
    msg.header.frame_id = "imu_link"
    msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z = map(float, rate)
    msg.linear_acceleration.x, msg.linear_acceleration.y, msg.linear_acceleration.z = map(
        float, force
    )
    return bytes(serialize_message(msg))


def trace(call: Callable[[], None]) -> list[str]:
    """The repository files the interpreter is in during ``call``, repeats collapsed."""
    walk: list[str] = []

    def enter(path: str) -> None:
        outside = any(f"/{folder}/" in path for folder in ("bench", "test", ".venv"))
        if path.startswith(str(REPO)) and not outside:
            name = Path(path).relative_to(REPO).as_posix()
            if not walk or walk[-1] != name:
                walk.append(name)

    def profile(frame: FrameType, event: str, arg: Any) -> None:
        kernel = getattr(arg, "py_func", None)
        if event == "call":
            enter(frame.f_code.co_filename)
        elif event == "return" and frame.f_back is not None:
            enter(frame.f_back.f_code.co_filename)
        elif event == "c_call" and kernel is not None:
            enter(kernel.__code__.co_filename)
        elif event == "c_return" and kernel is not None:
            enter(frame.f_code.co_filename)

    sys.setprofile(profile)
    try:
        call()
    finally:
        sys.setprofile(None)
    return walk


def main() -> None:
    rclpy.init()
    node = InsFusionNode(parameter_overrides=[Parameter("alignment.duration", value=1.0)])
    feed = {
        GnssFixMeasurement: node.engine.add_gnss_fix,
        GnssVelocityMeasurement: node.engine.add_gnss_velocity,
        AttitudeMeasurement: node.engine.add_attitude,
    }
    (t_s, rate, force, _), measurements = synthetic_drive()
    pending = collections.deque(measurements)
    walks: dict[str, list[str]] = {}
    try:
        for k in range(len(t_s)):
            while pending and pending[0][0] <= k:
                measurement = pending.popleft()[1]
                if type(measurement) in feed:
                    node._take_held()
                    feed[type(measurement)](measurement)  # its own stamp: the drive's clock
            t = float(t_s[k])
            data = imu_message(t, rate[k], force[k])
            engine = node.engine
            case = None
            if t > MOVING_AFTER_S and node._output_clock.due(t) and not engine._timeline.due_by(t):
                case = "epoch (NHC)" if t >= engine._next_pseudo_t_s else "ordinary"
            if case is not None and case not in walks and engine._timeline.replay_from is None:
                node._take_held()
                walks[case] = trace(lambda data=data: node._on_imu(data))
            else:
                node._on_imu(data)
    finally:
        node.destroy_node()
        rclpy.shutdown()
    for case, walk in walks.items():
        files = collections.Counter(walk)
        print(
            f"{case}: {len(walk)} stops in {len(files)} files, "
            f"{len(walk) - len(files)} returns to a file already left"
        )
        print("  " + " > ".join(Path(name).name for name in walk))


if __name__ == "__main__":
    main()
