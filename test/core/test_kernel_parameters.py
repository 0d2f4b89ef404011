"""No function of the fusion core takes more than MAX_POSITIONAL positional parameters (self and
cls aside): what a kernel reads beyond that goes into a named record (a NamedTuple numba
compiles, as sample_runs.RunSettings, solution.RowModel) or a field of a named layout (as the
intake array's S_READING_*)."""

from __future__ import annotations

import ast

from support.paths import REPO

CORE = REPO / "ins_fusion" / "core"
MAX_POSITIONAL = 8


def too_many(source: str, limit: int = MAX_POSITIONAL) -> list[tuple[str, int]]:
    """(name, count) of each function in ``source`` with more than ``limit`` positional
    parameters (a leading self or cls not counted; *args counts as one more than the limit)."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            continue
        args = [*node.args.posonlyargs, *node.args.args]
        count = len(args) - (1 if args and args[0].arg in ("self", "cls") else 0)
        if node.args.vararg is not None:
            count = max(count, limit + 1)
        if count > limit:
            found.append((node.name, count))
    return found


def test_the_check_sees_a_long_signature() -> None:
    source = "def f(a, b, c):\n    pass\nclass C:\n    def g(self, a, b):\n        pass\n"
    assert too_many(source, limit=2) == [("f", 3)]
    assert too_many("def h(*values):\n    pass\n", limit=2) == [("h", 3)]


def test_no_core_function_takes_more_than_eight_positional_parameters() -> None:
    found = {
        path.relative_to(CORE).as_posix(): too_many(path.read_text(encoding="utf-8"))
        for path in sorted(CORE.rglob("*.py"))
    }
    assert len(found) > 40
    assert {path: names for path, names in found.items() if names} == {}
