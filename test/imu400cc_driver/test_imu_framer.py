"""PacketFramer: golden stream, exact counters, property tests over arbitrary bytes and chunking."""

from __future__ import annotations

import dataclasses
import itertools
import random

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from support.framer_damage import KINDS, realistic_packets, run_damaged
from support.imu_strategies import raw_packets

from imu400cc_driver.framer import FramerStats, PacketFramer
from imu400cc_driver.protocol import PACKET_LENGTH, RawPacket, decode_packet, encode_packet

GOLDEN = [
    bytes.fromhex(h)
    for h in (
        "FF 00 12 00 0C FF D8 FF FB 00 B6 2B E1 05 EA A2 86 C8",
        "FF 00 05 FF EB 00 2E 00 35 00 6D 2B 17 05 EA 7D C6 33",
        "FF FF 6E FF CE 00 20 00 5F FF 5A 2A 97 05 E9 58 FA 13",
        "FF 00 55 00 2A 00 67 FF 89 FF 8A 2A 65 05 EB 34 3F E9",
    )
]
GOLDEN_PACKETS = [decode_packet(p) for p in GOLDEN]

garbage_without_header = st.binary(max_size=40).map(lambda b: b.replace(b"\xff", b"\x00"))
packet_bytes = raw_packets.map(encode_packet)
# Arbitrary bytes mixed with what makes framing hard: whole, cut and corrupted packets, 0xFF runs.
byte_soup = st.one_of(
    st.binary(max_size=400),
    st.lists(
        st.one_of(
            st.binary(max_size=30),
            packet_bytes,
            st.tuples(packet_bytes, st.integers(1, 17)).map(lambda t: t[0][: t[1]]),
            st.tuples(packet_bytes, st.integers(1, 17), st.integers(1, 255)).map(
                lambda t: t[0][: t[1]] + bytes([t[0][t[1]] ^ t[2]]) + t[0][t[1] + 1 :]
            ),
            st.binary(min_size=1, max_size=20).map(lambda b: b"\xff" * len(b)),
        ),
        max_size=20,
    ).map(b"".join),
)


def _clean_packet(n: int) -> bytes:
    """A valid packet with no 0xFF after its header."""
    return encode_packet(RawPacket((n, 2 * n, 3), (4, 5, 6), 1500, 1000 + n))


def _feed_chunks(framer: PacketFramer, data: bytes, cuts: list[int]) -> list[RawPacket]:
    packets: list[RawPacket] = []
    bounds = [0, *sorted({c for c in cuts if 0 < c < len(data)}), len(data)]
    for start, end in itertools.pairwise(bounds):
        packets += framer.feed(data[start:end])
        _assert_accounting(framer)
    return packets


def _assert_accounting(framer: PacketFramer) -> None:
    s = framer.stats
    assert (
        s.bytes_in + s.shared_bytes == PACKET_LENGTH * s.packets + s.skipped_bytes + framer.buffered
    )
    assert framer.buffered < 2 * PACKET_LENGTH


def test_golden_stream_byte_by_byte():
    framer = PacketFramer()
    stream = b"".join(GOLDEN)
    packets = _feed_chunks(framer, stream, list(range(len(stream))))
    assert packets == GOLDEN_PACKETS
    assert framer.stats == FramerStats(bytes_in=72, packets=4)
    assert framer.locked


def test_garbage_then_three_packets():
    framer = PacketFramer()
    packets = framer.feed(b"\x01\x02\x03\x04\x05" + b"".join(GOLDEN[:3]))
    assert packets == GOLDEN_PACKETS[:3]
    assert framer.stats == FramerStats(bytes_in=59, packets=3, skipped_bytes=5)
    assert framer.buffered == 0


def test_corrupted_packet_in_the_middle_is_one_resync():
    bad = bytearray(_clean_packet(2))
    bad[17] ^= 0x01
    framer = PacketFramer()
    packets = framer.feed(_clean_packet(1) + bytes(bad) + _clean_packet(3))
    assert packets == [decode_packet(_clean_packet(1)), decode_packet(_clean_packet(3))]
    assert framer.stats == FramerStats(
        bytes_in=54, packets=2, bad_checksums=1, skipped_bytes=18, resyncs=1
    )


