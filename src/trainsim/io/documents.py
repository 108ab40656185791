"""Bounded reading of YAML, JSON and XML documents: the one place every reader parses a file.

Input files are data, and hostile data must not be able to crash, hang or exhaust the process.
Every reader of trainsim goes through this module, which enforces:

* a size limit on the file (:data:`LIMITS` ``max_bytes``);
* a nesting-depth limit (``max_depth``): deeper documents are refused before any recursive code
  sees them (PyYAML's composer and libyaml recurse per level: 100,000 ``[`` crash the process);
* a limit on the number of values once YAML aliases are expanded (``max_nodes``) and on the values
  added by aliases (``max_alias_nodes``): a 1.3 KB "billion laughs" alias bomb is refused at once;
* YAML through libyaml's event parser (C), read once, with duplicate keys refused and scalars
  resolved as PyYAML's ``SafeLoader`` resolves them (YAML 1.1: ``yes`` is true, ``1_000`` is 1000),
  except that an unquoted ``1e3`` is the number 1000 (as in YAML 1.2), not the text "1e3";
* JSON with duplicate keys refused and ``NaN`` / ``Infinity`` refused (they are not JSON);
* XML through lxml with no entity expansion, no DTD loading, no network, bounded depth and size;
  files that declare entities are refused with a message about the file, not about libxml2.

Every failure is an :class:`~trainsim.errors.InputError` naming the file and, where known, the line.
"""

from __future__ import annotations

import dataclasses
import functools
import gc
import itertools
import json
import re
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, ParamSpec, TypeVar

import yaml

from trainsim.errors import InputError, shown_value

P = ParamSpec("P")
R = TypeVar("R")

__all__ = [
    "LIMITS",
    "DocumentLimits",
    "gc_paused",
    "read_bytes",
    "read_document",
    "read_json",
    "read_json_text",
    "read_text",
    "read_xml",
    "read_yaml",
    "read_yaml_text",
    "xml_root",
    "yaml_line",
    "yaml_lines",
]


@dataclasses.dataclass(frozen=True)
class DocumentLimits:
    """Bounds on the documents trainsim reads.

    Attributes:
        max_bytes: largest file [bytes]; a 200,000-entry route is about 9 MB.
        max_depth: deepest nesting of mappings/sequences (YAML, JSON) or elements (XML); trainsim's
            own files nest about 6 deep, railML about 12.
        max_nodes: most values (scalars, mappings, sequences, counted with aliases expanded).
        max_alias_nodes: most values added by YAML aliases (``*name``) on top of those written.
    """

    max_bytes: int = 64 * 1024 * 1024
    max_depth: int = 100
    max_nodes: int = 5_000_000
    max_alias_nodes: int = 200_000


#: The limits in force (a setting: replace with ``dataclasses.replace`` in tests or tools).
LIMITS = DocumentLimits()


def gc_paused(func: Callable[P, R]) -> Callable[P, R]:
    """Decorator: run ``func`` with Python's cyclic garbage collector paused.

    Reading a file creates millions of small objects and no reference cycles; the collector's
    passes over them cost about as much as the reading itself (a 200,000-entry route: 0.5 s of
    1.3 s in validation). Nested calls keep it paused; it is enabled again as it was.
    """

    @functools.wraps(func)
    def wrapper(*args: P.args, **kwargs: P.kwargs) -> R:
        was_enabled = gc.isenabled()
        gc.disable()
        try:
            return func(*args, **kwargs)
        finally:
            if was_enabled:
                gc.enable()

    return wrapper


