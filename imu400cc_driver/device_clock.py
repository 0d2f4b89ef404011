"""Sample times of IMU400CC packets on the host clock, from the device's 16-bit timer.

Constants cite shared/reference/imu400cc-aalborg-notes.md ("notes"). The time field is a uint16
that counts down by about 9411.75 per packet at 134 Hz, so one tick is about 0.793 us and the
counter wraps every ~52 ms, about 7 packets (notes §2.6). ``DeviceClock`` unwraps it into a
continuous device time, bridges longer gaps with the host clock, counts dropped packets and maps
device time onto the host clock with ``EnvelopeClockSync`` (notes §11.1 item 6; method in
docs/timing.md).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from itertools import pairwise

from gnss_ins_common.clock_sync import EnvelopeClockSync
from gnss_ins_common.rates import IMU400CC_RATE_HZ
from imu400cc_driver.protocol import PACKET_LENGTH

#: The time field is a uint16 (notes §2.3).
TIMER_MODULUS = 1 << 16
#: Mean timer decrement per packet, our derivation from the App. D.5 example rows read as
#: consecutive packets (the report states no tick period or direction; notes §2.6).
COUNTS_PER_PACKET = 9411.75
#: Nominal tick, (1/134 s) / 9411.75 ≈ 0.793 us [s] (notes §2.6); the true one is estimated online.
NOMINAL_TICK_S = 1.0 / IMU400CC_RATE_HZ / COUNTS_PER_PACKET
#: Wire time of one packet at 38400 baud 8N1, 18 bytes x 10 bits = 4.6875 ms [s] (notes §2.1,
#: §7.1; the report's 3.75 ms forgets the start and stop bits).
PACKET_TRANSMISSION_S = PACKET_LENGTH * 10 / 38400
#: Below this implied receive delay a whole-wrap candidate is rejected as "sampled after it
#: arrived" [ticks]: an eighth of a wrap (~6.5 ms) absorbs errors of the mapping and of the tick
#: over a gap, and leaves delays up to ~45 ms resolvable.
_UNWRAP_MARGIN_TICKS = TIMER_MODULUS // 8
#: Largest plausible relative error of the nominal tick (the 134 Hz of notes §2.6 and the
#: oscillator's drift): the mapping's skew is held within it, so that receive delays that keep
#: shrinking for a while (a backlog read out after a stall) do not tilt it.
MAX_TICK_ERROR = 0.02
#: Device time after a gap bridged with whole wraps that only the host clock gave, during which
#: a later read may still show them to be a late read's [s]: under CPU contention a prompt read
#: comes within a few packets, and a sender that fell behind catches up within a second. Holding
#: the points out of the mapping that long costs nothing (100 ppm of drift is 0.1 ms).
_CONFIRM_S = 1.0


@dataclass(frozen=True, slots=True)
class DeviceStamp:
    """The result of ``DeviceClock.stamp`` for one packet."""

    #: Sample time on the host clock [s].
    host_stamp_s: float
    #: Unwrapped device time since the first packet after the last reset, in nominal ticks [s].
    device_time_s: float
    #: Packets missing between the previous packet and this one (0 in polled mode, and after a
    #: silence over ``max_gap_s``).
    dropped_packets: int
    #: The gap before this packet was at least one whole timer wrap (~52 ms), more than the
    #: count alone can measure.
    wrapped_gap: bool


@dataclass(slots=True)
class _PinnedGap:
    """A gap before a read bridged with whole wraps that only the host clock gave."""

    first: int  # index in DeviceClock._held of the packet after the gap
    ticks: int  # the gap [ticks]
    wraps: int  # its whole wraps beyond the fewest the timer allows


class DeviceClock:
    """Stamps packets from their timer values and host receive times.

    Give it every packet in arrival order: ``stamp_chunk`` with the packets one read completed,
    or ``stamp`` per packet. Call ``reset`` after a reconnect. One thread stamps; the statistics
    may be read from any thread.

    Unwrapping: the count gives the ticks since the previous packet modulo one wrap,
    (previous - timer) mod 65536 as it counts down (notes §2.6). Within a read, consecutive
    packets are taken as less than a wrap apart. For the gap before a read, of the candidates
    with more whole wraps the most are taken that keep the read's last packet from seeming
    sampled over a margin after it arrived: its receive delay is >= 0 and, since it is the
    freshest packet in the buffer, far below a wrap, so a reader stall is not mistaken for lost
    packets. A read stamped over ~45 ms after that packet arrived (with ``stamp``: after any
    packet), e.g. on a loaded machine, makes the gap a wrap too long. So such host-pinned wraps
    stay open for 1 s of device time, their packets held out of the mapping: a later read
    that would seem sampled before it arrived takes them back (drops, wrap count and device
    time), latest first, without restarting the mapping. Only a contradiction after that
    restarts it.
    """

    def __init__(
        self,
        nominal_tick_s: float = NOMINAL_TICK_S,
        nominal_period_s: float | None = 1.0 / IMU400CC_RATE_HZ,
        transmission_s: float = PACKET_TRANSMISSION_S,
        latency_s: float = 0.0,
        window_s: float = 60.0,
        min_points: int = 134,
        max_gap_s: float = 1.0,
    ):
        """``nominal_tick_s``: timer tick assumed for device time [s]. ``nominal_period_s``:
        packet period for counting drops [s], None in polled mode (no count).
        ``transmission_s``: wire time of one packet [s], subtracted from the receive time together
        with ``latency_s``, the device's constant delay from sampling to the first byte [s]
        (not observable here). ``window_s``, ``min_points``: of the ``EnvelopeClockSync`` (1 s of
        packets by default). ``max_gap_s``: a longer silence [s] restarts the mapping, since the
        device may have restarted and the host clock pins the wraps less well (must exceed the
        poll period in polled mode); stamps follow a host clock stepping back by more."""
        if nominal_tick_s <= 0.0 or (nominal_period_s is not None and nominal_period_s <= 0.0):
            raise ValueError("nominal_tick_s and nominal_period_s must be > 0")
        self.nominal_tick_s = nominal_tick_s
        self.nominal_period_s = nominal_period_s
        self.transmission_s = transmission_s
        self.latency_s = latency_s
        self.max_gap_s = max_gap_s
        self._sync = EnvelopeClockSync(
            window_s, min_points, max_jump_s=max_gap_s, max_skew=MAX_TICK_ERROR
        )
        self._confirm_ticks = round(_CONFIRM_S / nominal_tick_s)
        self._dropped = 0
        self._timer_gaps = 0
        self._taken_back = 0
        self._clear()

    def _clear(self) -> None:
        self._timer: int | None = None
        self._ticks = 0  # unwrapped ticks since the first packet
        self._last_stamp_s = -math.inf
        # Gaps bridged with whole wraps that only the host clock gave, still open to be taken
        # back, and the (ticks, host time) points after the first of them, held out of the
        # mapping until they are confirmed.
        self._pinned: list[_PinnedGap] = []
        self._held: list[tuple[int, float]] = []

    def reset(self) -> None:
        """Start over (device time and mapping), e.g. after a reconnect; counted in ``resets``."""
        self._sync.reset()
        self._clear()

    def stamp(self, timer: int, host_receive_s: float) -> DeviceStamp:
        """Stamp one packet: its timer field [ticks] and the host time it was read [s]."""
        return self.stamp_chunk((timer,), host_receive_s)[0]

    def stamp_chunk(self, timers: Sequence[int], host_receive_s: float) -> list[DeviceStamp]:
        """Stamp the packets one read completed, in order: their timer fields [ticks] and the
        host time the read returned [s].

        Host stamps are device times mapped onto the host clock, held strictly increasing (at
        least half the device spacing apart, so that a young mapping that steps back is rejoined
        within a few packets) unless the host clock stepped back by over ``max_gap_s``.
        """
        if not all(0 <= t < TIMER_MODULUS for t in timers):
            raise ValueError(f"timers {list(timers)} are not all uint16")
        if not math.isfinite(host_receive_s):
            raise ValueError(f"non-finite receive time {host_receive_s}")
        if not timers:
            return []
        last_host_s = host_receive_s - self.transmission_s - self.latency_s
        gaps = [(a - b) % TIMER_MODULUS or TIMER_MODULUS for a, b in pairwise(timers)]
        first, pinned = 0, 0
        if self._timer is not None:
            first, pinned = self._first_gap(self._timer, timers[0], sum(gaps), last_host_s)
            # A later read that did not take the open wraps back confirms them once it is
            # _CONFIRM_S past the first: packets read together give no evidence of each other.
            if self._pinned and self._ticks + first - self._held[0][0] >= self._confirm_ticks:
                self._release_held()
        self._timer = timers[-1]
        if pinned and first * self.nominal_tick_s <= self.max_gap_s:
            self._pinned.append(_PinnedGap(len(self._held), first, pinned))

        device_times = []
        for ticks in (first, *gaps):
            self._ticks += ticks
            device_times.append(self._ticks * self.nominal_tick_s)
            if self._pinned:
                self._held.append((self._ticks, last_host_s))
            else:
                self._sync.update(device_times[-1], last_host_s)

        stamps = []
        for ticks, device_time_s in zip((first, *gaps), device_times, strict=True):
            stamp_s = self._sync.to_host(device_time_s)
            if self._last_stamp_s - stamp_s < self.max_gap_s:
                stamp_s = max(stamp_s, self._last_stamp_s + ticks * self.nominal_tick_s / 2)
            self._last_stamp_s = stamp_s
            # A silence over max_gap_s is no count of lost packets: the unit may have restarted
            # (a power-cycle restarts its timer and stream), and whole wraps pinned by the host
            # clock then counted every packet period of the silence as dropped.
            dropped = self._drops_of(ticks) if ticks * self.nominal_tick_s <= self.max_gap_s else 0
            wrapped = ticks >= TIMER_MODULUS
            self._dropped += dropped
            self._timer_gaps += int(wrapped)
            stamps.append(DeviceStamp(stamp_s, device_time_s, dropped, wrapped))
        return stamps

    def _drops_of(self, ticks: int) -> int:
        """Packets missing in a gap of ``ticks`` between two packets (0 in polled mode)."""
        if not ticks or self.nominal_period_s is None:
            return 0
        return max(round(ticks * self.nominal_tick_s / self.nominal_period_s) - 1, 0)

    def _first_gap(
        self, previous: int, timer: int, later_ticks: int, last_host_s: float
    ) -> tuple[int, int]:
        """Ticks from the packet with timer ``previous`` to the one with ``timer``, given the
        ``later_ticks`` from that to the read's last packet, received at ``last_host_s``
        (corrected) [s]; and how many of its whole wraps only the host clock gave."""
        delta = (previous - timer) % TIMER_MODULUS
        previous_s = self._sync.to_host(self._ticks * self.nominal_tick_s)
        host_gap_ticks = (last_host_s - previous_s) / self.tick_period_s  # nominal until ready
        margin = _UNWRAP_MARGIN_TICKS
        wraps = math.floor((host_gap_ticks + margin - delta - later_ticks) / TIMER_MODULUS)
        if wraps < 0:
            # Sampled over the margin after it arrived: wraps pinned before were a late read's
            # (stamped over ~45 ms after its last packet arrived, e.g. a loaded machine), not
            # lost packets. Take them back, latest first.
            wraps += self._take_back(-wraps)
        if wraps < 0 and self._sync.ready:
            # Still early: the host clock stepped back, or a late read's wraps were already
            # confirmed. Restart the mapping rather than bend it for a whole window.
            self._sync.reset()
        minimum = 0 if delta else 1
        return delta + max(wraps, minimum) * TIMER_MODULUS, max(wraps - minimum, 0)

    def _take_back(self, wraps: int) -> int:
        """Remove up to ``wraps`` host-pinned wraps from the open gaps, latest first: their drops
        and wrap counts, and a wrap of device time from every packet after each; returns how
        many were removed. The held points go into the mapping once no gap is open."""
        taken = 0
        while self._pinned and taken < wraps:
            gap = self._pinned[-1]
            count = min(gap.wraps, wraps - taken)
            shorter = gap.ticks - count * TIMER_MODULUS
            self._dropped -= self._drops_of(gap.ticks) - self._drops_of(shorter)
            self._timer_gaps -= int(shorter < TIMER_MODULUS)
            gap.ticks, gap.wraps = shorter, gap.wraps - count
            shift = count * TIMER_MODULUS
            self._held[gap.first :] = [(t - shift, h) for t, h in self._held[gap.first :]]
            taken += count
            if not gap.wraps:
                self._pinned.pop()
        self._ticks -= taken * TIMER_MODULUS
        self._taken_back += taken
        if not self._pinned:
            self._release_held()
        return taken

    def _release_held(self) -> None:
        """Confirm the open gaps: the held points go into the mapping."""
        for ticks, host_s in self._held:
            self._sync.update(ticks * self.nominal_tick_s, host_s)
        self._held.clear()
        self._pinned.clear()

    @property
    def ready(self) -> bool:
        """The mapping has enough points (``min_points``) to be trusted."""
        return self._sync.ready

    @property
    def tick_period_s(self) -> float:
        """Estimated timer tick on the host clock [s]: nominal * (1 + skew)."""
        return self.nominal_tick_s * (1.0 + self._sync.skew)

    @property
    def drift_ppm(self) -> float:
        """Rate error of device time against the host clock [ppm]: the oscillator's drift plus
        the error of the nominal tick. Positive: the device clock runs slow."""
        return self._sync.skew * 1e6

    @property
    def jitter_s(self) -> float:
        """RMS receive delay above the envelope [s]: USB/OS jitter and read chunking."""
        return self._sync.jitter_s

    @property
    def dropped_packets(self) -> int:
        """Packets missing from the timer sequence so far (continuous mode only)."""
        return self._dropped

    @property
    def timer_gaps(self) -> int:
        """Gaps of at least one whole timer wrap (~52 ms) so far (every packet in polled mode)."""
        return self._timer_gaps

    @property
    def wraps_taken_back(self) -> int:
        """Host-pinned whole wraps a later read took back: reads stamped over ~45 ms after their
        last packet arrived (a loaded machine), not lost packets."""
        return self._taken_back

    @property
    def resets(self) -> int:
        """Restarts of the mapping: ``reset()`` calls, silences over ``max_gap_s`` and packets
        that seemed sampled after they arrived (see the class docstring)."""
        return self._sync.resets
