"""Every message that reached the disk, from one storage file of a recording that did not finish.

A recorder killed with SIGKILL or by a power cut leaves its last storage file unfinished: MCAP
without its summary and footer (and perhaps a chunk cut in the middle, or a tail of zeros that a
file system extended but never wrote), sqlite3 with an uncommitted transaction in its rollback
journal. Readers that need the file's index or its messages in log-time order refuse such a file.

``salvage`` reads it the other way:

- MCAP: record by record in the order they were written, with the ``mcap`` library's streaming
  reader (chunks decompressed and split into their schema, channel and message records, whatever
  the messages' times), up to the first record that is cut short or invalid. Everything before
  it is kept; the bytes from there to the end are counted as dropped.
- sqlite3: a copy of the file and its rollback journal is opened, which undoes the uncommitted
  transaction (SQLite's own crash recovery), then the topics and messages tables are read row by
  row until the end or the first unreadable page.

The messages come back sorted by log time (stable: equal times keep their order in the file).
Nothing here writes into the recording; ``recover`` and ``BagWriter.resume`` write the result.
"""

from __future__ import annotations

import shutil
import sqlite3
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

from mcap.exceptions import EndOfFile
from mcap.records import Channel, Chunk, Footer, McapRecord, Message, MessageIndex, Schema
from mcap.stream_reader import StreamReader, breakup_chunk
from rosbags.interfaces import Qos
from rosbags.rosbag2.metadata import parse_qos

#: Storage file extension -> ``--storage`` name.
STORAGE_OF_SUFFIX = {".mcap": "mcap", ".db3": "sqlite3"}


class SalvagedTopic(NamedTuple):
    """A topic found in a storage file: its type and the QoS its publishers offered."""

    msgtype: str
    qos: tuple[Qos, ...]


class SalvagedMessage(NamedTuple):
    """One message as stored: topic, log time (ns since the epoch), serialized CDR bytes."""

    log_time_ns: int
    topic: str
    data: bytes


@dataclass
class Salvaged:
    """What one storage file still holds."""

    path: Path
    topics: dict[str, SalvagedTopic] = field(default_factory=dict)
    #: sorted by log time
    messages: list[SalvagedMessage] = field(default_factory=list)
    #: bytes at the end of the file that hold no complete record (MCAP; 0 for sqlite3)
    dropped_bytes: int = 0
    #: why reading stopped before the end of the file (None: it reached the end)
    stopped: str | None = None
    #: when the file was last written (ns since the epoch): no later than the recorder's death
    last_write_ns: int = 0


def salvage(path: Path) -> Salvaged:
    """Every complete message of the storage file ``path`` (``.mcap`` or ``.db3``). Never raises
    for the file's content; OSError if it cannot be read at all."""
    if path.suffix not in STORAGE_OF_SUFFIX:
        raise ValueError(f"{path}: not a .mcap or .db3 storage file")
    found = Salvaged(path, last_write_ns=path.stat().st_mtime_ns)
    if path.suffix == ".mcap":
        _salvage_mcap(path, found)
    else:
        _salvage_sqlite(path, found)
    found.messages.sort(key=lambda m: m.log_time_ns)
    return found


def _salvage_mcap(path: Path, found: Salvaged) -> None:
    size = path.stat().st_size
    schemas: dict[int, str] = {}
    channels: dict[int, str] = {}
    end = 0  # file offset after the last record taken
    pending: _PendingChunk | None = None  # a chunk waiting for its message indexes
    with path.open("rb") as stream:
        # A length larger than the file is damage: refuse it before allocating it.
        reader = StreamReader(stream, emit_chunks=True, record_size_limit=max(size, 1))
        try:
            for record in reader.records:
                if isinstance(record, MessageIndex) and pending is not None:
                    pending.indexed += [(record.channel_id, t) for t, _ in record.records]
                    pending.end = stream.tell()
                    continue
                if pending is not None:  # a record follows the chunk and its indexes
                    if pending.indexed and not pending.is_whole():
                        found.stopped = "a chunk whose messages differ from its indexes"
                        pending = None
                        break
                    _take(pending.records, found, channels, schemas)
                    end, pending = pending.end, None
                if isinstance(record, Chunk):
                    pending = _PendingChunk(breakup_chunk(record), stream.tell())
                elif isinstance(record, Footer):
                    end = size  # a complete file: only its closing magic follows
                elif not isinstance(record, MessageIndex):
                    _take([record], found, channels, schemas)
                    end = stream.tell()
        except Exception as exc:  # any damage ends the readable part; what came before stays
            found.stopped = _reason(exc)
    if pending is not None and pending.is_whole():  # the last chunk, its indexes complete
        _take(pending.records, found, channels, schemas)
        end = pending.end
    found.dropped_bytes = size - end


