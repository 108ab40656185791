"""Dotted paths into a scenario's data: ``train.formation[1].load_t``, ``route.stations[name=S2].dwell_s``.

A study varies a scenario by writing values into its YAML data (plain dicts and lists) BEFORE
validation, so that every value of a sweep goes through the normal file reader and its checks.

Grammar: segments separated by ``.``; a segment is a mapping key, optionally followed by any number of
selectors in brackets:

* ``[2]``: the list item at index 2 (negative indices count from the end);
* ``[*]``: every item of the list (``train.formation[*].load_t`` sets the load of every vehicle type);
* ``[name=S2]``: the list item(s) whose ``name`` is ``S2`` (any key: ``[id=7]``).

Mapping keys that do not exist yet are created when a value is set (``dwell_s.S2`` with no ``dwell_s``
in the scenario); list items are never created.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Any

from trainsim.errors import InputError

__all__ = ["Path", "Selector", "get_values", "parse_path", "set_value"]


@dataclass(frozen=True)
class Selector:
    """One step of a path: a mapping key (``key``), a list index (``index``), every list item
    (``every``) or the list items whose ``match_key`` equals ``match_value``."""

    key: str | None = None
    index: int | None = None
    every: bool = False
    match_key: str | None = None
    match_value: str | None = None

    def __str__(self) -> str:
        if self.key is not None:
            return self.key
        if self.index is not None:
            return f"[{self.index}]"
        if self.every:
            return "[*]"
        return f"[{self.match_key}={self.match_value}]"


@dataclass(frozen=True)
class Path:
    """A parsed dotted path; ``text`` is how it was written."""

    text: str
    steps: tuple[Selector, ...]

    @property
    def root(self) -> str:
        """The first key: ``train``, ``route``, ``settings``, ``stops``, ``dwell_s``, ``driving``, ``model`` or
        ``multi_point``."""
        return self.steps[0].key or ""

    def tail(self) -> Path:
        """The path without its root key (relative to the train, route... data)."""
        steps = self.steps[1:]
        text = "".join(("." + str(s)) if s.key is not None else str(s) for s in steps).lstrip(".")
        return Path(text, steps)


def _bad(text: str, why: str) -> InputError:
    return InputError(
        f"invalid field path: {why}",
        value=text,
        allowed="keys separated by '.', list items as [2], [*] or [name=S2], e.g. train.formation[1].load_t",
    )


@lru_cache(maxsize=1024)
def parse_path(text: str) -> Path:
    """Parse ``a.b[1].c`` into selectors; InputError for a malformed path."""
    if not isinstance(text, str) or not text.strip():
        raise _bad(str(text), "empty path")
    steps: list[Selector] = []
    i, n = 0, len(text)
    expect_key = True
    while i < n:
        ch = text[i]
        if ch == "[":
            end = text.find("]", i)
            if end < 0:
                raise _bad(text, "'[' without ']'")
            inner = text[i + 1 : end].strip()
            if not steps:
                raise _bad(text, "a path starts with a key")
            if inner == "*":
                steps.append(Selector(every=True))
            elif "=" in inner:
                k, v = (p.strip() for p in inner.split("=", 1))
                if not k or not v:
                    raise _bad(text, f"selector [{inner}] needs a key and a value")
                steps.append(Selector(match_key=k, match_value=v))
            else:
                try:
                    steps.append(Selector(index=int(inner)))
                except ValueError:
                    raise _bad(text, f"[{inner}] is not a list index, [*] or [key=value]") from None
            i = end + 1
            expect_key = False
        elif ch == ".":
            if expect_key:
                raise _bad(text, "empty key")
            i += 1
            expect_key = True
        else:
            j = i
            while j < n and text[j] not in ".[":
                j += 1
            key = text[i:j].strip()
            if not expect_key or not key:
                raise _bad(text, "missing '.' between parts")
            steps.append(Selector(key=key))
            i = j
            expect_key = False
    if expect_key:
        raise _bad(text, "the path ends with '.'")
    return Path(text, tuple(steps))


def _children(node: Any, step: Selector, where: str, *, create: bool) -> list[tuple[Any, Any]]:
    """(container, key) pairs a step selects in ``node``; ``where`` is the path so far."""
    if step.key is not None:
        if not isinstance(node, dict):
            raise InputError(f"'{where}' is not a mapping: no key '{step.key}' in it", field=where)
        if step.key not in node and not create:
            raise InputError(f"no field '{step.key}' in '{where or '(top)'}'", field=where)
        return [(node, step.key)]
    if not isinstance(node, list):
        raise InputError(f"'{where}' is not a list: {step} selects list items", field=where)
    if step.index is not None:
        if not -len(node) <= step.index < len(node):
            raise InputError(
                f"'{where}' has {len(node)} item(s): no item {step}",
                field=where,
                allowed=f"0 .. {len(node) - 1}",
            )
        return [(node, step.index % len(node))]
    if step.every:
        return [(node, k) for k in range(len(node))]
    found = [
        (node, k)
        for k, item in enumerate(node)
        if isinstance(item, dict) and str(item.get(step.match_key)) == step.match_value
    ]
    if not found:
        names = [str(item.get(step.match_key)) for item in node if isinstance(item, dict)]
        raise InputError(
            f"no item of '{where}' has {step.match_key} = {step.match_value}",
            field=where,
            allowed=", ".join(names) or None,
        )
    return found


def _targets(data: Any, path: Path, *, create: bool) -> list[tuple[Any, Any]]:
    nodes: list[Any] = [data]
    where = ""
    last = len(path.steps) - 1
    targets: list[tuple[Any, Any]] = []
    for k, step in enumerate(path.steps):
        pairs = [pair for node in nodes for pair in _children(node, step, where, create=create)]
        where += ("." + str(step)) if step.key is not None and where else str(step)
        if k == last:
            targets = pairs
            break
        nodes = []
        for container, key in pairs:
            if isinstance(container, dict) and key not in container:
                # only reached with create=True: a missing mapping on the way is made
                container[key] = {}
            nodes.append(container[key])
    return targets


def get_values(data: Any, path: Path | str) -> list[Any]:
    """The values at a path (several with ``[*]`` or a match selector); InputError if absent."""
    p = parse_path(path) if isinstance(path, str) else path
    return [container[key] for container, key in _targets(data, p, create=False)]


def set_value(data: Any, path: Path | str, value: Any, *, scale: bool = False) -> None:
    """Write ``value`` at a path in place (every selected item); with ``scale`` multiply the value
    there by ``value`` instead. Missing mapping keys are created; InputError for a missing list item or
    a path through something that is not a mapping or a list."""
    p = parse_path(path) if isinstance(path, str) else path
    for container, key in _targets(data, p, create=True):
        if scale:
            old = container.get(key) if isinstance(container, dict) else container[key]
            if isinstance(old, bool) or not isinstance(old, int | float):
                raise InputError(
                    "a relative value needs a number to scale", field=p.text, value=old, allowed="a number"
                )
            container[key] = old * value
        else:
            container[key] = value
