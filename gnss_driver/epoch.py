"""Grouping sentences into epochs: everything a receiver sends about one instant (no I/O).

Sentences with a UTC time (GGA, RMC, GLL, GST, ZDA, LLQ, PASHR PAT and ATT) belong to the
epoch of that time. Sentences without one (VTG, HDT, or any of the former with an empty time)
join the open epoch, or open an untimed one that the next timed sentence dates: the Leica rover
sends VTG *first* (imu400cc-aalborg-notes.md §7.1), other receivers after GGA.

An epoch is closed, and handed on, when
- a sentence with another time arrives, or one of a type the epoch already holds;
- the line has been idle for ``idle_s`` (``flush_idle``);
- it holds every type of the last epoch that was closed by one of the two rules above
  (the *learned* content): this publishes an epoch as soon as its last sentence is in.
A timed sentence for an epoch already closed (or a timeless one of a new type arriving within
``idle_s`` of that close) is *late*: it is dropped and its type is added to the learned content,
so the next epochs wait for it. ``stats`` counts epochs, late and duplicate sentences.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TypeVar

import pynmea2

from gnss_driver.plausibility import within_limits
from gnss_driver.sentences import ASHRATT, ASHRPAT, LLQ, FieldError, number, time_of_day_ms
from gnss_driver.utc import gps_time_of_week_to_time_of_day_ms

#: Sentence types that form epochs; all but VTG and HDT carry a UTC time (ATT a GPS week time).
EPOCH_TYPES: tuple[type[pynmea2.NMEASentence], ...] = (
    pynmea2.GGA,
    pynmea2.RMC,
    pynmea2.GLL,
    pynmea2.GST,
    pynmea2.ZDA,
    LLQ,
    ASHRPAT,
    ASHRATT,
    pynmea2.VTG,
    pynmea2.HDT,
)

S = TypeVar("S", bound=pynmea2.NMEASentence)


@dataclass
class Epoch:
    """Sentences of one instant in arrival order, with when and how many bytes arrived.

    ``time_of_day_ms``: UTC time of day [ms since midnight], None for an untimed epoch.
    ``arrivals``: per sentence, (host receive time [s], bytes of the epoch on the wire up to and
    including that sentence): the receive time minus their transmission time is an upper bound
    of the host time at which the epoch's first byte left the receiver.
    """

    time_of_day_ms: int | None
    sentences: list[pynmea2.NMEASentence] = field(default_factory=list)
    arrivals: list[tuple[float, int]] = field(default_factory=list)

    def add(self, sentence: pynmea2.NMEASentence, wire_bytes: int, arrival_s: float) -> None:
        """Append a sentence."""
        total = (self.arrivals[-1][1] if self.arrivals else 0) + wire_bytes
        self.sentences.append(sentence)
        self.arrivals.append((arrival_s, total))

    def types(self) -> set[type[pynmea2.NMEASentence]]:
        """The sentence classes present."""
        return {type(s) for s in self.sentences}

    def get(self, cls: type[S]) -> S | None:
        """The first sentence of class ``cls``, or None."""
        for sentence in self.sentences:
            if isinstance(sentence, cls):
                return sentence
        return None


@dataclass(slots=True)
class AssemblerStats:
    """Counters since the assembler was created."""

    epochs: int = 0
    untimed_epochs: int = 0
    late_sentences: int = 0
    duplicate_sentences: int = 0


def sentence_time_of_day_ms(sentence: pynmea2.NMEASentence, gps_utc_leap_s: int) -> int | None:
    """UTC time of day [ms] of a sentence, None when it has none (raises FieldError if bad)."""
    if isinstance(sentence, ASHRATT):
        tow = number(sentence, "time_of_week")
        if tow is None:
            return None
        if not within_limits("time_of_week", tow):
            raise FieldError(f"time_of_week={tow}")
        return gps_time_of_week_to_time_of_day_ms(tow, gps_utc_leap_s)
    if isinstance(sentence, pynmea2.VTG | pynmea2.HDT):
        return None
    return time_of_day_ms(sentence)


class EpochAssembler:
    """Feeds sentences in, gets closed epochs out; see the module docstring."""

    def __init__(self, idle_s: float = 0.5) -> None:
        """``idle_s``: a quiet line for this long ends the open epoch [s]."""
        self.idle_s = idle_s
        self.stats = AssemblerStats()
        self.reset()

    def reset(self) -> None:
        """Drop the open epoch and what was learned (e.g. after the port was reopened)."""
        self._open: Epoch | None = None
        self._learned: set[type[pynmea2.NMEASentence]] = set()
        self._last_closed_time: int | None = None
        self._closed_complete_at: float | None = None  # arrival of the last sentence then
        self._last_arrival = 0.0

    def add(
        self,
        sentence: pynmea2.NMEASentence,
        time_ms: int | None,
        wire_bytes: int,
        arrival_s: float,
    ) -> list[Epoch]:
        """Add one sentence whose UTC time of day is ``time_ms`` (None: untimed)."""
        closed: list[Epoch] = []
        kind = type(sentence)
        epoch = self._open
        self._last_arrival = arrival_s
        if epoch is None:
            if self._is_late(kind, time_ms, arrival_s):
                self.stats.late_sentences += 1
                self._learned.add(kind)
                return closed
        elif time_ms is not None and epoch.time_of_day_ms == time_ms:
            if kind in epoch.types():
                self.stats.duplicate_sentences += 1
                return closed
        elif kind in epoch.types() or None not in (time_ms, epoch.time_of_day_ms):
            # A repeated type, or another time (an untimed epoch takes the first time that comes).
            closed.append(self._close(natural=True))
            epoch = None
        if epoch is None:
            epoch = self._open = Epoch(time_ms)
        elif epoch.time_of_day_ms is None:
            epoch.time_of_day_ms = time_ms
        epoch.add(sentence, wire_bytes, arrival_s)
        if epoch.time_of_day_ms is not None and self._learned and self._learned <= epoch.types():
            closed.append(self._close(natural=False))
            self._closed_complete_at = arrival_s
        return closed

    def flush_idle(self, now_s: float) -> list[Epoch]:
        """Close the open epoch if nothing arrived for ``idle_s`` before ``now_s`` [s]."""
        if self._open is None or now_s - self._last_arrival < self.idle_s:
            return []
        return [self._close(natural=True)]

    def _is_late(
        self, kind: type[pynmea2.NMEASentence], time_ms: int | None, arrival_s: float
    ) -> bool:
        """With no epoch open: does the sentence belong to the one closed last?"""
        if time_ms is not None:
            return time_ms == self._last_closed_time
        return (
            kind not in self._learned
            and self._closed_complete_at is not None
            and arrival_s - self._closed_complete_at < self.idle_s
        )

    def _close(self, natural: bool) -> Epoch:
        epoch = self._open
        assert epoch is not None
        self._open = None
        self._closed_complete_at = None
        if natural:
            self._learned = epoch.types()
        self._last_closed_time = epoch.time_of_day_ms
        self.stats.epochs += 1
        if epoch.time_of_day_ms is None:
            self.stats.untimed_epochs += 1
        return epoch
