"""Test-session set-up shared by all tests.

ROS traffic of one pytest process is isolated from any other (parallel sessions, other
developers' nodes) by a random DDS domain restricted to this host; subprocess nodes inherit it.
Under pytest-xdist every worker (gw0, gw1, ...) takes the next domains after the controller's,
so the nodes of tests running at the same time in two workers never see each other. With
``--dist loadgroup`` the tests that run real nodes (marker ``ros``, all under test/ros/) form one
group, run one after another in one worker (never two real-time node tests at once; make pytest
runs them in a session of their own beside the others), and every other test module is a group
of its own: its module-scoped fixtures (simulated drives and records) are built once, not once
per worker. The groups with a test marked ``slow`` are handed out first (the long ones, so that
the workers finish together; make pytest passes --no-loadscope-reorder to keep that order), the
others in the order of the tree.
"""

from __future__ import annotations

import os
import random

import pytest

os.environ.setdefault("ROS_DOMAIN_ID", str(random.SystemRandom().randint(1, 100)))
_WORKER = os.environ.get("PYTEST_XDIST_WORKER", "")
if _WORKER.startswith("gw"):  # the controller's domain (inherited) + 1 + the worker's number
    _DOMAIN = int(os.environ["ROS_DOMAIN_ID"]) + 1 + int(_WORKER[2:])
    os.environ["ROS_DOMAIN_ID"] = str(_DOMAIN % 102)  # Fast DDS: 0..101 on every OS
os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")


def _group(ros: bool, nodeid: str) -> str:
    """The xdist group of a test: ``ros`` for the real-node tests, else its module."""
    return "ros" if ros else nodeid.split("::")[0]


@pytest.hookimpl(tryfirst=True)  # before pytest-xdist reads the groups
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Mark each test with its xdist group; the groups holding a slow test first."""
    groups = {}
    for item in items:
        group = _group(item.get_closest_marker("ros") is not None, item.nodeid)
        item.add_marker(pytest.mark.xdist_group(group))
        groups[item.nodeid] = group
    slow = {groups[item.nodeid] for item in items if item.get_closest_marker("slow")}
    if _WORKER:  # a serial run keeps the collection order
        items.sort(key=lambda item: groups[item.nodeid] not in slow)  # stable: tree order
