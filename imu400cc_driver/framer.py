"""Byte stream -> IMU400CC packets, over arbitrary chunk boundaries (no I/O).

Modelled on pyubx2's reader: hunt for the 0xFF header, confirm a candidate by its checksum only
(0xFF also occurs inside payloads, e.g. in negative MSBs; notes §2.3, §11.1 item 3), and on a bad
checksum slide one byte and hunt again. Confirming by the checksum alone, not also by the next
header, keeps polled mode working (one packet per 'G', no next header to wait for); the price is
that, while hunting, a false candidate passes the 8-bit checksum with probability 1/256.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from enum import Enum

from imu400cc_driver.protocol import (
    HEADER,
    PACKET_LENGTH,
    Buffer,
    RawPacket,
    checksum,
    unpack_packet,
)

_HEADER_BYTE = bytes((HEADER,))


@dataclass(slots=True)
class FramerStats:
    """Counters since the framer was created (``reset`` keeps them).

    Invariant: ``bytes_in == PACKET_LENGTH * packets + skipped_bytes + framer.buffered``.
    """

    bytes_in: int = 0
    """Bytes fed."""
    packets: int = 0
    """Packets accepted (header and checksum good)."""
    bad_checksums: int = 0
    """Header candidates (0xFF with 17 bytes after it) rejected by the checksum; one corrupted
    packet can add more than one, as every 0xFF in its remains is tried too."""
    skipped_bytes: int = 0
    """Bytes dropped while hunting for a header, or discarded by ``reset``."""
    unconfirmed: int = 0
    """Candidates with a good checksum rejected because no valid packet followed them (only
    with ``confirm_with_next_packet``)."""
    resyncs: int = 0
    """Times sync was lost (bytes skipped after an accepted packet) and then found again; the
    first lock after start-up or ``reset`` is not a resync."""


class _Sync(Enum):
    HUNTING = "hunting"  # no packet yet since start-up / reset
    LOCKED = "locked"  # the last thing seen was an accepted packet
    LOST = "lost"  # bytes skipped since the last accepted packet


class PacketFramer:
    """Incremental framer: ``feed`` bytes as they arrive, get the complete valid packets back.

    Between calls at most ``PACKET_LENGTH - 1`` bytes are kept (a header candidate waiting for
    the rest of its packet), or ``2 * PACKET_LENGTH - 1`` with ``confirm_with_next_packet`` (a
    candidate waiting for the packet that confirms it), so the buffer is bounded whatever the input.
    """

    def __init__(self, confirm_with_next_packet: bool = False) -> None:
        """``confirm_with_next_packet``: out of sync, trust a packet only if a valid one follows."""
        self._confirm = confirm_with_next_packet
        self._buffer = bytearray()
        self._stats = FramerStats()
        self._sync = _Sync.HUNTING

    @property
    def stats(self) -> FramerStats:
        """A snapshot of the counters."""
        return dataclasses.replace(self._stats)

    @property
    def buffered(self) -> int:
        """Bytes held back, waiting for the rest of a candidate (< 2 * PACKET_LENGTH)."""
        return len(self._buffer)

    @property
    def locked(self) -> bool:
        """True when the last thing seen was a valid packet (no bytes skipped since)."""
        return self._sync is _Sync.LOCKED

    def feed(self, chunk: Buffer) -> list[RawPacket]:
        """Add ``chunk`` to the stream; return the packets completed by it, in stream order."""
        buf = self._buffer
        start = len(buf)
        buf += chunk
        end = len(buf)
        pos = 0
        packets: list[RawPacket] = []
        stats = self._stats
        sync = self._sync
        while True:
            if pos < end and buf[pos] != HEADER:
                # Hunt: no packet can start before the next 0xFF.
                found = buf.find(_HEADER_BYTE, pos + 1)
                nxt = end if found < 0 else found
                stats.skipped_bytes += nxt - pos
                pos = nxt
                if sync is _Sync.LOCKED:
                    sync = _Sync.LOST
            if end - pos < PACKET_LENGTH:
                break
            last = pos + PACKET_LENGTH - 1
            sum_ok = checksum(buf[pos + 1 : last]) == buf[last]
            good = sum_ok
            if good and self._confirm and sync is not _Sync.LOCKED:
                after = last + 1
                if end - after < PACKET_LENGTH:
                    break  # wait for the packet that would confirm the candidate
                nxt_last = after + PACKET_LENGTH - 1
                if buf[after] != HEADER or checksum(buf[after + 1 : nxt_last]) != buf[nxt_last]:
                    stats.unconfirmed += 1
                    good = False
            if good:
                packets.append(unpack_packet(buf, pos))
                pos = last + 1
                if sync is _Sync.LOST:
                    stats.resyncs += 1
                sync = _Sync.LOCKED
            else:
                stats.bad_checksums += not sum_ok
                stats.skipped_bytes += 1
                pos += 1
                if sync is _Sync.LOCKED:
                    sync = _Sync.LOST
        del buf[:pos]
        stats.bytes_in += end - start
        stats.packets += len(packets)
        self._sync = sync
        return packets

    def reset(self) -> None:
        """Forget the partial packet and the sync state (e.g. after the port was reopened).

        The discarded bytes count as skipped, so the byte accounting still holds.
        """
        self._stats.skipped_bytes += len(self._buffer)
        self._buffer.clear()
        self._sync = _Sync.HUNTING
