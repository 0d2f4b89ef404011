"""Many serialized messages held where they were read: slices of a few shared buffers.

A bag's chunk holds thousands of messages back to back. Cutting each out as its own ``bytes``
(~0.6 µs and an object a message) and joining them again to decode a topic as columns
(cdr_fields) copies every byte twice; ``Payloads`` keeps (buffer, start, length) per message,
the buffer being bytes or a file mapped into memory (an uncompressed MCAP file holds its
messages as they are), and copies the messages a decoder asks for into one matrix (``rows``:
~0.1 µs a message, what numpy's indexing costs per row, whatever its width). A single message
is still ``payloads[i]`` (bytes).
"""

from __future__ import annotations

import mmap
from collections.abc import Iterator, Sequence
from typing import TypeAlias, overload

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from numpy.typing import NDArray

from gnss_ins_common.types import IntArray

_NO_INDEX = np.zeros(0, np.int64)
#: What holds the messages: bytes, or a file mapped read-only (slicing either gives bytes).
Buffer: TypeAlias = bytes | mmap.mmap


class Payloads(Sequence[bytes]):
    """Messages ``buffers[buffer[i]][start[i] : start[i] + length[i]]`` (i: 0..n-1, in order)."""

    __slots__ = ("_buffer", "_buffers", "_length", "_start")

    def __init__(
        self, buffers: Sequence[Buffer], buffer: IntArray, start: IntArray, length: IntArray
    ) -> None:
        """ValueError when the three index arrays differ in length or a message lies outside
        its buffer."""
        if not len(buffer) == len(start) == len(length):
            raise ValueError(f"{len(buffer)} buffer, {len(start)} start, {len(length)} length")
        if len(buffer):
            sizes = np.array([len(b) for b in buffers], np.int64)
            if buffer.min() < 0 or buffer.max() >= len(sizes) or start.min() < 0:
                raise ValueError("a message refers to no buffer or starts before it")
            if length.min() < 0 or np.any(start + length > sizes[buffer]):
                raise ValueError("a message runs past the end of its buffer")
        self._buffers = list(buffers)
        self._buffer, self._start, self._length = buffer, start, length

    @classmethod
    def of(cls, messages: Sequence[bytes]) -> Payloads:
        """Payloads of ``messages`` (itself when it is one; else the messages joined once)."""
        if isinstance(messages, Payloads):
            return messages
        length = np.fromiter(map(len, messages), np.int64, len(messages))
        start = np.zeros(len(messages), np.int64)
        np.cumsum(length[:-1], out=start[1:])
        return cls([b"".join(messages)], np.zeros(len(messages), np.int64), start, length)

    @classmethod
    def joined(cls, parts: Sequence[Payloads]) -> Payloads:
        """The messages of ``parts``, one after the other (a buffer they share listed once)."""
        buffers: list[Buffer] = []
        number_of: dict[int, int] = {}  # id(buffer) -> its number in ``buffers``
        numbers = []
        for part in parts:
            for buffer in part._buffers:
                if number_of.setdefault(id(buffer), len(buffers)) == len(buffers):
                    buffers.append(buffer)
            renumber = np.array([number_of[id(b)] for b in part._buffers], np.int64)
            numbers.append(renumber[part._buffer])
        if not parts:
            return cls([], _NO_INDEX, _NO_INDEX, _NO_INDEX)
        return cls(
            buffers,
            np.concatenate(numbers),
            np.concatenate([p._start for p in parts]),
            np.concatenate([p._length for p in parts]),
        )

    @property
    def lengths(self) -> IntArray:
        """Length of each message [bytes] (n,)."""
        return self._length

    def __len__(self) -> int:
        return len(self._start)

    @overload
    def __getitem__(self, index: int) -> bytes: ...

    @overload
    def __getitem__(self, index: slice) -> Payloads: ...

    def __getitem__(self, index: int | slice) -> bytes | Payloads:
        if isinstance(index, slice):
            return self.take(np.arange(len(self))[index])
        i = range(len(self))[index]  # IndexError as a list gives it
        start = int(self._start[i])
        return self._buffers[int(self._buffer[i])][start : start + int(self._length[i])]

    def __iter__(self) -> Iterator[bytes]:
        buffers = self._buffers
        for b, start, length in zip(
            self._buffer.tolist(), self._start.tolist(), self._length.tolist(), strict=True
        ):
            yield buffers[b][start : start + length]

    def take(self, indices: IntArray) -> Payloads:
        """The messages at ``indices``, in that order (the buffers shared, not copied)."""
        return Payloads(
            self._buffers, self._buffer[indices], self._start[indices], self._length[indices]
        )

    def rows(self, indices: IntArray, width: int) -> NDArray[np.uint8]:
        """The first ``width`` bytes of the messages at ``indices`` (each at least that long),
        one row each (m, width), copied once from their buffers."""
        if np.any(self._length[indices] < width):
            raise ValueError(f"a message is shorter than {width} bytes")
        out = np.empty((len(indices), width), np.uint8)
        if not len(indices) or not width:
            return out
        owner, start = self._buffer[indices], self._start[indices]
        by_buffer = np.argsort(owner, kind="stable")
        cuts = np.flatnonzero(np.diff(owner[by_buffer])) + 1
        for rows in np.split(by_buffer, cuts):
            raw = np.frombuffer(self._buffers[int(owner[rows[0]])], np.uint8)
            window = sliding_window_view(raw, width)
            out[rows] = window[start[rows]]
        return out
