"""Where the installed package keeps its shared files (config/*.yaml)."""

from __future__ import annotations

import os
import sys
from pathlib import Path

PACKAGE = "gnss_ins"


def config_file(name: str) -> Path:
    """``config/NAME`` of gnss_ins: the share directory of a sourced ROS install
    (``AMENT_PREFIX_PATH``, as ament_index resolves it) or of this Python prefix, else the source
    tree (editable install). Raises FileNotFoundError naming the places searched."""
    prefixes = [p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    candidates = [
        Path(prefix) / "share" / PACKAGE / "config" / name for prefix in [*prefixes, sys.prefix]
    ]
    candidates.append(Path(__file__).resolve().parents[1] / "config" / name)
    for candidate in candidates:
        if candidate.is_file():
            return candidate
    searched = ", ".join(map(str, candidates))
    raise FileNotFoundError(f"config file {name} not found in: {searched}")
