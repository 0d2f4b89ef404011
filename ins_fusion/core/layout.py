"""Offsets of the flat float arrays the compiled kernels use as structs (``FilterState.x``, the
intake's array, the noise monitors' arrays, the calibration table, the navigation array).

Each array is described once by a table of (name, width) in array order; ``offsets`` turns it
into the offset of every field and the array's size, which a module unpacks into its plain int
constants (numba reads module globals as compile-time constants)::

    NAV_LAYOUT = (("lat", 1), ("lon", 1), ("height", 1), ("vel", 3), ("quat", 4))
    NAV_LAT, NAV_LON, NAV_HEIGHT, NAV_VEL, NAV_QUAT, NAV_SIZE = offsets(NAV_LAYOUT)

The constant of a field is the module's prefix and the field's name in capitals (``NAV_VEL``
for "vel"); test/core/test_layout.py checks every table against its constants.
"""

from __future__ import annotations

from collections.abc import Sequence

#: A layout: (name, width) of each field, in array order.
Layout = Sequence[tuple[str, int]]


def offsets(layout: Layout) -> tuple[int, ...]:
    """The offset of each field of ``layout`` in table order, then the array's size."""
    names = [name for name, _ in layout]
    if len(set(names)) != len(names):
        raise ValueError(f"a field name repeats in {names}")
    starts = [0]
    for name, width in layout:
        if width < 1:
            raise ValueError(f"field {name!r} has width {width}")
        starts.append(starts[-1] + width)
    return tuple(starts)


def fields(layout: Layout) -> dict[str, tuple[int, int]]:
    """name -> (offset, width) of each field of ``layout``."""
    starts = offsets(layout)[:-1]
    return {name: (start, width) for (name, width), start in zip(layout, starts, strict=True)}
