"""The GNSS driver without ROS: serial bytes in, stamped epoch results out.

``GnssDriver.feed(chunk, receive_time_s)`` runs the reader, groups the sentences into epochs,
solves each closed epoch and stamps it on the host clock:

- each sentence of an epoch gives an upper bound of the host time at which the epoch's first
  byte left the receiver: its receive time minus the transmission time of the epoch's bytes up
  to and including it (10 bits per character at ``baud``; notes §7.1 (7.2) with start and stop
  bits); the smallest bound is paired with the epoch's UTC time;
- ``EnvelopeClockSync`` (gnss_ins_common.clock_sync) maps UTC to host time by the lower
  envelope of those pairs (ARCHITECTURE.md, "The shared clock");
- the stamp is the mapped UTC minus ``latency_s``, the receiver's fixed delay from the epoch
  to its first output byte (0 unless known, e.g. from a PPS test);
- with ``use_gnss_time`` (a host clock disciplined to UTC by NTP/PTP/PPS) the stamp is the UTC
  instant itself and the mapping only measures host - UTC (``clock_offset_s``: the receiver's
  output delay plus the host clock's error).
An epoch without any UTC time (a receiver without fix may leave the time empty) yields only its
fix, NO_FIX as a rule, stamped with its host bound minus ``latency_s``; its velocity or attitude
could not be placed in time and is dropped.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import pynmea2

from gnss_driver.attitude import AttitudeConfig, AttitudeConverter
from gnss_driver.epoch import EPOCH_TYPES, Epoch, EpochAssembler, sentence_time_of_day_ms
from gnss_driver.reader import NmeaReader
from gnss_driver.sentences import ASHRACK, ASHRATT, ASHRNAK, FieldError
from gnss_driver.solution import (
    EpochSolver,
    GnssAttitude,
    GnssFix,
    GnssVelocity,
    SolutionConfig,
)
from gnss_driver.utc import UtcResolver, UtcTime
from gnss_ins_common.clock_sync import EnvelopeClockSync

#: Bits on the wire per character: start bit, 8 data bits, stop bit (8N1).
BITS_PER_CHARACTER = 10
#: GPS - UTC [s] since 2017-01-01 [external: IERS Bulletin C].
GPS_UTC_LEAP_S = 18


@dataclass(frozen=True)
class DriverConfig:
    """Everything the driver core needs to know about the receiver and its link."""

    baud: int = 9600
    allow_missing_checksum: bool = False
    latency_s: float = 0.0
    use_gnss_time: bool = False
    epoch_idle_s: float = 0.5
    gps_utc_leap_s: int = GPS_UTC_LEAP_S
    solution: SolutionConfig = field(default_factory=SolutionConfig)
    attitude: AttitudeConfig = field(default_factory=AttitudeConfig)


@dataclass(frozen=True, slots=True)
class EpochOutput:
    """One epoch's results, stamped: ``stamp_s`` is the time [s] of its UTC instant on the host
    clock: the UTC mapped by the envelope (``host_s``), or with ``use_gnss_time`` the UTC itself.

    ``extends``: the parts of an epoch published before that only a later sentence gave.
    """

    stamp_s: float
    host_s: float
    utc: UtcTime | None
    fix: GnssFix | None
    velocity: GnssVelocity | None
    attitude: GnssAttitude | None
    extends: bool = False


@dataclass(slots=True)
class DriverStats:
    """Counters of the driver core itself (the parts have their own ``stats``)."""

    epochs: int = 0
    #: Extensions of published epochs that had something new (velocity, attitude, a fix).
    extensions: int = 0
    acks: int = 0
    naks: int = 0
    #: Exceptions caught inside the core (a bug: every input should be handled), and the last.
    internal_errors: int = 0
    last_internal_error: str = ""


class GnssDriver:
    """Reader + epoch assembler + solver + clock; see the module docstring."""

    def __init__(self, config: DriverConfig, clock: EnvelopeClockSync | None = None) -> None:
        """``clock`` defaults to an ``EnvelopeClockSync`` with its default window."""
        self.config = config
        self.reader = NmeaReader(config.allow_missing_checksum)
        self.assembler = EpochAssembler(config.epoch_idle_s)
        self.solver = EpochSolver(config.solution, AttitudeConverter(config.attitude))
        self.utc = UtcResolver()
        self.clock = clock or EnvelopeClockSync()
        self.stats = DriverStats()
        self._seconds_per_byte = BITS_PER_CHARACTER / config.baud
        self._last_utc_s: float | None = None

    def reset(self) -> None:
        """Start afresh after the port was reopened (counters are kept)."""
        self.reader.reset()
        self.assembler.reset()
        self.utc.reset()
        self.clock.reset()

    def feed(
        self, chunk: bytes, receive_time_s: float, lines: list[bytes] | None = None
    ) -> list[EpochOutput]:
        """Bytes received at host time ``receive_time_s`` [s] -> results of the closed epochs;
        ``lines`` gets every line read, accepted or not (``NmeaReader.feed``).

        Never raises: an exception from one sentence is counted (``internal_errors``) and the
        rest of the chunk is still read.
        """
        outputs: list[EpochOutput] = []
        self.assembler.note_traffic(receive_time_s)
        for read in self.reader.feed(chunk, lines):
            try:
                self._take(read.sentence, read.wire_bytes, receive_time_s, outputs)
            except Exception as exc:  # a bug must cost one sentence, never the stream
                self._note_internal_error(exc)
        return outputs

    def flush_idle(self, now_s: float) -> list[EpochOutput]:
        """Results of an epoch closed because the line was idle up to ``now_s`` [s]."""
        outputs: list[EpochOutput] = []
        for epoch in self.assembler.flush_idle(now_s):
            self._finish_into(epoch, outputs)
        return outputs

    def _take(
        self,
        sentence: pynmea2.NMEASentence,
        wire_bytes: int,
        receive_time_s: float,
        outputs: list[EpochOutput],
    ) -> None:
        if isinstance(sentence, pynmea2.GSA):
            self.solver.note_gsa(sentence)
            self.assembler.attach(sentence)
        elif isinstance(sentence, ASHRACK):
            self.stats.acks += 1
        elif isinstance(sentence, ASHRNAK):
            self.stats.naks += 1
        elif isinstance(sentence, EPOCH_TYPES):
            try:
                time_ms = sentence_time_of_day_ms(sentence, self.config.gps_utc_leap_s)
            except FieldError:
                time_field = "time_of_week" if isinstance(sentence, ASHRATT) else "timestamp"
                self.solver.fields.reject(sentence, time_field)
                return
            for epoch in self.assembler.add(sentence, time_ms, wire_bytes, receive_time_s):
                self._finish_into(epoch, outputs)

    def _finish_into(self, epoch: Epoch, outputs: list[EpochOutput]) -> None:
        try:
            out = self._finish(epoch)
        except Exception as exc:  # a bug must cost one epoch, never the stream
            self._note_internal_error(exc)
            return
        if out is not None:
            outputs.append(out)

    def _note_internal_error(self, exc: Exception) -> None:
        self.stats.internal_errors += 1
        self.stats.last_internal_error = repr(exc)[:200]

    def _finish(self, epoch: Epoch) -> EpochOutput | None:
        solution = self.solver.solve(epoch)
        before = epoch.previous.published if epoch.previous is not None else None
        if isinstance(before, EpochOutput):
            # An extension: publish only what the first close could not, at the same stamp.
            self.stats.extensions += 1
            new = EpochOutput(
                before.stamp_s,
                before.host_s,
                before.utc,
                None if before.fix else solution.fix,
                None if before.velocity else solution.velocity,
                None if before.attitude else solution.attitude,
                extends=True,
            )
            epoch.published = EpochOutput(
                before.stamp_s,
                before.host_s,
                before.utc,
                before.fix or new.fix,
                before.velocity or new.velocity,
                before.attitude or new.attitude,
            )
            return new if new.fix or new.velocity or new.attitude else None
        self.stats.epochs += 1
        first_byte_s = min(
            arrival - total * self._seconds_per_byte for arrival, total in epoch.arrivals
        )
        if epoch.time_of_day_ms is None:
            host_s = first_byte_s - self.config.latency_s
            out = EpochOutput(host_s, host_s, None, solution.fix, None, None)
        else:
            utc = self.utc.resolve(epoch.time_of_day_ms, solution.date, first_byte_s)
            self.clock.update(utc.utc_s, first_byte_s)
            self._last_utc_s = utc.utc_s
            host_s = self.clock.to_host(utc.utc_s) - self.config.latency_s
            out = EpochOutput(
                utc.utc_s if self.config.use_gnss_time else host_s,
                host_s,
                utc,
                solution.fix,
                solution.velocity,
                solution.attitude,
            )
        epoch.published = out
        return out

    def clock_offset_s(self) -> float:
        """Host minus UTC at the latest epoch on the current mapping [s] (the receiver's output
        delay plus the host clock's error); NaN before the first epoch."""
        if self._last_utc_s is None or self.clock.points == 0:
            return math.nan
        return self.clock.to_host(self._last_utc_s) - self._last_utc_s
