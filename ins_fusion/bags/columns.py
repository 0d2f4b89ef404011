"""The messages of some topics of a bag as columns: log times, receive order and raw payloads.

``gnss_ins replay``, ``allan`` and ``calibrate`` read every message of their topics (a 437 s
bag at 200 Hz: 160 000; an hour's static record: 480 000), and rosbags' reader spends ~8 µs on
each (a record parsed through BytesIO, a generator merge per chunk and per file, a message
tuple). Indexed MCAP files (what rosbags, hence ``gnss_ins record`` / ``simulate``, and ``ros2
bag record`` write) are read here a chunk at a time instead: the chunk's records in one read,
the log time and offset of each message of a topic from its message index (one numpy array per
chunk and channel) and the payload lengths gathered by numpy; the payloads stay in the chunk's
bytes (adapters.payloads: no object per message). Other bags (sqlite3, file-compressed,
unindexed MCAP) are read message by message through ins_fusion.bags.bag_io.

Receive order: by log time, ties in file order (file, then chunk, then position in the chunk),
as rosbags' reader yields a bag. MCAP layout: https://mcap.dev/spec (Chunk, Message Index and
Message records); the chunk index and channels come from rosbags' own MCAP reader.
"""

from __future__ import annotations

import mmap
import struct
import zlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

import numpy as np
from numpy.typing import NDArray
from rosbags.rosbag2 import ReaderError
from rosbags.rosbag2.storage_mcap import ChunkInfo, McapReader, decompress

from gnss_ins_common.types import IntArray
from ins_fusion.adapters.payloads import Buffer, Payloads
from ins_fusion.bags.bag_io import BagError, BagReader, storage_files

_MESSAGE_OP, _MESSAGE_INDEX_OP = 0x05, 0x07
#: Message record: opcode (1), record length (u64), channel id (u16), sequence (u32), log time
#: (u64), publish time (u64), then the payload.
_MESSAGE_HEADER = 1 + 8 + 2 + 4 + 8 + 8
#: Chunk record: opcode, length, start and end time, uncompressed size (u64 each), CRC (u32),
#: then the compression name (u32 length + characters), the records' size (u64), the records.
_CHUNK_CRC_AT = 1 + 8 + 8 + 8 + 8
_CHUNK_HEADER = _CHUNK_CRC_AT + 4 + 4 + 8
#: Message index record: opcode, length (u64), channel id (u16), then the byte length (u32) of
#: its (log time, offset in the chunk's records) u64 pairs.
_MESSAGE_INDEX = struct.Struct("<BQHI")


@dataclass(frozen=True)
class TopicColumns:
    """A topic's messages in receive order: type (``pkg/msg/Name``), log times [ns since the
    epoch] (n,), positions in the receive order of all the topics read (n,), raw CDR payloads."""

    msgtype: str
    log_time_ns: IntArray
    order: IntArray
    payloads: Payloads


@dataclass
class _Part:
    """Messages of one topic from one chunk (or all of a bag read message by message), with the
    sort keys of the receive order."""

    topic: str
    log_time_ns: IntArray
    file: int
    chunk_offset: int
    offset: IntArray
    payloads: Payloads


def read_topics(
    reader: BagReader,
    topics: Sequence[str],
    progress: Callable[[int], None] | None = None,
) -> dict[str, TopicColumns]:
    """The messages of ``topics`` (present in the bag) of an open bag, as columns in receive
    order; ``progress(messages read)`` after every chunk (or every few thousand messages)."""
    types = {topic: reader.topics[topic].msgtype for topic in topics}
    parts = _indexed_mcap(storage_files(reader.path), set(topics), progress)
    # The indexes must account for every message the bag's metadata counts (an MCAP file
    # without a chunk index, say, lists none): otherwise read message by message.
    expected = sum(reader.topics[topic].count for topic in topics)
    if parts is None or sum(len(p.offset) for p in parts) != expected:
        parts = _message_by_message(reader, topics, progress)
    return _columns(parts, types)


def _columns(parts: list[_Part], types: dict[str, str]) -> dict[str, TopicColumns]:
    """Number every message in receive order and gather the parts of each topic in it."""
    empty = np.zeros(0, np.int64)

    def joined(values: list[IntArray]) -> IntArray:
        return np.concatenate(values) if values else empty

    sizes = [len(p.offset) for p in parts]
    keys = (
        joined([p.offset for p in parts]),
        np.repeat(np.array([p.chunk_offset for p in parts], np.int64), sizes),
        np.repeat(np.array([p.file for p in parts], np.int64), sizes),
        joined([p.log_time_ns for p in parts]),
    )
    order = np.empty(len(keys[0]), dtype=np.int64)
    order[np.lexsort(keys)] = np.arange(len(order))
    bounds = np.cumsum([0, *sizes]).tolist()
    columns: dict[str, TopicColumns] = {}
    for topic, msgtype in types.items():
        mine = [i for i, p in enumerate(parts) if p.topic == topic]
        positions = joined([order[bounds[i] : bounds[i + 1]] for i in mine])
        sort = np.argsort(positions, kind="stable")
        payloads = Payloads.joined([parts[i].payloads for i in mine])
        log_times = joined([parts[i].log_time_ns for i in mine])
        columns[topic] = TopicColumns(
            msgtype, log_times[sort], positions[sort], payloads.take(sort)
        )
    return columns


