"""Every relative Markdown link of README.md and docs/*.md resolves inside the repository, and
`gnss_ins --version` matches the package's declared version and license files agree."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
DOCS = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]
LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")
CODE = re.compile(r"```.*?```|`[^`\n]*`", re.DOTALL)  # code is not a link


def _targets(text: str) -> list[str]:
    """Relative link targets (no scheme, not a bare #anchor) outside code."""
    found = LINK.findall(CODE.sub("", text))
    return [t for t in found if not re.match(r"[a-z]+:|#", t)]


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.name)
def test_relative_links_resolve_inside_the_repository(doc):
    for target in _targets(doc.read_text()):
        path = (doc.parent / target.split("#")[0]).resolve()
        assert path.is_relative_to(REPO), f"{doc.name}: {target} points outside the repository"
        assert path.exists(), f"{doc.name}: {target} does not exist"


def test_link_check_catches_a_broken_and_an_outside_link():
    text = "[a](../shared/x.md) [b](docs/none.md) [c](https://x.org) [d](#top) `f[i](x)`"
    assert _targets(text) == ["../shared/x.md", "docs/none.md"]


def test_version_and_license_agree():
    version = re.search(r'version="([^"]+)"', (REPO / "setup.py").read_text()).group(1)
    package = (REPO / "package.xml").read_text()
    assert f"<version>{version}</version>" in package
    out = subprocess.run(
        [Path(sys.executable).parent / "gnss_ins", "--version"], capture_output=True, text=True
    )
    assert (out.returncode, out.stdout.strip()) == (0, f"gnss_ins {version}")
    assert "<license>Apache-2.0</license>" in package
    assert 'license="Apache-2.0"' in (REPO / "setup.py").read_text()
    assert "Version 2.0, January 2004" in (REPO / "LICENSE").read_text()
