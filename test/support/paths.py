"""The repository's folders, for tests at any depth of test/."""

from __future__ import annotations

from pathlib import Path

#: The repository root.
REPO = Path(__file__).resolve().parents[2]
#: test/, the root of the test tree (holds the support package).
TESTS = REPO / "test"
#: Recorded inputs the tests replay (test/fixtures/*/README.md say where each comes from).
FIXTURES = TESTS / "fixtures"
#: The shipped configuration files.
CONFIG = REPO / "config"
