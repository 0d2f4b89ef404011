"""Grouping sentences into epochs: everything a receiver sends about one instant (no I/O).

Sentences with a UTC time (GGA, RMC, GLL, GNS, GST, ZDA, LLQ, PASHR PAT and ATT) belong to the
epoch of that time. Sentences without one (VTG, HDT, or any of the former with an empty time)
join the open epoch, or open an untimed one that the next timed sentence dates: the Leica rover
sends VTG *first* (imu400cc-aalborg-notes.md §7.1), other receivers after GGA.

An epoch is closed, and handed on, when
- a sentence with a newer time arrives, or an untimed one of a type the epoch already holds;
- the line has carried no byte at all for ``idle_s`` (``note_traffic`` sees every chunk, so a
  long GSV block keeps the epoch open; ``flush_idle``);
- it holds the *learned* content of its sub-second phase (UTC time modulo 1 s, so a receiver
  with 10 Hz GGA and 1 Hz RMC/ZDA/HDT has one content for .0 and one for .1 to .9): the types
  of the last epoch of that phase closed by the two rules above, once two such epochs in a row
  held the same types. This publishes an epoch as soon as its last sentence is in; a partial
  first epoch (a cut line) is never confirmed.
A sentence for the epoch closed last that it does not hold yet (same UTC time, or an untimed one
within ``idle_s`` of an early close) *extends* it: the epoch is reopened as an extension that
holds the earlier sentences too (``previous``), the consumer publishes only what is new, and the
phase's learned content is unconfirmed so the next epochs wait for that type. Only a sentence
older than the epoch closed last, or than the open one (by up to ``LATE_WINDOW_MS``), is *late*
and dropped. ``stats`` counts
epochs, extensions, late and duplicate sentences.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TypeVar

import pynmea2

from gnss_driver.plausibility import within_limits
from gnss_driver.sentences import (
    ASHRATT,
    ASHRPAT,
    LLQ,
    MS_PER_DAY,
    FieldError,
    number,
    time_of_day_ms,
)
from gnss_driver.utc import gps_time_of_week_to_time_of_day_ms

#: Sentence types that form epochs; all but VTG and HDT carry a UTC time (ATT a GPS week time).
EPOCH_TYPES: tuple[type[pynmea2.NMEASentence], ...] = (
    pynmea2.GGA,
    pynmea2.GNS,
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
    ``previous``: the closed epoch this one extends (its sentences come first here).
    ``published``: set by the consumer: what it made of the epoch (kept for an extension).
    ``gsa``: the GSA sentences that arrived while it was open (GSA carries no time and is not
    one of its sentences; one per constellation, NMEA 0183 4.10).
    """

    time_of_day_ms: int | None
    sentences: list[pynmea2.NMEASentence] = field(default_factory=list)
    arrivals: list[tuple[float, int]] = field(default_factory=list)
    previous: Epoch | None = None
    published: object = None
    gsa: list[pynmea2.GSA] = field(default_factory=list)

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

    def extension(self) -> Epoch:
        """A new open epoch of the same instant that holds this one's sentences."""
        return Epoch(
            self.time_of_day_ms, list(self.sentences), list(self.arrivals), self, gsa=list(self.gsa)
        )


@dataclass(slots=True)
class AssemblerStats:
    """Counters since the assembler was created."""

    epochs: int = 0
    sentences: int = 0
    untimed_epochs: int = 0
    extended_epochs: int = 0
    late_sentences: int = 0
    duplicate_sentences: int = 0


@dataclass(slots=True)
class _Learned:
    """The sentence types of a phase's last naturally closed epoch; ``confirmed`` when the one
    before held the same."""

    types: frozenset[type[pynmea2.NMEASentence]]
    confirmed: bool = False


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


#: A sentence at most this much older than the newest epoch is late [ms]; one further back is
#: a jump of the receiver's time (a reset, a corrupt time) and starts a new epoch.
LATE_WINDOW_MS = 2000


def _older(time_ms: int, than_ms: int) -> bool:
    """Is ``time_ms`` (a time of day) late relative to ``than_ms`` (see ``LATE_WINDOW_MS``)?"""
    return 0 < (than_ms - time_ms) % MS_PER_DAY <= LATE_WINDOW_MS


