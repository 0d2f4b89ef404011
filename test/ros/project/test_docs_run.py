"""Docs that are true: every shell block of README.md and docs/*.md a reader is told to run
without hardware runs (in a scratch directory, in page order, each within its time limit), and
every example output on a page is what its commands print now (test/support/docs_pages.py has the
rules and rewrites the examples). Blocks not meant to run are marked with their reason."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest
from support.docs_pages import PAGES, REPO, Session, blocks, differences

#: Anything of these in a block's output fails it, whatever its exit status.
FAILURE = re.compile(
    r"Traceback \(most recent call last\)|command not found|exists already"
    r"|does not exist; \S+ keeps trying"
)


def test_every_command_block_is_marked() -> None:
    unmarked = [
        b.where for page in PAGES for b in blocks(page) if b.has_commands and b.kind is None
    ]
    assert not unmarked, f"command blocks without a docs-test marker: {unmarked}"
    reasonless = [b.where for p in PAGES for b in blocks(p) if b.kind == "skip" and not b.reason]
    assert not reasonless, f"skipped without a reason: {reasonless}"


def run_page(page: Path, scratch: Path, text: str | None = None) -> list[str]:
    """Run the page's blocks in order; the failures (empty: every block ran and every example
    matched)."""
    session = Session(scratch)
    for block in blocks(page, text):
        if block.kind not in ("run", "example"):
            continue
        result = session.run(block)
        tail = "\n".join(result.output.splitlines()[-30:])
        if result.timed_out:
            return [f"{block.where}: still running after its time limit\n{tail}"]
        if result.status != 0:
            return [f"{block.where}: exit status {result.status}\n{tail}"]
        if found := FAILURE.search(result.output):
            start = result.output.count("\n", 0, found.start())
            lines = result.output.splitlines()[max(0, start - 5) : start + 25]
            return [f"{block.where}: printed {found.group()!r}\n" + "\n".join(lines)]
        if block.kind == "example" and (found := differences(block, result.output)):
            return [f"{block.where}: the example differs from the output now:", *found]
    return []


RUN_PAGES = [p for p in PAGES if any(b.kind in ("run", "example") for b in blocks(p))]
#: A command that starts real nodes (a live tool, a node's executable): a page that runs one is
#: tested in the session of the real-time tests; the others beside it.
NODES = re.compile(r"\bgnss_ins (demo|launch|play|record|echo|topics|status|imu-demo)\b|\w_node\b")


def _runs_nodes(page: Path) -> bool:
    return any(
        NODES.search("\n".join(b.lines)) for b in blocks(page) if b.kind in ("run", "example")
    )


def _page(page: Path) -> object:
    """The page as a parameter: marked ros when it runs real nodes, else slow (seconds of
    commands)."""
    return pytest.param(page, marks=pytest.mark.ros if _runs_nodes(page) else pytest.mark.slow)


#: What the session puts in a scratch directory itself.
SESSION_ENTRIES = {"config", "test", ".venv", ".docs_test_env"}


def not_ignored(scratch: Path) -> list[str]:
    """The blocks' outputs at the top of ``scratch`` that the repository's .gitignore does
    not cover (a reader running the page from the repository root would see them untracked)."""
    names = sorted(
        f"{p.name}/" if p.is_dir() else p.name
        for p in scratch.iterdir()
        if p.name not in SESSION_ENTRIES
    )
    ignored = subprocess.run(
        ["git", "check-ignore", "--no-index", "--stdin"],
        cwd=REPO,
        input="\n".join(names),
        capture_output=True,
        text=True,
    ).stdout.split()
    return [name for name in names if name not in ignored]


@pytest.mark.parametrize("page", [_page(p) for p in RUN_PAGES], ids=lambda p: p.name)
def test_the_page_runs_and_its_examples_are_current(page: Path, tmp_path: Path) -> None:
    failures = run_page(page, tmp_path)
    assert not failures, "\n".join(failures)
    if page.name == "README.md":  # a newcomer's first commands leave the clone clean
        assert not not_ignored(tmp_path), f"outputs git does not ignore: {not_ignored(tmp_path)}"


BAGS = REPO / "docs" / "bags.md"


def test_a_stale_number_or_a_failing_command_fails_the_page(tmp_path: Path) -> None:
    text = BAGS.read_text()
    example = next(b for b in blocks(BAGS) if b.kind == "example")
    shown = "\n".join(example.example_split()[1])
    count = re.search(r"^(\d+) messages", shown, re.M)
    assert count is not None
    stale = text.replace(f"\n{count.group(0)}", f"\n{int(count.group(1)) + 20} messages", 1)
    assert stale != text
    (tmp_path / "current").mkdir()
    assert run_page(BAGS, tmp_path / "current", text) == []
    (tmp_path / "stale").mkdir()
    failures = run_page(BAGS, tmp_path / "stale", stale)
    assert failures and "differs" in failures[0] and f"{count.group(0)}" in "\n".join(failures)
    broken = text.replace("$ gnss_ins import-qfree", "$ gnss_ins import-qfree --no-such-option", 1)
    (tmp_path / "broken").mkdir()
    failures = run_page(BAGS, tmp_path / "broken", broken)
    assert failures and "exit status 2" in failures[0]


def test_a_check_run_beside_a_command_decides_its_line(tmp_path: Path) -> None:
    """``until=SCRIPT``: the line marked Ctrl-C runs until the script has ended, is then
    interrupted, and the script's failure is the block's."""
    text = "<!-- docs-test: run until=check.py -->\n```sh\nsleep 600  # Ctrl-C\necho after\n```\n"
    for status in (0, 1):
        scratch = tmp_path / str(status)
        scratch.mkdir()
        (scratch / "check.py").write_text(f"import sys\nsys.exit({status})\n")
        failures = run_page(BAGS, scratch, text)
        if status == 0:
            assert failures == []
        else:
            assert failures and "exit status 1" in failures[0]


def test_a_traceback_fails_a_block_that_exits_0_and_is_shown(tmp_path: Path) -> None:
    text = (
        "<!-- docs-test: run -->\n```sh\n"
        "seq 1 100\necho 'Traceback (most recent call last):'\necho '  the cause'\nseq 1 100\n```\n"
    )
    failures = run_page(BAGS, tmp_path, text)
    assert failures and "printed 'Traceback" in failures[0] and "the cause" in failures[0]