def test_start_in_the_middle_of_a_packet_with_0xff_in_its_payload():
    framer = PacketFramer()
    # Row 1 from byte 5 on: 'FF D8 FF FB ...' holds two false header candidates.
    stream = GOLDEN[0][5:] + b"".join(GOLDEN[1:])
    packets = _feed_chunks(framer, stream, list(range(0, len(stream), 5)))
    assert packets == GOLDEN_PACKETS[1:]
    assert framer.stats == FramerStats(
        bytes_in=67, packets=3, bad_checksums=2, skipped_bytes=13, resyncs=0
    )


def test_extra_header_byte_before_a_packet_whose_payload_starts_with_0xff():
    framer = PacketFramer()
    packets = framer.feed(GOLDEN[0] + b"\xff" + GOLDEN[2])
    assert packets == [GOLDEN_PACKETS[0], GOLDEN_PACKETS[2]]
    assert framer.stats == FramerStats(
        bytes_in=37, packets=2, bad_checksums=1, skipped_bytes=1, resyncs=1
    )


def test_all_0xff_stream_yields_nothing():
    framer = PacketFramer()
    assert framer.feed(b"\xff" * 100) == []
    assert framer.stats == FramerStats(bytes_in=100, bad_checksums=83, skipped_bytes=83)
    assert framer.buffered == 17
    _assert_accounting(framer)


def test_partial_packet_waits_for_the_rest():
    framer = PacketFramer()
    assert framer.feed(GOLDEN[0][:17]) == []
    assert framer.buffered == 17
    assert not framer.locked
    assert framer.feed(GOLDEN[0][17:]) == GOLDEN_PACKETS[:1]
    assert framer.buffered == 0


def test_reset_drops_the_partial_packet_and_keeps_the_counts():
    framer = PacketFramer()
    framer.feed(GOLDEN[0] + GOLDEN[1][:10])
    framer.reset()
    assert framer.buffered == 0
    assert not framer.locked
    assert framer.feed(GOLDEN[2]) == GOLDEN_PACKETS[2:3]
    assert framer.stats == FramerStats(bytes_in=46, packets=2, skipped_bytes=10, resyncs=0)
    _assert_accounting(framer)


def test_stats_is_a_snapshot():
    framer = PacketFramer()
    snapshot = framer.stats
    framer.feed(GOLDEN[0])
    assert snapshot.packets == 0
    assert dataclasses.replace(snapshot, packets=1, bytes_in=18) == framer.stats


@pytest.mark.parametrize("confirm", [False, True])
@given(data=byte_soup, cuts=st.lists(st.integers(0, 600), max_size=30))
def test_any_byte_soup_any_chunking(confirm, data, cuts):
    chunked = PacketFramer(confirm_with_next_packet=confirm)
    packets = _feed_chunks(chunked, data, cuts)
    assert chunked.stats.packets == len(packets)
    assert chunked.stats.bytes_in == len(data)
    if not confirm:
        assert chunked.buffered < PACKET_LENGTH
    whole = PacketFramer(confirm_with_next_packet=confirm)
    assert whole.feed(data) == packets  # chunking never changes the result ...
    assert whole.stats == chunked.stats  # ... nor the counters
    assert whole.buffered == chunked.buffered
    for packet in packets:  # every packet is really in the input
        assert encode_packet(packet) in data


@given(
    st.lists(st.tuples(garbage_without_header, raw_packets), max_size=8),
    garbage_without_header,
    st.lists(st.integers(0, 500), max_size=40),
)
def test_embedded_packets_recovered_exactly_once_in_order(pieces, tail, cuts):
    stream = b"".join(gap + encode_packet(p) for gap, p in pieces) + tail
    framer = PacketFramer()
    packets = _feed_chunks(framer, stream, cuts)
    assert packets == [p for _, p in pieces]
    gaps = [len(gap) for gap, _ in pieces]
    assert framer.stats == FramerStats(
        bytes_in=len(stream),
        packets=len(pieces),
        skipped_bytes=sum(gaps) + len(tail),
        resyncs=sum(1 for g in gaps[1:] if g),
    )
    assert framer.buffered == 0


