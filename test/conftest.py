"""Test-session set-up shared by all tests.

ROS traffic of one pytest process is isolated from any other (parallel sessions, other
developers' nodes) by a random DDS domain restricted to this host; subprocess nodes inherit it.
Under pytest-xdist every worker (gw0, gw1, ...) takes the next domains after the controller's,
so the nodes of tests running at the same time in two workers never see each other. With
``--dist loadgroup`` the tests that run real nodes (marker ``ros``) form one group, run one
after another in one worker (never two real-time node tests at once; make pytest runs them in a
session of their own beside the others), and every other test module is a group of its own:
its module-scoped fixtures (simulated drives and records) are built once, not once per worker.
The groups are handed out longest first, by the seconds they took in the previous run (pytest's
cache; on a fresh clone, as in CI, those of test/group_seconds.json; unknown ones first), so that
the workers finish together (make pytest passes --no-loadscope-reorder to keep that order).
`make group-seconds` writes the last run's seconds to test/group_seconds.json.
"""

from __future__ import annotations

import json
import math
import os
import random
from pathlib import Path

import pytest

os.environ.setdefault("ROS_DOMAIN_ID", str(random.SystemRandom().randint(1, 100)))
_WORKER = os.environ.get("PYTEST_XDIST_WORKER", "")
if _WORKER.startswith("gw"):  # the controller's domain (inherited) + 1 + the worker's number
    _DOMAIN = int(os.environ["ROS_DOMAIN_ID"]) + 1 + int(_WORKER[2:])
    os.environ["ROS_DOMAIN_ID"] = str(_DOMAIN % 102)  # Fast DDS: 0..101 on every OS
os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")


#: pytest cache key of the seconds each xdist group took in the last run.
_DURATIONS_KEY = "gnss_ins/group_seconds"
#: The seconds of a full run kept in the repository, for a run without a cache.
_FALLBACK = Path(__file__).with_name("group_seconds.json")
_SECONDS: dict[str, float] = {}


def _group(ros: bool, nodeid: str) -> str:
    """The xdist group of a test: ``ros`` for the real-node tests, else its module."""
    return "ros" if ros else nodeid.split("::")[0]


@pytest.hookimpl(tryfirst=True)  # before pytest-xdist reads the groups
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Mark each test with its xdist group; the longest groups of the last run first."""
    cache = getattr(config, "cache", None)  # None with -p no:cacheprovider
    seconds = json.loads(_FALLBACK.read_text(encoding="utf-8"))
    seconds.update(cache.get(_DURATIONS_KEY, {}) if cache is not None else {})
    groups = {}
    for item in items:
        group = _group(item.get_closest_marker("ros") is not None, item.nodeid)
        item.add_marker(pytest.mark.xdist_group(group))
        groups[item.nodeid] = group
    if _WORKER:  # a serial run keeps the collection order
        items.sort(key=lambda item: -seconds.get(groups[item.nodeid], math.inf))


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    """Add up the seconds of each group (setup, call and teardown; in the xdist controller)."""
    nodeid, at = report.nodeid, report.nodeid.rfind("@")  # xdist appends @group
    if at > nodeid.rfind("]"):
        nodeid = nodeid[:at]
    group = _group("ros" in report.keywords, nodeid)
    _SECONDS[group] = _SECONDS.get(group, 0.0) + report.duration


def pytest_sessionfinish(session: pytest.Session) -> None:
    """Keep the groups' seconds for the next run's order (not from the xdist workers)."""
    cache = getattr(session.config, "cache", None)  # None with -p no:cacheprovider
    if cache is not None and _SECONDS and not hasattr(session.config, "workerinput"):
        cache.set(_DURATIONS_KEY, {**cache.get(_DURATIONS_KEY, {}), **_SECONDS})
