"""Byte stream -> IMU400CC packets, over arbitrary chunk boundaries (no I/O).

Modelled on pyubx2's reader: hunt for the 0xFF header, confirm a candidate by its checksum, and
on a bad checksum slide one byte and hunt again. 0xFF also occurs inside payloads (negative
MSBs; notes §2.3, §11.1 item 3), so the 8-bit checksum alone lets a false candidate through
1 time in 256. Polled mode (one packet per 'G', no next header to wait for) has only the
checksum. In continuous mode (``confirm_with_next_packet``) a candidate must also fit the stream:
in sync, its device-timer step from the last packet must match the last step within
TIMER_STEP_TOLERANCE (the step is 9412 ± 9 counts at 134 Hz, notes §2.6); otherwise — out of
sync, or a step that does not fit — it must be followed by a valid packet one to six packet
periods later by its timer, whose wait delays it by one packet but does not lose it. A candidate
one byte off the packet boundary that a lost or inserted 0xFF would also give is taken only if
its readings continue the last packet's (``_fits_stream``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from enum import Enum

from imu400cc_driver.device_clock import COUNTS_PER_PACKET, MAX_TICK_ERROR
from imu400cc_driver.protocol import (
    HEADER,
    PACKET_LENGTH,
    Buffer,
    RawPacket,
    checksum,
    unpack_packet,
)

_HEADER_BYTE = bytes((HEADER,))
#: Largest difference between a device-timer step and the mean of the last ones [counts]: the
#: App. D.5 steps are within 9 of their mean (notes §2.6). A false candidate fits with p ≈ 1/800.
TIMER_STEP_TOLERANCE = 40
#: Most packet periods a confirming packet may follow a candidate by (whole packets lost in
#: between); 7 periods are about one timer wrap, where any step fits.
MAX_STEP_PACKETS = 6
#: Largest change of a rate or acceleration [counts] between consecutive packets with which a
#: candidate that may be a shifted packet is still taken: 9.4 deg/s or 0.19 g with the
#: IMU400CC-100's scaling (notes §2.4), far above its noise (notes §1.3), far below what a byte
#: shifted from a neighbouring field gives.
MAX_FIELD_STEP = 1024
#: Weight of a new step in the running mean of the steps.
_STEP_WEIGHT = 0.125
_TIMER_MODULUS = 65536


def _timer_at(buf: bytearray, pos: int) -> int:
    """The timer field (uint16, big-endian, bytes 15..16) of the candidate at ``pos``."""
    return (buf[pos + 15] << 8) | buf[pos + 16]


def _periods(step: int) -> int:
    """How many packet periods, 1 to MAX_STEP_PACKETS, a timer step [counts] spans at the
    nominal step within MAX_TICK_ERROR; 0 if none (a pair of false candidates: 88 % of steps)."""
    for n in range(1, MAX_STEP_PACKETS + 1):
        if abs(step - n * COUNTS_PER_PACKET) <= n * COUNTS_PER_PACKET * MAX_TICK_ERROR:
            return n
    return 0


@dataclass(slots=True)
class FramerStats:
    """Counters since the framer was created (``reset`` keeps them).

    Invariant: ``bytes_in + shared_bytes == PACKET_LENGTH * packets + skipped_bytes +
    framer.buffered``.
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
    """Candidates with a good checksum that did not fit the stream and were rejected because no
    valid packet followed them (only with ``confirm_with_next_packet``)."""
    shared_bytes: int = 0
    """0xFF bytes taken both as a packet's checksum and as the next packet's header (only with
    ``confirm_with_next_packet``)."""
    ambiguous: int = 0
    """Candidates with a good checksum rejected as a possible one-byte shift of the packet
    before them (only with ``confirm_with_next_packet``; see ``_fits_stream``)."""
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
        """``confirm_with_next_packet`` (continuous mode): trust a packet only if its timer step
        fits the stream or a valid packet follows it."""
        self._confirm = confirm_with_next_packet
        self._buffer = bytearray()
        self._stats = FramerStats()
        self._sync = _Sync.HUNTING
        self._timer = 0  # timer of the last accepted packet [counts]
        self._step: float | None = None  # running mean of the timer steps [counts]
        self._packet_end = -2  # buffer index just after the last accepted packet (-2: none)
        self._last: RawPacket | None = None  # the last accepted packet

    def _fits(self, timer: int) -> bool:
        """True if ``timer`` follows the last accepted packet's by about the mean step; if so,
        it becomes the last one and its step updates the mean."""
        if self._step is None:
            return False
        step = (self._timer - timer) % _TIMER_MODULUS
        if abs(step - self._step) > TIMER_STEP_TOLERANCE:
            return False
        self._step += _STEP_WEIGHT * (step - self._step)
        self._timer = timer
        return True

    def _continues(self, packet: RawPacket) -> bool:
        """Every rate and acceleration of ``packet`` within MAX_FIELD_STEP of the last accepted
        packet's."""
        last = self._last
        if last is None:
            return False
        fields = zip((*packet.rates, *packet.accels), (*last.rates, *last.accels), strict=True)
        return all(abs(a - b) <= MAX_FIELD_STEP for a, b in fields)

    def _shares_header(self, buf: bytearray, pos: int, sync: _Sync) -> bool:
        """Continuous mode: no packet starts at ``pos``, right after an accepted packet whose
        checksum byte is 0xFF. Either its checksum byte was lost and the next header taken for
        it, or the next header was lost: that 0xFF is the next packet's header too."""
        return (
            self._confirm
            and sync is _Sync.LOCKED
            and pos == self._packet_end
            and buf[pos - 1] == HEADER
        )

    def _fits_stream(self, buf: bytearray, pos: int, end: int, locked: bool) -> bool | None:
        """Continuous mode: does the candidate at ``pos`` (checksum good) fit the stream? None
        while the packet that would confirm it is incomplete."""
        timer = _timer_at(buf, pos)
        last = pos + PACKET_LENGTH - 1
        # One byte off the packet boundary after an accepted packet, a candidate followed or
        # preceded by a 0xFF there is also what a packet starting there gives when one of its
        # 0xFF payload bytes was lost (the candidate shares its header with the last packet's
        # checksum) or a 0xFF was inserted (the byte before is a rejected header): the checksum
        # is a plain sum, and the fields behind that byte, the timer among them, are the
        # packet's own. Those before it are shifted into their neighbours: such a candidate is
        # taken only if its rates and accelerations continue the last packet's.
        shared = pos == self._packet_end - 1
        after_packet = pos == self._packet_end + 1 and buf[pos - 1] == HEADER
        shifted = (shared and buf[pos + 1] == HEADER) or after_packet
        if shifted and not self._continues(unpack_packet(buf, pos)):
            self._stats.ambiguous += 1
            return False
        if locked and self._fits(timer):
            return True
        if shared:
            return False  # its header is the last packet's checksum: its timer must fit
        after = last + 1
        if end - after < PACKET_LENGTH:
            return None
        nxt_last = after + PACKET_LENGTH - 1
        step = (timer - _timer_at(buf, after)) % _TIMER_MODULUS
        periods = _periods(step)
        if (
            buf[after] != HEADER
            or checksum(buf[after + 1 : nxt_last]) != buf[nxt_last]
            or not periods
        ):
            self._stats.unconfirmed += 1
            return False
        self._step = step / periods
        self._timer = timer
        return True

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
            if pos < end and buf[pos] != HEADER and self._shares_header(buf, pos, sync):
                pos -= 1
                stats.shared_bytes += 1
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
            if good and self._confirm:
                verdict = self._fits_stream(buf, pos, end, sync is _Sync.LOCKED)
                if verdict is None:
                    break  # wait for the packet that would confirm the candidate
                good = verdict
            if good:
                self._last = unpack_packet(buf, pos)
                packets.append(self._last)
                pos = last + 1
                self._packet_end = pos
                if sync is _Sync.LOST:
                    stats.resyncs += 1
                sync = _Sync.LOCKED
            elif self._shares_header(buf, pos, sync):
                stats.bad_checksums += not sum_ok
                pos -= 1
                stats.shared_bytes += 1
            else:
                stats.bad_checksums += not sum_ok
                stats.skipped_bytes += 1
                pos += 1
                if sync is _Sync.LOCKED:
                    sync = _Sync.LOST
        del buf[:pos]
        self._packet_end -= pos
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
        self._step = None
        self._packet_end = -2
        self._last = None
