"""New ROS processes joining the domain do not stall the data path.

imu400cc_node, the Leica's gnss_node and ins_fusion_node run as their own processes with
``gnss_ins launch``'s command lines and environment (``vehicle_nodes.command``,
``discovery_environment("LOCALHOST")``: UDP only), on an emulated IMU400CC and Leica at rest
(``gnss_ins emulate-imu``, ``emulate-gnss``: processes of their own, so that nothing in this
process delays a packet), so that /imu/data_raw (134 Hz) and /ins/odometry (50 Hz) flow. Then
six processes join the domain one after the other, each with this session's plain environment
(Fast DDS's shared memory on, as an operator's shell gives it): ``gnss_ins status --json`` and a
bare rclpy node that spins 2 s once it has its first IMU message, three times each.

Why six: with shared memory a join stalls the nodes only when a node opens the joiner's port
while the port's listener has been verified by Fast DDS's watchdog and not yet re-armed (a
window of up to 333 ms a second), so not every join stalls: with the nodes' environment removed
5 of 6 runs of this test failed (4 with the 333 ms stall), against 2 of 5 with 3 + 1 joins.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import rclpy
from nav_msgs.msg import Odometry
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu
from support.ros_harness import spinning, wait_for

from ins_fusion.runtime.processes import gnss_ins_command
from ins_fusion.runtime.vehicle_nodes import FUSION, IMU, LEICA, command, discovery_environment

pytestmark = pytest.mark.ros

#: The nodes' environment: what `gnss_ins launch` gives its processes.
NODE_ENV = {**os.environ, **discovery_environment("LOCALHOST")}
#: The subscriber's (this process's) environment while it joins: Fast DDS's builtin transports,
#: UDP only. Not the nodes' profile: Fast DDS reads a profile file once per process, at the first
#: participant, which an earlier test of this session may have created; and with the LOCALHOST
#: range rmw_fastrtps adds shared memory whatever else is set (vehicle_nodes.py). With shared
#: memory this subscriber stalled itself: arrivals 331 ms apart, publications not.
SUBSCRIBER_ENV = {
    "ROS_AUTOMATIC_DISCOVERY_RANGE": "SYSTEM_DEFAULT",
    "FASTDDS_BUILTIN_TRANSPORTS": "UDPv4",
}
TOPICS = {"/imu/data_raw": Imu, "/ins/odometry": Odometry}
#: The bound [ms]: below the 270-377 ms of the shared-memory stall (9 of 10 runs caught with it).
#: Not the issue's 40 ms (two odometry periods), which bench/bench_latency.py --disturb measures
#: on a quiet machine: this test runs beside the rest of the suite on 2 cores, where CPU
#: contention alone delayed the nodes' publications by 45-57 ms (3 of 3 runs with two busy
#: processes beside it); a join over UDP was once seen to delay a publication by ~190 ms on a
#: quiet machine.
LONGEST_GAP_MS = 250.0
#: A bare rclpy process that joins the domain, spins until its first IMU message (at most 20 s)
#: and then 2 s more, and prints the number of IMU messages it got.
BARE_NODE = """
import time, rclpy
from sensor_msgs.msg import Imu
rclpy.init()
node = rclpy.create_node("joining_node")
got = []
node.create_subscription(Imu, "/imu/data_raw", got.append, 10)
end = time.monotonic() + 20.0
while time.monotonic() < end:
    rclpy.spin_once(node, timeout_sec=0.1)
    if len(got) == 1:
        end = min(end, time.monotonic() + 2.0)
