"""gnss_ins_common.quiet_start: how launch starts its processes (runtime.processes.python_main).
A Ctrl-C while the program still imports ends it with status 130 and no traceback; afterwards
the program's own Ctrl-C handling is Python's as usual; a SIGINT ignored (a background job)
stays ignored."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

from support.pacing import pause

from ins_fusion.runtime.processes import python_main

#: A program whose import takes a while and whose main waits for Ctrl-C and says so.
SLOW_PROGRAM = """
import time
time.sleep({import_s})

def main():
    try:  # the print inside: a Ctrl-C right after it is still main's
        print("imported", flush=True)
        time.sleep(30)
    except KeyboardInterrupt:
        print("main saw Ctrl-C", flush=True)
        return 3
    return 0
"""


def _start(
    tmp_path: Path, import_s: float, sigint: object, wrapped: bool = True
) -> subprocess.Popen[str]:
    """The slow program started as launch starts it (``wrapped``) or with a plain ``-c``."""
    (tmp_path / "slow_program.py").write_text(SLOW_PROGRAM.format(import_s=import_s))
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), *sys.path])}
    plain = [sys.executable, "-c", "import sys, slow_program; sys.exit(slow_program.main())"]
    return subprocess.Popen(
        python_main("slow_program") if wrapped else plain,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        # The SIGINT disposition a terminal (SIG_DFL) or a background job (SIG_IGN) gives.
        preexec_fn=lambda: signal.signal(signal.SIGINT, sigint),  # type: ignore[arg-type]
    )


def test_a_ctrl_c_during_the_import_ends_quietly(tmp_path):
    process = _start(tmp_path, 5.0, signal.SIG_DFL)
    pause(1.0)  # into its 5 s import
    process.send_signal(signal.SIGINT)
    stdout, stderr = process.communicate(timeout=20)
    assert process.returncode == 130
    assert "Traceback" not in stderr and stdout == ""


def test_after_the_import_the_program_handles_ctrl_c_itself(tmp_path):
    """The same status and output as the program started without the wrapper: main catches
    the KeyboardInterrupt and returns 3."""
    outcomes = []
    for wrapped in (True, False):
        process = _start(tmp_path, 0.0, signal.SIG_DFL, wrapped)
        assert process.stdout is not None and process.stdout.readline() == "imported\n"
        process.send_signal(signal.SIGINT)
        stdout, _ = process.communicate(timeout=20)
        outcomes.append((process.returncode, stdout))
    assert outcomes[0] == outcomes[1] == (3, "main saw Ctrl-C\n")


def test_an_ignored_sigint_stays_ignored(tmp_path):
    process = _start(tmp_path, 2.0, signal.SIG_IGN)
    pause(0.5)  # into its 2 s import
    process.send_signal(signal.SIGINT)  # during the import
    assert process.stdout is not None and process.stdout.readline() == "imported\n"
    process.send_signal(signal.SIGINT)  # in main
    pause(0.5)  # time to end, had it not ignored the signal
    assert process.poll() is None
    process.terminate()
    process.communicate(timeout=20)
