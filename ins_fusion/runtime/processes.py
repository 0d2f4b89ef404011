"""Child processes of the tools (nodes, recorder, simulator), each logging to its own file.

A group started with a ``Backoff`` supervises its processes: one that ends, whatever its exit
code or signal, is started again with the same command after a delay that doubles with each
failure in a row; the others are not touched. Logs are appended to, never truncated: NAME.log
gets a banner line at each (re)start and is rotated by size (``LogRotation``).
"""

from __future__ import annotations

import os
import shlex
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

#: Console lines of a ROS node (rcutils format) or of Python that report a problem.
_PROBLEM_PREFIXES = ("[WARN]", "[ERROR]", "[FATAL]", "Traceback")


@dataclass(frozen=True)
class Backoff:
    """Restart delays of a supervised process: ``first_s`` after its first failure, doubling with
    each failure in a row up to ``max_s``; the count starts again once it has run
    ``reset_after_s``."""

    first_s: float = 0.5
    max_s: float = 30.0
    reset_after_s: float = 60.0

    def delay_s(self, failures: int) -> float:
        """Delay before the restart after the ``failures``-th failure in a row (1, 2, ...)."""
        return min(self.first_s * 2.0 ** min(max(failures - 1, 0), 64), self.max_s)


@dataclass(frozen=True)
class LogRotation:
    """NAME.log larger than ``max_bytes`` when its process (re)starts becomes NAME.log.1, the
    older ones NAME.log.2 ... NAME.log.KEEP; the one beyond KEEP is deleted."""

    max_bytes: int = 10 * 1024 * 1024
    keep: int = 5

    def __post_init__(self) -> None:
        if self.keep < 1:
            raise ValueError("LogRotation keeps at least one older file")

    def rotate(self, path: Path) -> bool:
        """Rotate ``path`` if it is too large; True if it was."""
        if not path.is_file() or path.stat().st_size <= self.max_bytes:
            return False
        numbered = [path.with_name(f"{path.name}.{index}") for index in range(self.keep + 1)]
        numbered[-1].unlink(missing_ok=True)  # the only log file ever deleted
        for index in range(self.keep - 1, 0, -1):
            if numbered[index].exists():
                numbered[index].rename(numbered[index + 1])
        path.rename(numbered[1])
        return True


def default_log_dir(environ: Mapping[str, str] = os.environ) -> Path:
    """``$XDG_STATE_HOME/gnss_ins/logs``; ``~/.local/state`` when XDG_STATE_HOME is unset, empty
    or relative (the XDG base directory rule)."""
    state = Path(environ.get("XDG_STATE_HOME", ""))
    base = state if state.is_absolute() else Path.home() / ".local" / "state"
    return base / "gnss_ins" / "logs"


def describe_exit(returncode: int) -> str:
    """``code 3`` or ``signal SIGKILL`` (Popen's negative return code)."""
    if returncode >= 0:
        return f"code {returncode}"
    try:
        return f"signal {signal.Signals(-returncode).name}"
    except ValueError:
        return f"signal {-returncode}"


@dataclass
class Child:
    """One process of a group: how to start it again and, when supervised, its restarts."""

    name: str
    command: list[str]
    options: dict[str, Any]
    process: subprocess.Popen[str]
    started_s: float
    #: Bytes of its NAME.log already scanned by ``ProcessGroup.problems``.
    log_offset: int
    #: Times it has been started again.
    restarts: int = 0
    #: Ends in a row (each after less than ``Backoff.reset_after_s`` of running).
    failures: int = 0
    #: When it is due to start again (None: running, or not supervised).
    restart_at_s: float | None = None