def read_bytes(path: str | Path, limits: DocumentLimits | None = None) -> bytes:
    """The bytes of a file; InputError if it is missing, a directory, too big or unreadable."""
    limits = limits or LIMITS
    file = str(path)
    p = Path(path)
    try:
        exists, is_dir = p.exists(), p.is_dir()
    except (OSError, ValueError) as exc:  # a name too long, a NUL byte in it...
        raise InputError(
            "not a usable file name", file=shown_value(file)[1:-1], allowed="a path to a file"
        ) from exc
    if not exists:
        raise InputError("file not found", file=file)
    if is_dir:
        raise InputError("this is a directory, not a file", file=file)
    try:
        size = p.stat().st_size
        if size > limits.max_bytes:
            raise InputError(
                "file too large",
                file=file,
                value=f"{size} bytes",
                allowed=f"at most {limits.max_bytes} bytes",
            )
        with p.open("rb") as fh:
            data = fh.read(limits.max_bytes + 1)
    except OSError as exc:
        raise InputError(f"cannot read the file ({exc.strerror or exc})", file=file) from exc
    if len(data) > limits.max_bytes:
        raise InputError("file too large", file=file, allowed=f"at most {limits.max_bytes} bytes")
    return data


def read_text(path: str | Path, limits: DocumentLimits | None = None) -> str:
    """The text of a file (UTF-8, an optional BOM dropped); InputError if missing, too big or unreadable."""
    data = read_bytes(path, limits)
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise InputError(
            "the file is not UTF-8 text", file=str(path), line=line, allowed="UTF-8 text (YAML, JSON or XML)"
        ) from exc


# ====================================================================== YAML
_SAFE = yaml.SafeLoader  # resolver tables and scalar constructors of PyYAML's safe loader
_RESOLVER = yaml.resolver.Resolver()
_CONSTRUCTOR = yaml.constructor.SafeConstructor()
_STR_TAG = "tag:yaml.org,2002:str"
_SEQ_TAG = "tag:yaml.org,2002:seq"
_MAP_TAG = "tag:yaml.org,2002:map"
_MERGE_TAG = "tag:yaml.org,2002:merge"
#: Explicit scalar tags a file may use (``!!str 5``); any other tag is refused.
_SCALAR_TAGS = {
    "tag:yaml.org,2002:str",
    "tag:yaml.org,2002:int",
    "tag:yaml.org,2002:float",
    "tag:yaml.org,2002:bool",
    "tag:yaml.org,2002:null",
    "tag:yaml.org,2002:timestamp",
}
_PLAIN_CACHE: dict[str, Any] = {}
_PLAIN_CACHE_SIZE = 50_000
_IMMUTABLE = (str, int, float, bool, type(None))
_DECIMAL_INT = re.compile(r"[-+]?(?:0|[1-9][0-9]{0,17})")
_EXPONENT_FLOAT = re.compile(r"[-+]?(?:\.[0-9]{1,17}|[0-9]{1,18}(?:\.[0-9]{0,17})?)[eE][-+]?[0-9]{1,3}")
_DECIMAL_FLOAT = re.compile(r"[-+]?(?:0|[1-9][0-9]{0,17})\.[0-9]{0,17}(?:[eE][-+][0-9]{1,3})?")


def _plain_scalar(value: str) -> Any:
    """A plain (unquoted) scalar resolved as PyYAML's SafeLoader does (cached: files repeat values)."""
    try:
        return _PLAIN_CACHE[value]
    except KeyError:
        pass
    # fast paths for the usual decimal numbers (same result as the resolver: YAML 1.1 reads "012"
    # as octal and "1e3" as text, so those take the slow path)
    if _DECIMAL_INT.fullmatch(value):
        result: Any = int(value)
    elif _DECIMAL_FLOAT.fullmatch(value) or _EXPONENT_FLOAT.fullmatch(value):
        result = float(value)  # YAML 1.2 also reads 1e3 as a number (YAML 1.1 as text)
    else:
        result = _tagged_scalar(_RESOLVER.resolve(yaml.ScalarNode, value, (True, False)), value)
    if isinstance(result, _IMMUTABLE):
        if len(_PLAIN_CACHE) >= _PLAIN_CACHE_SIZE:
            _PLAIN_CACHE.clear()
        _PLAIN_CACHE[value] = result
    return result


def _tagged_scalar(tag: str, value: str) -> Any:
    if tag == _STR_TAG:
        return value
    if tag == _MERGE_TAG:
        return _MergeKey()
    node = yaml.ScalarNode(tag, value)
    return _CONSTRUCTOR.yaml_constructors[tag](_CONSTRUCTOR, node)


