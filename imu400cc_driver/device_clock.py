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
from imu400cc_driver.protocol import PACKET_LENGTH

#: The time field is a uint16 (notes §2.3).
TIMER_MODULUS = 1 << 16
#: Continuous-mode packet rate [Hz] (notes §2.6, §10).
NOMINAL_RATE_HZ = 134.0
#: Mean timer decrement per packet, our derivation from the App. D.5 example rows read as
#: consecutive packets (the report states no tick period or direction; notes §2.6).
COUNTS_PER_PACKET = 9411.75
#: Nominal tick, (1/134 s) / 9411.75 ≈ 0.793 us [s] (notes §2.6); the true one is estimated online.
NOMINAL_TICK_S = 1.0 / NOMINAL_RATE_HZ / COUNTS_PER_PACKET
#: Wire time of one packet at 38400 baud 8N1, 18 bytes x 10 bits = 4.6875 ms [s] (notes §2.1,
#: §7.1; the report's 3.75 ms forgets the start and stop bits).
PACKET_TRANSMISSION_S = PACKET_LENGTH * 10 / 38400
#: Below this implied receive delay a whole-wrap candidate is rejected as "sampled after it
#: arrived" [ticks]: an eighth of a wrap (~6.5 ms) absorbs errors of the mapping and of the tick
#: over a gap, and leaves delays up to ~45 ms resolvable.
_UNWRAP_MARGIN_TICKS = TIMER_MODULUS // 8
#: A tick estimate further than this from nominal is not trusted for unwrapping.
_MAX_TICK_ERROR = 0.1


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
    packets. Receive delays over ~45 ms of that packet (of every packet, with ``stamp``) make
    the gap a wrap too long; the next packet then seems early, and the mapping restarts.
    """

    def __init__(
        self,
        nominal_tick_s: float = NOMINAL_TICK_S,
        nominal_period_s: float | None = 1.0 / NOMINAL_RATE_HZ,
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
        self._sync = EnvelopeClockSync(window_s, min_points, max_jump_s=max_gap_s)
        self._dropped = 0
        self._timer_gaps = 0
        self._clear()

    def _clear(self) -> None:
        self._timer: int | None = None
        self._ticks = 0  # unwrapped ticks since the first packet
        self._last_stamp_s = -math.inf
        # Drops counted for host-pinned whole wraps, still open to be taken back until device
        # time passes _wrap_drops_until [ticks].
        self._wrap_drops = 0
        self._wrap_drops_until = 0

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
        if self._timer is None:
            steps = [0, *gaps]
        else:
            steps = [self._first_gap(self._timer, timers[0], sum(gaps), last_host_s), *gaps]
        self._timer = timers[-1]

        device_times = []
        for ticks in steps:
            self._ticks += ticks
            device_times.append(self._ticks * self.nominal_tick_s)
            self._sync.update(device_times[-1], last_host_s)

        stamps = []
        for index, (ticks, device_time_s) in enumerate(zip(steps, device_times, strict=True)):
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
            if index == 0 and wrapped:  # the gap before the read: whole wraps pinned by the
                # host clock, taken back if a packet within the next wrap contradicts them
                self._wrap_drops += dropped - self._drops_of(ticks % TIMER_MODULUS)
                self._wrap_drops_until = round(device_time_s / self.nominal_tick_s) + TIMER_MODULUS
            stamps.append(DeviceStamp(stamp_s, device_time_s, dropped, wrapped))
        return stamps

    def _drops_of(self, ticks: int) -> int:
        """Packets missing in a gap of ``ticks`` between two packets (0 in polled mode)."""
        if not ticks or self.nominal_period_s is None:
            return 0
        return max(round(ticks * self.nominal_tick_s / self.nominal_period_s) - 1, 0)

    def _first_gap(self, previous: int, timer: int, later_ticks: int, last_host_s: float) -> int:
        """Ticks from the packet with timer ``previous`` to the one with ``timer``, given the
        ``later_ticks`` from that to the read's last packet, received at ``last_host_s``
        (corrected) [s]."""
        delta = (previous - timer) % TIMER_MODULUS
        if self._ticks > self._wrap_drops_until:
            self._wrap_drops = 0
        previous_s = self._sync.to_host(self._ticks * self.nominal_tick_s)
        host_gap_ticks = (last_host_s - previous_s) / self._unwrap_tick_s()
        margin = _UNWRAP_MARGIN_TICKS
        wraps = math.floor((host_gap_ticks + margin - delta - later_ticks) / TIMER_MODULUS)
        if wraps < 0 and self._sync.ready:
            # Sampled over the margin after it arrived: the previous gap took a wrap too many
            # (a read over ~45 ms late, e.g. a loaded machine), or the host clock stepped back.
            # Restart the mapping rather than bend it for a whole window, and take back the
            # drops that gap's wraps counted: they were a late read, not lost packets.
            self._sync.reset()
        if wraps < 0:
            self._dropped -= self._wrap_drops
            self._wrap_drops = 0
        return delta + max(wraps, 0 if delta else 1) * TIMER_MODULUS

    def _unwrap_tick_s(self) -> float:
        """The estimated tick once the mapping is ready and plausible, else the nominal one [s]."""
        if self._sync.ready and abs(self._sync.skew) < _MAX_TICK_ERROR:
            return self.tick_period_s
        return self.nominal_tick_s

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
    def resets(self) -> int:
        """Restarts of the mapping: ``reset()`` calls, silences over ``max_gap_s`` and packets
        that seemed sampled after they arrived (see the class docstring)."""
        return self._sync.resets
