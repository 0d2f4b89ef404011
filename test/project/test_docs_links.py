"""Every relative Markdown link of README.md, ARCHITECTURE.md and docs/*.md resolves inside the
repository (file and #anchor), the prose names no file that is not shipped and no internal issue
number, and `gnss_ins --version` matches the package's declared version and license files agree."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest
from support.paths import REPO

DOCS = [REPO / "README.md", REPO / "ARCHITECTURE.md", *sorted((REPO / "docs").glob("*.md"))]
LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")
CODE = re.compile(r"```.*?```|`[^`\n]*`", re.DOTALL)  # code is not a link


def _targets(text: str) -> list[str]:
    """Relative link targets (no scheme, not a bare #anchor) outside code."""
    found = LINK.findall(CODE.sub("", text))
    return [t for t in found if not re.match(r"[a-z]+:|#", t)]


#: Prose that points at what a clone does not have: the project's internal notes and issues.
UNSHIPPED = re.compile(r"shared/reference|[a-z-]+-notes\.md|\bissues? \d+|\bissue-\d+", re.I)


def _anchors(text: str) -> set[str]:
    """GitHub's anchors of a Markdown text: each heading's slug (repeats get -1, -2, ...) and
    every explicit ``<a id="...">``."""
    found: set[str] = set(re.findall(r'<a id="([^"]+)">', text))
    seen: dict[str, int] = {}
    for heading in re.findall(r"^#+ (.+)$", re.sub(r"```.*?```", "", text, flags=re.S), re.M):
        slug = re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")
        found.add(f"{slug}-{seen[slug]}" if slug in seen else slug)
        seen[slug] = seen.get(slug, 0) + 1
    return found


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.name)
def test_relative_links_resolve_inside_the_repository(doc):
    text = doc.read_text()
    for target in [*_targets(text), *re.findall(r"\]\((#[^)\s]+)\)", CODE.sub("", text))]:
        file, _, anchor = target.partition("#")
        path = (doc.parent / file).resolve() if file else doc
        assert path.is_relative_to(REPO), f"{doc.name}: {target} points outside the repository"
        assert path.exists(), f"{doc.name}: {target} does not exist"
        if anchor and path.suffix == ".md":
            assert anchor in _anchors(path.read_text()), f"{doc.name}: no anchor {target}"


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.name)
def test_prose_names_nothing_a_clone_lacks(doc):
    found = [m.group(0) for m in UNSHIPPED.finditer(doc.read_text())]
    assert not found, f"{doc.name}: {found}"


def test_link_check_catches_a_broken_and_an_outside_link():
    text = "[a](../shared/x.md) [b](docs/none.md) [c](https://x.org) [d](#top) `f[i](x)`"
    assert _targets(text) == ["../shared/x.md", "docs/none.md"]
    assert _anchors("# A b\n## Speed (C++)\n## A b\n") == {"a-b", "speed-c", "a-b-1"}
    assert UNSHIPPED.search("see shared/reference/x") and UNSHIPPED.search("(issue 5)")
    assert not UNSHIPPED.search("an issue with 5 GNSS fixes")


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
