"""rosbag2 bags through ``rosbags``: a splitting writer, a time-ordered reader, a summary.

Bags are rosbag2 metadata version 9 (Jazzy): every connection carries its message definition
(``ros2msg`` with its dependencies) and its RIHS01 type-description hash from the Jazzy typestore,
so ``ros2 bag info/play`` and this reader accept them. A bag is a directory ``NAME/`` with
``metadata.yaml`` and one storage file per split, ``NAME_0.mcap``, ``NAME_1.mcap``, ... (or
``.db3``), the layout ``ros2 bag record`` produces. Times are ROS times in integer nanoseconds
since the Unix epoch (``log_time_ns``: the bag's receive/record time of a message).

No rclpy here: the recorder, the player, the importer and the simulator share this module.
"""

from __future__ import annotations

import os
import shutil
import struct
from collections.abc import Collection, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path, PurePath
from types import TracebackType
from typing import Any, Literal, NamedTuple, cast

import yaml
from rosbags.highlevel import AnyReader, AnyReaderError
from rosbags.interfaces import Connection, Qos
from rosbags.rosbag2 import ReaderError, StoragePlugin, Writer
from rosbags.rosbag2.storage_mcap import McapWriter
from rosbags.rosbag2.storage_sqlite3 import Sqlite3Writer
from rosbags.typesys.store import Typestore

from ins_fusion.bags.resume import PARTS_DIR, existing_recording, keep_part_metadata
from ins_fusion.bags.salvage import Salvaged, salvage
from ins_fusion.bags.summary import BagSummary
from ins_fusion.bags.typestore import jazzy_typestore

#: ``--storage`` choices -> rosbags storage plugin (MCAP is the Jazzy default).
STORAGES: dict[str, StoragePlugin] = {"mcap": StoragePlugin.MCAP, "sqlite3": StoragePlugin.SQLITE3}
#: rosbag2 metadata version written (Jazzy).
BAG_VERSION: Literal[9] = 9

RawMessage = bytes | memoryview


class BagError(Exception):
    """A bag cannot be written or read as asked."""


# --------------------------------------------------------------------------------------------
# Writer
# --------------------------------------------------------------------------------------------


class _Topic(NamedTuple):
    msgtype: str
    qos: tuple[Qos, ...]


