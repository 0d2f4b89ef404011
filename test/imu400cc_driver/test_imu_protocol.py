"""IMU400CC protocol core: App. D.5 golden packets, errors, replies, commands, scaling.

Golden data: shared/reference/imu400cc-aalborg-notes.md §2.7 (printed rows and reconstructed hex).
"""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from support.imu_strategies import int16s, raw_packets, uint16s

from imu400cc_driver.protocol import (
    HEADER,
    PACKET_LENGTH,
    SERIAL_NUMBER_REPLY_LENGTH,
    Command,
    PacketError,
    RawPacket,
    Scaling,
    checksum,
    decode_packet,
    decode_serial_number_reply,
    decode_version_reply,
    encode_packet,
    encode_serial_number_reply,
    encode_version_reply,
)

# (hex, printed rates deg/s, printed accels g, printed temperature degC, time, printed checksum)
GOLDEN_ROWS = [
    (
        "FF 00 12 00 0C FF D8 FF FB 00 B6 2B E1 05 EA A2 86 C8",
        (0.082397461, 0.054931641, -0.183105469),
        (-0.000457764, 0.016662598, 1.028411865),
        21.027,
        41606,
        200,
    ),
    (
        "FF 00 05 FF EB 00 2E 00 35 00 6D 2B 17 05 EA 7D C6 33",
        (0.022888184, -0.096130371, 0.210571289),
        (0.004852295, 0.009979248, 1.009918213),
        21.027,
        32198,
        51,
    ),
    (
        "FF FF 6E FF CE 00 20 00 5F FF 5A 2A 97 05 E9 58 FA 13",
        (-0.668334961, -0.228881836, 0.146484375),
        (0.008697510, -0.015197754, 0.998199463),
        20.972,
        22778,
        19,
    ),
    (
        "FF 00 55 00 2A 00 67 FF 89 FF 8A 2A 65 05 EB 34 3F E9",
        (0.389099121, 0.192260742, 0.471496582),
        (-0.010894775, -0.010803223, 0.993621826),
        21.081,
        13375,
        233,
    ),
]
# Row 5 as printed: corrupt in the report (omega_y is no count multiple; checksum 81 fails).
ROW5_RATES = (0.022888184, 0.283456653, -0.137329102)
ROW5_ACCELS = (-0.000091553, -0.004760742, 1.007995605)
ROW5_TEMPERATURE, ROW5_TIME, ROW5_CHECKSUM = 21.027, 3959, 81

PRINTED_9_DECIMALS = 0.5e-9 + 1e-15
PRINTED_3_DECIMALS = 0.5e-3 + 1e-12


@pytest.mark.parametrize(("hex_bytes", "rates", "accels", "temp", "time", "check"), GOLDEN_ROWS)
def test_golden_rows_decode_to_printed_values(hex_bytes, rates, accels, temp, time, check):
    data = bytes.fromhex(hex_bytes)
    packet = decode_packet(data)
    scaling = Scaling()
    assert data[17] == check
    assert packet.timer == time
    np.testing.assert_allclose(
        scaling.rate_dps(packet.rates), rates, rtol=0, atol=PRINTED_9_DECIMALS
    )
    np.testing.assert_allclose(
        scaling.accel_g(packet.accels), accels, rtol=0, atol=PRINTED_9_DECIMALS
    )
    assert scaling.temperature_c(packet.temperature) == pytest.approx(temp, abs=PRINTED_3_DECIMALS)


@pytest.mark.parametrize("row", GOLDEN_ROWS)
def test_golden_rows_encode_to_the_same_bytes(row):
    data = bytes.fromhex(row[0])
    assert encode_packet(decode_packet(data)) == data


def _row5_packet_bytes() -> bytes:
    scaling = Scaling()
    rates = scaling.rate_counts(ROW5_RATES).counts.tolist()
    accels = scaling.accel_counts(ROW5_ACCELS).counts.tolist()
    temperature = int(scaling.temperature_counts(ROW5_TEMPERATURE).counts)
    body = struct.pack(">6h2H", *rates, *accels, temperature, ROW5_TIME)
    return bytes((HEADER, *body, ROW5_CHECKSUM))


def test_row5_omega_y_is_not_a_count_multiple():
    counts = ROW5_RATES[1] / Scaling().rate_dps(1)
    assert abs(counts - round(counts)) > 0.05


def test_row5_is_a_bad_checksum_case():
    data = _row5_packet_bytes()
    with pytest.raises(PacketError, match=r"expected 143 .* got 81"):
        decode_packet(data)


