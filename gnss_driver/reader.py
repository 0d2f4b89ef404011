"""Byte stream -> NMEA sentences, over arbitrary chunk boundaries (no I/O).

Modelled on pynmeagps' ``NMEAReader``: a sentence starts at ``$`` and ends at CR or LF; every
problem is counted per kind and the reader resynchronises on the next ``$``. ``feed`` never
raises and always consumes its input: between calls it keeps at most one partial sentence of at
most ``max_line_bytes`` bytes.

Kinds of rejected input (``ReaderStats``):

- ``garbage``: a run of bytes between sentences that is not whitespace, or a line holding a
  byte outside printable ASCII (0x20..0x7E);
- ``truncated``: a sentence cut off by the ``$`` of the next one (garbage if it holds
  non-printable bytes);
- ``overlong``: more than ``max_line_bytes`` without a line end;
- ``bad_checksum``: ``*hh`` present and wrong, or not two hex digits;
- ``missing_checksum``: no ``*hh`` (the sentence is still accepted when allowed);
- ``unknown_sentence``: a sentence type no pynmea2 class is registered for;
- ``malformed``: a registered type whose text pynmea2 could not build.

``feed``'s ``lines`` output also hands back every line as received, accepted or not: each run
from a ``$`` to its end (CR, LF, or the ``$`` of the next sentence), without the line end; only
an overlong line is left out (counted as such).
"""

from __future__ import annotations

import functools
import operator
import re
from collections import Counter
from dataclasses import dataclass, field

import pynmea2
from pynmea2.types.proprietary import ash

from gnss_driver.sentences import parse, sentence_id

#: Longest accepted line, '$' to the last checksum digit [bytes]. NMEA 0183 allows 82 characters
#: including CR LF; Ashtech's PAT and Leica's LLQ run longer, so twice that.
MAX_LINE_BYTES = 164

_LINE_END = re.compile(rb"[\r\n$]")
_NOT_PRINTABLE = re.compile(rb"[^\x20-\x7e]")
_HEX2 = re.compile(r"[0-9A-Fa-f]{2}")
_WHITESPACE = b" \t\r\n"
_DOLLAR = 0x24
#: Classes pynmea2 falls back to for types nothing is registered for.
_GENERIC_CLASSES = (pynmea2.ProprietarySentence, ash.ASH, pynmea2.QuerySentence)


@dataclass(slots=True)
class ReaderStats:
    """Counters since the reader was created (see the module docstring for the kinds)."""

    bytes_in: int = 0
    sentences: int = 0
    garbage: int = 0
    truncated: int = 0
    overlong: int = 0
    bad_checksum: int = 0
    missing_checksum: int = 0
    unknown_sentence: int = 0
    malformed: int = 0
    by_type: Counter[str] = field(default_factory=Counter)

    def rejected(self) -> dict[str, int]:
        """The problem counters by kind."""
        return {
            "garbage": self.garbage,
            "truncated": self.truncated,
            "overlong": self.overlong,
            "bad_checksum": self.bad_checksum,
            "missing_checksum": self.missing_checksum,
            "unknown_sentence": self.unknown_sentence,
            "malformed": self.malformed,
        }


@dataclass(frozen=True, slots=True)
class ReadSentence:
    """One accepted sentence and its length on the wire (with CR LF) [bytes]."""

    sentence: pynmea2.NMEASentence
    wire_bytes: int


def nmea_checksum(body: bytes) -> int:
    """XOR of the bytes between ``$`` and ``*``."""
    return functools.reduce(operator.xor, body, 0)


def frame_sentence(body: str) -> bytes:
    """``$body*hh`` CR LF: a sentence as a receiver sends it (``body`` without ``$``)."""
    raw = body.encode("ascii")
    return b"$%s*%02X\r\n" % (raw, nmea_checksum(raw))


class NmeaReader:
    """Incremental NMEA framer and parser; ``feed`` bytes, get the accepted sentences back."""

    def __init__(
        self, allow_missing_checksum: bool = False, max_line_bytes: int = MAX_LINE_BYTES
    ) -> None:
        """``allow_missing_checksum`` accepts sentences without ``*hh`` (still counted)."""
        self.allow_missing_checksum = allow_missing_checksum
        self.max_line_bytes = max_line_bytes
        self.stats = ReaderStats()
        self._buffer = bytearray()
        self._discarding = False  # inside an overlong line: drop bytes until the next '$'
        self._in_junk = False  # inside a counted garbage run

    @property
    def buffered(self) -> int:
        """Bytes of a partial sentence held until its line end arrives (<= max_line_bytes)."""
        return len(self._buffer)

    def reset(self) -> None:
        """Forget a partial sentence (e.g. after the port was reopened); counters are kept."""
        self._buffer.clear()
        self._discarding = False
        self._in_junk = False

    def feed(self, chunk: bytes, lines: list[bytes] | None = None) -> list[ReadSentence]:
        """Add ``chunk`` to the stream; return the sentences it completed, in stream order.
        ``lines``, when given, gets every line the chunk completed (module docstring)."""
        stats = self.stats
        stats.bytes_in += len(chunk)
        buf = self._buffer
        buf += chunk
        end = len(buf)
        pos = 0
        out: list[ReadSentence] = []
        while pos < end:
            if buf[pos] != _DOLLAR:
                found = buf.find(b"$", pos)
                stop = end if found < 0 else found
                if not self._discarding and buf[pos:stop].strip(_WHITESPACE):
                    if not self._in_junk:
                        stats.garbage += 1
                    self._in_junk = True
                pos = stop
                continue
            self._discarding = self._in_junk = False
            match = _LINE_END.search(buf, pos + 1)
            if match is None:
                if end - pos > self.max_line_bytes:
                    stats.overlong += 1
                    self._discarding = True
                    pos = end
                break
            line_end = match.start()
            if lines is not None and line_end - pos <= self.max_line_bytes:
                lines.append(bytes(buf[pos:line_end]))
            if buf[line_end] == _DOLLAR:
                if _NOT_PRINTABLE.search(buf, pos, line_end):
                    stats.garbage += 1
                else:
                    stats.truncated += 1
            elif line_end - pos > self.max_line_bytes:
                stats.overlong += 1
            else:
                sentence = self._parse_line(bytes(buf[pos:line_end]))
                if sentence is not None:
                    out.append(ReadSentence(sentence, line_end - pos + 2))
            pos = line_end
        del buf[:pos]
        return out

    def _parse_line(self, line: bytes) -> pynmea2.NMEASentence | None:
        stats = self.stats
        if _NOT_PRINTABLE.search(line):
            stats.garbage += 1
            return None
        star = line.rfind(b"*")
        if star < 0:
            stats.missing_checksum += 1
            if not self.allow_missing_checksum:
                return None
            body = line[1:]
        else:
            body, given = line[1:star], line[star + 1 :].decode("ascii")
            if not _HEX2.fullmatch(given) or int(given, 16) != nmea_checksum(body):
                stats.bad_checksum += 1
                return None
        try:
            sentence = parse("$" + body.decode("ascii"))
        except pynmea2.SentenceTypeError:
            stats.unknown_sentence += 1
            return None
        except Exception:  # pynmea2 raises ParseError, IndexError, ValueError, ... on bad text
            stats.malformed += 1
            return None
        if type(sentence) in _GENERIC_CLASSES:
            stats.unknown_sentence += 1
            return None
        stats.sentences += 1
        stats.by_type[sentence_id(sentence)] += 1
        return sentence
