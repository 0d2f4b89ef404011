"""RTCM 3 frames out of any byte stream (no I/O, no ROS).

A frame (RTCM 10403.3 §4.1): the preamble 0xD3, 6 reserved bits that are zero, a 10-bit payload
length (0..1023 bytes), the payload, whose first 12 bits are the message number, and a 24-bit
CRC-24Q over everything before it. ``RtcmFramer.feed`` returns the whole frames with a valid CRC,
in stream order, over arbitrary chunk boundaries; every other byte (HTTP text, chunk headers,
noise, a frame whose CRC fails) is counted and, when asked, handed back (``feed``'s ``other``),
never returned as part of a frame. The CRC is pyrtcm's ``calc_crc24q`` (bitwise, ~1 µs a byte:
0.1 % of a core at 1 kB/s); pyrtcm's ``RTCMReader`` is not used because it decodes every
payload, which nothing here needs.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

from pyrtcm.rtcmhelpers import calc_crc24q

PREAMBLE = 0xD3
#: Bytes before the payload (preamble, reserved bits and length) and after it (CRC-24Q).
HEADER_BYTES = 3
CRC_BYTES = 3
MAX_PAYLOAD_BYTES = 1023
#: The longest frame [bytes].
MAX_FRAME_BYTES = HEADER_BYTES + MAX_PAYLOAD_BYTES + CRC_BYTES


def frame_length(header: bytes | bytearray) -> int | None:
    """The whole frame's length [bytes] from its first three bytes; None when they are no RTCM 3
    header (no preamble, or reserved bits set)."""
    if len(header) < HEADER_BYTES or header[0] != PREAMBLE or header[1] & 0xFC:
        return None
    return HEADER_BYTES + ((header[1] & 0x03) << 8 | header[2]) + CRC_BYTES


def message_number(frame: bytes) -> int:
    """The message number of a whole frame (its payload's first 12 bits; 0 for an empty
    payload)."""
    if len(frame) < HEADER_BYTES + 2 + CRC_BYTES:
        return 0
    return frame[HEADER_BYTES] << 4 | frame[HEADER_BYTES + 1] >> 4


def make_frame(payload: bytes) -> bytes:
    """A frame around ``payload`` (at most 1023 bytes) with its CRC."""
    if len(payload) > MAX_PAYLOAD_BYTES:
        raise ValueError(f"RTCM 3 payload of {len(payload)} bytes: at most {MAX_PAYLOAD_BYTES}")
    head = bytes((PREAMBLE, len(payload) >> 8, len(payload) & 0xFF)) + payload
    crc: int = calc_crc24q(head)
    return head + crc.to_bytes(CRC_BYTES, "big")


def split_frames(data: bytes) -> tuple[list[bytes], int]:
    """The valid frames of a self-contained byte string (e.g. one rtcm_msgs/Message) and the
    number of its bytes outside them (a partial frame at the end included)."""
    framer = RtcmFramer()
    frames = framer.feed(data)
    return frames, framer.stats.skipped_bytes + framer.buffered


@dataclass(slots=True)
class RtcmStats:
    """Counters since the framer was created."""

    bytes_in: int = 0
    frames: int = 0
    frame_bytes: int = 0
    #: Candidate frames (preamble, zero reserved bits, all bytes there) whose CRC failed.
    crc_failures: int = 0
    #: Bytes outside valid frames: not RTCM, or a failed candidate's preamble.
    skipped_bytes: int = 0
    by_number: Counter[int] = field(default_factory=Counter)


class RtcmFramer:
    """Incremental RTCM 3 framer; see the module docstring."""

    def __init__(self) -> None:
        """An empty framer."""
        self.stats = RtcmStats()
        self._buffer = bytearray()

    @property
    def buffered(self) -> int:
        """Bytes of a possible frame held until the rest arrives (< MAX_FRAME_BYTES)."""
        return len(self._buffer)

    def reset(self) -> None:
        """Forget a partial frame (its bytes counted as skipped); counters are kept."""
        self.stats.skipped_bytes += len(self._buffer)
        self._buffer.clear()

    def feed(self, chunk: bytes, other: bytearray | None = None) -> list[bytes]:
        """Add ``chunk``; return the frames it completed. Bytes found to be outside any frame
        are appended to ``other`` when given, in stream order."""
        stats = self.stats
        stats.bytes_in += len(chunk)
        buf = self._buffer
        buf += chunk
        frames: list[bytes] = []
        pos, end = 0, len(buf)
        while pos < end:
            start = buf.find(PREAMBLE, pos)
            if start < 0:
                start = end
            if start > pos:
                self._skip(buf, pos, start, other)
                pos = start
                continue
            if end - pos < HEADER_BYTES:
                break
            length = frame_length(buf[pos : pos + HEADER_BYTES])
            if length is None:
                self._skip(buf, pos, pos + 1, other)
                pos += 1
                continue
            if end - pos < length:
                break
            frame = bytes(buf[pos : pos + length])
            if calc_crc24q(frame) != 0:
                stats.crc_failures += 1
                self._skip(buf, pos, pos + 1, other)
                pos += 1
                continue
            frames.append(frame)
            stats.frames += 1
            stats.frame_bytes += length
            stats.by_number[message_number(frame)] += 1
            pos += length
        del buf[:pos]
        return frames

    def _skip(self, buf: bytearray, start: int, stop: int, other: bytearray | None) -> None:
        self.stats.skipped_bytes += stop - start
        if other is not None:
            other += buf[start:stop]
