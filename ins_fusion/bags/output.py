"""A new bag written under a scratch name and renamed when complete (no ROS).

A bag under its final name is always whole: an error (or Ctrl-C) leaves nothing behind, and an
existing directory is never overwritten. ``gnss_ins recover`` and ``redecode`` write this way.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from ins_fusion.bags.bag_io import BagError


def refuse_existing(output: Path) -> None:
    """BagError if ``output`` exists (a bag is never overwritten)."""
    if output.exists():
        raise BagError(f"{output} exists already, not overwriting")


@contextmanager
def whole_bag(output: Path, doing: str) -> Iterator[Path]:
    """The path to write the bag ``output`` at (in a scratch directory beside it, ``doing``
    naming it); renamed to ``output`` when the block ends without an error, else removed."""
    refuse_existing(output)
    output.parent.mkdir(parents=True, exist_ok=True)
    scratch = Path(tempfile.mkdtemp(dir=output.parent, prefix=f".{output.name}.{doing}."))
    try:
        yield scratch / output.name
        if output.exists():
            raise BagError(f"{output} appeared while {doing}; the new bag is {scratch}")
        os.rename(scratch / output.name, output)
    except BaseException:
        if not output.exists():  # nothing half-written stays behind; the input is untouched
            shutil.rmtree(scratch, ignore_errors=True)
        raise
    scratch.rmdir()
