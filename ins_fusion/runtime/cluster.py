"""Tasks on a Dask cluster (dask.distributed), the engine of ``gnss_ins batch`` and of the sweeps
of ``gnss_ins replay``.

``cluster`` connects to a running scheduler (``tcp://HOST:PORT``, its workers started with the
standard ``dask worker`` command) or starts a LocalCluster on this machine: one single-threaded
worker process per core (the engine holds the GIL, so threads would not run two tasks at once),
no dashboard, its log silent. ``completed`` yields each task's result or exception as it
finishes, so that one failing task is reported and the others complete. docs/fleet.md describes
the set-ups.
"""

from __future__ import annotations

import atexit
import gc
import logging
import os
from collections.abc import Callable, Hashable, Iterator, Mapping
from contextlib import contextmanager
from typing import Any, TypeVar

from distributed import Client, Future, LocalCluster, as_completed

#: Seconds to wait for a scheduler given by address before giving up.
CONNECT_TIMEOUT_S = 20.0

Key = TypeVar("Key", bound=Hashable)


class ClusterError(Exception):
    """The scheduler cannot be reached, or it has no workers."""


def local_workers(workers: int | None, tasks: int) -> int:
    """Worker processes of a LocalCluster: ``workers`` (default one per core), at most one per
    task and at least one."""
    return max(1, min(workers or os.cpu_count() or 1, tasks))


@contextmanager
def cluster(scheduler: str | None, workers: int | None, tasks: int) -> Iterator[Client]:
    """A client of the scheduler at ``scheduler`` or, when None, of a LocalCluster of
    ``local_workers(workers, tasks)`` processes; closed (the LocalCluster stopped) on exit."""
    if scheduler is not None:
        try:
            client = Client(scheduler, timeout=CONNECT_TIMEOUT_S)
        except (OSError, TimeoutError) as exc:
            raise ClusterError(f"cannot reach the Dask scheduler {scheduler}: {exc}") from None
        with client:
            if not client.scheduler_info().get("workers"):
                raise ClusterError(
                    f"the Dask scheduler {scheduler} has no workers (start them with"
                    f" `dask worker {scheduler}`)"
                )
            yield client
        return
    with (
        LocalCluster(
            n_workers=local_workers(workers, tasks),
            threads_per_worker=1,
            processes=True,
            # No dashboard; its HTTP server (health routes) on a free port, not 8787, so that two
            # sweeps at once start without a warning.
            dashboard_address=":0",
            scheduler_kwargs={"dashboard": False},
            # The cluster's own log stays quiet: a task's failure reaches its future (reported by
            # the command), and a loaded machine's shutdown race (a worker's heartbeat to the
            # scheduler that just closed) is logged by distributed as an ERROR with a traceback.
            silence_logs=logging.CRITICAL,
        ) as local,
        Client(local) as client,
    ):
        client.run(_quick_exit)
        yield client


def _quick_exit() -> None:
    """Freeze the objects left at a worker's exit: the interpreter's shutdown then skips its
    full collections over numba's kernels (~0.6 s of CPU, seconds on a busy machine, past the
    nanny's 4 s before it kills the worker), as ``gnss_ins`` itself does (tools/cli.py)."""
    atexit.unregister(gc.freeze)
    atexit.register(gc.freeze)


def submit_each(
    client: Client,
    function: Callable[..., Any],
    arguments: Mapping[Key, tuple[Any, ...]],
) -> dict[Future, Key]:
    """One task per key: ``function(*arguments[key])``; future -> key."""
    return {client.submit(function, *args, pure=False): key for key, args in arguments.items()}


def completed(futures: Mapping[Future, Key]) -> Iterator[tuple[Key, Any, BaseException | None]]:
    """(key, result, None) or (key, None, exception) of each task as it finishes."""
    for future in as_completed(list(futures)):
        key = futures[future]
        if future.status == "finished":
            yield key, future.result(), None
        elif future.status == "error":
            yield key, None, future.exception()
        else:  # cancelled, e.g. the scheduler went away
            yield key, None, ClusterError(f"the task of {key!r} was {future.status}")
