"""Recover the bag of a recording that did not finish (killed, power cut) into a readable bag.

``BagWriter`` (with ``flush`` called at a bounded interval, as ``gnss_ins record`` does) leaves
on disk: the closed split files ``NAME/NAME_<i>.<ext>`` (complete), the file being written in its
own directory ``NAME/NAME_<k>/NAME_<k>.<ext>``, and no ``metadata.yaml``.

- MCAP: the writer appends whole chunks; an unfinished file lacks its last chunk(s), the summary
  and the footer. ``seal_mcap`` copies every complete record up to the first truncated or invalid
  one and appends a Data End record and a footer without summary (MCAP spec, "Footer": a summary
  start of 0 means none) — a valid MCAP that readers scan linearly.
- sqlite3: the data of committed transactions are in the file; an uncommitted one is undone from
  the rollback journal, which SQLite does when a copy of the file and its journal is opened.

``recover_bag`` then copies every message of every file, in file order, into a new bag.
"""

from __future__ import annotations

import re
import shutil
import sqlite3
import struct
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

from ins_fusion.bags.bag_io import BagError, BagReader, BagSummary, BagWriter

MCAP_MAGIC = b"\x89MCAP0\r\n"
#: Record opcodes of the MCAP spec (Header 0x01 .. Data End 0x0F, Footer 0x02 included).
_MCAP_OPCODES = frozenset(range(0x01, 0x10))
_HEADER, _FOOTER, _DATA_END = 0x01, 0x02, 0x0F
_RECORD_HEAD = struct.Struct("<BQ")
#: Storage file extension -> ``--storage`` name.
_EXTENSIONS = {"mcap": "mcap", "db3": "sqlite3"}


@dataclass(frozen=True)
class Recovered:
    """What ``recover_bag`` did: input files, bytes of incomplete records dropped, summary."""

    files: list[Path]
    dropped_bytes: int
    summary: BagSummary


def _complete_record(fin: BinaryIO, size: int) -> bytes | None:
    """The next record at ``fin`` if it is whole and not Data End, else None."""
    head = fin.read(_RECORD_HEAD.size)
    if len(head) < _RECORD_HEAD.size:
        return None
    opcode, length = _RECORD_HEAD.unpack(head)
    if opcode == _DATA_END or opcode not in _MCAP_OPCODES or fin.tell() + length > size:
        return None
    return head + fin.read(length)


def seal_mcap(source: Path, target: Path) -> int | None:
    """Copy ``source``'s complete records up to its Data End (or first incomplete record) into a
    new ``target`` ending with Data End and a summary-less footer; returns the bytes dropped
    (the summary of a complete file included), or None (and no ``target``) when not even the
    Header record was written."""
    size = source.stat().st_size
    with source.open("rb") as fin:
        if not MCAP_MAGIC.startswith(magic := fin.read(len(MCAP_MAGIC))):
            raise BagError(f"{source}: not an MCAP file")
        record = _complete_record(fin, size) if magic == MCAP_MAGIC else None
        if record is None or record[0] != _HEADER:
            return None
        with target.open("xb") as fout:
            fout.write(MCAP_MAGIC)
            while record is not None:
                fout.write(record)
                end = fin.tell()
                record = _complete_record(fin, size)
            fout.write(_RECORD_HEAD.pack(_DATA_END, 4) + struct.pack("<I", 0))
            fout.write(_RECORD_HEAD.pack(_FOOTER, 20) + struct.pack("<QQI", 0, 0, 0) + MCAP_MAGIC)
    return size - end


def _rolled_back_sqlite(source: Path, target: Path) -> None:
    """Copy ``source`` and its rollback journal to ``target``; opening the copy undoes the
    uncommitted transaction."""
    shutil.copyfile(source, target)
    journal = source.with_name(source.name + "-journal")
    if journal.exists():
        shutil.copyfile(journal, target.with_name(target.name + "-journal"))
    try:
        with sqlite3.connect(target) as db:
            db.execute("SELECT count(*) FROM messages").fetchone()
        db.close()
    except sqlite3.Error as exc:
        raise BagError(f"{source}: unreadable sqlite3 file ({exc})") from exc


def storage_files_left(bag: Path) -> list[Path]:
    """The storage files an unfinished recording left in ``bag``, in split order."""
    pattern = re.compile(rf"{re.escape(bag.name)}_(\d+)\.({'|'.join(_EXTENSIONS)})")
    found = [
        (int(match.group(1)), path)
        for path in [*bag.glob("*.*"), *bag.glob("*/*.*")]
        if (match := pattern.fullmatch(path.name))
    ]
    return [path for _, path in sorted(found)]


def recover_bag(bag: Path, output: Path) -> Recovered:
    """Write every message the unfinished recording ``bag`` holds into the new bag ``output``
    (same storage). ``bag`` is only read. BagError if it is complete or holds nothing."""
    if (bag / "metadata.yaml").exists():
        raise BagError(f"{bag} has its metadata.yaml: complete, nothing to recover")
    files = storage_files_left(bag)
    if not files:
        raise BagError(f"{bag}: no {bag.name}_<n>.mcap or .db3 file to recover")
    storages = {_EXTENSIONS[f.suffix[1:]] for f in files}
    if len(storages) > 1:
        raise BagError(f"{bag}: both MCAP and sqlite3 files; move one kind away")
    dropped = 0
    with (
        tempfile.TemporaryDirectory(dir=output.parent, prefix=f".{output.name}.") as scratch,
        BagWriter(output, storage=storages.pop()) as writer,
    ):
        for index, source in enumerate(files):
            copy = Path(scratch) / f"part{index}{source.suffix}"
            if source.suffix == ".mcap":
                sealed = seal_mcap(source, copy)
                if sealed is None:  # killed before its first record: nothing in it
                    dropped += source.stat().st_size
                    continue
                dropped += sealed
            else:
                _rolled_back_sqlite(source, copy)
            with BagReader(copy) as reader:
                for topic, info in reader.topics.items():
                    writer.add_topic(topic, info.msgtype, info.qos)
                for msg in reader.messages():
                    writer.write(msg.topic, msg.log_time_ns, msg.message)
    return Recovered(files, dropped, writer.summary)
