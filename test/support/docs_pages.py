"""The shell blocks of README.md and docs/*.md, run as a reader runs them, and their example
outputs compared with what the commands print now (test/ros/project/test_docs_run.py); also the
script that rewrites those examples from real runs:

    .venv/bin/python test/support/docs_pages.py docs/replay.md ...     # rewrites their examples

A fenced block with commands (``sh``/``bash``/no language, a line starting with ``$ ``,
``gnss_ins``, ``.venv/bin/``, ``ros2 ``, ``sudo `` ...) carries a marker on the line before it:

- ``<!-- docs-test: run [timeout=S] -->``: run in the page's scratch directory (a copy of the
  repository root's ``config``, ``test`` and ``.venv`` as links), after the page's earlier
  blocks, in one bash session per block whose exports carry over; a line whose comment says
  ``Ctrl-C`` gets SIGINT after CTRL_C_S seconds, as a reader would press it, or, with the
  option ``until=SCRIPT``, once the Python script SCRIPT (run beside it) has ended, whose exit
  status is then the line's (a check of what the command does while it runs); background jobs
  left at the end are stopped.
- ``<!-- docs-test: example [from=REGEX] [ignore=REGEX] [tolerance=PCT] -->``: ``$ `` lines
  (with ``\\`` continuations) and their printed output (stdout and stderr); the output must
  match line by line: text exactly (runs of spaces as one), numbers within PCT percent
  (default TOLERANCE_PCT) or two units of their last printed digit, parts matching ``ignore``
  (wall times) not compared, a ``...`` line for any lines; ``from``: the example shows the
  output from the first line matching REGEX on.
- ``<!-- docs-test: skip REASON -->``: not run (hardware, root, systemd, a laboratory record,
  a synopsis); the reason is required.
"""

from __future__ import annotations

import contextlib
import os
import random
import re
import shlex
import signal
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
PAGES = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]
#: Default numeric tolerance of an example [%].
TOLERANCE_PCT = 3.0
#: Seconds after which a ``# Ctrl-C`` line is interrupted.
CTRL_C_S = 15.0
#: Time limit of a block without ``timeout=`` [s].
TIMEOUT_S = 120.0
#: What the test sets that the pages do not show: a demo's drive capped (real time; 30 s of the
#: test pattern's standstill leave the 10 s alignment room when the live nodes start late on a
#: loaded machine, as test_demo_output's short demo shows), output unbuffered (stdout and
#: stderr in the order printed), a ROS domain of its own.
HIDDEN_ENV = {"GNSS_INS_DEMO_DURATION_LIMIT_S": "30", "PYTHONUNBUFFERED": "1", "MPLBACKEND": "Agg"}

_MARKER = re.compile(r"<!--\s*docs-test:\s*(run|example|skip)\b(.*?)-->")
_FENCE = re.compile(r"^```(\w*)\s*$")
_COMMAND = re.compile(r"^\s*(\$ |gnss_ins\b|\.venv/bin/|ros2 |sudo |B=|\$B/|timeout |make )")
_NUMBER = re.compile(r"[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?")


@dataclass
class Block:
    """A fenced block of a page: its first line number (1-based), language, lines and marker."""

    page: Path
    line: int
    language: str
    lines: list[str]
    kind: str | None = None  # run, example, skip; None: no marker
    options: dict[str, str] = field(default_factory=dict)
    reason: str = ""

    @property
    def where(self) -> str:
        return f"{self.page.name}:{self.line}"

    @property
    def has_commands(self) -> bool:
        return self.language in ("", "sh", "bash") and any(map(_COMMAND.match, self.lines))

    def commands(self) -> str:
        """The shell text: the whole block (run) or its ``$`` lines and continuations."""
        if self.kind == "run":
            return "\n".join(self.lines)
        return "\n".join(line.removeprefix("$ ") for line in self.example_split()[0])

    def example_split(self) -> tuple[list[str], list[str]]:
        """(command lines, output lines) of an example."""
        commands: list[str] = []
        rest = list(self.lines)
        while rest and (rest[0].startswith("$ ") or (commands and commands[-1].endswith("\\"))):
            commands.append(rest.pop(0))
        return commands, rest