class _MergeKey:
    """The ``<<`` key of a YAML merge (``<<: *defaults``)."""

    def __hash__(self) -> int:
        return hash("<<")

    def __eq__(self, other: object) -> bool:
        return isinstance(other, _MergeKey)


class _Frame:
    __slots__ = ("anchor", "container", "has_key", "key", "line", "merges", "nodes", "seen")

    def __init__(self, container: Any, anchor: str | None, line: int) -> None:
        self.container = container
        self.anchor = anchor
        self.key: Any = None
        self.has_key = False
        self.line = line
        self.nodes = 1
        self.merges: list[Any] = []
        self.seen: dict[Any, int] = {}


def _yaml_fail(reason: str, file: str, mark: Any, value: Any = None, allowed: str | None = None) -> None:
    line = mark.line + 1 if mark is not None else None
    raise InputError(f"invalid YAML: {reason}", file=file, line=line, value=value, allowed=allowed)


#: One line ``- {key: value, ...}`` of a block sequence whose keys are names and whose values are
#: short plain scalars (numbers, words): the shape of the long lists of a route (gradients, speed
#: limits, curves). Values hold none of ``,:{}[]#'"&*!|>%@``, so the line is exactly one flow mapping.
_FLOW_PAIR = r"[A-Za-z_][A-Za-z0-9_]*: +[-+.]?[A-Za-z0-9_][A-Za-z0-9_.+-]*"
_FLOW_LINE = re.compile(rf"( *)- \{{ *({_FLOW_PAIR}(?: *, *{_FLOW_PAIR})*) *\}} *")
#: Line breaks of YAML other than "\n" (libyaml counts lines at each).
_OTHER_BREAKS = ("\r", "\x85", "\u2028", "\u2029")
_FLOW_KEY = re.compile(r"([A-Za-z_][A-Za-z0-9_]*):")
_FLOW_VALUE = re.compile(r": +([^ ,\n]+)")
#: Fewest such lines for which they are read by the shortcut (below, the plain event loop is as fast).
_FLOW_LINES_MIN = 200


class _FallbackError(Exception):
    """The shortcut for flow-mapping lines does not apply: read the original text event by event."""


def read_yaml_text(text: str, file: str = "<yaml>", limits: DocumentLimits | None = None) -> Any:
    """The content of one YAML document, read once by libyaml's event parser within ``limits``.

    Values resolve as with ``yaml.safe_load`` (YAML 1.1 scalars, merge keys ``<<``); duplicate keys,
    non-scalar keys, unknown tags, several documents, too deep nesting and alias bombs are refused
    with an InputError naming the line.

    Long lists of one-line flow mappings (``- {from_m: 0, gradient_permille: 3}``, 200,000 of them in
    a long route) cost libyaml six Python event objects per line, about 1.5 s of the 2 s budget of
    issue 13. Such lines are given to libyaml as ``- ~`` (the same lines and columns before them,
    the same structure) and the mapping is built from the line's text with the same scalar
    resolution; the result is only used if every such line came back as that ``~`` at its own line
    and column (so not inside a block scalar, a quoted text or a flow collection), with no error.
    Otherwise the original text is read event by event, which gives the exact error of the file.
    """
    limits = limits or LIMITS
    if len(text) > limits.max_bytes:
        raise InputError("document too large", file=file, allowed=f"at most {limits.max_bytes} characters")
    shortened, flow = _flow_lines(text, limits)
    if flow:
        try:
            return _read_events(shortened, file, limits, flow)
        except (_FallbackError, InputError):
            pass  # the original text says what is wrong, at its own line
    return _read_events(text, file, limits, None)


