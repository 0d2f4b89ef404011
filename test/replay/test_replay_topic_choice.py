"""A replay whose default topics are absent takes the bag's only topic of a role's type and says
so, or refuses with the candidates; the same for the reference (PREFIX/fix)."""

from __future__ import annotations

from pathlib import Path

import pytest
from support.sim_bags import FIGURE_EIGHT_90_S, shared_bag

from ins_fusion.bags.bag_io import BagReader, BagWriter
from ins_fusion.bags.topics import FIX_TYPE, IMU_TYPE, VELOCITY_TYPE
from ins_fusion.replay.inputs import InputError, load_bag
from ins_fusion.replay.topics import (
    DEFAULT_TOPICS,
    TopicChoiceError,
    TopicMap,
    choose_reference,
    choose_topics,
)

#: The demo's recorded bag: receivers under their namespaces, the node's output, the truth.
DEMO_TOPICS = {
    "/imu/data_raw": IMU_TYPE,
    "/leica/gnss/fix": FIX_TYPE,
    "/leica/gnss/vel": VELOCITY_TYPE,
    "/adu5/gnss/attitude": IMU_TYPE,
    "/ins/fix": FIX_TYPE,
    "/ground_truth/fix": FIX_TYPE,
    "/ground_truth/vel": VELOCITY_TYPE,
    "/ground_truth/attitude": IMU_TYPE,
}


def test_the_only_candidate_of_each_role_is_taken_and_said() -> None:
    topics, notes = choose_topics(DEFAULT_TOPICS, DEMO_TOPICS, "/ground_truth")
    assert topics.by_role() == {
        "imu": "/imu/data_raw",
        "fix": "/leica/gnss/fix",
        "vel": "/leica/gnss/vel",
        "attitude": "/adu5/gnss/attitude",
        "speed": "/vehicle/speed",  # absent: optional, never chosen, nothing said
    }
    assert notes == [
        f"no /gnss/fix: fix from /leica/gnss/fix, the bag's only {FIX_TYPE}",
        f"no /gnss/vel: vel from /leica/gnss/vel, the bag's only {VELOCITY_TYPE}",
        f"no /gnss/attitude: attitude from /adu5/gnss/attitude, the bag's only {IMU_TYPE}",
    ]


def test_several_candidates_are_refused_with_the_list() -> None:
    two_receivers = {**DEMO_TOPICS, "/rover2/gnss/fix": FIX_TYPE}
    with pytest.raises(TopicChoiceError) as error:
        choose_topics(DEFAULT_TOPICS, two_receivers, "/ground_truth")
    assert "/leica/gnss/fix, /rover2/gnss/fix" in str(error.value)
    assert "--topics fix=TOPIC" in str(error.value)
    # Naming the role settles it; a missing role without a candidate is said, not hidden.
    named = TopicMap.parse("fix=/rover2/gnss/fix")
    topics, notes = choose_topics(named, two_receivers, "/ground_truth")
    assert topics.fix == "/rover2/gnss/fix" and topics.vel == "/leica/gnss/vel"
    _, notes = choose_topics(DEFAULT_TOPICS, {"/imu/data_raw": IMU_TYPE}, "/ground_truth")
    assert f"no /gnss/fix and no other {FIX_TYPE} topic: replaying without fix" in notes


def test_the_reference_prefix_is_chosen_the_same_way() -> None:
    sensors = ["/imu/data_raw", "/leica/gnss/fix", "/leica/gnss/vel", "/adu5/gnss/attitude"]
    assert choose_reference("/ground_truth", DEMO_TOPICS, sensors) == ("/ground_truth", None)
    spatial = {k.replace("/ground_truth", "/spatial"): v for k, v in DEMO_TOPICS.items()}
    prefix, note = choose_reference("/ground_truth", spatial, sensors)
    assert prefix == "/spatial" and note is not None and "/spatial/*" in note
    with pytest.raises(TopicChoiceError, match="/novatel/fix, /spatial/fix"):
        choose_reference("/ground_truth", {**spatial, "/novatel/fix": FIX_TYPE}, sensors)
    assert choose_reference("/ground_truth", {"/ins/fix": FIX_TYPE}, []) == ("/ground_truth", None)
    # The vehicle's recording: no truth, the ADU5's own fix beside its attitude (a sensor topic).
    vehicle = {k: v for k, v in DEMO_TOPICS.items() if not k.startswith("/ground_truth")}
    vehicle["/adu5/gnss/fix"] = FIX_TYPE
    assert choose_reference("/ground_truth", vehicle, sensors) == ("/ground_truth", None)


def _renamed(source: Path, target: Path, names: dict[str, str]) -> None:
    """A copy of ``source`` with topics renamed (raw messages, the same log times)."""
    with BagReader(source) as reader, BagWriter(target) as writer:
        for name, topic in reader.topics.items():
            writer.add_topic(names.get(name, name), topic.msgtype, topic.qos)
        for message in reader.messages():
            writer.write(
                names.get(message.topic, message.topic), message.log_time_ns, message.message
            )


def test_a_namespaced_bag_replays_like_the_plain_one(
    tmp_path_factory: pytest.TempPathFactory, tmp_path: Path
) -> None:
    plain = shared_bag(tmp_path_factory, "figure_eight_90", FIGURE_EIGHT_90_S)
    names = {
        "/gnss/fix": "/leica/gnss/fix",
        "/gnss/vel": "/leica/gnss/vel",
        "/gnss/attitude": "/adu5/gnss/attitude",
    }
    _renamed(plain, tmp_path / "namespaced", names)
    expected = load_bag(plain)
    chosen = load_bag(tmp_path / "namespaced")
    assert [(k, role) for k, role, _ in chosen.measurements] == [
        (k, role) for k, role, _ in expected.measurements
    ]
    assert chosen.reference is not None and len(chosen.notes) == 3 and expected.notes == ()
    # The truth under another prefix: the reference found there, and said.
    truth = {f"/ground_truth/{s}": f"/spatial/{s}" for s in ("fix", "vel", "attitude")}
    _renamed(plain, tmp_path / "spatial", truth)
    moved = load_bag(tmp_path / "spatial")
    assert moved.reference is not None and moved.reference_prefix == "/spatial"
    assert len(moved.notes) == 1 and "/spatial/*" in moved.notes[0]
    # A second receiver's fix makes the choice ambiguous: refused, nothing guessed.
    _renamed(plain, tmp_path / "two", {**names, "/ground_truth/fix": "/rover2/gnss/fix"})
    with pytest.raises(InputError, match="/leica/gnss/fix, /rover2/gnss/fix"):
        load_bag(tmp_path / "two")


def test_the_vehicle_speed_is_never_taken_from_another_topic_of_its_type() -> None:
    """A bag's other TwistWithCovarianceStamped (here a wheel odometry's twist under another
    name) is not the vehicle speed unless named: reading a GNSS velocity as a forward speed
    would corrupt the filter."""
    available = {
        "/imu/data_raw": IMU_TYPE,
        "/gnss/vel": VELOCITY_TYPE,
        "/wheels/twist": VELOCITY_TYPE,
    }
    topics, notes = choose_topics(DEFAULT_TOPICS, available, "/ground_truth")
    assert topics.speed == "/vehicle/speed"
    assert not [note for note in notes if "speed" in note]
