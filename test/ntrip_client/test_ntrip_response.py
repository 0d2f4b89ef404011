"""The caster's answer: heads of every protocol, read in pieces, and the chunked decoder."""

from __future__ import annotations

import itertools

import pytest
from hypothesis import given
from hypothesis import strategies as st

from ntrip_client.response import MAX_HEAD_BYTES, ChunkedDecoder, parse_head

NTRIP2_DATA = (
    b"HTTP/1.1 200 OK\r\nNtrip-Version: Ntrip/2.0\r\nContent-Type: gnss/data\r\n"
    b"Transfer-Encoding: chunked\r\n\r\n"
)


def test_ntrip2_data_head_with_body_bytes_after_it():
    data = NTRIP2_DATA + b"5\r\nhello\r\n"
    head = parse_head(data)
    assert head is not None
    assert (head.protocol, head.status, head.reason) == ("HTTP/1.1", 200, "OK")
    assert head.headers["ntrip-version"] == "Ntrip/2.0"
    assert head.chunked and head.is_data and not head.is_sourcetable
    assert data[head.body_start :] == b"5\r\nhello\r\n"


def test_every_prefix_of_a_head_is_incomplete_never_an_error():
    for end in range(len(NTRIP2_DATA)):
        assert parse_head(NTRIP2_DATA[:end]) is None
    assert parse_head(NTRIP2_DATA) is not None


@pytest.mark.parametrize(
    ("data", "protocol", "status", "body"),
    [
        (b"ICY 200 OK\r\n\xd3\x00\x13", "ICY", 200, b"\xd3\x00\x13"),  # data after one CRLF
        (b"ICY 200 OK\r\n\r\n\xd3", "ICY", 200, b"\xd3"),
        (b"ICY 200 OK\r\nServer: x\r\n\r\n\xd3", "ICY", 200, b"\xd3"),
        (b"HTTP/1.0 401 Unauthorized\r\nWWW-Authenticate: Basic\r\n\r\n", "HTTP/1.0", 401, b""),
        (b"SOURCETABLE 200 OK\r\nContent-Length: 3\r\n\r\nSTR", "SOURCETABLE", 200, b"STR"),
    ],
)
def test_heads_of_each_protocol(data, protocol, status, body):
    head = parse_head(data)
    assert head is not None
    assert (head.protocol, head.status) == (protocol, status)
    assert data[head.body_start :] == body


def test_icy_status_line_alone_waits_for_what_follows():
    assert parse_head(b"ICY 200 OK\r\n") is None
    assert parse_head(b"ICY 200 OK\r\nSer") is None
    assert parse_head(b"ICY 200 OK\r\n\r") is None


def test_status_text_and_kinds():
    head = parse_head(b"HTTP/1.1 404 Not Found\r\n\r\n")
    assert head is not None and head.status_text == "404 Not Found" and not head.is_data
    table = parse_head(b"HTTP/1.1 200 OK\r\nContent-Type: gnss/sourcetable\r\n\r\n")
    assert table is not None and table.is_sourcetable and not table.is_data
    ntrip1 = parse_head(b"SOURCETABLE 200 OK\r\n\r\n")
    assert ntrip1 is not None and ntrip1.is_sourcetable and not ntrip1.is_data


@pytest.mark.parametrize(
    "data", [b"<html>", b"\xd3\x00\x13", b"HTTP/2 200\r\n\r\n", b"HTTP/1.1 OK\r\n\r\n"]
)
def test_an_answer_of_another_protocol_is_refused(data):
    with pytest.raises(ValueError, match="not HTTP, ICY or SOURCETABLE"):
        parse_head(data)


def test_a_head_without_end_is_refused_past_16_kilobytes():
    data = b"HTTP/1.1 200 OK\r\n" + b"X-Pad: y\r\n" * (MAX_HEAD_BYTES // 10 + 1)
    with pytest.raises(ValueError, match="no end of head"):
        parse_head(data)


def _chunked(pieces: list[bytes], extensions: bool) -> bytes:
    out = b"".join(
        b"%x%s\r\n%s\r\n" % (len(p), b";name=value" if extensions else b"", p) for p in pieces if p
    )
    return out + b"0\r\nTrailer: x\r\n\r\n"


@given(
    pieces=st.lists(st.binary(min_size=1, max_size=300), max_size=12),
    extensions=st.booleans(),
    cuts=st.lists(st.integers(min_value=0, max_value=5000), max_size=20),
)
def test_any_split_of_a_chunked_stream_decodes_to_the_original(pieces, extensions, cuts):
    stream = _chunked(pieces, extensions)
    bounds = sorted({0, len(stream), *(c for c in cuts if c < len(stream))})
    decoder = ChunkedDecoder()
    out = b"".join(decoder.feed(stream[a:b]) for a, b in itertools.pairwise(bounds))
    assert out == b"".join(pieces)
    assert decoder.finished


def test_upper_case_hex_sizes_and_bytes_after_the_end_are_ignored():
    decoder = ChunkedDecoder()
    data = b"A\r\n" + b"x" * 10 + b"\r\n0\r\n\r\nleftover"
    assert decoder.feed(data) == b"x" * 10 and decoder.finished


@pytest.mark.parametrize("data", [b"zz\r\nab\r\n", b"\r\n", b"2\r\nabXY", b"-1\r\n", b"1" * 2000])
def test_malformed_chunk_framing_raises(data):
    with pytest.raises(ValueError, match="chunked body"):
        ChunkedDecoder().feed(data)
