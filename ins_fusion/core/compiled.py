"""Compilation of the engine's per-sample arithmetic with numba.

``jit(f)`` compiles a plain Python function (floats, tuples and numpy arrays only) to machine
code on its first call and keeps the result in numba's on-disk cache (the package's
``__pycache__``, else the user's cache directory), so a later start loads it in milliseconds.
The functions stay ordinary Python source: with ``NUMBA_DISABLE_JIT=1`` in the environment
numba returns them unchanged and the engine runs as pure Python (the reference path the tests
compare the compiled one with).

numba checks a cached function against its own source file only, not against the functions it
calls, which it compiles into it: after an update that changes a callee, a caller's cached code
would keep the old callee. ``drop_stale_kernels`` (run at import) therefore keeps a digest of
the sources of the core and its sub-packages beside the cache and empties every sub-package's
cache when they changed.

Compiled code calls only compiled functions. ``compilable(f)`` marks a small helper (the
earth model's and the quaternions' scalar formulas) that compiled code may call: for Python
callers it stays the plain function, without a dispatcher's overhead.
"""

from __future__ import annotations

import hashlib
import os
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar, cast

import numba
import numpy as np
from numba.extending import register_jitable

F = TypeVar("F", bound=Callable[..., Any])
R = TypeVar("R", bound=tuple[Any, ...])

#: The file beside numba's cache files that holds the digest of the sources they were made from.
SOURCE_DIGEST_FILE = "kernels.source-digest"


def drop_stale_kernels(package: Path = Path(__file__).parent) -> bool:
    """Remove numba's cache files of ``package`` and its sub-packages (each folder's
    ``__pycache__``) when any of their sources or numba's version differ from those they were
    compiled from (a kernel compiles in the callees of other folders); True if it removed them.
    The digest is kept in ``package``'s ``__pycache__``. Does nothing where that is not writable
    (numba then caches elsewhere or not)."""
    digest = hashlib.sha256(numba.__version__.encode())
    for source in sorted(package.rglob("*.py")):
        name = source.relative_to(package).as_posix()
        digest.update(name.encode() + b"\0" + source.read_bytes())
    cache = package / "__pycache__"
    stamp = cache / SOURCE_DIGEST_FILE
    try:
        if stamp.read_text(encoding="ascii") == digest.hexdigest():
            return False
    except OSError:  # no stamp yet (or unreadable): the cache is of unknown sources
        pass
    try:
        cache.mkdir(exist_ok=True)
        for kernel in [*package.rglob("__pycache__/*.nbi"), *package.rglob("__pycache__/*.nbc")]:
            kernel.unlink(missing_ok=True)
        scratch = cache / f".{SOURCE_DIGEST_FILE}.{os.getpid()}"
        scratch.write_text(digest.hexdigest(), encoding="ascii")
        scratch.replace(stamp)
    except OSError:
        return False
    return True


drop_stale_kernels()


def jit(function: F) -> F:
    """``function`` compiled in nopython mode with the on-disk cache (see the module
    docstring); IEEE arithmetic as written (no fastmath), so results match the Python path.
    Where no cache directory is writable (a read-only install and home), it is compiled at
    every start instead, with a warning."""
    try:
        return cast(F, numba.njit(cache=True)(function))
    except RuntimeError as exc:  # numba: "cannot cache function ...: no locator available"
        warnings.warn(
            f"{exc}; compiling at every start (set NUMBA_CACHE_DIR to a writable directory)",
            RuntimeWarning,
            stacklevel=2,
        )
        return cast(F, numba.njit(function))


def compilable(function: F) -> F:
    """``function`` unchanged for Python, compiled inline where a ``jit`` function calls it."""
    compiled: F = register_jitable(function)
    return compiled


def kernel_array(values: Any) -> Any:
    """``values`` as a writable C-contiguous float64 array (copied only when it is not one):
    numba compiles a kernel anew for every array layout and for read-only arrays, so the
    engine hands over arrays of one kind (core.engine.warm_up compiles them)."""
    flags = getattr(values, "flags", None)
    if flags is not None and flags.c_contiguous and flags.writeable and values.dtype == np.float64:
        return values
    return np.array(values, dtype=np.float64)


def plain(record: R) -> R:
    """A named record (a NamedTuple) as the plain tuple of its fields, for a kernel called from
    Python that unpacks it by position in the record's field order: numba types a plain tuple
    in C but a named one in Python, some microseconds a call (core.engine.sample_runs)."""
    return cast(R, tuple(record))
