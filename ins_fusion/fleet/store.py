"""The output folder of a batch, kept so that a rerun resumes where the last one stopped.

``DIR/<bag name>/`` per bag: ``report.json``, ``plot.png``, the exports, ``replay.log`` and
``outcome.json`` (status, error, seconds, worker). A bag's folder appears complete or not at
all: it is written as ``DIR/.partial-<name>``, its files synced, then renamed into place (a
``--force`` rerun moves the old one aside first). ``DIR/batch.json`` keeps the options the
results were made with: a rerun with other options is refused instead of mixing results. One
batch at a time writes a folder (``DIR/.batch.lock``).
"""

from __future__ import annotations

import fcntl
import json
import os
import shutil
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import asdict
from pathlib import Path
from typing import Any

from ins_fusion.fleet.task import REPORT, BagResult

OUTCOME = "outcome.json"
OPTIONS = "batch.json"
_LOCK = ".batch.lock"
_PARTIAL = ".partial-"
_OLD = ".old-"


class StoreError(Exception):
    """The output folder cannot be used as asked (another batch writes it, other options, a
    bag's folder holds another bag's result, or the file system refuses)."""


def write_atomic(path: Path, data: bytes) -> None:
    """``path`` holds ``data`` or its previous content, never a part: a synced temporary file
    renamed over it."""
    partial = path.with_name(f"{_PARTIAL}{path.name}")
    with partial.open("wb") as file:
        file.write(data)
        file.flush()
        os.fsync(file.fileno())
    os.replace(partial, path)


def _read_json(path: Path) -> dict[str, Any] | None:
    if not path.is_file():
        return None
    content: dict[str, Any] = json.loads(path.read_text(encoding="utf-8"))
    return content


class BatchStore:
    """The results in ``root`` (open it with ``open_store``)."""

    def __init__(self, root: Path) -> None:
        self.root = root

    def outcome(self, name: str) -> dict[str, Any] | None:
        """The saved outcome of bag ``name`` (None: not done)."""
        return _read_json(self.root / name / OUTCOME)

    def report(self, name: str) -> dict[str, Any] | None:
        """The saved replay report of bag ``name`` (None: none written)."""
        return _read_json(self.root / name / REPORT)

    def pending(self, bags: Mapping[str, str], force: bool, retry_failed: bool) -> list[str]:
        """The names of ``bags`` (name -> path) to replay: not done yet, all with ``force``, and
        those that did not end "ok" with ``retry_failed``."""
        todo = []
        for name, bag in bags.items():
            outcome = None if force else self.outcome(name)
            if outcome is not None and outcome["bag"] != bag:
                raise StoreError(
                    f"{self.root / name} holds the result of {outcome['bag']}, not of {bag}"
                    " (bags of one name: give another --out, or --force to replace it)"
                )
            if outcome is None or (retry_failed and outcome["status"] != "ok"):
                todo.append(name)
        return todo

    def save(self, name: str, result: BagResult) -> None:
        """Write the bag's folder atomically (replacing an earlier one)."""
        final = self.root / name
        partial = self.root / f"{_PARTIAL}{name}"
        old = self.root / f"{_OLD}{name}"
        for leftover in (partial, old):
            shutil.rmtree(leftover, ignore_errors=True)
        partial.mkdir()
        outcome = {k: v for k, v in asdict(result).items() if k != "files"}
        outcome["files"] = sorted(result.files)
        files = {**result.files, OUTCOME: json.dumps(outcome, indent=2).encode()}
        for file_name, data in files.items():
            with (partial / file_name).open("wb") as file:
                file.write(data)
                file.flush()
                os.fsync(file.fileno())
        if final.exists():
            final.rename(old)
        partial.rename(final)
        shutil.rmtree(old, ignore_errors=True)


@contextmanager
def open_store(root: Path, options: dict[str, Any], force: bool) -> Iterator[BatchStore]:
    """The batch folder ``root`` (created), locked for this batch, its options checked against
    those it was made with (``force``: replaced by these)."""
    try:
        root.mkdir(parents=True, exist_ok=True)
        lock = (root / _LOCK).open("w")
    except OSError as exc:
        raise StoreError(f"cannot use {root}: {exc}") from None
    with lock:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
            # The batch before removed the file after this one opened it: another may lock
            # the new file, so this lock is not the folder's.
            if os.stat(root / _LOCK).st_ino != os.fstat(lock.fileno()).st_ino:
                raise BlockingIOError
        except (BlockingIOError, FileNotFoundError):
            raise StoreError(f"another batch is writing {root}") from None
        try:
            yield _checked_store(root, options, force)
        finally:
            (root / _LOCK).unlink(missing_ok=True)  # while locked: no empty file left behind


def _checked_store(root: Path, options: dict[str, Any], force: bool) -> BatchStore:
    """The store of the locked ``root``, its options checked and saved (see ``open_store``)."""
    saved = root / OPTIONS
    text = json.dumps(options, indent=2, sort_keys=True)
    if saved.is_file() and not force:
        before = json.loads(saved.read_text(encoding="utf-8"))
        if before != json.loads(text):
            changed = sorted(k for k in {*before, *options} if before.get(k) != options.get(k))
            raise StoreError(
                f"{root} holds results made with other options ({', '.join(changed)}):"
                " give another --out, or --force to redo every bag"
            )
    write_atomic(saved, text.encode())
    return BatchStore(root)
