"""Receiver set-up commands: checking, sending and reading the ACK / NAK answers (no ROS).

Only proprietary NMEA-style commands are sent: ``$P`` + an upper-case manufacturer/verb
(``$PASHS`` sets, ``$PASHQ`` queries on the ADU5), then comma-separated printable ASCII fields,
at most 80 characters, no ``$``, ``*`` or control characters, so a parameter can never inject
a second command or binary data. Each command is terminated with CR LF (notes §7.3). The ADU5
answers ``$PASHR,ACK*3D`` or ``$PASHR,NAK*30``; other receivers may not answer at all, which is
reported, not treated as an error. Whatever the receiver streams while the set-up waits for an
answer is passed on (``run_setup``'s ``on_data``), so the set-up costs no data.
"""

from __future__ import annotations

import re
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from enum import StrEnum
from typing import Protocol

from gnss_driver.reader import NmeaReader
from gnss_driver.sentences import ASHRACK, ASHRNAK

#: Longest command accepted, ``$`` to the last character before CR LF (NMEA: 82 with CR LF).
MAX_COMMAND_CHARS = 80
_COMMAND = re.compile(r"\$P[A-Z]{3}[A-Z0-9]*(,[\x20-\x23\x25-\x29\x2B\x2D-\x7E]*)*")


class Answer(StrEnum):
    """The receiver's reaction to one command."""

    ACK = "ACK"
    NAK = "NAK"
    NONE = "no answer"


@dataclass(frozen=True, slots=True)
class CommandResult:
    """One command and what the receiver said."""

    command: str
    answer: Answer


class BytePort(Protocol):
    """What this module needs of a pyserial ``Serial`` (its reads time out by themselves)."""

    def write(self, data: bytes, /) -> int | None: ...
    def read(self, size: int = 1, /) -> bytes: ...
    @property
    def in_waiting(self) -> int: ...


def command_error(command: str) -> str | None:
    """Why ``command`` may not be sent, or None when it is fine."""
    if len(command) > MAX_COMMAND_CHARS:
        return f"longer than {MAX_COMMAND_CHARS} characters"
    if not _COMMAND.fullmatch(command):
        return "not a $P<maker>,<fields> command of printable ASCII without '$', '*' or controls"
    return None


def encode_command(command: str) -> bytes:
    """The bytes to send: the checked command and CR LF (ValueError when it fails the check)."""
    problem = command_error(command)
    if problem is not None:
        raise ValueError(f"set-up command {command!r}: {problem}")
    return command.encode("ascii") + b"\r\n"


def run_setup(
    port: BytePort,
    commands: Sequence[str],
    *,
    answer_timeout_s: float = 0.5,
    log: Callable[[str], None] = print,
    on_data: Callable[[bytes], None] | None = None,
    on_sent: Callable[[str], None] | None = None,
) -> list[CommandResult]:
    """Send each command and wait up to ``answer_timeout_s`` for its ACK / NAK; ``on_sent``
    is called with each command once it is written.

    The receiver may already be streaming: every byte read meanwhile is also handed to
    ``on_data`` as soon as it is read, so no epoch is lost to the set-up.
    """
    results = []
    for command in commands:
        port.write(encode_command(command))
        if on_sent is not None:
            on_sent(command)
        answer = _wait_for_answer(port, answer_timeout_s, on_data)
        results.append(CommandResult(command, answer))
        log(f"{command}: {answer.value}")
    return results


def _wait_for_answer(
    port: BytePort, timeout_s: float, on_data: Callable[[bytes], None] | None
) -> Answer:
    reader = NmeaReader()
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        chunk = port.read(max(1, port.in_waiting))  # what is there, or wait for one byte
        if chunk and on_data is not None:
            on_data(chunk)
        for read in reader.feed(chunk):
            if isinstance(read.sentence, ASHRACK):
                return Answer.ACK
            if isinstance(read.sentence, ASHRNAK):
                return Answer.NAK
    return Answer.NONE