def _flow_lines(text: str, limits: DocumentLimits) -> tuple[str, dict[int, tuple[int, list[Any], int]]]:
    """(text with each run of one-line flow mappings of a block sequence (same indentation, one line
    after the other) replaced by ``- ~`` on its first line and blank lines, {first line (0-based):
    (column of the ``~``, the run's mappings, their values as the event loop counts them)}); the
    text unchanged and {} if there are few such lines, or too many values (the event loop says so)."""
    if "- {" not in text or any(c in text for c in _OTHER_BREAKS):
        return text, {}  # line numbers as libyaml counts them are those of "\n" only
    lines = text.split("\n")
    runs: list[tuple[int, int, list[str]]] = []
    prev, prev_indent = -2, None
    for i, m in enumerate(map(_FLOW_LINE.fullmatch, lines)):  # one match object alive at a time
        if m is None:
            continue
        indent, inner = m.group(1, 2)
        if i == prev + 1 and indent == prev_indent:
            runs[-1][2].append(inner)
            lines[i] = ""  # left blank: the next entry of the same block sequence
        else:
            runs.append((i, len(indent) + 2, [inner]))
            lines[i] = f"{indent}- ~"
        prev, prev_indent = i, indent
    inners = [inner for run in runs for inner in run[2]]
    if len(inners) < _FLOW_LINES_MIN:
        return text, {}
    counts = [inner.count(",") + 1 for inner in inners]
    if len(inners) + 2 * sum(counts) > limits.max_nodes:
        return text, {}
    joined = "\n".join(inners)
    del inners
    sizes = [(first, column, len(items)) for first, column, items in runs]
    del runs  # the lines' texts are in ``joined`` now
    # keys and values as two flat lists of texts (not 2-tuples: a third of the memory)
    key_texts = _FLOW_KEY.findall(joined)
    resolved_keys = {k: _plain_scalar(k) for k in set(key_texts)}
    keys = list(map(resolved_keys.__getitem__, key_texts))
    del key_texts
    values = _resolve_plain(_FLOW_VALUE.findall(joined))
    del joined
    if len(keys) != sum(counts) or len(values) != len(keys):
        return text, {}  # not expected from _FLOW_LINE; the event loop reads what the file says
    n = counts[0]
    if all(c == n for c in counts):  # every line with the same number of keys: built in C
        key_rows = zip(*[iter(keys)] * n, strict=True)
        rows = list(map(dict, map(zip, key_rows, zip(*[iter(values)] * n, strict=True))))
        if any(len(row) != n for row in rows):
            return text, {}  # a duplicate key: the event loop names it and its line
    else:
        rows, at = [], 0
        for c in counts:
            rows.append(dict(zip(keys[at : at + c], values[at : at + c], strict=True)))
            at += c
            if len(rows[-1]) != c:
                return text, {}
    flow: dict[int, tuple[int, list[Any], int]] = {}
    at = 0
    for first, column, size in sizes:
        flow[first] = (column, rows[at : at + size], size + 2 * sum(counts[at : at + size]))
        at += size
    return "\n".join(lines), flow


def _resolve_plain(texts: Sequence[str]) -> list[Any]:
    """:func:`_plain_scalar` of many texts (decimal integers, the usual positions, in one pass)."""
    out = list(map(_PLAIN_CACHE.get, texts, itertools.repeat(_MISSING)))
    missing = [i for i, v in enumerate(out) if v is _MISSING]
    fullmatch = _DECIMAL_INT.fullmatch
    for i in missing:
        t = texts[i]
        out[i] = int(t) if fullmatch(t) else _plain_scalar(t)
    return out