print(len(got))
"""


@pytest.fixture(scope="module", autouse=True)
def ros_context():
    """This process's participant over UDP only too (SUBSCRIBER_ENV), the environment restored
    once it exists (the joiners take the plain one)."""
    saved = {name: os.environ.get(name) for name in SUBSCRIBER_ENV}
    os.environ.update(SUBSCRIBER_ENV)
    try:
        rclpy.init()
    finally:
        for name, value in saved.items():
            if value is None:
                del os.environ[name]
            else:
                os.environ[name] = value
    yield
    rclpy.shutdown()


class Arrivals:
    """Reception and publication times [ns, host wall clock: the middleware's
    ``received_timestamp`` (not this process's callback) and ``source_timestamp``] of the
    messages of TOPICS, taken raw."""

    def __init__(self) -> None:
        self.node = rclpy.create_node("join_arrivals")
        self.times: dict[str, list[int]] = {topic: [] for topic in TOPICS}
        self.published: dict[str, list[int]] = {topic: [] for topic in TOPICS}
        qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
        for topic, msg_type in TOPICS.items():
            self.node.create_subscription(
                msg_type,
                topic,
                lambda _data, info, topic=topic: self._store(topic, info),
                qos,
                raw=True,
                event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False),
            )

    def _store(self, topic: str, info: dict[str, int]) -> None:
        self.times[topic].append(info["received_timestamp"])
        self.published[topic].append(info["source_timestamp"])

    def since(self, topic: str) -> float:
        """Seconds since the first message of ``topic`` (0 before it)."""
        times = self.times[topic]
        return (time.time_ns() - times[0]) / 1e9 if times else 0.0

    def past(self, topic: str, t_ns: int) -> bool:
        """Whether a message of ``topic`` arrived after ``t_ns``."""
        times = self.times[topic]
        return bool(times) and times[-1] > t_ns

    def largest_gap_ms(
        self, topic: str, start_ns: int, end_ns: int, published: bool = False
    ) -> tuple[float, float]:
        """The longest interval between consecutive arrivals (or publications) that overlaps
        [start, end] [ms], and when it ended [s after start_ns]."""
        t = np.sort(np.array((self.published if published else self.times)[topic], dtype=np.int64))
        overlaps = (t[1:] >= start_ns) & (t[:-1] <= end_ns)
        interval = np.where(overlaps, np.diff(t), 0)
        worst = int(np.argmax(interval))
        return round(float(interval[worst]) / 1e6, 1), round(
            float(t[worst + 1] - start_ns) / 1e9, 2
        )


@contextmanager
def vehicle_nodes(work: Path) -> Iterator[None]:
    """The emulated IMU and Leica (at rest) and the three nodes on them, stopped at the end."""
    ports = {"imu": work / "imu", "leica": work / "leica"}
    emulators = [
        gnss_ins_command("emulate-imu", "--link", str(ports["imu"])),
        gnss_ins_command("emulate-gnss", "--receiver", "leica", "--link", str(ports["leica"])),
    ]
    nodes = [
        command(IMU, None, str(ports["imu"])),
        command(LEICA, None, str(ports["leica"])),
        command(FUSION, None, None),
    ]
    with ExitStack() as stack:
        started: list[subprocess.Popen[Any]] = []
        for index, args in enumerate([*emulators, *nodes]):
            if index == len(emulators):  # the nodes once the ports are there
                assert wait_for(lambda: all(p.exists() for p in ports.values()), 30.0)
            log = stack.enter_context((work / f"process{index}.log").open("w"))
            env = NODE_ENV if index >= len(emulators) else None
            started.append(subprocess.Popen(args, env=env, stdout=log, stderr=subprocess.STDOUT))
        try:
            yield
        finally:
            for process in reversed(started):  # the nodes first, then the emulators
                process.terminate()
                process.wait(timeout=30)


def join_with_status(log_dir: Path) -> None:
    """``gnss_ins status --json``: it hears the IMU node's /diagnostics (it did join)."""
    result = subprocess.run(
        gnss_ins_command("status", "--json", "--wait", "1", "--log-dir", str(log_dir)),
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert "imu400cc_node" in json.loads(result.stdout)["processes"], result.stderr


def join_with_bare_node() -> None:
    """The bare rclpy node of BARE_NODE: it got IMU messages (it did join)."""
    result = subprocess.run(
        [sys.executable, "-c", BARE_NODE], capture_output=True, text=True, timeout=60
    )
    assert result.returncode == 0, result.stderr
    assert int(result.stdout) > 0


def test_processes_joining_the_domain_leave_imu_and_odometry_without_a_gap(tmp_path):
    """No gap longer than LONGEST_GAP_MS in the publications of /imu/data_raw or /ins/odometry
    (their source timestamps, taken at a subscriber), from 1 s before the first process joins
    until 3 s after the last one has ended.

    A timed bound, unlike this project's other tests, because the stall is a time: with Fast
    DDS's shared-memory transport every process that joined stalled every
    publication of every node for 333 ms (the port health check's sleep, taken while holding
    the participant's send lock; docs/operation.md), beyond the bound. Without it
    the gaps are the output clock's (22.4 ms at most) and the nodes' delays; the failure message
    tells the two apart by the publications' own gaps (the publishers' source timestamps).
    """
    arrivals = Arrivals()
    with vehicle_nodes(tmp_path), spinning(arrivals.node):
        # Both topics flowing for a while (the fusion's first outputs come after its start-up).
        assert wait_for(lambda: arrivals.since("/ins/odometry") > 2.0, 60.0), {
            topic: len(times) for topic, times in arrivals.times.items()
        }
        start_ns = time.time_ns() - 1_000_000_000  # 1 s before the first join
        for _ in range(3):
            join_with_status(tmp_path)
            join_with_bare_node()
        end_ns = time.time_ns() + 3_000_000_000  # 3 s after the last one ended
        assert wait_for(lambda: all(arrivals.past(t, end_ns) for t in TOPICS), 10.0)
    gaps = {topic: arrivals.largest_gap_ms(topic, start_ns, end_ns) for topic in TOPICS}
    # Where a gap comes from: the publisher (its publications have it too) or the way here.
    published = {t: arrivals.largest_gap_ms(t, start_ns, end_ns, published=True) for t in TOPICS}
    print(f"largest gaps [ms, s after the start]: arrived {gaps}, published {published}")
    # Judged on the publications: this process's own participant may run on shared memory
    # whatever SUBSCRIBER_ENV says (Fast DDS takes its transports once per process, at the first
    # participant, which an earlier test module may have created), and then it stalls its own
    # arrivals by 331 ms at each join (seen in the suite: arrivals 331.8 ms apart, publications
    # 14.9 / 28.9 ms). A node stalled in publish() cannot publish its next message either, so
    # its stall is a gap in its publication times.
    assert all(ms <= LONGEST_GAP_MS for ms, _ in published.values()), (published, gaps)
