"""The vehicle's recorder: `gnss_ins record` as one more supervised process of `gnss_ins launch
--record` and of launch/vehicle.launch.py (``record_dir:=``).

The recording's name is fixed once per launch, so a recorder started again after a crash
continues the same recording (``gnss_ins record --resume``: a new split file in the same bag
directory). Pure data plus command-line building (no ROS).
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import yaml

from ins_fusion.runtime.processes import gnss_ins_command

#: Process name of the recorder (its log: recorder.log).
RECORDER = "recorder"
#: config/ file listing the topics to record.
TOPICS_FILE = "recorded_topics.yaml"
#: Seconds of recorded time per bag file.
DEFAULT_SPLIT_S = 600.0
#: rosbag2 storage plugins of `gnss_ins record --storage`.
STORAGES = ("mcap", "sqlite3")


def recording_name(now: datetime | None = None) -> str:
    """``vehicle_YYYYmmdd_HHMMSS`` of ``now`` (default: the present) in UTC."""
    return f"vehicle_{(now or datetime.now(UTC)).astimezone(UTC):%Y%m%d_%H%M%S}"


def read_topics(path: Path) -> list[str]:
    """The ``topics:`` list of a YAML file (absolute topic names). Raises ValueError when the
    file holds something else, OSError when it cannot be read."""
    content = yaml.safe_load(path.read_text(encoding="utf-8"))
    topics = content.get("topics") if isinstance(content, dict) else None
    if not isinstance(topics, list) or not topics:
        raise ValueError(f"{path}: expected a non-empty list 'topics:'")
    wrong = [t for t in topics if not isinstance(t, str) or not t.startswith("/")]
    if wrong:
        raise ValueError(f"{path}: not absolute topic names: {wrong}")
    return topics


@dataclass(frozen=True)
class Recording:
    """One launch's recording: bag directory, topics, file split, storage, free-space limit."""

    output: Path
    topics: tuple[str, ...]
    split_s: float = DEFAULT_SPLIT_S
    storage: str = "mcap"
    #: ``gnss_ins record --min-free`` as given (None: the recorder's own default).
    min_free: str | None = None

    def command(self) -> list[str]:
        """``gnss_ins record -o OUTPUT --resume --max-bag-duration S --name recorder ...
        TOPICS``."""
        options = ["-o", str(self.output), "--resume", "--max-bag-duration", str(self.split_s)]
        options += ["--name", RECORDER]  # its status is the recorder's row, a hand-started one not
        options += ["--storage", self.storage]
        if self.min_free is not None:
            options += ["--min-free", self.min_free]
        return gnss_ins_command("record", *options, *self.topics)