def _read_events(
    text: str, file: str, limits: DocumentLimits, flow: dict[int, tuple[int, list[Any], int]] | None
) -> Any:
    """The document of ``text`` read event by event; ``flow``: the lines of :func:`_flow_lines`."""
    substituted = 0
    extra = 0  # values of a run of flow lines, beyond the node of its '~'
    run = False  # the value is a run of flow lines' mappings, to extend the sequence with
    anchors: dict[str, tuple[Any, int]] = {}
    stack: list[_Frame] = []
    root: Any = None
    documents = 0
    total = 0
    aliased = 0
    parser = yaml.CSafeLoader(text) if yaml.__with_libyaml__ else yaml.SafeLoader(text)
    cache_get = _PLAIN_CACHE.get
    try:
        while True:
            event = parser.get_event()
            cls = event.__class__
            if cls is yaml.ScalarEvent:
                tag = event.tag
                if tag is None or tag == "!":
                    if event.implicit[0]:
                        value = cache_get(event.value, _MISSING)
                        if value is _MISSING:
                            value = _plain_scalar(event.value)
                        if flow and value is None and event.value == "~":
                            where = flow.get(event.start_mark.line)
                            if where is not None:
                                # the run's first entry must come back where it was, as an entry
                                # of a block sequence within the depth limit
                                if (
                                    where[0] != event.start_mark.column
                                    or event.anchor is not None
                                    or not stack
                                    or stack[-1].container.__class__ is not list
                                    or len(stack) >= limits.max_depth
                                ):
                                    raise _FallbackError
                                value = where[1]
                                run = True
                                substituted += 1
                                extra = where[2] - 1
                    else:
                        value = event.value
                elif tag in _SCALAR_TAGS:
                    value = _tagged_scalar(tag, event.value)
                else:
                    _yaml_fail(
                        "tags are not allowed here", file, event.start_mark, tag, "!!str, !!int, !!float"
                    )
                nodes = 1 + extra
                extra = 0
                if event.anchor is not None:
                    anchors[event.anchor] = (value, 1)
            elif cls is yaml.AliasEvent:
                if event.anchor not in anchors:
                    _yaml_fail(f"unknown alias '*{event.anchor}'", file, event.start_mark)
                value, nodes = anchors[event.anchor]
                if value is _OPEN:
                    _yaml_fail(f"alias '*{event.anchor}' refers to itself", file, event.start_mark)
                aliased += nodes
                if aliased > limits.max_alias_nodes:
                    _yaml_fail(
                        "aliases expand to too many values (an alias bomb?)",
                        file,
                        event.start_mark,
                        allowed=f"at most {limits.max_alias_nodes} values added by aliases",
                    )
            elif cls is yaml.MappingStartEvent or cls is yaml.SequenceStartEvent:
                is_map = cls is yaml.MappingStartEvent
                if event.tag not in (None, "!", _MAP_TAG if is_map else _SEQ_TAG):
                    _yaml_fail("tags are not allowed here", file, event.start_mark, event.tag, "no tag")
                if len(stack) >= limits.max_depth:
                    _yaml_fail(
                        "nested too deep",
                        file,
                        event.start_mark,
                        allowed=f"at most {limits.max_depth} levels of nesting",
                    )
                frame = _Frame({} if is_map else [], event.anchor, event.start_mark.line)
                if event.anchor is not None:
                    anchors[event.anchor] = (_OPEN, 0)
                stack.append(frame)
                continue
            elif cls is yaml.MappingEndEvent or cls is yaml.SequenceEndEvent:
                frame = stack.pop()
                value, nodes = frame.container, frame.nodes
                if frame.merges:
                    value = _merged(frame, file, event.start_mark)
                if frame.anchor is not None:
                    anchors[frame.anchor] = (value, nodes)
            elif cls is yaml.DocumentStartEvent:
                documents += 1
                if documents > 1:
                    _yaml_fail(
                        "the file holds several YAML documents ('---')",
                        file,
                        event.start_mark,
                        allowed="one document",
                    )
                anchors.clear()
                continue
            elif cls is yaml.StreamEndEvent:
                if flow is not None and substituted != len(flow):
                    raise _FallbackError  # a replaced line was not a sequence entry: read the original
                break
            else:  # stream start, document end
                continue
            total += nodes
            if total > limits.max_nodes:
                _yaml_fail("too many values", file, event.start_mark, allowed=f"at most {limits.max_nodes}")
            if not stack:
                root = value
                continue
            parent = stack[-1]
            parent.nodes += nodes
            container = parent.container
            if container.__class__ is list:
                if run:
                    container.extend(value)
                    run = False
                else:
                    container.append(value)
            elif not parent.has_key:
                if value.__class__ not in _IMMUTABLE and not isinstance(value, _MergeKey):
                    _yaml_fail("a key must be text or a number", file, event.start_mark, allowed="plain keys")
                if value in parent.seen:
                    _yaml_fail(
                        f"duplicate key '{shown_value(value)[:60].strip(chr(39))}' "
                        f"(first at line {parent.seen[value] + 1})",
                        file,
                        event.start_mark,
                    )
                parent.seen[value] = event.start_mark.line
                parent.key, parent.has_key = value, True
            else:
                if isinstance(parent.key, _MergeKey):
                    parent.merges.append(value)
                else:
                    container[parent.key] = value
                parent.has_key = False
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line = mark.line + 1 if mark else None
        if "maximum nesting depth" in str(exc.problem):
            # libyaml 0.2.6+ (PyYAML 6.0.4's wheels) stops deep flow nesting itself, before the events
            # reach our own depth check: the same message and range either way
            raise InputError(
                "invalid YAML: nested too deep",
                file=file,
                line=line,
                allowed=f"at most {limits.max_depth} levels of nesting",
            ) from exc
        reason = " ".join(str(x) for x in (exc.context, exc.problem) if x)
        raise InputError(f"invalid YAML: {reason}", file=file, line=line) from exc
    except yaml.YAMLError as exc:
        raise InputError(f"invalid YAML: {exc}", file=file) from exc
    except InputError:
        raise
    except (ValueError, OverflowError, TypeError) as exc:  # e.g. a timestamp out of range
        raise InputError(f"invalid YAML value ({exc})", file=file) from exc
    finally:
        parser.dispose()
    return root