def _message_by_message(
    reader: BagReader, topics: Sequence[str], progress: Callable[[int], None] | None
) -> list[_Part]:
    """Any bag through bag_io's reader: one part per topic, ordered as it yields them."""
    found: dict[str, tuple[list[int], list[int], list[bytes]]] = {t: ([], [], []) for t in topics}
    for index, msg in enumerate(reader.messages(topics)):
        times, indices, payloads = found[msg.topic]
        times.append(msg.log_time_ns)
        indices.append(index)
        payloads.append(msg.message)
        if progress is not None and index % 4096 == 0:
            progress(index)
    return [
        _Part(
            topic, np.array(times, np.int64), 0, 0, np.array(indices, np.int64), Payloads.of(data)
        )
        for topic, (times, indices, data) in found.items()
    ]


def _indexed_mcap(
    files: list[Path], topics: set[str], progress: Callable[[int], None] | None
) -> list[_Part] | None:
    """Parts of every chunk of every file; None when a file is not MCAP or a chunk holding a
    wanted channel has no message index for it."""
    if not all(f.suffix == ".mcap" and f.is_file() for f in files):
        return None
    parts: list[_Part] = []
    done = 0
    for number, path in enumerate(files):
        storage = McapReader(path)
        try:
            storage.open()
            with path.open("rb") as handle:  # the chunks' records, read where they lie
                whole = mmap.mmap(handle.fileno(), 0, access=mmap.ACCESS_READ)
        except (ReaderError, ValueError) as exc:
            raise BagError(f"{path}: unreadable MCAP ({exc})") from exc
        try:
            channels = {cid: c.topic for cid, c in storage.channels.items() if c.topic in topics}
            chunks = [c for c in storage.chunks if any(c.channel_count.get(i) for i in channels)]
            if any(
                c.channel_count.get(i) and i not in c.message_index_offsets
                for c in chunks
                for i in channels
            ):
                return None
            assert storage.bio is not None
            for chunk in chunks:
                parts.extend(_chunk_parts(storage.bio, whole, chunk, channels, (number, path)))
                done += sum(chunk.channel_count.get(i, 0) for i in channels)
                if progress is not None:
                    progress(done)
        finally:
            storage.close()
    return parts


def _chunk_parts(
    bio: BinaryIO,
    whole: mmap.mmap,
    chunk: ChunkInfo,
    channels: dict[int, str],
    file: tuple[int, Path],
) -> list[_Part]:
    """The messages of the wanted channels in one chunk, from its message indexes (``whole``:
    the file mapped; ``file``: its number in the bag and its path)."""
    number, path = file
    bio.seek(chunk.chunk_start_offset + _CHUNK_CRC_AT)
    (crc,) = struct.unpack("<I", bio.read(4))
    at = chunk.chunk_start_offset + _CHUNK_HEADER + len(chunk.compression)
    size = chunk.uncompressed_size
    records: Buffer
    if chunk.compression:
        bio.seek(at)
        records, base = decompress(bio.read(chunk.compressed_size), chunk.compression, size, crc), 0
    else:  # stored as they are: the mapped file holds them
        if at + size > len(whole) or size != chunk.compressed_size:
            raise BagError(f"{path}: the chunk at byte {chunk.chunk_start_offset} is cut short")
        with memoryview(whole)[at : at + size] as stored:
            if crc and zlib.crc32(stored) != crc:
                raise BagError(f"{path}: checksum mismatch of the chunk at byte {at}")
        records, base = whole, at
    raw = np.frombuffer(records, dtype=np.uint8, count=size, offset=base)
    parts = []
    for cid, topic in channels.items():
        if not chunk.channel_count.get(cid):
            continue
        at = chunk.message_index_offsets[cid]
        bio.seek(at)
        op, _, channel, size = _MESSAGE_INDEX.unpack(bio.read(_MESSAGE_INDEX.size))
        if op != _MESSAGE_INDEX_OP or channel != cid or size % 16:
            raise BagError(f"{path}: no message index of channel {cid} at byte {at}")
        pairs = np.frombuffer(bio.read(size), dtype="<u8").reshape(-1, 2)
        log_time, offset = pairs[:, 0].astype(np.int64), pairs[:, 1].astype(np.int64)
        if len(offset) and (offset.max() + _MESSAGE_HEADER > len(raw) or offset.min() < 0):
            raise BagError(f"{path}: message index of channel {cid} points outside its chunk")
        lengths = _gather_u64(raw, offset + 1)
        if np.any(raw[offset] != _MESSAGE_OP) or np.any(lengths < _MESSAGE_HEADER - 9):
            raise BagError(f"{path}: message index of channel {cid} points at no message")
        starts = offset + _MESSAGE_HEADER
        ends = offset + 9 + lengths.astype(np.int64)
        if len(ends) and ends.max() > len(raw):
            raise BagError(f"{path}: a message of channel {cid} runs past its chunk")
        payloads = Payloads(
            [records], np.zeros(len(starts), np.int64), base + starts, ends - starts
        )
        parts.append(_Part(topic, log_time, number, chunk.chunk_start_offset, offset, payloads))
    return parts


def _gather_u64(raw: NDArray[np.uint8], at: IntArray) -> NDArray[np.uint64]:
    """Little-endian uint64 values at byte offsets ``at`` of ``raw`` (n,)."""
    index = at[:, None] + np.arange(8)
    return np.ascontiguousarray(raw[index]).view("<u8")[:, 0]
