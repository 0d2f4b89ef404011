"""Test-session set-up shared by all tests.

ROS traffic of one pytest process is isolated from any other (parallel sessions, other
developers' nodes) by a random DDS domain restricted to this host; subprocess nodes inherit it.
"""

from __future__ import annotations

import os
import random

os.environ.setdefault("ROS_DOMAIN_ID", str(random.SystemRandom().randint(1, 100)))
os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
