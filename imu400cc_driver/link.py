"""Putting an IMU400CC into its operating mode over an open serial port (no ROS).

Sequence after every (re)open, from imu400cc-aalborg-notes.md §2.2 and §11.1:
1. 'P' stops a stream the unit may still be sending (polled mode), then the input is flushed.
2. 'c' selects scaled-sensor mode; the unit answers 'C'. The command is [external, unverified],
   so a missing answer is only logged.
3. 'S' asks for the serial number (also [external]; optional, used as hardware id).
4. 'G' must be answered with a valid 18-byte packet within the time-out: this is the check that
   a working IMU400CC is on the port (it is the command the report's own polled logger uses).
5. 'C' starts continuous 134 Hz output when continuous mode is wanted.
On shutdown the stream is stopped with 'P'.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

from imu400cc_driver.framer import PacketFramer
from imu400cc_driver.protocol import (
    PACKET_LENGTH,
    Command,
    PacketError,
    decode_serial_number_reply,
)

#: Serial-number reply length: 0xFF, 4-byte big-endian number, checksum (notes §2.2, external).
_SERIAL_REPLY_LENGTH = 6


class DeviceNotAnsweringError(RuntimeError):
    """The unit on the port did not answer a packet request."""


class BytePort(Protocol):
    """What this module needs of a pyserial ``Serial``."""

    def write(self, data: bytes, /) -> int | None: ...
    def read(self, size: int = 1, /) -> bytes: ...
    def reset_input_buffer(self) -> None: ...


@dataclass(frozen=True)
class DeviceInfo:
    """What the set-up learnt about the unit."""

    scaled_mode_confirmed: bool
    serial_number: int | None


def _read_for(port: BytePort, seconds: float, enough: Callable[[bytes], bool]) -> bytes:
    """Read until ``enough(data)`` or ``seconds`` have passed (each port read times out)."""
    data = b""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline and not enough(data):
        data += port.read(64)
    return data


def configure_device(
    port: BytePort,
    continuous: bool,
    *,
    reply_timeout_s: float = 0.5,
    log: Callable[[str], None] = print,
) -> DeviceInfo:
    """Run the start-up sequence above; raises DeviceNotAnsweringError when 'G' goes unanswered."""
    port.write(Command.POLLED.wire)
    time.sleep(0.05)
    port.reset_input_buffer()

    ack = Command.SCALED_MODE.reply or b"C"
    port.write(Command.SCALED_MODE.wire)
    scaled = ack in _read_for(port, reply_timeout_s, lambda d: ack in d)
    if not scaled:
        log("no answer to 'c' (scaled mode); assuming the unit is already in scaled mode")

    port.write(Command.SERIAL_NUMBER.wire)
    reply = _read_for(port, reply_timeout_s, lambda d: len(d) >= _SERIAL_REPLY_LENGTH)
    serial_number: int | None = None
    try:
        serial_number = decode_serial_number_reply(reply[:_SERIAL_REPLY_LENGTH])
    except PacketError:
        log("no valid answer to 'S' (serial number)")

    framer = PacketFramer()
    port.write(Command.GET_PACKET.wire)
    deadline = time.monotonic() + 2 * reply_timeout_s
    while time.monotonic() < deadline and framer.stats.packets == 0:
        framer.feed(port.read(PACKET_LENGTH))
    if framer.stats.packets == 0:
        raise DeviceNotAnsweringError("the unit did not answer 'G' with a valid packet")
    if continuous:
        port.write(Command.CONTINUOUS.wire)
    return DeviceInfo(scaled_mode_confirmed=scaled, serial_number=serial_number)


def stop_stream(port: BytePort) -> None:
    """Stop continuous output ('P'), as the notes ask for on shutdown (§11.1 item 2)."""
    port.write(Command.POLLED.wire)