_OPEN = object()  # an anchored collection whose end has not been read yet
_MISSING = object()


def _merged(frame: _Frame, file: str, mark: Any) -> dict[Any, Any]:
    """The mapping with its ``<<`` merges applied (keys written in the mapping win)."""
    out: dict[Any, Any] = {}
    for merge in frame.merges:
        sources = merge if isinstance(merge, list) else [merge]
        for source in reversed(sources):
            if not isinstance(source, dict):
                _yaml_fail("'<<' merges mappings only", file, mark, allowed="a mapping or a list of mappings")
            out.update(source)
    out.update(frame.container)
    frame.container.clear()
    frame.container.update(out)
    return frame.container


def read_yaml(path: str | Path, limits: DocumentLimits | None = None) -> Any:
    """The content of a YAML file within ``limits`` (see :func:`read_yaml_text`)."""
    return read_yaml_text(read_text(path, limits), str(path), limits)


def yaml_line(text: str, loc: Sequence[str | int]) -> int | None:
    """Line (1-based) of the value at ``loc`` (keys and list indices) in YAML ``text`` (the line of its
    key inside a mapping), or of its deepest existing parent; None if the text cannot be read."""
    return yaml_lines(text, [loc])[0]


def yaml_lines(text: str, locs: Sequence[Sequence[str | int]]) -> list[int | None]:
    """:func:`yaml_line` of several locations, in one pass over the text."""
    targets = [tuple(loc) for loc in locs]
    best: list[int | None] = [None] * len(targets)
    best_len = [-1] * len(targets)
    # one frame per open collection: [path, is_map, next index, expecting a key, pending key, key line]
    stack: list[list[Any]] = []
    starts = (yaml.MappingStartEvent, yaml.SequenceStartEvent)
    try:
        parser = yaml.CSafeLoader(text) if yaml.__with_libyaml__ else yaml.SafeLoader(text)
        try:
            while True:
                event = parser.get_event()
                cls = event.__class__
                if cls is yaml.StreamEndEvent:
                    break
                if cls in (yaml.MappingEndEvent, yaml.SequenceEndEvent):
                    stack.pop()
                    continue
                if cls not in (yaml.ScalarEvent, yaml.AliasEvent, *starts):
                    continue
                line = event.start_mark.line + 1
                here: tuple[Any, ...] | None
                if not stack:
                    here = ()
                else:
                    top = stack[-1]
                    if top[0] is None:  # inside a complex key: no path
                        here = None
                    elif top[1] and top[3]:  # a mapping's key
                        top[3], top[4], top[5] = False, getattr(event, "value", None), line
                        if cls in starts:
                            stack.append([None, cls is yaml.MappingStartEvent, 0, True, None, line])
                        continue
                    elif top[1]:  # a mapping's value
                        here, line = (*top[0], top[4]), top[5]
                        top[3] = True
                    else:
                        here = (*top[0], top[2])
                        top[2] += 1
                if here is not None:
                    n = len(here)
                    for i, target in enumerate(targets):
                        if n > best_len[i] and target[:n] == here:
                            best[i], best_len[i] = line, n
                if cls in starts:
                    if len(stack) >= LIMITS.max_depth:
                        break
                    stack.append([here, cls is yaml.MappingStartEvent, 0, True, None, line])
        finally:
            parser.dispose()
    except yaml.YAMLError:
        return best
    return best


