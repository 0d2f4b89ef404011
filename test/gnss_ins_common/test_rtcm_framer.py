"""gnss_ins_common.rtcm: real captures, and frames out of any stream split anywhere."""

from __future__ import annotations

import itertools
from collections import Counter

import pytest
from hypothesis import given
from hypothesis import strategies as st
from support.paths import FIXTURES

from gnss_ins_common.rtcm import (
    MAX_FRAME_BYTES,
    MAX_PAYLOAD_BYTES,
    PREAMBLE,
    RtcmFramer,
    make_frame,
    message_number,
    split_frames,
)

FIXTURES = FIXTURES / "rtcm"
NTRIP_CAPTURE = (FIXTURES / "pygpsdata-NTRIP-USCL00CHL0.log").read_bytes()
MIXED_CAPTURE = (FIXTURES / "pygpsdata-RTCM3.log").read_bytes()
CAPTURE_FRAMES, _ = split_frames(NTRIP_CAPTURE)


def test_the_ntrip_capture_is_35_frames_and_nothing_else():
    framer = RtcmFramer()
    frames = framer.feed(NTRIP_CAPTURE)
    assert len(frames) == 35 and b"".join(frames) == NTRIP_CAPTURE
    stats = framer.stats
    assert (stats.bytes_in, stats.frame_bytes, stats.skipped_bytes, stats.crc_failures) == (
        4606,
        4606,
        0,
        0,
    )
    assert stats.by_number[1077] == 1 and sum(stats.by_number.values()) == 35
    assert [message_number(f) for f in frames[:3]] == [1003, 1004, 1005]


def test_the_mixed_capture_hands_back_its_nmea_and_ubx():
    other = bytearray()
    framer = RtcmFramer()
    frames = framer.feed(MIXED_CAPTURE, other)
    assert [message_number(f) for f in frames] == [
        1005, 4072, 1077, 1087, 1097, 1127, 1230, 1007, 1117, 1059, 1060,
    ]  # fmt: skip
    assert framer.stats.skipped_bytes == len(other) == 222
    assert framer.stats.frame_bytes + len(other) == len(MIXED_CAPTURE)
    assert other.startswith(b"$GNGLL,") and b"\xb5b\x01\x07" in other  # NMEA, UBX NAV-PVT


def test_a_corrupted_frame_is_a_crc_failure_and_its_neighbours_survive():
    first, second, third = CAPTURE_FRAMES[:3]
    broken = bytearray(second)
    broken[10] ^= 0x01
    framer = RtcmFramer()
    assert framer.feed(first + bytes(broken) + third) == [first, third]
    assert framer.stats.crc_failures == 1 and framer.stats.skipped_bytes == len(second)


def test_reset_counts_a_partial_frame_as_skipped():
    framer = RtcmFramer()
    frame = CAPTURE_FRAMES[0]
    assert framer.feed(frame[:-5]) == [] and framer.buffered == len(frame) - 5
    framer.reset()
    assert framer.buffered == 0 and framer.stats.skipped_bytes == len(frame) - 5
    assert framer.feed(frame) == [frame]


def test_make_frame_and_split_frames():
    payload = bytes([0x3E, 0xD0]) + bytes(17)  # message 1005
    frame = make_frame(payload)
    assert message_number(frame) == 1005 and len(frame) == len(payload) + 6
    assert split_frames(b"xx" + frame + frame[:4]) == ([frame], 6)
    assert message_number(make_frame(b"")) == 0
    with pytest.raises(ValueError, match="at most 1023"):
        make_frame(bytes(MAX_PAYLOAD_BYTES + 1))


NOT_PREAMBLE = st.binary(max_size=40).map(lambda b: b.replace(bytes([PREAMBLE]), b"\x00"))
FRAMES = st.one_of(
    st.sampled_from(CAPTURE_FRAMES),
    st.binary(max_size=MAX_PAYLOAD_BYTES).map(make_frame),
)


def _feed_in_pieces(
    framer: RtcmFramer, stream: bytes, cuts: list[int], other: bytearray
) -> list[bytes]:
    bounds = sorted({0, len(stream), *(c % (len(stream) + 1) for c in cuts)})
    return [f for a, b in itertools.pairwise(bounds) for f in framer.feed(stream[a:b], other)]


@given(
    parts=st.lists(st.tuples(NOT_PREAMBLE, FRAMES), max_size=8),
    tail=NOT_PREAMBLE,
    cuts=st.lists(st.integers(min_value=0), max_size=30),
)
def test_frames_between_other_bytes_come_out_exactly_in_order_over_any_cuts(parts, tail, cuts):
    stream = b"".join(junk + frame for junk, frame in parts) + tail
    junk = b"".join(junk for junk, _ in parts) + tail
    framer, other = RtcmFramer(), bytearray()
    frames = _feed_in_pieces(framer, stream, cuts, other)
    assert frames == [frame for _, frame in parts]
    assert bytes(other) == junk
    stats = framer.stats
    assert (stats.bytes_in, stats.skipped_bytes, stats.crc_failures) == (len(stream), len(junk), 0)
    assert stats.frames == len(frames) and stats.frame_bytes == sum(map(len, frames))
    assert stats.by_number == Counter(message_number(f) for f in frames)
    assert framer.buffered == 0


@given(
    parts=st.lists(st.tuples(st.binary(max_size=40), FRAMES), max_size=6),
    cuts=st.lists(st.integers(min_value=0), max_size=30),
)
def test_stray_preambles_in_the_noise_cost_no_frame(parts, cuts):
    """Noise with 0xD3 bytes: a false candidate fails its CRC and the search goes on; the padding
    at the end lets every candidate resolve."""
    stream = b"".join(junk + frame for junk, frame in parts) + bytes(MAX_FRAME_BYTES)
    framer, other = RtcmFramer(), bytearray()
    frames = _feed_in_pieces(framer, stream, cuts, other)
    assert frames == [frame for _, frame in parts]
    assert framer.stats.skipped_bytes == len(other) == len(stream) - sum(map(len, frames))