def test_row5_no_nearby_omega_y_reproduces_checksum_81():
    data = bytearray(_row5_packet_bytes())
    omega_y = struct.unpack_from(">h", data, 3)[0]
    for candidate in range(omega_y - 10, omega_y + 11):
        struct.pack_into(">h", data, 3, candidate)
        assert checksum(data[1:17]) != ROW5_CHECKSUM


def test_checksum_is_the_8_bit_sum():
    assert checksum(bytes(16)) == 0
    assert checksum(bytes([0xFF] * 16)) == (16 * 255) % 256
    assert checksum(bytes(range(1, 17))) == 136
    assert checksum(bytearray(b"\x80\x80")) == 0


def test_decode_rejects_wrong_length():
    data = bytes.fromhex(GOLDEN_ROWS[0][0])
    with pytest.raises(PacketError, match="must be 18 bytes, got 17"):
        decode_packet(data[:-1])
    with pytest.raises(PacketError, match="got 19"):
        decode_packet(data + b"\x00")


def test_decode_rejects_bad_header():
    data = b"\xfe" + bytes.fromhex(GOLDEN_ROWS[0][0])[1:]
    with pytest.raises(PacketError, match="bad header 0xFE"):
        decode_packet(data)


def test_decode_rejects_bad_checksum_with_expected_and_got():
    data = bytearray.fromhex(GOLDEN_ROWS[0][0])
    data[17] = 201
    with pytest.raises(PacketError, match=r"expected 200 .* got 201"):
        decode_packet(data)


def test_packet_error_is_a_value_error():
    assert issubclass(PacketError, ValueError)


@given(raw_packets)
def test_encode_decode_round_trip(packet):
    data = encode_packet(packet)
    assert len(data) == PACKET_LENGTH
    assert data[0] == HEADER
    assert decode_packet(data) == packet
    assert decode_packet(memoryview(data)) == packet


@given(st.binary(min_size=16, max_size=16))
def test_any_valid_bytes_decode_and_encode_back(body):
    data = bytes((HEADER, *body, checksum(body)))
    assert encode_packet(decode_packet(data)) == data


@pytest.mark.parametrize(
    "packet",
    [
        RawPacket((2**15, 0, 0), (0, 0, 0), 0, 0),
        RawPacket((0, 0, 0), (0, -(2**15) - 1, 0), 0, 0),
        RawPacket((0, 0, 0), (0, 0, 0), -1, 0),
        RawPacket((0, 0, 0), (0, 0, 0), 0, 2**16),
        RawPacket((0, 0, 0.5), (0, 0, 0), 0, 0),  # type: ignore[arg-type]
        RawPacket((0, 0), (0, 0, 0), 0, 0),  # type: ignore[arg-type]
    ],
)
def test_encode_rejects_out_of_range_fields(packet):
    with pytest.raises(ValueError, match="RawPacket"):
        encode_packet(packet)


@given(st.integers(0, 2**32 - 1))
def test_serial_number_reply_round_trip(number):
    reply = encode_serial_number_reply(number)
    assert len(reply) == SERIAL_NUMBER_REPLY_LENGTH
    assert reply[0] == HEADER
    assert reply[1:5] == number.to_bytes(4, "big")
    assert decode_serial_number_reply(reply) == number


def test_serial_number_reply_errors():
    reply = encode_serial_number_reply(0x01020304)
    assert reply == bytes([0xFF, 1, 2, 3, 4, 10])
    with pytest.raises(PacketError, match="6 bytes"):
        decode_serial_number_reply(reply[:5])
    with pytest.raises(PacketError, match="header"):
        decode_serial_number_reply(b"\x00" + reply[1:])
    with pytest.raises(PacketError, match="expected 10, got 11"):
        decode_serial_number_reply(reply[:5] + b"\x0b")
    for bad in (-1, 2**32):
        with pytest.raises(ValueError, match="32 bits"):
            encode_serial_number_reply(bad)


@given(st.text(st.characters(min_codepoint=0x20, max_codepoint=0x7E), min_size=1, max_size=40))
def test_version_reply_round_trip(version):
    reply = encode_version_reply(version)
    assert reply[:-1] == version.encode("ascii")
    assert reply[-1] == sum(reply[:-1]) % 256
    assert decode_version_reply(reply) == version
    assert decode_version_reply(b"\xff" + reply) == version


def test_version_reply_errors():
    reply = encode_version_reply("DMU v1")
    with pytest.raises(PacketError, match="bad version checksum"):
        decode_version_reply(reply[:-1] + bytes([(reply[-1] + 1) % 256]))
    for bad_reply in (b"", b"\xff", b"A", b"\x01\x02\x03"):
        with pytest.raises(PacketError, match="printable ASCII"):
            decode_version_reply(bad_reply)
    for bad_version in ("", "tab\there", "café"):
        with pytest.raises(ValueError, match="printable ASCII"):
            encode_version_reply(bad_version)


