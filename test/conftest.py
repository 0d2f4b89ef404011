"""Test-session set-up shared by all tests.

ROS traffic of one pytest process is isolated from any other (parallel sessions, other
developers' nodes) by a random DDS domain restricted to this host; subprocess nodes inherit it.
Under pytest-xdist every worker (gw0, gw1, ...) takes the next domains after the controller's,
so the nodes of tests running at the same time in two workers never see each other. With
``--dist loadgroup`` (make pytest) the tests that run real nodes (marker ``ros``) form one group,
run one after another in one worker (never two real-time node tests at once), and every other
test module is a group of its own: its module-scoped fixtures (simulated drives and records)
are built once, not once per worker.
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


@pytest.hookimpl(tryfirst=True)  # before pytest-xdist reads the groups
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """xdist groups: ``ros`` for the tests marked so, else the test's module."""
    for item in items:
        ros = item.get_closest_marker("ros") is not None
        item.add_marker(pytest.mark.xdist_group("ros" if ros else item.nodeid.split("::")[0]))
