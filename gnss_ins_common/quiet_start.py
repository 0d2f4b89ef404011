"""Run a program's ``main`` so that a Ctrl-C while it is still importing ends it quietly.

A node or tool started by ``gnss_ins launch`` spends seconds importing (rclpy, numpy, scipy) on
a loaded machine; Python's default SIGINT handler turns a Ctrl-C in that time into a
KeyboardInterrupt traceback from the middle of an import. Here SIGINT ends the process with
exit status 130 and no traceback until the program's module is imported; then the handler it
found is restored (Python's default, or "ignored" for a background job), so the program's own
Ctrl-C handling (a recorder closing its bag) is as without this wrapper.
"""

from __future__ import annotations

import importlib
import signal
import sys
from types import FrameType

#: Exit status of a process ended by SIGINT (128 + 2), as a shell reports it.
INTERRUPTED = 130


def _exit_quietly(_signum: int, _frame: FrameType | None) -> None:
    sys.exit(INTERRUPTED)


def run(module: str) -> int:
    """``module.main()``'s exit status; INTERRUPTED if a SIGINT came during the import."""
    previous = signal.getsignal(signal.SIGINT)
    if previous is signal.default_int_handler:
        signal.signal(signal.SIGINT, _exit_quietly)
    main = importlib.import_module(module).main
    signal.signal(signal.SIGINT, previous)
    status: int = main()
    return status