class ProcessGroup:
    """Processes stopped with SIGINT (a clean ROS shutdown) in reverse start order, optionally
    supervised (``backoff``; ``poll`` restarts them)."""

    def __init__(
        self,
        log_dir: Path,
        env: Mapping[str, str] | None = None,
        *,
        backoff: Backoff | None = None,
        rotation: LogRotation = LogRotation(),
        clock: Callable[[], float] = time.monotonic,
        stop_timeout_s: float = 15.0,
    ) -> None:
        """``log_dir`` receives NAME.log per process; ``env``: their environment (default: ours);
        ``backoff``: restart the processes that end (None: never); ``clock``: monotonic seconds;
        ``stop_timeout_s``: wait after SIGINT before SIGKILL."""
        log_dir.mkdir(parents=True, exist_ok=True)
        self.log_dir, self.env = log_dir, dict(env) if env is not None else None
        self.backoff, self.rotation, self.clock = backoff, rotation, clock
        self.stop_timeout_s = stop_timeout_s
        #: The processes by name, in start order.
        self.children: dict[str, Child] = {}
        self._stopping = False
        self._pending: list[str] = []  # problem lines of runs whose log moved on before a scan

    def log_path(self, name: str) -> Path:
        """NAME.log of a process."""
        return self.log_dir / f"{name}.log"

    def start(self, name: str, command: Sequence[str], **kwargs: Any) -> subprocess.Popen[str]:
        """Start ``command``; its output is appended to NAME.log unless ``stdout`` is given
        (then its stderr is). Other ``kwargs`` go to Popen."""
        if name in self.children:
            raise ValueError(f"a process named {name} was already started")
        process, offset = self._spawn(name, list(command), kwargs, restart=0)
        self.children[name] = Child(name, list(command), kwargs, process, self.clock(), offset)
        return process

    def _spawn(
        self, name: str, command: list[str], options: Mapping[str, Any], restart: int
    ) -> tuple[subprocess.Popen[str], int]:
        """Rotate NAME.log if due, open it for appending, start the process and write the banner
        (right after the start: a Python child prints nothing before its interpreter is up).
        Returns the process and the log's size before the banner."""
        path = self.log_path(name)
        self.rotation.rotate(path)
        with path.open("a", encoding="utf-8") as log:
            offset = os.fstat(log.fileno()).st_size
            popen: dict[str, Any] = {"env": self.env, "text": True, "stdout": log}
            popen["stderr"] = subprocess.STDOUT if "stdout" not in options else log
            popen.update(options)
            process = subprocess.Popen(command, **popen)
            again = f", restart {restart}" if restart else ""
            log.write(f"=== {_utc_now()} {name} started (pid {process.pid}{again}): ")
            log.write(f"{shlex.join(command)}\n")
        return process, offset

    def poll(self) -> list[str]:
        """One supervision step (call it a few times a second): schedule the restart of each
        process that ended and start those that are due. Returns console lines (nothing when not
        supervised or stopping)."""
        if self.backoff is None or self._stopping:
            return []
        lines: list[str] = []
        now = self.clock()
        for child in self.children.values():
            if child.restart_at_s is None:
                line = self._check(child, self.backoff, now)
            elif now >= child.restart_at_s:
                line = self._restart(child, self.backoff, now)
            else:
                continue
            if line:
                lines.append(line)
        return lines

    def _check(self, child: Child, backoff: Backoff, now: float) -> str | None:
        """Schedule the restart of ``child`` if it ended; the line saying so."""
        ran_s = now - child.started_s
        returncode = child.process.poll()
        if returncode is None:
            if ran_s >= backoff.reset_after_s:
                child.failures = 0
            return None
        child.failures = 1 if ran_s >= backoff.reset_after_s else child.failures + 1
        delay_s = backoff.delay_s(child.failures)
        child.restart_at_s = now + delay_s
        line = (
            f"{child.name} exited ({describe_exit(returncode)}) after {ran_s:.1f} s; "
            f"restart {child.restarts + 1} in {delay_s:.1f} s"
        )
        self._note(child.name, line)
        return line

    def _restart(self, child: Child, backoff: Backoff, now: float) -> str:
        """Start ``child`` again with its command; the line saying so."""
        self._pending += self._scan(child)  # the end of the run's log, before it moves on
        try:
            process, offset = self._spawn(
                child.name, child.command, child.options, child.restarts + 1
            )
        except OSError as exc:
            child.failures += 1
            delay_s = backoff.delay_s(child.failures)
            child.restart_at_s = now + delay_s
            return f"{child.name} could not be started ({exc}); next try in {delay_s:.1f} s"
        child.process, child.log_offset, child.started_s = process, offset, now
        child.restarts += 1
        child.restart_at_s = None
        return f"{child.name} restarted (pid {process.pid})"

    def _note(self, name: str, line: str) -> None:
        """Append a supervisor's line to NAME.log."""
        with self.log_path(name).open("a", encoding="utf-8") as log:
            log.write(f"=== {_utc_now()} {line}\n")

    def state(self) -> dict[str, dict[str, Any]]:
        """Each process's pid, restarts, whether it runs and its last (re)start [``clock`` s]
        (``supervisor.json``)."""
        return {
            name: {
                "pid": child.process.pid,
                "restarts": child.restarts,
                "running": child.process.poll() is None,
                "started_s": round(child.started_s, 3),
            }
            for name, child in self.children.items()
        }

    def running_since(self) -> dict[str, float]:
        """Each running process's last (re)start [``clock`` s]."""
        return {
            name: child.started_s
            for name, child in self.children.items()
            if child.restart_at_s is None and child.process.poll() is None
        }

    def kill(self, name: str, why: str) -> str:
        """SIGKILL a running process that no longer works (``why``); ``poll`` then restarts it
        as any process that ended. The line saying so, also in its log."""
        self.children[name].process.kill()
        line = f"{name} killed: {why}"
        self._note(name, line)
        return line

    def restarts(self) -> dict[str, int]:
        """How many times each process was started again."""
        return {name: child.restarts for name, child in self.children.items()}

    def problems(self, limit: int = 3) -> list[str]:
        """New WARN/ERROR/FATAL lines (and tracebacks) of the processes' logs since the last
        call, as ``NAME: line``; at most ``limit`` per process and run, the rest counted. Lines
        in NAME.log before the process started are not read."""
        found, self._pending = self._pending, []
        for child in self.children.values():
            found += self._scan(child, limit)
        return found

    def _scan(self, child: Child, limit: int = 3) -> list[str]:
        """Problem lines of ``child``'s log past its offset (complete lines only)."""
        path = self.log_path(child.name)
        try:
            with path.open("rb") as log:
                log.seek(child.log_offset)
                text = log.read()
        except FileNotFoundError:
            return []
        complete = text[: text.rfind(b"\n") + 1]  # a line still being written waits
        child.log_offset += len(complete)
        lines = [
            line
            for line in complete.decode(errors="replace").splitlines()
            if line.startswith(_PROBLEM_PREFIXES)
        ]
        found = [f"{child.name}: {line}" for line in lines[:limit]]
        if len(lines) > limit:
            found.append(f"{child.name}: ... {len(lines) - limit} more in {path}")
        return found

    def exited(self) -> list[str]:
        """Names of the processes that have ended (and not been started again)."""
        return [name for name, child in self.children.items() if child.process.poll() is not None]

    def stop_all(self) -> list[str]:
        """Stop every process (none is restarted after this); returns the ones that had already
        exited with an error code."""
        self._stopping = True
        failed = [
            f"{name} (exit code {child.process.returncode})"
            for name, child in self.children.items()
            if child.process.poll() not in (None, 0)
        ]
        for name, child in reversed(self.children.items()):
            child.restart_at_s = None
            process = child.process
            if process.poll() is None:
                process.send_signal(signal.SIGINT)
                how = "stopped"
                try:
                    process.wait(timeout=self.stop_timeout_s)
                except subprocess.TimeoutExpired:
                    print(f"{name} did not stop; killing it", flush=True)
                    process.kill()
                    process.wait()
                    how = f"killed (no stop within {self.stop_timeout_s:g} s)"
                ran_s = self.clock() - child.started_s
                # The log's last line: how the run ended, as its banner says how it began.
                self._note(
                    name,
                    f"{name} {how} by the supervisor ({describe_exit(process.returncode)})"
                    f" after {ran_s:.1f} s",
                )
        return failed


def _utc_now() -> str:
    """The time now in UTC, ISO 8601 to the second."""
    return datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ")


def python_main(module: str, *args: str) -> list[str]:
    """``module.main()`` with ARGS, run by this interpreter: works for venv, pip and colcon
    installs alike, with no need for the console scripts on PATH; a Ctrl-C while it imports ends
    it quietly (gnss_ins_common.quiet_start)."""
    program = f"import sys; from gnss_ins_common.quiet_start import run; sys.exit(run({module!r}))"
    return [sys.executable, "-c", program, *args]


def gnss_ins_command(*args: str) -> list[str]:
    """``gnss_ins ARGS``."""
    return python_main("ins_fusion.tools.cli", *args)