def test_command_table():
    assert {c.value for c in Command} == set("RPCGcrvS")
    assert all(c.wire == c.value.encode() and len(c.wire) == 1 for c in Command)
    assert Command.POLLED.wire == b"P"
    assert Command.CONTINUOUS.wire == b"C"
    assert Command.GET_PACKET.wire == b"G"
    assert {c.value for c in Command if c.unverified} == set("RcrvS")
    replies = {c.value: c.reply for c in Command if c.reply is not None}
    assert replies == {"R": b"H", "c": b"C", "r": b"R"}
    assert Command("G") is Command.GET_PACKET


def test_resolution_per_count_matches_the_notes():
    scaling = Scaling()
    assert scaling.rate_dps(1) == pytest.approx(0.0045776, abs=5e-8)
    assert scaling.accel_g(1) * 1000 == pytest.approx(0.091553, abs=5e-7)
    assert scaling.temperature_c(1) - scaling.temperature_c(0) == pytest.approx(0.05425, abs=5e-6)
    assert scaling.rate_dps(-(2**15)) == -150.0
    assert scaling.accel_g(-(2**15)) == -3.0


def test_scaling_is_linear_in_the_ranges():
    assert Scaling(gyro_range_dps=300.0).rate_dps(1000) == 3 * Scaling().rate_dps(1000)
    assert Scaling(accel_range_g=10.0).accel_g(1000) == 5 * Scaling().accel_g(1000)


def test_scaling_vectorised():
    counts = np.array([[0, 1, -1], [100, 200, 300]])
    out = Scaling().rate_dps(counts)
    assert out.shape == (2, 3)
    assert out.dtype == np.float64


@pytest.mark.parametrize("bad", [0.0, -1.0, math.nan, math.inf])
@pytest.mark.parametrize("field", ["gyro_range_dps", "accel_range_g"])
def test_scaling_rejects_bad_ranges(field, bad):
    with pytest.raises(ValueError, match=field):
        Scaling(**{field: bad})


def test_voltage_and_temperature_agree_with_d4():
    counts = np.arange(0, 4096, 7)
    scaling = Scaling()
    np.testing.assert_allclose(
        scaling.temperature_c(counts), (scaling.volts(counts) - 1.375) * 44.44, atol=1e-12
    )
    assert scaling.volts(4096) == 5.0


@given(st.lists(int16s, min_size=1, max_size=8))
def test_rate_and_accel_inverses_round_trip(counts):
    scaling = Scaling(gyro_range_dps=100.0, accel_range_g=2.0)
    for forward, inverse in (
        (scaling.rate_dps, scaling.rate_counts),
        (scaling.accel_g, scaling.accel_counts),
    ):
        back = inverse(forward(counts))
        assert back.counts.tolist() == counts
        assert not back.saturated.any()


@given(uint16s)
def test_temperature_inverse_round_trip(count):
    back = Scaling().temperature_counts(Scaling().temperature_c(count))
    assert int(back.counts) == count
    assert not back.saturated


@given(st.integers(0, 4095))
def test_volts_inverse_round_trip(count):
    back = Scaling().volts_counts(Scaling().volts(count))
    assert int(back.counts) == count
    assert not back.saturated


def test_inverses_round_to_nearest_count():
    scaling = Scaling()
    step = scaling.rate_dps(1)
    assert scaling.rate_counts([1.4 * step, 1.6 * step, -1.6 * step]).counts.tolist() == [1, 2, -2]


def test_inverses_saturate_and_say_so():
    scaling = Scaling()
    rate = scaling.rate_counts([1e6, -1e6, 0.0, math.inf])
    assert rate.counts.tolist() == [32767, -32768, 0, 32767]
    assert rate.saturated.tolist() == [True, True, False, True]
    accel = scaling.accel_counts(3.0)  # +3 g is one count past the int16 range
    assert int(accel.counts) == 32767
    assert bool(accel.saturated)
    cold = scaling.temperature_counts(-100.0)
    assert (int(cold.counts), bool(cold.saturated)) == (0, True)
    high = scaling.volts_counts(6.0)
    assert (int(high.counts), bool(high.saturated)) == (4095, True)


def test_inverses_reject_nan():
    with pytest.raises(ValueError, match="NaN"):
        Scaling().rate_counts([0.0, math.nan])
