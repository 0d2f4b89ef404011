"""A measurement kind's name is spelled in its own module of ins_fusion/core/measurements only:
everything else takes it from the kind's ``Kind`` (core.engine.measurement_kinds lists them)."""

from __future__ import annotations

import re
from pathlib import Path

from ins_fusion.core.engine.measurement_kinds import MEASUREMENT_NAMES

REPO = Path(__file__).resolve().parents[2]
PACKAGES = ("gnss_ins_common", "imu400cc_driver", "gnss_driver", "ntrip_client", "ins_fusion")
#: The same word meaning something else: the attitude topic's role in a replay and the
#: attitude block of the output covariances.
OTHER_MEANINGS = {
    "attitude": {
        "ins_fusion/replay/inputs.py",
        "ins_fusion/replay/topics.py",
        "ins_fusion/replay/run.py",
        "ins_fusion/core/output/output_numbers.py",
    }
}


def test_each_kind_name_is_spelled_in_one_module() -> None:
    sources = {
        str(path.relative_to(REPO)): path.read_text()
        for package in PACKAGES
        for path in (REPO / package).rglob("*.py")
    }
    for name in MEASUREMENT_NAMES:
        quoted = re.compile(rf"""["']{name}["']""")
        spelled = {path for path, text in sources.items() if quoted.search(text)}
        spelled -= OTHER_MEANINGS.get(name, set())
        assert len(spelled) == 1, (name, sorted(spelled))
        assert next(iter(spelled)).startswith("ins_fusion/core/measurements/"), (name, spelled)
