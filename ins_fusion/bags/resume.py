"""What a recording directory already holds, for a writer that continues it (``BagWriter`` with
``resume=True``, used by ``gnss_ins record --resume`` when a supervised recorder restarts).

A recording ``NAME/`` written by ``BagWriter`` holds, at any moment:

- ``NAME_<i>.<ext>``: closed files, complete; each with its one-file metadata in
  ``NAME/.parts/NAME_<i>.yaml`` (written before the file is moved up, removed when the whole
  recording is closed and its ``metadata.yaml`` merges them);
- ``NAME_<k>/NAME_<k>.<ext>``: the file being written; a killed recorder leaves it unfinished
  (no ``metadata.yaml`` beside it), or whole with its ``metadata.yaml`` when it died between
  closing and moving it;
- ``metadata.yaml`` once the recording was closed (a later resume continues it all the same).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, cast

import yaml

from ins_fusion.bags.salvage import STORAGE_OF_SUFFIX

#: The hidden directory of the closed files' one-file metadata.
PARTS_DIR = ".parts"


@dataclass
class ExistingRecording:
    """The state of a recording directory found by ``existing_recording``."""

    #: one-file metadata of the closed files (or the merged metadata of a closed recording)
    part_metadata: list[dict[str, Any]] = field(default_factory=list)
    #: closed storage files, in split order
    files: list[Path] = field(default_factory=list)
    #: unfinished storage files (killed while written), in split order
    unfinished: list[Path] = field(default_factory=list)
    #: the split index the next file takes
    next_index: int = 0


def load_yaml(path: Path) -> dict[str, Any]:
    """A rosbag2 metadata file's ``rosbag2_bagfile_information``; ValueError when unreadable."""
    try:
        info = yaml.safe_load(path.read_text(encoding="utf-8"))["rosbag2_bagfile_information"]
    except (OSError, yaml.YAMLError, KeyError, TypeError) as exc:
        raise ValueError(f"{path}: unreadable rosbag2 metadata ({exc})") from exc
    return cast(dict[str, Any], info)


def split_name(name: str) -> tuple[str, int] | None:
    """The bag name and split index of a storage file name ``NAME_<i>.mcap`` or ``.db3``
    (None: not one)."""
    suffixes = "|".join(re.escape(suffix) for suffix in STORAGE_OF_SUFFIX)
    match = re.fullmatch(rf"(.+)_(\d+)({suffixes})", name)
    return (match.group(1), int(match.group(2))) if match else None


def file_index(bag: Path, name: str) -> int | None:
    """The split index of a storage file name ``BAG_<i>.mcap`` or ``.db3`` of the bag ``bag``
    (None: not one)."""
    split = split_name(name)
    return split[1] if split is not None and split[0] == bag.name else None


def existing_recording(bag: Path) -> ExistingRecording:
    """What ``bag`` holds (see the module docstring). A part directory holding a complete file
    has that file moved up with its metadata kept, as its writer would have done."""
    found = ExistingRecording()
    indices: list[int] = []
    closed = bag / "metadata.yaml"
    if closed.exists():
        merged = load_yaml(closed)
        found.part_metadata.append(merged)
        found.files = [bag / Path(p).name for p in merged["relative_file_paths"]]
    for part_dir in sorted(p for p in bag.iterdir() if p.is_dir() and p.name != PARTS_DIR):
        for storage in part_dir.iterdir():
            if (index := file_index(bag, storage.name)) is None:
                continue
            indices.append(index)
            if (part_dir / "metadata.yaml").exists():  # closed, not yet moved up
                keep_part_metadata(bag, storage.name, load_yaml(part_dir / "metadata.yaml"))
                storage.replace(bag / storage.name)
            else:
                found.unfinished.append(storage)
    known = {f.name for f in found.files}
    for storage in sorted(bag.iterdir(), key=lambda p: file_index(bag, p.name) or -1):
        if (index := file_index(bag, storage.name)) is None or not storage.is_file():
            continue
        indices.append(index)
        if storage.name in known:
            continue
        part = bag / PARTS_DIR / f"{storage.name}.yaml"
        if not part.exists():
            found.unfinished.append(storage)  # closed by another writer: read it again
            continue
        found.part_metadata.append(load_yaml(part))
        found.files.append(storage)
    found.unfinished.sort(key=lambda p: file_index(bag, p.name) or 0)
    found.next_index = max(indices, default=-1) + 1
    return found


def keep_part_metadata(bag: Path, file_name: str, info: dict[str, Any]) -> None:
    """Store a closed file's one-file metadata in ``bag/.parts`` (whole or not at all)."""
    parts = bag / PARTS_DIR
    parts.mkdir(exist_ok=True)
    scratch = parts / f".{file_name}.yaml.writing"
    text = yaml.safe_dump({"rosbag2_bagfile_information": info}, sort_keys=False)
    scratch.write_text(text, encoding="utf-8")
    scratch.replace(parts / f"{file_name}.yaml")