def _options(text: str) -> tuple[dict[str, str], list[str]]:
    """``key=value`` options (values may be quoted) and the other words."""
    options, words = {}, []
    for word in shlex.split(text):
        key, sep, value = word.partition("=")
        if sep and key in ("timeout", "from", "ignore", "tolerance", "until"):
            options[key] = value
        else:
            words.append(word)
    return options, words


def blocks(page: Path, text: str | None = None) -> list[Block]:
    """The fenced blocks of ``page`` (or of ``text`` as that page) with their markers."""
    lines = (page.read_text() if text is None else text).splitlines()
    found: list[Block] = []
    i = 0
    while i < len(lines):
        fence = _FENCE.match(lines[i])
        if not fence:
            i += 1
            continue
        end = next(j for j in range(i + 1, len(lines)) if lines[j].startswith("```"))
        block = Block(page, i + 1, fence.group(1), lines[i + 1 : end])
        if i and (marker := _MARKER.search(lines[i - 1])):
            block.kind, text = marker.group(1), marker.group(2).strip()
            if block.kind == "skip":
                block.reason = text
            else:
                block.options, _ = _options(text)
        found.append(block)
        i = end + 1
    return found


@dataclass
class Result:
    """What a block printed (stdout and stderr, in order) and its exit status."""

    output: str
    status: int
    timed_out: bool = False


class Session:
    """A page's scratch directory and environment: its blocks run there in order."""

    def __init__(self, root: Path) -> None:
        self.root = root
        venv = Path(sys.executable).parent.parent
        for name, target in (("config", REPO / "config"), ("test", REPO / "test"), (".venv", venv)):
            (root / name).symlink_to(target)
        self.state = root / ".docs_test_env"
        env = dict(os.environ)
        bin_dir = str(venv / "bin")
        env["PATH"] = os.pathsep.join(p for p in env["PATH"].split(os.pathsep) if p != bin_dir)
        env.update(HIDDEN_ENV)
        env["ROS_DOMAIN_ID"] = str(random.SystemRandom().randint(1, 100))
        env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
        self.env = env

    def run(self, block: Block) -> Result:
        """Run a run or example block; on its time limit the block's processes are killed."""
        script = "\n".join(
            [
                "set -m",  # job control as in a terminal: background jobs take SIGINT
                f"[ -f {self.state} ] && . {self.state}",
                f"trap 'rc=$?; export -p > {self.state}; jobs -p | xargs -r kill; exit $rc' EXIT",
                "set -e",
                *(
                    _interruptible(line, block.options.get("until"))
                    for line in block.commands().splitlines()
                ),
            ]
        )
        limit = float(block.options.get("timeout", TIMEOUT_S))
        process = subprocess.Popen(
            ["bash", "-c", script],
            cwd=self.root,
            env=self.env,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            start_new_session=True,
            # As in a terminal, Ctrl-C interrupts: a test process started in the background of a
            # shell (make's two sessions) ignores SIGINT, and the block would inherit that.
            preexec_fn=_default_interrupt,
        )
        try:
            output, _ = process.communicate(timeout=limit)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            output, _ = process.communicate()
            return Result(output, -1, timed_out=True)
        finally:
            with contextlib.suppress(ProcessLookupError):  # what a block left behind
                os.killpg(process.pid, signal.SIGKILL)
        return Result(output, process.returncode)


