"""First line of defence: bounds on every document the web application accepts, before the core sees it.

The core validates meaning (a mass is > 0, positions increase); this module bounds size, so that no
request can make the core allocate or loop without limit: nesting depth, nodes in a document,
entries per list, string length, number magnitude (finite, at most ``max_number_magnitude``) and
vehicle counts (``formation[i].count`` summed over the formation). The same checks run on ``PUT``
bodies, uploaded files (after parsing) and the examples, so a document accepted by one path is
accepted by every other.

Each problem found is a :class:`trainsim.errors.Problem` naming the field; a document with problems
raises one :class:`trainsim.errors.InputError` with all of them (at most 20).
"""

from __future__ import annotations

import datetime
import math
from typing import Any

from trainsim.errors import InputError, Problem
from trainsim.web.config import WebSettings

__all__ = ["MAX_PROBLEMS", "check_document", "max_depth"]

#: problems reported per document; past that the check stops
MAX_PROBLEMS = 20
#: keys in one mapping (the formats have a few dozen at most)
MAX_KEYS = 1000


def _path(parts: list[str | int]) -> str:
    text = ""
    for part in parts:
        text += f"[{part}]" if isinstance(part, int) else ("." if text else "") + str(part)
    return text


def max_depth(data: Any, limit: int) -> int:
    """Nesting depth of a JSON-like document, counted without recursion; stops past ``limit``."""
    deepest = 0
    stack: list[tuple[Any, int]] = [(data, 1)]
    while stack:
        node, depth = stack.pop()
        deepest = max(deepest, depth)
        if deepest > limit:
            return deepest
        if isinstance(node, dict):
            stack.extend((v, depth + 1) for v in node.values())
        elif isinstance(node, list | tuple):
            stack.extend((v, depth + 1) for v in node)
    return deepest


def check_document(data: Any, limits: WebSettings, file: str | None = None) -> None:
    """Raise :class:`InputError` if ``data`` (a parsed JSON / YAML document) exceeds a bound.

    Walks the document iteratively (deep documents cannot exhaust the stack) and stops after
    ``limits.max_document_nodes`` nodes or :data:`MAX_PROBLEMS` problems.
    """
    problems: list[Problem] = []
    if max_depth(data, limits.max_depth) > limits.max_depth:
        raise InputError(
            "document nested too deeply",
            file=file,
            allowed=f"at most {limits.max_depth} levels of mappings and lists",
        )
    magnitude = limits.max_number_magnitude
    nodes = 0
    vehicles = 0
    stack: list[tuple[Any, list[str | int]]] = [(data, [])]
    while stack and len(problems) < MAX_PROBLEMS:
        node, path = stack.pop()
        nodes += 1
        if nodes > limits.max_document_nodes:
            problems.append(
                Problem(
                    "document too large",
                    file=file,
                    allowed=f"at most {limits.max_document_nodes} values in one document",
                )
            )
            break
        if isinstance(node, dict):
            if len(node) > MAX_KEYS:
                problems.append(
                    Problem(
                        "too many keys",
                        file=file,
                        field=_path(path) or None,
                        value=len(node),
                        allowed=f"at most {MAX_KEYS}",
                    )
                )
                continue
            for key, value in node.items():
                if not isinstance(key, str | int | float | bool) or key is None:
                    problems.append(Problem("keys must be text", file=file, field=_path(path) or None))
                    continue
                stack.append((value, [*path, str(key)]))
        elif isinstance(node, list | tuple):
            if len(node) > limits.max_list_items:
                problems.append(
                    Problem(
                        "too many entries",
                        file=file,
                        field=_path(path) or None,
                        value=len(node),
                        allowed=f"at most {limits.max_list_items}",
                    )
                )
                continue
            stack.extend((v, [*path, i]) for i, v in enumerate(node))
        elif isinstance(node, bool | datetime.date) or node is None:
            continue  # (YAML reads unquoted dates as dates; the core says where they are not allowed)
        elif isinstance(node, int | float):
            value = float(node) if not isinstance(node, int) or abs(node) < 10**300 else math.inf
            if not math.isfinite(value) or abs(value) > magnitude:
                problems.append(
                    Problem(
                        "number out of range",
                        file=file,
                        field=_path(path) or None,
                        value=node if isinstance(node, float) else f"{float(value):g}",
                        allowed=f"a finite number between -{magnitude:g} and {magnitude:g}",
                    )
                )
                continue
            if path and path[-1] == "count":
                if value != int(value) or value < 0:
                    continue  # the core names what a count may be
                vehicles += int(value)
                if vehicles > limits.max_vehicles:
                    problems.append(
                        Problem(
                            "too many vehicles in the formation",
                            file=file,
                            field=_path(path),
                            value=node,
                            allowed=f"at most {limits.max_vehicles} vehicles in a train",
                        )
                    )
        elif isinstance(node, str):
            if len(node) > limits.max_string_chars:
                problems.append(
                    Problem(
                        "text too long",
                        file=file,
                        field=_path(path) or None,
                        value=f"{len(node)} characters",
                        allowed=f"at most {limits.max_string_chars} characters",
                    )
                )
        else:
            problems.append(
                Problem(
                    "unexpected value",
                    file=file,
                    field=_path(path) or None,
                    value=type(node).__name__,
                    allowed="text, numbers, true/false, lists and mappings",
                )
            )
    if problems:
        raise InputError.from_problems(problems, file=file)
