"""ins_fusion.adapters.payloads: messages kept as slices of shared buffers read back as the
bytes they are, one by one, reordered, joined and as rows of a matrix."""

from __future__ import annotations

import mmap

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ins_fusion.adapters.payloads import Payloads

_MESSAGES = st.lists(st.binary(min_size=0, max_size=40), min_size=0, max_size=30)


def _scattered(messages: list[bytes], cuts: list[int]) -> Payloads:
    """``messages`` laid into several buffers with filler bytes between them."""
    buffers: list[bytes] = []
    buffer, start, length = [], [], []
    current = b""
    for i, message in enumerate(messages):
        if i in cuts and current:
            buffers.append(current)
            current = b""
        current += b"\xaa" * (i % 3)
        buffer.append(len(buffers))
        start.append(len(current))
        length.append(len(message))
        current += message
    buffers.append(current + b"\xbb")
    as_int = lambda v: np.array(v, np.int64)  # noqa: E731
    return Payloads(buffers, as_int(buffer), as_int(start), as_int(length))


@settings(max_examples=200, deadline=None)
@given(_MESSAGES, st.lists(st.integers(0, 30), max_size=5), st.data())
def test_payloads_are_the_messages(messages, cuts, data):
    payloads = _scattered(messages, cuts)
    assert len(payloads) == len(messages)
    assert list(payloads) == messages
    assert [payloads[i] for i in range(-len(messages), len(messages))] == messages * 2
    assert list(payloads[1::2]) == messages[1::2]
    order = np.array(data.draw(st.permutations(range(len(messages)))), np.int64)
    assert list(payloads.take(order)) == [messages[i] for i in order]
    assert list(Payloads.of(messages)) == messages
    joined = Payloads.joined([payloads, payloads.take(order), Payloads.of(messages)])
    assert list(joined) == messages + [messages[i] for i in order] + messages
    width = min(map(len, messages), default=0)
    rows = payloads.take(order).rows(np.arange(len(order)), width)
    assert rows.shape == (len(messages), width)
    assert [row.tobytes() for row in rows] == [messages[i][:width] for i in order]


def test_a_shared_buffer_is_listed_once_and_a_mapped_file_serves(tmp_path):
    path = tmp_path / "data"
    path.write_bytes(bytes(range(200)))
    with path.open("rb") as handle:
        whole = mmap.mmap(handle.fileno(), 0, access=mmap.ACCESS_READ)
    one = Payloads([whole], np.zeros(2, np.int64), np.array([10, 50]), np.array([5, 5]))
    other = Payloads([whole], np.zeros(1, np.int64), np.array([100]), np.array([3]))
    joined = Payloads.joined([one, other, one])
    first, second = bytes(range(10, 15)), bytes(range(50, 55))
    assert list(joined) == [first, second, bytes(range(100, 103)), first, second]
    assert len(joined._buffers) == 1
    assert joined.rows(np.array([2, 0]), 3).tolist() == [[100, 101, 102], [10, 11, 12]]


def test_bad_indexes_are_refused():
    with pytest.raises(ValueError, match="runs past"):
        Payloads([b"abc"], np.zeros(1, np.int64), np.array([2]), np.array([2]))
    with pytest.raises(ValueError, match="no buffer"):
        Payloads([b"abc"], np.array([1]), np.array([0]), np.array([1]))
    with pytest.raises(ValueError, match="1 buffer, 2 start"):
        Payloads([b"abc"], np.zeros(1, np.int64), np.array([0, 1]), np.array([1]))
    with pytest.raises(ValueError, match="shorter than 3"):
        Payloads.of([b"ab", b"abc"]).rows(np.array([0, 1]), 3)
    with pytest.raises(IndexError):
        Payloads.of([b"ab"])[1]
