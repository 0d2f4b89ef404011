"""Receiver profiles and set-up commands (gnss_driver.profiles, gnss_driver.commands)."""

from __future__ import annotations

import pytest

from gnss_driver.commands import Answer, command_error, encode_command, run_setup
from gnss_driver.profiles import (
    PROFILES,
    Adu5Setup,
    Receiver,
    adu5_commands,
    default_setup_commands,
)
from gnss_driver.reader import frame_sentence


def test_adu5_default_commands_in_the_notes_formats():
    assert adu5_commands(Adu5Setup()) == [
        "$PASHS,ELM,15",
        "$PASHS,3DF,V12,+000.000,+003.939,+000.000",
        "$PASHS,3DF,V13,-001.172,+004.010,-000.025",
        "$PASHS,3DF,V14,+001.179,+004.010,-000.025",
        "$PASHS,3DF,OFS,+000.00,+01.14,-01.48",
        "$PASHS,NME,PER,0.2",
        "$PASHS,NME,PAT,A,ON",
    ]
    custom = Adu5Setup(offsets_deg=(-12.5, 0.0, 3.25), period_s=1.0, port="B")
    assert adu5_commands(custom)[4:] == [
        "$PASHS,3DF,OFS,-012.50,+00.00,+03.25",
        "$PASHS,NME,PER,1",
        "$PASHS,NME,PAT,B,ON",
    ]
    assert all(command_error(c) is None for c in adu5_commands(Adu5Setup()))


def test_only_the_adu5_gets_default_commands():
    assert default_setup_commands(Receiver.LEICA, Adu5Setup()) == []
    assert default_setup_commands(Receiver.GENERIC, Adu5Setup()) == []
    assert len(default_setup_commands(Receiver.ADU5, Adu5Setup())) == 7
    assert PROFILES[Receiver.LEICA].baud == 9600
    assert PROFILES[Receiver.ADU5].rate_hz == 5.0


@pytest.mark.parametrize(
    "command",
    ["$PASHS,RST", "$PASHQ,PRT", "$PASHS,NME,PAT,A,ON", "$PMTK220,200", "$PASHS,3DF,V12,-1.0,+2"],
)
def test_accepted_commands(command):
    assert command_error(command) is None
    assert encode_command(command) == command.encode() + b"\r\n"


@pytest.mark.parametrize(
    "command",
    [
        "PASHS,RST",  # no '$'
        "$GPGGA,1,2",  # not proprietary
        "$pashs,rst",  # lower-case address
        "$PASHS,RST\r\n$PASHS,ELM,5",  # a second command smuggled in
        "$PASHS,RST*3D",  # checksum / '*'
        "$PASHS,ELM,1\x00",  # control character
        "$PASHS,ELM,1\x7f",
        "$PASHS,ELM,é",  # not ASCII
        "$PASHS," + "A" * 80,  # too long
        "$PASHS,ELM,$5",
        "",
    ],
)
def test_rejected_commands(command):
    assert command_error(command) is not None
    with pytest.raises(ValueError, match="set-up command"):
        encode_command(command)


class FakeAdu5Port:
    """Answers each written command from a script; interleaves streaming data."""

    def __init__(self, answers: list[bytes]):
        self.answers = list(answers)
        self.written: list[bytes] = []
        self._pending = b""

    def write(self, data: bytes) -> int:
        self.written.append(data)
        noise = frame_sentence("GPGGA,,,,,,0,00,99.99,,,,,,") + b"\x00garbage"
        self._pending += noise + self.answers.pop(0)
        return len(data)

    def read(self, size: int = 1) -> bytes:
        chunk, self._pending = self._pending[:size], self._pending[size:]
        return chunk

    @property
    def in_waiting(self) -> int:
        return len(self._pending)


def test_run_setup_reads_ack_nak_and_silence():
    port = FakeAdu5Port(
        [frame_sentence("PASHR,ACK"), frame_sentence("PASHR,NAK"), b"$PASHR,ACK*3E\r\n"]
    )
    log: list[str] = []
    passed_on: list[bytes] = []
    results = run_setup(
        port,
        ["$PASHS,ELM,15", "$PASHS,ELM,99", "$PASHS,NME,PER,0.2"],
        answer_timeout_s=0.05,
        log=log.append,
        on_data=passed_on.append,
    )
    # Everything read while waiting is passed on: the streamed GGAs too.
    assert b"".join(passed_on).count(frame_sentence("GPGGA,,,,,,0,00,99.99,,,,,,")) == 3
    assert [r.answer for r in results] == [Answer.ACK, Answer.NAK, Answer.NONE]  # bad checksum
    assert port.written[0] == b"$PASHS,ELM,15\r\n"
    assert log == ["$PASHS,ELM,15: ACK", "$PASHS,ELM,99: NAK", "$PASHS,NME,PER,0.2: no answer"]