@dataclass
class _PendingChunk:
    """A chunk's records, and the message indexes that followed it: a chunk whose messages all
    appear in its indexes was written whole (a chunk cut by a power cut and filled with zeros by
    the file system parses, but its messages do not match the indexes written after it)."""

    records: list[McapRecord]
    end: int
    indexed: list[tuple[int, int]] = field(default_factory=list)

    def is_whole(self) -> bool:
        stored = [(r.channel_id, r.log_time) for r in self.records if isinstance(r, Message)]
        return bool(stored) and sorted(stored) == sorted(self.indexed)


def _take(
    records: list[McapRecord], found: Salvaged, channels: dict[int, str], schemas: dict[int, str]
) -> None:
    """Schemas, channels and messages of whole records into ``found``."""
    for record in records:
        if isinstance(record, Schema):
            schemas[record.id] = record.name
        elif isinstance(record, Channel):
            _add_channel(found, channels, schemas, record)
        elif isinstance(record, Message) and record.channel_id in channels:
            topic = channels[record.channel_id]
            found.messages.append(SalvagedMessage(record.log_time, topic, record.data))


def _add_channel(
    found: Salvaged, channels: dict[int, str], schemas: dict[int, str], channel: Channel
) -> None:
    """Take a channel whose schema is known and whose encoding is CDR."""
    msgtype = schemas.get(channel.schema_id)
    if msgtype is None or channel.message_encoding != "cdr":
        return
    channels[channel.id] = channel.topic
    if channel.topic not in found.topics:
        qos = _qos(channel.metadata.get("offered_qos_profiles", ""))
        found.topics[channel.topic] = SalvagedTopic(msgtype, qos)


def _qos(text: str) -> tuple[Qos, ...]:
    """QoS profiles from rosbag2's YAML text; none when it is missing or unreadable."""
    if not text:
        return ()
    try:
        return tuple(parse_qos(text))
    except Exception:  # damaged metadata text: the profiles are optional
        return ()


def _salvage_sqlite(path: Path, found: Salvaged) -> None:
    with tempfile.TemporaryDirectory(prefix="gnss_ins_salvage.") as scratch:
        copy = Path(scratch) / path.name
        shutil.copyfile(path, copy)
        journal = path.with_name(path.name + "-journal")
        if journal.exists():
            shutil.copyfile(journal, copy.with_name(copy.name + "-journal"))
        db = sqlite3.connect(copy)
        try:
            ids: dict[int, str] = {}
            for row in _rows(db, "SELECT id, name, type, offered_qos_profiles FROM topics", found):
                topic_id, name, msgtype, qos = row
                ids[int(topic_id)] = str(name)
                found.topics.setdefault(str(name), SalvagedTopic(str(msgtype), _qos(str(qos))))
            for topic_id, stamp, data in _rows(
                db, "SELECT topic_id, timestamp, data FROM messages", found
            ):
                if topic_id in ids:
                    found.messages.append(SalvagedMessage(int(stamp), ids[topic_id], bytes(data)))
        finally:
            db.close()


def _rows(db: sqlite3.Connection, query: str, found: Salvaged) -> list[tuple[Any, ...]]:
    """The rows of ``query`` up to the end or the first unreadable page (noted in ``found``)."""
    rows: list[tuple[Any, ...]] = []
    try:
        for row in db.execute(query):
            rows.append(tuple(row))
    except sqlite3.Error as exc:
        found.stopped = found.stopped or f"sqlite3: {exc}"
    return rows


def _reason(exc: Exception) -> str:
    """A short text for the record that could not be read."""
    if isinstance(exc, EndOfFile):
        return "the file ends inside a record (written when the recording stopped)"
    name = type(exc).__name__
    text = str(exc)
    return f"{name}: {text}" if text else name
