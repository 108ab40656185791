"""No import circles and no repeated code between source files (issue 15's house plan)."""

from __future__ import annotations

import ast
import contextlib
import io
import re
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _import_cycles() -> list[list[str]]:
    """Strongly connected groups of more than one module in trainsim's import graph (grimp)."""
    import grimp

    graph = grimp.build_graph("trainsim", exclude_type_checking_imports=True)
    modules = sorted(graph.modules)
    imports = {m: sorted(graph.find_modules_directly_imported_by(m)) for m in modules}
    # Tarjan's algorithm, iterative so that deep chains cannot hit the recursion limit
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles: list[list[str]] = []
    counter = 0
    for root in modules:
        if root in index:
            continue
        work = [(root, 0)]
        while work:
            node, i = work.pop()
            if i == 0:
                index[node] = low[node] = counter
                counter += 1
                stack.append(node)
                on_stack.add(node)
            targets = imports[node]
            if i < len(targets):
                work.append((node, i + 1))
                target = targets[i]
                if target not in index:
                    work.append((target, 0))
                elif target in on_stack:
                    low[node] = min(low[node], index[target])
                continue
            if low[node] == index[node]:
                group = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    group.append(member)
                    if member == node:
                        break
                if len(group) > 1:
                    cycles.append(sorted(group))
            if work:
                parent = work[-1][0]
                low[parent] = min(low[parent], low[node])
    return cycles


def test_no_import_circles():
    assert _import_cycles() == []


def _left_out_lines(text: str) -> set[int]:
    """The lines (1-based) pylint's similarity checker leaves out with ``--ignore-imports=y`` and its
    default ``--ignore-signatures=y``: every import statement, and every function's decorators and
    signature (from the first decorator to the line before the body), functions being those in the
    bodies of the module, its classes and its functions, as pylint finds them.

    The same sets as pylint's from its astroid trees (checked for every file of src/, tests/ and
    benchmarks/ when this was written), from the standard library's parser: building astroid trees
    of the whole package took most of the check's time (about 25 s on CI)."""
    tree = ast.parse(text)
    lines: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import | ast.ImportFrom):
            lines.update(range(node.lineno, (node.end_lineno or node.lineno) + 1))

    def functions(parent: ast.AST) -> Iterator[ast.FunctionDef | ast.AsyncFunctionDef]:
        for child in getattr(parent, "body", []):
            if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef):
                yield child
            if isinstance(child, ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef):
                yield from functions(child)

    for func in functions(tree):
        first = min([func.lineno] + [d.lineno for d in func.decorator_list])
        lines.update(range(first, func.body[0].lineno if func.body else (func.end_lineno or func.lineno) + 1))
    return lines


def test_no_repeated_code_between_source_files():
    # pylint's duplicate-code finder (its Symilar, as ``pylint --disable=all --enable=duplicate-code
    # --min-similarity-lines=6 --ignore-imports=y --ignore-docstrings=y --ignore-comments=y`` runs it):
    # no pair of files may share more than two runs of six or more identical lines (imports,
    # signatures, docstrings and comments aside). Unlike pylint it honours no "pylint: disable"
    # comment (src/ has none)
    pytest.importorskip("pylint")
    from pylint.checkers.symilar import LineSet, Symilar

    sims = Symilar(min_lines=6, ignore_comments=True, ignore_docstrings=True)
    package = ROOT / "src"
    for path in sorted((package / "trainsim").rglob("*.py")):
        parts = path.relative_to(package).with_suffix("").parts
        module = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        text = path.read_text(encoding="utf-8")
        left_out = _left_out_lines(text)
        sims.linesets.append(
            LineSet(
                module,
                text.splitlines(keepends=True),
                ignore_comments=True,
                ignore_docstrings=True,
                line_enabled_callback=lambda _msg, line, left_out=left_out: line not in left_out,
            )
        )
    report = io.StringIO()
    with contextlib.redirect_stdout(report):
        sims.run()
    pairs: dict[tuple[str, ...], int] = {}
    for block in report.getvalue().split(" similar lines in ")[1:]:
        files = tuple(sorted(set(re.findall(r"^==([\w.]+):", block, flags=re.MULTILINE))))
        pairs[files] = pairs.get(files, 0) + 1
    too_many = {pair: n for pair, n in pairs.items() if n > 2}
    assert not too_many, too_many