# ====================================================================== JSON
def _refuse_constant(name: str) -> Any:
    raise _JsonConstantError(name)


class _JsonConstantError(ValueError):
    pass


def _no_duplicates(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise _JsonDuplicateError(key)
        out[key] = value
    return out


class _JsonDuplicateError(ValueError):
    pass


def _depth_ok(data: Any, max_depth: int) -> bool:
    """Whether ``data`` (parsed JSON/YAML) nests at most ``max_depth`` deep (iterative)."""
    todo: list[tuple[Any, int]] = [(data, 1)]
    while todo:
        item, depth = todo.pop()
        if isinstance(item, dict):
            if depth > max_depth:
                return False
            todo.extend((v, depth + 1) for v in item.values() if isinstance(v, dict | list))
        elif isinstance(item, list):
            if depth > max_depth:
                return False
            todo.extend((v, depth + 1) for v in item if isinstance(v, dict | list))
    return True


def _json_max_depth_prescan(text: str) -> int:
    """Deepest bracket nesting of JSON text, ignoring brackets inside strings (cheap, iterative)."""
    depth = deepest = 0
    in_string = escaped = False
    for ch in text:
        if in_string:
            if escaped:
                escaped = False
            elif ch == "\\":
                escaped = True
            elif ch == '"':
                in_string = False
        elif ch == '"':
            in_string = True
        elif ch in "[{":
            depth += 1
            if depth > deepest:
                deepest = depth
        elif ch in "]}":
            depth -= 1
    return deepest


def read_json_text(text: str, file: str = "<json>", limits: DocumentLimits | None = None) -> Any:
    """The content of a JSON document within ``limits``; duplicate keys and NaN/Infinity refused."""
    limits = limits or LIMITS
    if len(text) > limits.max_bytes:
        raise InputError("document too large", file=file, allowed=f"at most {limits.max_bytes} characters")
    try:
        return _check_json_depth(
            json.loads(text, parse_constant=_refuse_constant, object_pairs_hook=_no_duplicates), file, limits
        )
    except _JsonConstantError as exc:
        raise InputError(
            f"invalid JSON: '{exc}' is not a number in JSON",
            file=file,
            line=_json_line_of(text, str(exc)),
            value=str(exc),
            allowed="finite numbers",
        ) from exc
    except _JsonDuplicateError as exc:
        raise InputError(f"invalid JSON: duplicate key '{shown_value(str(exc))[1:-1]}'", file=file) from exc
    except json.JSONDecodeError as exc:
        raise InputError(f"invalid JSON: {exc.msg}", file=file, line=exc.lineno) from exc
    except RecursionError as exc:
        raise InputError(
            "invalid JSON: nested too deep", file=file, allowed=f"at most {limits.max_depth} levels"
        ) from exc
    except InputError:
        raise
    except (ValueError, OverflowError) as exc:  # e.g. an integer of more than 4300 digits
        raise InputError(f"invalid JSON: {shown_value(str(exc))[1:-1]}", file=file) from exc


def _check_json_depth(data: Any, file: str, limits: DocumentLimits) -> Any:
    if not _depth_ok(data, limits.max_depth):
        raise InputError(
            "invalid JSON: nested too deep", file=file, allowed=f"at most {limits.max_depth} levels"
        )
    return data


def _json_line_of(text: str, word: str) -> int | None:
    at = text.find(word)
    return text.count("\n", 0, at) + 1 if at >= 0 else None


def read_json(path: str | Path, limits: DocumentLimits | None = None) -> Any:
    """The content of a JSON file within ``limits`` (see :func:`read_json_text`)."""
    limits = limits or LIMITS
    text = read_text(path, limits)
    file = str(path)
    if _json_max_depth_prescan(text) > limits.max_depth:
        raise InputError(
            "invalid JSON: nested too deep", file=file, allowed=f"at most {limits.max_depth} levels"
        )
    return read_json_text(text, file, limits)


def read_document(path: str | Path, limits: DocumentLimits | None = None) -> Any:
    """The content of a YAML or JSON file (``.json`` files are read as JSON, others as YAML)."""
    if Path(path).suffix.lower() == ".json":
        return read_json(path, limits)
    return read_yaml(path, limits)


# ====================================================================== XML
def _xml_parser() -> Any:
    from lxml import etree

    return etree.XMLParser(
        resolve_entities=False,
        no_network=True,
        load_dtd=False,
        dtd_validation=False,
        remove_comments=True,
        remove_pis=True,
        huge_tree=False,
    )


def _xml_message(msg: str) -> str:
    """libxml2's message in words about the file."""
    low = msg.lower()
    if "amplification" in low or ("entity" in low and ("loop" in low or "depth" in low)):
        return "the file declares entities that expand to too much text (an entity bomb); railML needs none"
    if "excessive depth" in low or ("depth" in low and "nest" in low):
        return "elements nested too deep"
    return msg


def read_xml(path: str | Path, limits: DocumentLimits | None = None) -> Any:
    """The lxml tree of an XML file within ``limits``: no entity expansion, no DTD, no network.

    Files that declare or use entities (``<!ENTITY``, ``&name;`` other than XML's five) are refused:
    railML files have no use for them and they are the usual way of attacking an XML reader.
    """
    from lxml import etree

    limits = limits or LIMITS
    file = str(path)
    data = read_bytes(path, limits)
    try:
        root = etree.fromstring(data, _xml_parser())
    except etree.XMLSyntaxError as exc:
        raise InputError(
            f"malformed XML: {_xml_message(exc.msg)}", file=file, line=exc.lineno or None
        ) from exc
    if root is None:
        raise InputError("malformed XML: no root element", file=file)
    tree = root.getroottree()
    dtd = tree.docinfo.internalDTD
    if dtd is not None and any(True for _ in dtd.iterentities()):
        raise InputError(
            "the file declares XML entities (<!ENTITY ...>); railML files need none",
            file=file,
            allowed="XML without entity declarations",
        )
    for el in root.iter(etree.Entity):
        raise InputError(
            f"the file uses an XML entity reference ({el.text}); railML files need none",
            file=file,
            line=el.sourceline,
        )
    depth = 0
    for event, el in etree.iterwalk(root, events=("start", "end")):
        if event == "start":
            depth += 1
            if depth > limits.max_depth:
                raise InputError(
                    "elements nested too deep",
                    file=file,
                    line=el.sourceline,
                    allowed=f"at most {limits.max_depth} levels",
                )
        else:
            depth -= 1
    return tree


def xml_root(path: str | Path, limits: DocumentLimits | None = None) -> tuple[str, dict[str, str]] | None:
    """(local name, attributes) of the root element of an XML file, or None if it is not XML."""
    try:
        tree = read_xml(path, limits)
    except InputError:
        return None
    root = tree.getroot()
    tag = root.tag if isinstance(root.tag, str) else ""
    return tag.rsplit("}", 1)[-1], dict(root.attrib)