# A continuous stream: the device timer counts down 9412 +- 9 counts per packet (notes §2.6).
continuous_packets = st.tuples(
    st.lists(raw_packets, min_size=1, max_size=12),
    st.integers(0, 65535),
    st.lists(st.integers(-9, 9), min_size=12, max_size=12),
).map(
    lambda t: [
        dataclasses.replace(p, timer=(t[1] - 9412 * i + t[2][i]) % 65536)
        for i, p in enumerate(t[0])
    ]
)


@given(continuous_packets, st.lists(st.integers(0, 300), max_size=20))
def test_confirming_framer_recovers_a_continuous_stream_completely(packets, cuts):
    stream = b"".join(encode_packet(p) for p in packets)
    framer = PacketFramer(confirm_with_next_packet=True)
    # The first packet waits for the next one; the last one is trusted as its timer fits.
    expected = packets if len(packets) > 1 else []
    assert _feed_chunks(framer, stream, cuts) == expected
    assert framer.stats.unconfirmed == 0


def test_confirming_framer_rejects_a_checksum_match_without_a_following_header():
    false_candidate = GOLDEN[0]  # a valid checksum, but a header with garbage after it
    framer = PacketFramer(confirm_with_next_packet=True)
    assert framer.feed(b"\x01" + false_candidate + b"\xff" + b"\x02" * 17) == []
    assert framer.stats.unconfirmed == 1
    assert framer.feed(GOLDEN[1] + GOLDEN[2][:17]) == []
    assert framer.buffered == 2 * PACKET_LENGTH - 1  # waits for the packet that confirms it
    # Confirmed by the next packet; then in sync, so that one needs no confirmation.
    assert framer.feed(GOLDEN[2][17:]) == [GOLDEN_PACKETS[1], GOLDEN_PACKETS[2]]


