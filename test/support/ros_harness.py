"""Helpers for tests that run real rclpy nodes in the test process."""

from __future__ import annotations

import gc
import subprocess
import sys
import threading
import time
from collections import defaultdict
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy

from support.waiting import wait_for


class Collector:
    """A node that records every message of the given topics, with its receive wall time."""

    def __init__(self, topics: dict[str, type], name: str = "test_collector") -> None:
        self.node = rclpy.create_node(name)
        self._lock = threading.Lock()
        self.messages: dict[str, list[Any]] = defaultdict(list)
        self.receive_times: dict[str, list[float]] = defaultdict(list)
        qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
        for topic, msg_type in topics.items():
            self.node.create_subscription(
                msg_type, topic, lambda msg, t=topic: self._store(t, msg), qos
            )

    def _store(self, topic: str, msg: Any) -> None:
        now = time.time()
        with self._lock:
            self.messages[topic].append(msg)
            self.receive_times[topic].append(now)

    def get(self, topic: str) -> list[Any]:
        with self._lock:
            return list(self.messages[topic])

    def count(self, topic: str) -> int:
        with self._lock:
            return len(self.messages[topic])

    def clear(self) -> None:
        with self._lock:
            self.messages.clear()
            self.receive_times.clear()

    def more(self, topic: str, count: int = 1, timeout_s: float = 10.0) -> bool:
        """Wait for ``count`` messages on ``topic`` beyond those received so far (a status
        published after this moment, the next samples)."""
        start = self.count(topic)
        return wait_for(lambda: self.count(topic) >= start + count, timeout_s)


@contextmanager
def spinning(*nodes: Node) -> Iterator[SingleThreadedExecutor]:
    """Spin the nodes on a background executor for the duration of the block.

    Single-threaded on purpose: rclpy's MultiThreadedExecutor busy-waits while a callback group
    is busy, holding the GIL and starving the drivers' serial reader threads. For the same
    reason the objects of earlier tests are frozen out of the garbage collector: a full
    collection over the pytest process's heap can hold the GIL for tens of milliseconds, and a
    serial reader that wakes over ~45 ms late takes its packets for a whole timer wrap later
    (docs/timing.md, "What it cannot see").

    The spin loop is ended from its own thread before the executor is shut down: rclpy
    Jazzy's ``Executor.shutdown`` destroys the executor's guard condition at once, without
    waiting for a spin in progress (its work-tracker wait sits behind a test of the flag it
    has just set), so a shutdown from this thread races a callback that ends by triggering
    that guard: ``InvalidHandle`` in the spin thread, seen under load.
    """
    gc.collect()
    gc.freeze()
    executor = SingleThreadedExecutor()
    for node in nodes:
        executor.add_node(node)
    stop = threading.Event()

    def spin() -> None:
        while not stop.is_set() and executor.context.ok():
            executor.spin_once(timeout_sec=0.05)

    thread = threading.Thread(target=spin, daemon=True)
    thread.start()
    try:
        yield executor
    finally:
        stop.set()
        thread.join(timeout=30.0)
        if thread.is_alive():
            raise RuntimeError("the spin thread did not stop within 30 s (a callback hangs)")
        executor.shutdown(timeout_sec=2.0)


def overrides(**values: Any) -> list[Parameter]:
    """Parameter overrides for a node constructor."""
    return [Parameter(name, value=value) for name, value in values.items()]


def stamp_s(msg: Any) -> float:
    """header.stamp in seconds."""
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def diagnostic_values(array: Any) -> dict[str, str]:
    """Key/values of the first status of a DiagnosticArray."""
    return {kv.key: kv.value for kv in array.status[0].values}


def node_executable(name: str) -> Path:
    """The console script of a node, next to this interpreter (the venv's bin/)."""
    return Path(sys.executable).parent / name


def assert_executable_refuses(name: str, parameter: str, value: str) -> None:
    """The node executable exits with code 2 and names the parameter when given a bad value."""
    result = subprocess.run(
        [node_executable(name), "--ros-args", "-p", f"{parameter}:={value}"],
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert result.returncode == 2, result.stderr
    assert f"parameter '{parameter}'" in result.stderr


#: How a program for ``other_process`` ends: it says it is ready and spins ``node`` until it
#: is terminated.
_SPIN_UNTIL_TERMINATED = """
print("ready", flush=True)
try:
    rclpy.spin(node)
except Exception:
    pass
"""


@contextmanager
def other_process(program: str, *args: str) -> Iterator[subprocess.Popen[str]]:
    """A plain rclpy program (not one of ours) in a process of its own: ``program`` (its
    ``sys.argv[1:]`` are ``args``) creates the publishers and timers of ``node``; yielded once
    the node spins, terminated at the end."""
    process = subprocess.Popen(
        [sys.executable, "-c", program + _SPIN_UNTIL_TERMINATED, *args],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert process.stdout is not None and process.stdout.readline() == "ready\n"
        yield process
    finally:
        process.terminate()
        process.wait(timeout=10)
