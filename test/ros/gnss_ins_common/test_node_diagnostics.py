"""Diagnostics common to the three nodes (real rclpy nodes, real emulated devices): callback
exceptions are caught around the callback or by the nodes' spin loop, counted in
``callback_errors`` and reported in the next status only (cleared on recovery); ins_fusion_node's
level is stable through an outage."""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager

import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from sensor_msgs.msg import Temperature
from support.ros_harness import Collector, diagnostic_values, overrides, spinning, wait_for

from gnss_driver.emulator import GnssEmulator, constant_velocity
from gnss_driver.node import GnssNode
from gnss_ins_common.ros_diagnostics import callback_errors
from gnss_ins_common.ros_endpoints import Endpoints
from gnss_ins_common.ros_node_main import spin_guarded
from imu400cc_driver.emulator import Imu400ccEmulator
from imu400cc_driver.node import Imu400ccNode
from ins_fusion.node import InsFusionNode

pytestmark = pytest.mark.ros

FAILURES = 3


@pytest.fixture(scope="module", autouse=True)
def ros_context():
    rclpy.init()
    yield
    rclpy.shutdown()


@contextmanager
def _imu(stack: ExitStack) -> Iterator[Node]:
    dev = stack.enter_context(Imu400ccEmulator())
    yield Imu400ccNode(parameter_overrides=overrides(port=dev.path, diagnostics_period=0.2))


@contextmanager
def _gnss(stack: ExitStack) -> Iterator[Node]:
    dev = stack.enter_context(GnssEmulator(constant_velocity((3.0, 4.0, 0.0))))
    yield GnssNode(
        parameter_overrides=overrides(port=dev.path, baud=dev.baud, diagnostics_period=0.2)
    )


@contextmanager
def _fusion(_stack: ExitStack) -> Iterator[Node]:
    yield InsFusionNode(parameter_overrides=overrides(diagnostics_period=0.2))


@contextmanager
def _spinning_guarded(node: Node) -> Iterator[None]:
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    stop = threading.Event()
    thread = threading.Thread(
        target=spin_guarded, args=(executor, node, lambda: not stop.is_set()), daemon=True
    )
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join(timeout=5.0)
        executor.shutdown(timeout_sec=2.0)


def _failing_timer(node: Node) -> list[int]:
    """A timer on ``node`` whose first FAILURES ticks raise; returns its tick counter."""
    ticks = [0]

    def tick() -> None:
        ticks[0] += 1
        if ticks[0] <= FAILURES:
            raise ValueError(f"test failure {ticks[0]}")

    node.create_timer(0.05, tick)
    return ticks


@pytest.mark.parametrize("make", [_imu, _gnss, _fusion], ids=["imu", "gnss", "fusion"])
def test_callback_errors_are_counted_reported_once_and_cleared(make: Callable):
    collector = Collector({"/diagnostics": DiagnosticArray})
    with ExitStack() as stack, make(stack) as node:
        ticks = _failing_timer(node)
        try:
            with spinning(collector.node), _spinning_guarded(node):

                def counted() -> bool:
                    arrays = collector.get("/diagnostics")
                    return bool(arrays) and diagnostic_values(arrays[-1])["callback_errors"] == "3"

                assert wait_for(counted, 20.0), "callback errors not counted"
                after = len(collector.get("/diagnostics"))
                assert wait_for(lambda: len(collector.get("/diagnostics")) >= after + 2, 10.0)
                assert ticks[0] > FAILURES  # the node went on after the errors
        finally:
            close = getattr(node, "close", None)
            if close is not None:
                close()
            node.destroy_node()
            collector.node.destroy_node()
    statuses = [array.status[0] for array in collector.get("/diagnostics")]
    reported = [s for s in statuses if "callback error (ValueError in tick)" in s.message]
    assert reported and all(s.level >= DiagnosticStatus.WARN for s in reported)
    # Once the errors stopped, later statuses no longer carry them.
    assert "callback error" not in statuses[-1].message
    assert diagnostic_values(collector.get("/diagnostics")[-1])["callback_errors"] == "3"


def test_fusion_level_is_stable_through_an_outage_with_sparse_fixes():
    node = InsFusionNode(parameter_overrides=overrides(degraded_after_s=5.0))
    try:
        # (IMU stamp [s], engine state): navigating, an outage with a fix used every 7 s (the
        # state flips for 5 s after each), then fixes again for good.
        timeline = [(1.0, "aligning"), (10.0, "navigating"), (20.0, "navigating")]
        timeline += [(26.0, "degraded"), (27.0, "navigating"), (31.0, "navigating")]
        timeline += [(33.0, "degraded"), (34.0, "navigating"), (38.0, "navigating")]
        timeline += [(40.0, "degraded"), (41.0, "navigating"), (45.0, "navigating")]
        timeline += [(46.5, "navigating")]
        positions = {"used": 0, "rejected": 0, "gated": 0, "too_old": 0}
        levels = [node._state_level(state, t, positions)[0] for t, state in timeline]
    finally:
        node.destroy_node()
    ok, warn = DiagnosticStatus.OK, DiagnosticStatus.WARN
    assert levels[:3] == [warn, ok, ok]
    assert levels[3:-1] == [warn] * (len(timeline) - 4)  # no OK/WARN flipping in the outage
    assert levels[-1] == ok  # 5.5 s of positions after the outage
    assert DiagnosticStatus.ERROR not in levels


def test_a_failing_subscription_callback_is_counted_and_every_message_still_arrives():
    """Endpoints guards its subscriptions' callbacks (ros_diagnostics.guarded): each exception
    is counted under the callback's name instead of reaching the executor (EventsExecutor
    would leave the rest of a burst queued), and every message of a burst is delivered."""
    node = rclpy.create_node("guarded_subscriber")
    received: list[float] = []

    def on_temperature(msg: Temperature) -> None:
        received.append(msg.temperature)
        raise ValueError("test failure")

    Endpoints(node).subscription(Temperature, "guarded_test", on_temperature, 100)
    sender = rclpy.create_node("guarded_sender")
    publisher = sender.create_publisher(Temperature, "guarded_test", 100)
    try:
        with spinning(node):
            assert wait_for(lambda: publisher.get_subscription_count() > 0, 10.0)
            for celsius in range(5):
                publisher.publish(Temperature(temperature=float(celsius)))
            assert wait_for(lambda: len(received) == 5, 10.0)
    finally:
        node.destroy_node()
        sender.destroy_node()
    assert received == [0.0, 1.0, 2.0, 3.0, 4.0]
    errors = callback_errors(node)
    assert errors.count == 5
    assert "callback error (ValueError in on_temperature): test failure" in errors.take_new()
