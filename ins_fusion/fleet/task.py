"""One bag of a batch, run on a Dask worker: ``gnss_ins replay`` itself
(ins_fusion.replay.command.run_replay) with its outputs in a temporary folder of the worker,
sent back to the client as bytes, so that the workers need only read the bags and the client
alone writes the results (ins_fusion.fleet.store).

The replay's printed table and notes go to the bag's ``replay.log``: the task redirects the
process's stdout and stderr while it runs, one task at a time per worker process.
"""

from __future__ import annotations

import argparse
import io
import socket
import tempfile
import threading
import time
import traceback
from collections.abc import Sequence
from contextlib import redirect_stderr, redirect_stdout
from dataclasses import dataclass, field
from pathlib import Path

from ins_fusion.replay.command import UsageError, run_replay

#: The files of a bag's folder the task writes (beside the exports it is asked for).
REPORT = "report.json"
PLOT = "plot.png"
LOG = "replay.log"
#: The replay's own prefix of its error lines on stderr.
_PREFIX = "gnss_ins replay: "

#: Standard streams are per process: one replay at a time in a worker with several threads.
_STREAMS = threading.Lock()


@dataclass(frozen=True)
class BagResult:
    """What a task produced: ``status`` "ok", "no solution" (exit status 1: the report is
    written, no plot nor exports) or "failed" (``error`` says why); ``seconds`` its wall time,
    ``cpu_seconds`` its process's CPU time meanwhile; ``files``: name -> bytes."""

    bag: str
    status: str
    error: str | None
    exit_status: int
    seconds: float
    cpu_seconds: float
    worker: str
    files: dict[str, bytes] = field(default_factory=dict)


def replay_bag(
    template: argparse.Namespace, bag: str, plot: bool, exports: Sequence[str]
) -> BagResult:
    """Replay ``bag`` with the options of ``template`` (a parsed ``gnss_ins replay`` command
    line), writing the report, the plot (``plot``) and ``exports`` (file names, their suffix the
    format). Never raises for a bad bag: the error is in the result."""
    start, cpu = time.perf_counter(), time.process_time()
    with tempfile.TemporaryDirectory(prefix="gnss_ins_batch_") as scratch:
        folder = Path(scratch)
        args = argparse.Namespace(**vars(template))
        args.bag = Path(bag)
        args.report = folder / REPORT
        args.plot = folder / PLOT if plot else None
        args.export = [folder / name for name in exports]
        out, err = io.StringIO(), io.StringIO()
        error = None
        with _STREAMS, redirect_stdout(out), redirect_stderr(err):
            try:
                exit_status = run_replay(args)
            except UsageError as exc:
                exit_status, error = 2, str(exc)
            except Exception as exc:  # a bug the bag revealed: reported, the batch goes on
                exit_status, error = 3, f"{type(exc).__name__}: {exc}"
                err.write(traceback.format_exc())
        if exit_status == 1:
            lines = [line for line in err.getvalue().splitlines() if line.startswith(_PREFIX)]
            error = lines[0].removeprefix(_PREFIX) if lines else "no fused solution"
        log = out.getvalue() + err.getvalue() + (f"error: {error}\n" if error else "")
        files = {LOG: log.encode()}
        files.update((p.name, p.read_bytes()) for p in folder.iterdir() if p.is_file())
    status = {0: "ok", 1: "no solution"}.get(exit_status, "failed")
    return BagResult(
        bag,
        status,
        error,
        exit_status,
        time.perf_counter() - start,
        time.process_time() - cpu,
        socket.gethostname(),
        files,
    )