class BagWriter:
    """Writes a rosbag2 bag directory, splitting into a new storage file on size or duration.

    ``write`` takes raw CDR bytes (e.g. from an rclpy ``raw=True`` subscription) or a rosbags
    message object of the topic's type. Topics are declared with ``add_topic`` (required for
    raw bytes); a message object declares its topic on first use. Files split when the payload
    bytes of the current file would exceed ``max_file_bytes`` or when a message is
    ``max_file_duration_s`` or more after the file's first message (0 = never). With ``resume``
    an existing recording directory is continued (``bags/resume.py``) instead of refused. Not
    thread-safe: the storage files are opened by the first ``add_topic``/``write``/``close``, and
    that thread must do all the writing and the closing (sqlite3 connections are bound to it).
    """

    def __init__(
        self,
        path: Path | str,
        *,
        storage: str = "mcap",
        max_file_bytes: int = 0,
        max_file_duration_s: float = 0.0,
        typestore: Typestore | None = None,
        resume: bool = False,
    ) -> None:
        if storage not in STORAGES:
            raise BagError(f"unknown storage {storage!r}; choose from {', '.join(STORAGES)}")
        self.path = Path(path)
        if self.path.exists() and not resume:
            raise BagError(f"{self.path} exists already, not overwriting")
        self.storage = storage
        self.max_file_bytes = max_file_bytes
        self.max_file_duration_ns = round(max_file_duration_s * 1e9)
        self.typestore = typestore if typestore is not None else jazzy_typestore()
        self.summary = BagSummary()
        self.files: list[Path] = []
        self._topics: dict[str, _Topic] = {}
        self._connections: dict[str, Connection] = {}
        self._part_metadata: list[dict[str, Any]] = []
        self._part: Writer | None = None
        self._part_bytes = 0
        self._part_start_ns = 0
        self._part_count = 0
        self._closed = False
        self._next_index = 0  # split index of the next file
        #: what a resumed recording held: the salvaged unfinished files, the end of its data (ns)
        self.resumed: list[Salvaged] = []
        self.resumed_end_ns = 0
        if self.path.exists():
            self._resume()
        else:
            self.path.mkdir(parents=True)

    def add_topic(self, topic: str, msgtype: str, qos: Sequence[Qos] = ()) -> None:
        """Declare a topic, its type (``pkg/msg/Name``) and the QoS profiles its publishers
        offered (empty: unknown; players then use their defaults)."""
        if topic in self._topics:
            if self._topics[topic].msgtype != msgtype:
                raise BagError(f"{topic} declared as {self._topics[topic].msgtype}, not {msgtype}")
            return
        if msgtype not in self.typestore.fielddefs:
            raise BagError(f"message type {msgtype} is not in the typestore")
        self._topics[topic] = _Topic(msgtype, tuple(qos))
        if self._part is not None:
            self._connect(topic)

    def write(self, topic: str, log_time_ns: int, message: RawMessage | object) -> None:
        """Write one message at ``log_time_ns`` (ns since the epoch)."""
        if isinstance(message, RawMessage):
            if topic not in self._topics:
                raise BagError(f"raw message on undeclared topic {topic}")
            data = message
        else:
            self.add_topic(topic, cast(str, getattr(message, "__msgtype__", "")))
            data = self.typestore.serialize_cdr(message, self._topics[topic].msgtype)
        if self._part_count and (
            (self.max_file_bytes and self._part_bytes + len(data) > self.max_file_bytes)
            or (
                self.max_file_duration_ns
                and log_time_ns - self._part_start_ns >= self.max_file_duration_ns
            )
        ):
            self._close_part()
            self._open_part()
        if not self._part_count:
            self._part_start_ns = log_time_ns
        part = self._current_part()
        part.write(self._connections[topic], log_time_ns, data)
        self._part_bytes += len(data)
        self._part_count += 1
        self.summary.add(topic, self._topics[topic].msgtype, log_time_ns)

    def flush(self) -> None:
        """Put every message written so far on disk so that a crash keeps it (``bag_recover``
        reads it back): MCAP closes the open chunk, flushes and fsyncs; sqlite3 commits."""
        storage = None if self._part is None else self._part.storage
        if isinstance(storage, McapWriter):  # rosbags internals: chunk, close_chunk, bio
            if storage.chunk.bio.tell():
                storage.close_chunk()
            storage.bio.flush()
            os.fsync(storage.bio.fileno())
        elif isinstance(storage, Sqlite3Writer):
            storage.conn.commit()

    def write_salvaged(self, salvaged: Salvaged) -> dict[str, str]:
        """Declare the topics of ``salvaged`` and write its messages (in log-time order);
        returns the topics left out because their type is not in the typestore (topic: type)."""
        skipped: dict[str, str] = {}
        for topic, info in salvaged.topics.items():
            if info.msgtype in self.typestore.fielddefs:
                self.add_topic(topic, info.msgtype, info.qos)
            else:
                skipped[topic] = info.msgtype
        for message in salvaged.messages:
            if message.topic not in skipped:
                self.write(message.topic, message.log_time_ns, message.data)
        return skipped

    def remove_oldest_file(self) -> tuple[Path, int, int] | None:
        """Delete the oldest closed file of this recording (to free disk space); returns it with
        its first and last message times (ns), or None when no closed file can be removed (a
        file of a previously closed recording counts as one with the others of it)."""
        if not self.files or len(self._part_metadata[0]["relative_file_paths"]) != 1:
            return None
        start, end = _span_ns(self._part_metadata.pop(0))
        path = self.files.pop(0)
        path.unlink()
        (self.path / PARTS_DIR / f"{path.name}.yaml").unlink(missing_ok=True)
        _fsync(self.path)
        return path, start, end

    def start_new_file(self) -> None:
        """Close the current file (complete, on disk) if it holds messages; the next message
        starts a new one."""
        if self._part is not None and self._part_count:
            self._close_part()

    def close(self) -> BagSummary:
        """Finish the current file and write ``metadata.yaml``; returns the summary."""
        if not self._closed:
            if self._part is not None or not self.files:
                self._current_part()
                self._close_part()
            self._write_metadata()
            shutil.rmtree(self.path / PARTS_DIR, ignore_errors=True)  # merged into metadata.yaml
            self._closed = True
        return self.summary

    def _current_part(self) -> Writer:
        if self._closed:
            raise BagError(f"{self.path} is closed")
        if self._part is None:
            self._open_part()
        assert self._part is not None
        return self._part

    def _connect(self, topic: str) -> None:
        info = self._topics[topic]
        self._connections[topic] = self._current_part().add_connection(
            topic,
            info.msgtype,
            typestore=self.typestore,
            serialization_format="cdr",
            offered_qos_profiles=info.qos,
        )

    def _open_part(self) -> None:
        # rosbags writes <dir>/<dir>.<ext>; each file is written as a one-file bag in a
        # sub-directory named like the final file, then moved up (see _close_part).
        part = Writer(
            self.path / f"{self.path.name}_{self._next_index}",
            version=BAG_VERSION,
            storage_plugin=STORAGES[self.storage],
        )
        part.open()
        self._next_index += 1
        self._part = part
        self._connections = {}
        self._part_bytes = 0
        self._part_count = 0
        for topic in self._topics:
            self._connect(topic)

    def _close_part(self) -> None:
        assert self._part is not None and self._part.storage is not None
        part_dir = self._part.path
        storage_file = self._part.storage.path
        self._part.close()
        self._part, self._part_count, self._part_bytes = None, 0, 0
        _fsync(storage_file)
        info = _load_metadata(part_dir)
        keep_part_metadata(self.path, storage_file.name, info)  # for a writer that resumes
        self._part_metadata.append(info)
        self.files.append(storage_file.replace(self.path / storage_file.name))
        _fsync(self.path)
        shutil.rmtree(part_dir)

    def _resume(self) -> None:
        """Continue the recording in ``path``: adopt its closed files, write what its unfinished
        files hold into a new file each (then delete them: their messages are on disk again)."""
        try:
            existing = existing_recording(self.path)
        except ValueError as exc:
            raise BagError(f"cannot continue {self.path}: {exc}") from exc
        self._part_metadata, self.files = existing.part_metadata, existing.files
        self._next_index = existing.next_index
        (self.path / "metadata.yaml").unlink(missing_ok=True)  # being written again
        ends = [_span_ns(p)[1] for p in self._part_metadata if p["message_count"]]
        for source in existing.unfinished:
            salvaged = salvage(source)
            self.resumed.append(salvaged)
            if salvaged.messages:
                self.write_salvaged(salvaged)
                self.start_new_file()
                ends.append(salvaged.messages[-1].log_time_ns)
            for leftover in (source, source.with_name(source.name + "-journal")):
                leftover.unlink(missing_ok=True)
            if source.parent != self.path:
                shutil.rmtree(source.parent)
        self.resumed_end_ns = max(ends, default=0)

    def _write_metadata(self) -> None:
        """Merge the one-file metadata of every part into the bag's metadata.yaml."""
        parts = self._part_metadata
        merged = dict(parts[0])
        with_messages = [p for p in parts if p["message_count"]] or parts[:1]
        start = min(_span_ns(p)[0] for p in with_messages)
        end = max(_span_ns(p)[1] for p in with_messages)
        counts: dict[str, int] = {}
        for part in parts:
            for item in part["topics_with_message_count"]:
                name = item["topic_metadata"]["name"]
                counts[name] = counts.get(name, 0) + item["message_count"]
        topics = [
            {**item, "message_count": counts[item["topic_metadata"]["name"]]}
            for item in parts[-1]["topics_with_message_count"]
        ]
        merged.update(
            relative_file_paths=[p for part in parts for p in part["relative_file_paths"]],
            starting_time={"nanoseconds_since_epoch": start},
            duration={"nanoseconds": max(0, end - start)},
            message_count=sum(p["message_count"] for p in parts),
            topics_with_message_count=topics,
            files=[f for part in parts for f in part["files"]],
        )
        text = yaml.safe_dump({"rosbag2_bagfile_information": merged}, sort_keys=False)
        # Written whole or not at all: a bag with a metadata.yaml is read as complete.
        scratch = self.path / ".metadata.yaml.writing"
        scratch.write_text(text, encoding="utf-8")
        _fsync(scratch)
        scratch.replace(self.path / "metadata.yaml")
        _fsync(self.path)

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        # Closing on errors too keeps every message written so far in a readable bag.
        self.close()


