"""Stream helpers the parser benchmarks share: corrupting bytes and cutting realistic reads."""

from __future__ import annotations

import itertools

import numpy as np

#: Fraction of bytes replaced by random values in the "corrupted" runs.
CORRUPT_FRACTION = 0.01


def corrupt(stream: bytes, rng: np.random.Generator) -> bytes:
    """``stream`` with CORRUPT_FRACTION of its bytes replaced by random values."""
    data = np.frombuffer(stream, dtype=np.uint8).copy()
    where = rng.choice(data.size, int(data.size * CORRUPT_FRACTION), replace=False)
    data[where] = rng.integers(0, 256, where.size)
    return data.tobytes()


def chunks(stream: bytes, rng: np.random.Generator) -> list[bytes]:
    """``stream`` cut into reads of 1..64 bytes, as a serial port delivers them."""
    sizes = rng.integers(1, 65, len(stream) // 16)
    bounds = np.concatenate(([0], np.cumsum(sizes)))
    return [
        stream[a:b] for a, b in itertools.pairwise([*bounds[bounds < len(stream)], len(stream)])
    ]