def _default_interrupt() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _interruptible(line: str, until: str | None = None) -> str:
    """A line whose comment says Ctrl-C, interrupted after CTRL_C_S s, or once the script
    ``until`` has ended and then failing as it failed (its exit status 0 or 130 accepted)."""
    command, hash_, comment = line.partition(" #")
    if not hash_ or "Ctrl-C" not in comment or command.rstrip().endswith(("&", "\\")):
        return line
    if until is None:
        return (
            f"{{ timeout --preserve-status -s INT {CTRL_C_S:g} {command.strip()}"
            " || [ $? -eq 130 ]; }"
        )
    return (
        f"{{ {command.strip()} & running=$!; .venv/bin/python {until} && checked=0 || checked=$?;"
        " kill -INT $running; wait $running || [ $? -eq 130 ]; [ $checked -eq 0 ]; }"
    )


def _masked(line: str, ignore: str | None) -> str:
    if ignore:
        line = re.sub(ignore, "<ignored>", line)
    return " ".join(line.split())


def _numbers_match(shown: str, actual: str, tolerance_pct: float) -> bool:
    a, b = _NUMBER.findall(shown), _NUMBER.findall(actual)
    if _NUMBER.sub("#", shown) != _NUMBER.sub("#", actual) or len(a) != len(b):
        return False
    for page_number, printed in zip(a, b, strict=True):
        digits = page_number.split("e")[0].partition(".")[2]
        unit = 10.0 ** -len(digits)
        allowed = max(abs(float(page_number)) * tolerance_pct / 100.0, 2.0 * unit)
        if abs(float(page_number) - float(printed)) > allowed:
            return False
    return True


def shown_output(block: Block, printed: str) -> list[str]:
    """The output lines an example shows of ``printed``: all, or from its ``from`` line on
    after a ``...`` line."""
    lines = [line.rstrip() for line in printed.splitlines()]
    start = block.options.get("from")
    if start is None:
        return lines
    first = next((i for i, line in enumerate(lines) if re.search(start, line)), None)
    return ["...", *lines[first:]] if first is not None else lines


def differences(block: Block, printed: str) -> list[str]:
    """How an example's output differs from ``printed`` (empty: it matches)."""
    ignore = block.options.get("ignore")
    tolerance = float(block.options.get("tolerance", TOLERANCE_PCT))
    actual = [_masked(line, ignore) for line in printed.splitlines()]
    position = 0
    gap = False
    problems: list[str] = []
    for shown_line in block.example_split()[1]:
        if shown_line.strip() in ("...", "(...)"):
            gap = True
            continue
        shown = _masked(shown_line, ignore)
        candidates = range(position, len(actual)) if gap else range(position, position + 1)
        match = next(
            (
                i
                for i in candidates
                if i < len(actual) and _numbers_match(shown, actual[i], tolerance)
            ),
            None,
        )
        if match is None:
            now = actual[position] if position < len(actual) else "(end of output)"
            problems.append(f"page: {shown_line.strip()}\n    now: {now}")
            break
        position, gap = match + 1, False
    return problems


def rewrite(page: Path) -> int:
    """Run ``page``'s blocks in order and write each example's output as printed now; returns
    the number of examples rewritten."""
    lines = page.read_text().splitlines()
    edits: list[tuple[int, int, list[str]]] = []  # first output line (0-based), old length, new
    with tempfile.TemporaryDirectory(prefix="docs_") as scratch:
        session = Session(Path(scratch))
        for block in blocks(page):
            if block.kind not in ("run", "example"):
                continue
            result = session.run(block)
            if result.status != 0:
                raise SystemExit(f"{block.where} failed ({result.status}):\n{result.output}")
            if block.kind == "example":
                commands, old = block.example_split()
                edits.append(
                    (block.line + len(commands), len(old), shown_output(block, result.output))
                )
    for start, length, new in reversed(edits):
        lines[start : start + length] = new
    page.write_text("\n".join(lines) + "\n")
    return len(edits)


if __name__ == "__main__":
    for name in sys.argv[1:]:
        print(f"{name}: {rewrite(Path(name).resolve())} example(s) written")