def test_confirmation_cuts_false_packets_in_a_corrupted_continuous_stream():
    rng = random.Random(7)
    # A unit at rest: small readings, half of them negative, so 0xFF MSBs fill the payloads.
    sent = [
        RawPacket(
            tuple(rng.randint(-200, 200) for _ in range(3)),
            (rng.randint(-200, 200), rng.randint(-200, 200), 10923 + rng.randint(-50, 50)),
            1500,
            (60000 - 9412 * i) % 65536,
        )
        for i in range(30000)
    ]
    stream = bytearray(b"".join(encode_packet(p) for p in sent))
    for index in rng.sample(range(len(stream)), len(stream) // 100):  # 1 % corrupted bytes
        stream[index] ^= rng.randint(1, 255)
    sent_set = set(sent)
    false = {}
    for confirm in (False, True):
        received = PacketFramer(confirm_with_next_packet=confirm).feed(bytes(stream))
        false[confirm] = sum(1 for p in received if p not in sent_set)
    assert false[False] > 20  # the checksum alone lets about 1 in 256 candidates through
    assert false[True] <= false[False] // 10


@pytest.mark.parametrize("kind", KINDS)
def test_continuous_framer_targets_under_single_byte_damage(kind: str):
    """Issue 12 targets on a small sample: at most 1 false packet per 10 000 damaged ones and
    no valid packet lost (bench/bench_framer.py measures them on 100 000 per kind); here at most
    1 in 4000, with right readings (a false one is a timer byte within the step tolerance). The
    checksum alone let about 1 in 120 through and lost the packet after it."""
    rng = np.random.default_rng(12)
    result = run_damaged(realistic_packets(20_000, rng), kind, rng)
    assert result.damaged == 4000
    assert result.false <= 1 and result.false_values == 0
    assert result.lost == 0


def test_a_lost_0xff_checksum_loses_no_other_packet():
    timers = [(30000 - 9412 * i) % 65536 for i in range(4)]
    packets = [RawPacket((1, 2, 3), (4, 5, 6), 1500, t) for t in timers]
    packets[1] = next(  # its checksum is 0xFF, which the next header then stands in for
        p
        for k in range(256)
        if encode_packet(p := RawPacket((1, 2, k), (4, 5, 6), 1500, timers[1]))[-1] == 0xFF
    )
    wire = [encode_packet(p) for p in packets]
    stream = wire[0] + wire[1][:-1] + wire[2] + wire[3]
    framer = PacketFramer(confirm_with_next_packet=True)
    assert framer.feed(stream) == packets
    assert framer.stats.shared_bytes == 1


def _with_checksum_ff(rates: tuple[int, int, int], timer: int) -> RawPacket:
    """A packet with these rates (the last one adjusted) whose checksum byte is 0xFF."""
    return next(
        p
        for k in range(256)
        if encode_packet(p := RawPacket((*rates[:2], rates[2] + k), (4, 5, 10923), 1500, timer))[-1]
        == 0xFF
    )


def test_a_lost_0xff_checksum_before_a_packet_starting_with_0xff_loses_no_other_packet():
    # The next packet's rate x is small and negative (0xFF MSB): once the lost checksum's place
    # is taken by its header, it is also what a packet with a lost 0xFF payload byte would give;
    # its readings continue the last packet's, so it is the packet itself.
    timers = [(30000 - 9412 * i) % 65536 for i in range(4)]
    packets = [RawPacket((-3, 2, -5), (4, -6, 10923), 1500, t) for t in timers]
    packets[1] = _with_checksum_ff((-1, 2, 3), timers[1])
    wire = [encode_packet(p) for p in packets]
    assert wire[2][1] == 0xFF and 0xFF in wire[2][2:17]
    framer = PacketFramer(confirm_with_next_packet=True)
    assert framer.feed(wire[0] + wire[1][:-1] + wire[2] + wire[3]) == packets
    assert framer.stats.shared_bytes == 1 and framer.stats.ambiguous == 0


def test_a_packet_shifted_by_a_lost_0xff_payload_byte_is_refused():
    # After a packet whose checksum is 0xFF, the next one loses its rate-y MSB (0xFF): taken
    # from that checksum on, the bytes have a good checksum and the packet's own timer, but
    # rates shifted by a byte (rate y = 0x4010 = 16400 counts, 75 deg/s) - not a packet.
    timers = [(30000 - 9412 * i) % 65536 for i in range(5)]
    packets = [RawPacket((64, -240, 32), (48, 80, 10923), 1500, t) for t in timers]
    packets[1] = _with_checksum_ff((64, -240, 32), timers[1])
    wire = [encode_packet(p) for p in packets]
    assert wire[2][3] == 0xFF and 0xFF not in wire[2][4:17]
    damaged = wire[2][:3] + wire[2][4:]
    framer = PacketFramer(confirm_with_next_packet=True)
    received = framer.feed(wire[0] + wire[1] + damaged + wire[3] + wire[4])
    assert received == [packets[0], packets[1], packets[3], packets[4]]
    assert framer.stats.ambiguous == 1


def test_two_candidates_confirm_each_other_only_with_a_timer_step_of_the_stream():
    # Two valid-checksum candidates back to back, with timers 30000 counts apart: no 1 to 6
    # packet periods of 9412 counts give that step, so the first is refused; the second is
    # confirmed by a packet one period after it, which then fits the stream.
    first, second, third = (
        encode_packet(RawPacket((1, 2, 3), (4, 5, 6), 1500, timer))
        for timer in (40000, 10000, 10000 - 9412)
    )
    framer = PacketFramer(confirm_with_next_packet=True)
    received = framer.feed(b"\x01" + first + second + third)
    assert received == [decode_packet(second), decode_packet(third)]
    assert framer.stats.unconfirmed == 1