class EpochAssembler:
    """Feeds sentences in, gets closed epochs out; see the module docstring."""

    def __init__(self, idle_s: float = 0.5) -> None:
        """``idle_s``: a line without any byte for this long ends the open epoch [s]."""
        self.idle_s = idle_s
        self.stats = AssemblerStats()
        self.reset()

    def reset(self) -> None:
        """Drop the open epoch and what was learned (e.g. after the port was reopened)."""
        self._open: Epoch | None = None
        self._learned: dict[int, _Learned] = {}
        self._last_closed: Epoch | None = None
        self._closed_early_at: float | None = None  # arrival of its last sentence then
        self._last_traffic = -math.inf

    def note_traffic(self, arrival_s: float) -> None:
        """Bytes of any kind arrived at host time ``arrival_s`` [s]."""
        self._last_traffic = max(self._last_traffic, arrival_s)

    def attach(self, gsa: pynmea2.GSA) -> None:
        """A GSA sentence: kept with the open epoch (``Epoch.gsa``); none open, not kept."""
        if self._open is not None:
            self._open.gsa.append(gsa)

    def add(
        self,
        sentence: pynmea2.NMEASentence,
        time_ms: int | None,
        wire_bytes: int,
        arrival_s: float,
    ) -> list[Epoch]:
        """Add one sentence whose UTC time of day is ``time_ms`` (None: untimed)."""
        self.note_traffic(arrival_s)
        closed: list[Epoch] = []
        kind = type(sentence)
        epoch = self._open
        last = self._last_closed
        untimed_open = epoch is not None and epoch.time_of_day_ms is None
        if untimed_open and time_ms is not None and last and last.time_of_day_ms == time_ms:
            epoch = self._extend(last, carrying=epoch)  # the untimed sentences were its tail
        if epoch is not None:
            open_ms = epoch.time_of_day_ms
            if time_ms is not None and open_ms is not None and _older(time_ms, open_ms):
                self.stats.late_sentences += 1
                return closed
            if kind in epoch.types() and time_ms is not None and time_ms == open_ms:
                self.stats.duplicate_sentences += 1
                return closed
            if kind in epoch.types() or (None not in (time_ms, open_ms) and time_ms != open_ms):
                closed.append(self._close(natural=True))
                epoch = None
        if epoch is None:
            epoch = self._start(kind, time_ms, arrival_s)
            if epoch is None:
                return closed
        if epoch.time_of_day_ms is None:
            epoch.time_of_day_ms = time_ms
        epoch.add(sentence, wire_bytes, arrival_s)
        self.stats.sentences += 1
        if self._complete(epoch):
            closed.append(self._close(natural=False))
            self._closed_early_at = arrival_s
        return closed

    def flush_idle(self, now_s: float) -> list[Epoch]:
        """Close the open epoch if no byte arrived for ``idle_s`` before ``now_s`` [s]."""
        if self._open is None or now_s - self._last_traffic < self.idle_s:
            return []
        return [self._close(natural=True)]

    def _start(
        self, kind: type[pynmea2.NMEASentence], time_ms: int | None, arrival_s: float
    ) -> Epoch | None:
        """The epoch a sentence opens with none open: new, an extension, or None (late)."""
        last = self._last_closed
        if last is None or kind in last.types():
            if time_ms is not None and last is not None and last.time_of_day_ms is not None:
                if time_ms == last.time_of_day_ms:
                    self.stats.duplicate_sentences += 1
                    return None
                if _older(time_ms, last.time_of_day_ms):
                    self.stats.late_sentences += 1
                    return None
            return self._new(Epoch(time_ms))
        last_ms = last.time_of_day_ms
        if time_ms is None:
            extends = (
                self._closed_early_at is not None
                and arrival_s - self._closed_early_at < self.idle_s
            )
        else:
            extends = time_ms == last_ms
            if last_ms is not None and _older(time_ms, last_ms):
                self.stats.late_sentences += 1
                return None
        return self._extend(last) if extends else self._new(Epoch(time_ms))

    def _extend(self, last: Epoch, carrying: Epoch | None = None) -> Epoch:
        """Open an extension of ``last`` with the sentences of ``carrying`` (an untimed open
        epoch) that ``last`` lacks; unconfirm the learned content of its phase."""
        epoch = last.extension()
        if carrying is not None:
            total = 0
            for sentence, (arrival_s, upto) in zip(
                carrying.sentences, carrying.arrivals, strict=True
            ):
                if type(sentence) in epoch.types():
                    self.stats.duplicate_sentences += 1
                else:
                    epoch.add(sentence, upto - total, arrival_s)
                total = upto
            epoch.gsa.extend(carrying.gsa)
        self.stats.extended_epochs += 1
        last_ms = last.time_of_day_ms
        if last_ms is not None and (learned := self._learned.get(last_ms % 1000)) is not None:
            learned.confirmed = False
        return self._new(epoch)

    def _new(self, epoch: Epoch) -> Epoch:
        self._open = epoch
        return epoch

    def _complete(self, epoch: Epoch) -> bool:
        if epoch.time_of_day_ms is None:
            return False
        learned = self._learned.get(epoch.time_of_day_ms % 1000)
        return learned is not None and learned.confirmed and learned.types <= epoch.types()

    def _close(self, natural: bool) -> Epoch:
        epoch = self._open
        assert epoch is not None
        self._open = None
        self._closed_early_at = None
        if natural and epoch.time_of_day_ms is not None:
            phase = epoch.time_of_day_ms % 1000
            types = frozenset(epoch.types())
            learned = self._learned.get(phase)
            if learned is not None and learned.types == types:
                learned.confirmed = True
            else:
                self._learned[phase] = _Learned(types)
        self._last_closed = epoch
        self.stats.epochs += 1
        if epoch.time_of_day_ms is None:
            self.stats.untimed_epochs += 1
        return epoch