def _span_ns(info: dict[str, Any]) -> tuple[int, int]:
    """Start and end (ns since the epoch) of the messages that rosbag2 metadata describes."""
    start = int(info["starting_time"]["nanoseconds_since_epoch"])
    return start, start + int(info["duration"]["nanoseconds"])


def _fsync(path: Path) -> None:
    """Put a file's data (or a directory's entries) on disk before the next step relies on it."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _load_metadata(bag_dir: Path) -> dict[str, Any]:
    if not (bag_dir / "metadata.yaml").exists():
        raise BagError(
            f"{bag_dir}: no metadata.yaml, the recording did not finish;"
            f" `gnss_ins recover {bag_dir}` makes a readable copy"
        )
    try:
        text = (bag_dir / "metadata.yaml").read_text(encoding="utf-8")
        info = yaml.safe_load(text)["rosbag2_bagfile_information"]
    except (OSError, yaml.YAMLError, KeyError, TypeError) as exc:
        raise BagError(f"{bag_dir}: unreadable metadata.yaml ({exc})") from exc
    return cast(dict[str, Any], info)


# --------------------------------------------------------------------------------------------
# Reader
# --------------------------------------------------------------------------------------------


class BagMessage(NamedTuple):
    """One message of a bag: raw CDR bytes, or a rosbags message object when deserialized."""

    topic: str
    msgtype: str
    log_time_ns: int
    message: Any


@dataclass(frozen=True)
class BagTopic:
    """A topic of a bag: type, message count, QoS profiles offered when it was recorded."""

    msgtype: str
    count: int
    qos: tuple[Qos, ...]


def storage_files(path: Path) -> list[Path]:
    """What rosbags opens for a bag: its storage files (so messages merge in time order across
    splits), or the directory itself when it is compressed (rosbags decompresses it)."""
    if not path.is_dir():
        return [path]
    info = _load_metadata(path)
    if str(info.get("compression_mode") or "none").lower() != "none":
        return [path]
    return [path / PurePath(p).name for p in info["relative_file_paths"]]


#: What rosbags' readers raise besides their own errors on a file that ends early (an MCAP
#: torn right after its magic: ``ord()`` of an empty read; a record cut short).
_TORN_FILE_ERRORS = (EOFError, TypeError, ValueError, IndexError, struct.error)


class BagReader:
    """Reads a rosbag2 bag (directory of MCAP or sqlite3 files, or one storage file).

    Messages come in log-time order across all files. Types come from the definitions stored
    in the bag, else from the Jazzy typestore (older bags without definitions).
    """

    def __init__(self, path: Path | str, typestore: Typestore | None = None) -> None:
        self.path = Path(path)
        if not self.path.exists():
            raise BagError(f"{self.path}: no such bag")
        default = typestore if typestore is not None else jazzy_typestore()
        files = storage_files(self.path)
        try:
            self._reader = AnyReader(files, default_typestore=default)
            self._reader.open()
        except (AnyReaderError, ReaderError, *_TORN_FILE_ERRORS) as exc:
            raise BagError(
                f"{self.path}: unreadable ({exc}); if its recording did not finish, run"
                f" `gnss_ins recover` on its bag directory"
            ) from exc
        self.topics: dict[str, BagTopic] = {}
        for conn in self._reader.connections:
            known = self.topics.get(conn.topic)
            qos = tuple(getattr(conn.ext, "offered_qos_profiles", ()))
            self.topics[conn.topic] = BagTopic(
                conn.msgtype,
                conn.msgcount + (known.count if known else 0),
                known.qos if known else qos,
            )

    @property
    def start_ns(self) -> int:
        """Log time of the first message."""
        return int(self._reader.start_time)

    @property
    def end_ns(self) -> int:
        """Log time of the last message."""
        return int(self._reader.end_time) - 1

    def messages(
        self,
        topics: Collection[str] | None = None,
        *,
        start_ns: int | None = None,
        deserialize: bool = False,
        raw_topics: Collection[str] = (),
    ) -> Iterator[BagMessage]:
        """Messages of ``topics`` (all if None) at or after ``start_ns``, in log-time order;
        with ``deserialize``, those of ``raw_topics`` still come as bytes."""
        if topics is not None and (unknown := set(topics) - set(self.topics)):
            raise BagError(f"{self.path}: no topic {', '.join(sorted(unknown))}")
        connections = [c for c in self._reader.connections if topics is None or c.topic in topics]
        if not connections:
            return
        for conn, log_time_ns, data in self._reader.messages(connections, start=start_ns):
            if deserialize and conn.topic not in raw_topics:
                message = self._reader.deserialize(data, conn.msgtype)
            else:
                message = bytes(data)
            yield BagMessage(conn.topic, conn.msgtype, log_time_ns, message)

    def deserialize(self, data: bytes, msgtype: str) -> Any:
        """A rosbags message object of raw CDR bytes of ``msgtype`` (types as ``messages``)."""
        return self._reader.deserialize(data, msgtype)

    def summary(self, topics: Collection[str] | None = None) -> BagSummary:
        """Counts, span and gaps of the bag (reads every message time)."""
        summary = BagSummary()
        for msg in self.messages(topics):
            summary.add(msg.topic, msg.msgtype, msg.log_time_ns)
        return summary

    def close(self) -> None:
        """Close the storage files."""
        self._reader.close()

    def __enter__(self) -> BagReader:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


def read_messages(
    path: Path | str,
    topics: Collection[str] | None = None,
    *,
    start_ns: int | None = None,
    deserialize: bool = False,
) -> Iterator[BagMessage]:
    """Every message of the bag at ``path`` in log-time order (see ``BagReader.messages``)."""
    with BagReader(path) as reader:
        yield from reader.messages(topics, start_ns=start_ns, deserialize=deserialize)
