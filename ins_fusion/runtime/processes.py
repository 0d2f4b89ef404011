"""Child processes of the tools (nodes, recorder, simulator), each logging to its own file."""

from __future__ import annotations

import signal
import subprocess
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

#: Console lines of a ROS node (rcutils format) or of Python that report a problem.
_PROBLEM_PREFIXES = ("[WARN]", "[ERROR]", "[FATAL]", "Traceback")


class ProcessGroup:
    """Processes stopped with SIGINT (a clean ROS shutdown) in reverse start order."""

    def __init__(self, log_dir: Path, env: Mapping[str, str] | None = None) -> None:
        """``log_dir`` receives NAME.log per process; ``env``: their environment (default: ours)."""
        log_dir.mkdir(parents=True, exist_ok=True)
        self.log_dir, self.env = log_dir, dict(env) if env is not None else None
        self.running: list[tuple[str, subprocess.Popen[str]]] = []
        self._read: dict[str, int] = {}  # bytes of each NAME.log already scanned by problems()

    def start(self, name: str, command: Sequence[str], **kwargs: Any) -> subprocess.Popen[str]:
        """Start ``command``; its output goes to NAME.log unless ``stdout`` is given (then its
        stderr does)."""
        log = (self.log_dir / f"{name}.log").open("w")
        options: dict[str, Any] = {"env": self.env, "text": True}
        options.update(stdout=log, stderr=subprocess.STDOUT if "stdout" not in kwargs else log)
        options.update(kwargs)
        process = subprocess.Popen(list(command), **options)
        self.running.append((name, process))
        return process

    def problems(self, limit: int = 3) -> list[str]:
        """New WARN/ERROR/FATAL lines (and tracebacks) of the processes' logs since the last
        call, as ``NAME: line``; at most ``limit`` per process, the rest counted."""
        found: list[str] = []
        for name, _ in self.running:
            path = self.log_dir / f"{name}.log"
            if not path.exists():
                continue
            with path.open("rb") as log:
                log.seek(self._read.get(name, 0))
                text = log.read()
            complete = text[: text.rfind(b"\n") + 1]  # a line still being written waits
            self._read[name] = self._read.get(name, 0) + len(complete)
            lines = [
                line
                for line in complete.decode(errors="replace").splitlines()
                if line.startswith(_PROBLEM_PREFIXES)
            ]
            found += [f"{name}: {line}" for line in lines[:limit]]
            if len(lines) > limit:
                found.append(f"{name}: ... {len(lines) - limit} more in {path}")
        return found

    def exited(self) -> list[str]:
        """Names of the processes that have ended."""
        return [name for name, process in self.running if process.poll() is not None]

    def stop_all(self) -> list[str]:
        """Stop every process; returns the ones that had already exited with an error code."""
        failed = [
            f"{name} (exit code {process.returncode})"
            for name, process in self.running
            if process.poll() not in (None, 0)
        ]
        for name, process in reversed(self.running):
            if process.poll() is None:
                process.send_signal(signal.SIGINT)
                try:
                    process.wait(timeout=15)
                except subprocess.TimeoutExpired:
                    print(f"{name} did not stop; killing it")
                    process.kill()
        self.running.clear()
        return failed


def python_main(module: str, *args: str) -> list[str]:
    """``module.main()`` with ARGS, run by this interpreter: works for venv, pip and colcon
    installs alike, with no need for the console scripts on PATH."""
    return [sys.executable, "-c", f"import sys; from {module} import main; sys.exit(main())", *args]


def gnss_ins_command(*args: str) -> list[str]:
    """``gnss_ins ARGS``."""
    return python_main("ins_fusion.tools.cli", *args)
