"""Crossbow IMU400CC-100 serial protocol: commands, packets, replies and scaling (no I/O).

Every constant cites shared/reference/imu400cc-aalborg-notes.md ("notes"). Items marked
*[external, unverified]* come from the GAVLab/xbow400 C++ library, not from the Aalborg report
(notes §2.2): the driver must treat their answers as optional and probe them with time-outs.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from enum import Enum
from typing import Final, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

#: Bytes of a scaled-sensor or voltage-mode packet (notes §2.3).
PACKET_LENGTH: Final = 18
#: First byte of every packet and of the serial-number reply (notes §2.3, §2.2).
HEADER: Final = 0xFF
#: Length of the 'S' reply: header, 4-byte big-endian serial number, checksum (notes §2.2).
SERIAL_NUMBER_REPLY_LENGTH: Final = 6

#: Ranges of the packet's int16 (rates, accels) and uint16 (temperature, timer) fields (§2.3).
INT16_MIN: Final = -(2**15)
INT16_MAX: Final = 2**15 - 1
UINT16_MAX: Final = 2**16 - 1

#: Bytes 1..16 of a packet: rates x/y/z and accels x/y/z as int16, temperature and timer as
#: uint16, all big-endian (notes §2.3 field summary).
_BODY: Final = struct.Struct(">6h2H")
_SERIAL_NUMBER: Final = struct.Struct(">I")

Buffer = bytes | bytearray | memoryview


class PacketError(ValueError):
    """Bytes that are not a valid packet or reply (length, header or checksum)."""


class Command(Enum):
    """Single-character commands; the value is the character to send (notes §2.2).

    'P', 'C' and 'G' appear in the Aalborg report (App. D.2, D.4); the others are
    *[external, unverified]* (``unverified`` is True). Reading of the report's contradiction:
    'P' selects polled mode and 'G' requests one packet (notes §2.2, §12 item 4).
    """

    PING = "R"  # [external, unverified] answered with 'H'
    POLLED = "P"  # polled mode; GAVLab/xbow400 stops a stream with 'G' then 'P' [external]
    CONTINUOUS = "C"  # continuous output at 134 Hz (notes §1.1)
    GET_PACKET = "G"  # one 18-byte packet
    SCALED_MODE = "c"  # [external, unverified] scaled-sensor mode, answered with 'C'
    VOLTAGE_MODE = "r"  # [external, unverified] voltage mode, answered with 'R'
    VERSION = "v"  # [external, unverified] version string + checksum, see decode_version_reply
    SERIAL_NUMBER = "S"  # [external, unverified] see decode_serial_number_reply

    @property
    def wire(self) -> bytes:
        """The byte to write to the port."""
        return self.value.encode("ascii")

    @property
    def reply(self) -> bytes | None:
        """The fixed one-byte acknowledgement, or None (no answer, or an answer carrying data)."""
        return _ACKNOWLEDGEMENTS.get(self)

    @property
    def unverified(self) -> bool:
        """True when the command is known only from the external library (notes §2.2)."""
        return self not in _IN_REPORT


_ACKNOWLEDGEMENTS: Final = {
    Command.PING: b"H",
    Command.SCALED_MODE: b"C",
    Command.VOLTAGE_MODE: b"R",
}
_IN_REPORT: Final = frozenset({Command.POLLED, Command.CONTINUOUS, Command.GET_PACKET})


@dataclass(frozen=True, slots=True)
class RawPacket:
    """One decoded packet in device counts and device axes (notes §2.3).

    ``rates`` (roll, pitch, yaw rate = about x, y, z) and ``accels`` (x, y, z) are int16 counts;
    ``temperature`` is the uint16 temperature-voltage count; ``timer`` the uint16 free-running,
    down-counting device timer (notes §2.6). In voltage mode the same fields carry ADC counts.
    """

    rates: tuple[int, int, int]
    accels: tuple[int, int, int]
    temperature: int
    timer: int


def checksum(data: Buffer) -> int:
    """8-bit sum of ``data`` (mod 256); for a packet pass bytes 1..16 (notes §2.5, §12 item 3)."""
    return sum(data) & 0xFF


def encode_packet(packet: RawPacket) -> bytes:
    """The 18 bytes of ``packet``; ValueError when a field is outside its integer range."""
    if len(packet.rates) != 3 or len(packet.accels) != 3:
        raise ValueError(f"RawPacket needs 3 rates and 3 accels, got {packet!r}")
    fields = (
        ("rates", packet.rates, INT16_MIN, INT16_MAX),
        ("accels", packet.accels, INT16_MIN, INT16_MAX),
        ("temperature", (packet.temperature,), 0, UINT16_MAX),
        ("timer", (packet.timer,), 0, UINT16_MAX),
    )
    for name, values, low, high in fields:
        if not all(isinstance(v, int | np.integer) and low <= v <= high for v in values):
            raise ValueError(f"RawPacket.{name}={values!r}: need integers in [{low}, {high}]")
    body = _BODY.pack(*packet.rates, *packet.accels, packet.temperature, packet.timer)
    return bytes((HEADER, *body, checksum(body)))


def unpack_packet(buffer: Buffer, offset: int = 0) -> RawPacket:
    """Fields of the packet at ``buffer[offset:offset + 18]``, NOT validated (see decode_packet).

    For framers that have already checked the header and the checksum.
    """
    r0, r1, r2, a0, a1, a2, temperature, timer = _BODY.unpack_from(buffer, offset + 1)
    return RawPacket((r0, r1, r2), (a0, a1, a2), temperature, timer)


def decode_packet(data: Buffer) -> RawPacket:
    """Validate and decode one 18-byte packet; PacketError on length, header or checksum."""
    if len(data) != PACKET_LENGTH:
        raise PacketError(f"packet must be {PACKET_LENGTH} bytes, got {len(data)}")
    if data[0] != HEADER:
        raise PacketError(f"bad header 0x{data[0]:02X}, expected 0x{HEADER:02X}")
    expected = checksum(data[1:17])
    if data[17] != expected:
        raise PacketError(
            f"bad checksum: expected {expected} (sum of bytes 1..16 mod 256), got {data[17]}"
        )
    return unpack_packet(data)


def encode_serial_number_reply(serial_number: int) -> bytes:
    """The 'S' reply: 0xFF, uint32 big-endian, checksum of the 4 number bytes.

    *[external, unverified]*: layout from GAVLab/xbow400 (notes §2.2).
    """
    if not 0 <= serial_number < 2**32:
        raise ValueError(f"serial number {serial_number} does not fit in 32 bits")
    number = _SERIAL_NUMBER.pack(serial_number)
    return bytes((HEADER, *number, checksum(number)))


def decode_serial_number_reply(data: Buffer) -> int:
    """Serial number from a 6-byte 'S' reply; PacketError when malformed (*[external]*)."""
    if len(data) != SERIAL_NUMBER_REPLY_LENGTH:
        raise PacketError(
            f"serial-number reply must be {SERIAL_NUMBER_REPLY_LENGTH} bytes, got {len(data)}"
        )
    if data[0] != HEADER:
        raise PacketError(f"bad serial-number reply header 0x{data[0]:02X}")
    expected = checksum(data[1:5])
    if data[5] != expected:
        raise PacketError(f"bad serial-number checksum: expected {expected}, got {data[5]}")
    number: int = _SERIAL_NUMBER.unpack_from(data, 1)[0]
    return number


def encode_version_reply(version: str) -> bytes:
    """The 'v' reply as the emulator sends it: printable ASCII text + checksum of the text.

    *[external, unverified]* design: the reply length and terminator are unknown; GAVLab/xbow400
    reads up to 32 bytes and checks the last one against the sum of the text (notes §2.2).
    """
    if not (version and version.isascii() and version.isprintable()):
        raise ValueError(f"version must be non-empty printable ASCII, got {version!r}")
    text = version.encode("ascii")
    return text + bytes((checksum(text),))


def decode_version_reply(data: Buffer) -> str:
    """Version text from a complete 'v' reply; PacketError when malformed (*[external]*).

    A leading 0xFF header is accepted and skipped: GAVLab/xbow400 discards the reply's first
    byte, which suggests the device sends one, as it does for 'S' (notes §2.2).
    """
    body = data[1:] if len(data) > 0 and data[0] == HEADER else data
    text = bytes(body[:-1])
    if not (text and all(0x20 <= b <= 0x7E for b in text)):
        raise PacketError(f"version reply is not printable ASCII + checksum: {bytes(data)!r}")
    if body[-1] != checksum(text):
        raise PacketError(f"bad version checksum: expected {checksum(text)}, got {body[-1]}")
    return text.decode("ascii")


class Quantized(NamedTuple):
    """Counts from an engineering value, and whether each one was clipped to its range."""

    counts: NDArray[np.int64]
    saturated: NDArray[np.bool_]


@dataclass(frozen=True, slots=True)
class _Channel:
    """Linear map ``units = counts * units_per_count + offset``; counts in [min, max]."""

    units_per_count: float
    offset: float
    min_count: int
    max_count: int

    def to_units(self, counts: ArrayLike) -> NDArray[np.float64]:
        return np.asarray(counts, dtype=np.float64) * self.units_per_count + self.offset

    def to_counts(self, units: ArrayLike) -> Quantized:
        exact = np.rint((np.asarray(units, dtype=np.float64) - self.offset) / self.units_per_count)
        if np.isnan(exact).any():
            raise ValueError(f"cannot convert NaN to counts: {units!r}")
        clipped = np.clip(exact, self.min_count, self.max_count)
        return Quantized(clipped.astype(np.int64), clipped != exact)


#: Full-scale factor of (D-2)/(D-3): counts * range * 1.5 / 2^15 (notes §2.4; 2^15, not 2^15 - 1).
_FULL_SCALE_PER_COUNT: Final = 1.5 / 2**15
#: ADC volts per count, 5 V / 4096, from (D-4) (notes §2.4).
ADC_VOLTS_PER_COUNT: Final = 5.0 / 4096
#: Largest 12-bit ADC count; *[derived]* from the 5/4096 V per count of (D-4).
ADC_MAX_COUNT: Final = 4095
#: Temperature sensor: degC = (volts - 1.375) * 44.44, (D-4) (notes §2.4).
TEMPERATURE_OFFSET_V: Final = 1.375
TEMPERATURE_C_PER_V: Final = 44.44
#: Variance of a temperature reading [degC^2]: one count of (D-4), 5/4096 * 44.44 = 0.054 degC
#: (notes §2.4); the formula itself is only as good as the report's calibration of it.
TEMPERATURE_VARIANCE_C2: Final = (ADC_VOLTS_PER_COUNT * TEMPERATURE_C_PER_V) ** 2

#: (D-4) as one linear map: degC = counts * TEMPERATURE_C_PER_COUNT + TEMPERATURE_OFFSET_C.
TEMPERATURE_C_PER_COUNT: Final = ADC_VOLTS_PER_COUNT * TEMPERATURE_C_PER_V
TEMPERATURE_OFFSET_C: Final = -TEMPERATURE_OFFSET_V * TEMPERATURE_C_PER_V

_TEMPERATURE: Final = _Channel(TEMPERATURE_C_PER_COUNT, TEMPERATURE_OFFSET_C, 0, UINT16_MAX)
_VOLTAGE: Final = _Channel(ADC_VOLTS_PER_COUNT, 0.0, 0, ADC_MAX_COUNT)


@dataclass(frozen=True)
class Scaling:
    """Count <-> engineering-unit conversions of scaled-sensor and voltage mode (notes §2.4).

    ``gyro_range_dps`` is RR and ``accel_range_g`` is GR of (D-3)/(D-2); the IMU400CC-100 has
    RR = 100 deg/s and GR = 2 g (notes §1.2). Full scale is 1.5x the range (notes §2.4).
    Forward methods take counts (scalar or array) and return float64 arrays; the ``*_counts``
    inverses (for the emulator) round to the nearest count, clip to the field's range and say
    which values were clipped.
    """

    gyro_range_dps: float = 100.0
    accel_range_g: float = 2.0

    def __post_init__(self) -> None:
        for name in ("gyro_range_dps", "accel_range_g"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"Scaling.{name} must be a finite number > 0, got {value!r}")

    @property
    def dps_per_count(self) -> float:
        """Angular rate of one count [deg/s], (D-3): RR * 1.5 / 2^15."""
        return self.gyro_range_dps * _FULL_SCALE_PER_COUNT

    @property
    def g_per_count(self) -> float:
        """Acceleration of one count [g], (D-2): GR * 1.5 / 2^15."""
        return self.accel_range_g * _FULL_SCALE_PER_COUNT

    @property
    def _rate(self) -> _Channel:
        return _Channel(self.dps_per_count, 0.0, INT16_MIN, INT16_MAX)

    @property
    def _accel(self) -> _Channel:
        return _Channel(self.g_per_count, 0.0, INT16_MIN, INT16_MAX)

    def rate_dps(self, counts: ArrayLike) -> NDArray[np.float64]:
        """Angular rate [deg/s] from int16 counts, (D-3): counts * RR * 1.5 / 2^15."""
        return self._rate.to_units(counts)

    def accel_g(self, counts: ArrayLike) -> NDArray[np.float64]:
        """Acceleration [g] from int16 counts, (D-2): counts * GR * 1.5 / 2^15."""
        return self._accel.to_units(counts)

    def temperature_c(self, counts: ArrayLike) -> NDArray[np.float64]:
        """Temperature [degC] from uint16 counts, (D-4): ((counts * 5/4096) - 1.375) * 44.44."""
        return _TEMPERATURE.to_units(counts)

    def volts(self, counts: ArrayLike) -> NDArray[np.float64]:
        """Voltage-mode channel [V] from ADC counts: counts * 5/4096, *[derived]* from (D-4)."""
        return _VOLTAGE.to_units(counts)

    def rate_counts(self, rate_dps: ArrayLike) -> Quantized:
        """Inverse of rate_dps, clipped to int16."""
        return self._rate.to_counts(rate_dps)

    def accel_counts(self, accel_g: ArrayLike) -> Quantized:
        """Inverse of accel_g, clipped to int16."""
        return self._accel.to_counts(accel_g)

    def temperature_counts(self, temperature_c: ArrayLike) -> Quantized:
        """Inverse of temperature_c, clipped to uint16."""
        return _TEMPERATURE.to_counts(temperature_c)

    def volts_counts(self, volts: ArrayLike) -> Quantized:
        """Inverse of volts, clipped to the 12-bit ADC range 0..4095 (0 V to 5 V - 1 count)."""
        return _VOLTAGE.to_counts(volts)
