"""gnss_ins_common.serial_reads: reads gathered into one raw-record message come back as they
were read, byte for byte and nanosecond for nanosecond."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from gnss_ins_common.serial_reads import ReadBatch, split_reads

reads = st.lists(
    st.tuples(st.binary(min_size=0, max_size=80), st.integers(0, 10**6)), min_size=1, max_size=60
)


@given(reads, st.integers(1, 20))
def test_batches_split_back_into_the_reads(timed: list[tuple[bytes, int]], max_reads: int) -> None:
    batch = ReadBatch(period_ns=50_000, max_reads=max_reads)
    now, sent, rebuilt = 10**12, [], []
    for chunk, step in timed:
        now += step
        sent.append((chunk, now))
        if batch.add(chunk, now):
            record = batch.take()
            assert record is not None and len(record.read_ends) <= max_reads
            rebuilt += split_reads(record.data, record.read_ends, record.read_times_ns, 0)
    if (rest := batch.take()) is not None:
        rebuilt += split_reads(rest.data, rest.read_ends, rest.read_times_ns, 0)
    assert rebuilt == sent
    assert batch.take() is None and len(batch) == 0


def test_a_batch_is_due_by_the_age_of_its_first_read_or_when_full() -> None:
    batch = ReadBatch(period_ns=100, max_reads=3)
    assert not batch.due(10**9)  # empty: never due
    assert not batch.add(b"a", 1000)
    assert not batch.add(b"b", 1099)
    assert batch.due(1100)  # the first read is 100 ns old
    assert batch.add(b"c", 1050)  # three reads: full
    record = batch.take()
    assert record is not None
    assert (record.data, record.read_ends, record.read_times_ns) == (
        b"abc",
        [1, 2, 3],
        [1000, 1099, 1050],
    )


def test_a_message_without_read_ends_is_one_read_at_its_stamp() -> None:
    assert split_reads(b"xyz", [], [], 42) == [(b"xyz", 42)]


@pytest.mark.parametrize(
    ("ends", "times", "why"),
    [
        ([2, 1, 3], [1, 2, 3], "do not cut"),
        ([1, 2], [1, 2], "do not cut"),  # the last end is not the length
        ([1, 3], [1], "2 read ends for 1 read times"),
        ([-1, 3], [1, 2], "do not cut"),
    ],
)
def test_inconsistent_reads_are_refused(ends: list[int], times: list[int], why: str) -> None:
    with pytest.raises(ValueError, match=why):
        split_reads(b"abc", ends, times, 0)


def test_bad_settings_are_refused() -> None:
    with pytest.raises(ValueError):
        ReadBatch(period_ns=10, max_reads=0)
