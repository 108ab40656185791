"""No import circles and no repeated code between source files (issue 15's house plan)."""

from __future__ import annotations

import re
import subprocess
import sys
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


def test_no_repeated_code_between_source_files():
    # pylint's duplicate-code finder: no pair of files may share more than two runs of six or more
    # identical lines (imports, docstrings and comments aside)
    pytest.importorskip("pylint")
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "pylint",
            "--disable=all",
            "--enable=duplicate-code",
            "--min-similarity-lines=6",
            "--ignore-imports=y",
            "--ignore-docstrings=y",
            "--ignore-comments=y",
            str(ROOT / "src" / "trainsim"),
        ],
        capture_output=True,
        text=True,
        timeout=900,
    )
    pairs: dict[tuple[str, ...], int] = {}
    for block in proc.stdout.split("R0801")[1:]:
        files = tuple(sorted(set(re.findall(r"^==([\w.]+):", block, flags=re.MULTILINE))))
        pairs[files] = pairs.get(files, 0) + 1
    too_many = {pair: n for pair, n in pairs.items() if n > 2}
    assert not too_many, too_many
