"""The base of trainsim's YAML readers: reading, the :class:`Spec` base model, problems in words.

Every block of a trainsim file is a pydantic model derived from :class:`Spec` (unknown fields are
errors, units in field names, every number checked against :mod:`trainsim.model.bounds`); a
validator reports a problem with :func:`fail`; :func:`validation_error` turns pydantic's errors into
one :class:`~trainsim.errors.InputError` with one :class:`~trainsim.errors.Problem` each (file, YAML
line, field path, value, allowed). The document kinds are in :mod:`trainsim.io.yaml_train`,
:mod:`trainsim.io.yaml_route` and :mod:`trainsim.io.yaml_scenario`; :mod:`trainsim.io.trainsim_yaml`
gathers them.
"""

from __future__ import annotations

import collections
import dataclasses
import difflib
import math
import operator
import types
import typing
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, ClassVar, Literal, NoReturn

import numpy as np
from pydantic import (
    BaseModel,
    ConfigDict,
    Discriminator,
    Field,
    Tag,
    ValidationError,
    WrapSerializer,
    WrapValidator,
    model_validator,
)
from pydantic.fields import FieldInfo
from pydantic_core import PydanticCustomError

from trainsim.errors import InputError, Problem, shown_value
from trainsim.io import documents
from trainsim.io.units import UNITS, split_suffix, to_unit
from trainsim.model import (
    bounds,
)

if TYPE_CHECKING:  # trainsim.optimize is imported where a driving block is read, not by every reader
    pass


#: The schema identifiers of this module and the versions it reads.
SCHEMAS: dict[str, tuple[int, ...]] = {
    "trainsim/train": (1,),
    "trainsim/route": (1,),
    "trainsim/scenario": (1,),
}


# ====================================================================== YAML reading
def read_yaml(path: str | Path) -> Any:
    """The content of a YAML (or ``.json``) file; InputError for a missing, unreadable or malformed file.

    Read once, within the bounds of :mod:`trainsim.io.documents` (size, nesting depth, alias
    expansion); duplicate keys are errors; the error of a malformed file names its line.
    """
    return documents.read_document(path)


def _yaml_line(path: str | Path, loc: Sequence[str | int]) -> int | None:
    """Line (1-based) of the YAML node at ``loc`` in the file, or of its deepest existing parent."""
    return _yaml_lines(path, [loc])[0]


def _yaml_lines(path: str | Path, locs: Sequence[Sequence[str | int]]) -> list[int | None]:
    """:func:`_yaml_line` of several locations (one pass over the file)."""
    try:
        text = documents.read_text(path)
    except InputError:
        return [None] * len(locs)
    return documents.yaml_lines(text, locs)


# ====================================================================== validation errors
def fail(reason: str, *, field: str | None = None, value: Any = None, allowed: str | None = None) -> NoReturn:
    """Raise a validation error inside a spec validator (a ``model_validator`` of a :class:`Spec`).

    ``field`` is relative to the model (``"speed_kmh[3]"``); :func:`validation_error` turns the
    error into a :class:`~trainsim.errors.Problem` with the full path, the file and the line.
    """
    raise PydanticCustomError(
        "trainsim", "{reason}", {"reason": reason, "field": field, "value": value, "allowed": allowed}
    )


# Fields holding a tagged union: pydantic puts the tag into the error location, which we drop.
_UNION_FIELDS: dict[str, tuple[str, str]] = {
    "traction": ("model", "table, piecewise, power_limited"),
    "braking": ("model", "table, fraction_of_full, deceleration"),
    "regenerative": ("model", "none, or a mapping with model: fraction_of_traction | table"),
    "resistance": ("family", ""),  # filled in below, once the families are known
    "train": ("", "a file name, or a mapping with the train"),
    "route": ("", "a file name, or a mapping with the route"),
}


def _parse_field(field: str) -> list[str | int]:
    """``"speed_kmh[3]"`` -> ``["speed_kmh", 3]``; ``"a.b[1].c"`` -> ``["a", "b", 1, "c"]``."""
    parts: list[str | int] = []
    for piece in field.split("."):
        name, *indices = piece.replace("]", "").split("[")
        if name:
            parts.append(name)
        parts += [int(i) if i.isdigit() else i for i in indices]
    return parts


def _union_field(loc: Sequence[str | int]) -> str | None:
    """The union field an error location ends at (``traction``, ``resistance[2]``...), or None."""
    if loc and isinstance(loc[-1], str) and loc[-1] in _UNION_FIELDS:
        return loc[-1]
    if len(loc) > 1 and isinstance(loc[-1], int) and loc[-2] == "resistance":
        return "resistance"
    return None


def _clean_loc(loc: Sequence[str | int]) -> list[str | int]:
    out: list[str | int] = []
    for i, part in enumerate(loc):
        prev = loc[i - 1] if i > 0 else None
        prev2 = loc[i - 2] if i > 1 else None
        is_tag = isinstance(part, str) and (
            prev in _UNION_FIELDS or (isinstance(prev, int) and prev2 == "resistance")
        )
        if not is_tag:
            out.append(part)
    return out


def _format_loc(loc: Sequence[str | int]) -> str:
    text = ""
    for part in loc:
        if isinstance(part, int):
            text += f"[{part}]"
        else:
            text += ("." if text else "") + str(part)
    return text


def _describe(err: Any) -> tuple[str, Any, str | None]:
    """(reason, value shown or None, allowed) of one pydantic error."""
    kind = err["type"]
    ctx = err.get("ctx") or {}
    value = err.get("input")
    if isinstance(value, dict | list):
        value = None
    bounds = {
        "greater_than": (">", "gt"),
        "greater_than_equal": (">=", "ge"),
        "less_than": ("<", "lt"),
        "less_than_equal": ("<=", "le"),
    }
    if kind == "trainsim":
        return ctx["reason"], ctx.get("value"), ctx.get("allowed")
    if kind == "missing":
        return "required field is missing", None, None
    if kind == "extra_forbidden":
        if isinstance(value, _UnknownField):
            hint = f" (did you mean '{value.suggestion}'?)" if value.suggestion else ""
            return f"unknown field{hint}", None, value.allowed
        return "unknown field", value, None
    if kind in bounds:
        op, key = bounds[kind]
        return "out of range", value, f"{op} {ctx[key]:g}"
    if kind == "literal_error":
        return "not an allowed value", value, str(ctx.get("expected", "")).replace("'", "")
    if kind == "union_tag_invalid":
        return (
            f"unknown {ctx.get('discriminator', 'kind')}".replace("'", ""),
            ctx.get("tag"),
            str(ctx.get("expected_tags", "")).replace("'", ""),
        )
    if kind == "union_tag_not_found":
        return "missing or wrong kind of entry", value, None
    if kind in ("float_type", "float_parsing", "int_type", "int_parsing", "int_from_float", "finite_number"):
        what = "a whole number" if kind.startswith("int") else "a finite number"
        return f"must be {what}", value, None
    if kind in ("bool_type", "bool_parsing"):
        return "must be true or false", value, "true, false"
    if kind in ("string_type",):
        return "must be text", value, None
    if kind in ("list_type", "tuple_type"):
        return "must be a list", value, None
    if kind in ("model_type", "dict_type", "model_attributes_type"):
        return "must be a mapping (key: value lines)", value, None
    if kind == "too_short":
        return f"needs at least {ctx.get('min_length')} item(s)", None, None
    if kind in ("value_error", "assertion_error"):
        return err["msg"].removeprefix("Value error, ").removeprefix("Assertion failed, "), value, None
    return err["msg"], value, None


def validation_error(
    exc: ValidationError, file: str, path: str | Path | None, prefix: str = ""
) -> InputError:
    """One InputError for all problems of a pydantic ValidationError of a :class:`Spec`.

    Args:
        exc: the error of ``SomeSpec.model_validate(data)``.
        file: the file name the problems name.
        path: the file, to find the YAML line of each problem (None: no lines).
        prefix: a field path put before every problem's field (e.g. ``multi_point``).
    """
    problems: list[tuple[list[str | int], str, Any, str | None]] = []
    errors = exc.errors(include_url=False)
    # A misspelt required field gives "unknown field" and "missing": report the typo only.
    typos = {
        (*_clean_loc(err["loc"])[:-1], err["input"].suggestion)
        for err in errors
        if err["type"] == "extra_forbidden" and isinstance(err["input"], _UnknownField)
    }
    for err in errors:
        loc = _clean_loc(err["loc"])
        if err["type"] == "missing" and tuple(loc) in typos:
            continue
        ctx = err.get("ctx") or {}
        union = _union_field(loc)
        if err["type"] == "trainsim" and ctx.get("field"):
            loc += _parse_field(str(ctx["field"]))
        elif err["type"] == "union_tag_not_found" and union:
            key, allowed = _UNION_FIELDS[union]
            shown = err.get("input") if not isinstance(err.get("input"), dict) else None
            if key and isinstance(err.get("input"), dict):
                loc += [key]
                problems.append((loc, f"'{key}' is required", None, allowed))
            else:
                problems.append((loc, "wrong kind of entry", shown, allowed))
            continue
        elif err["type"] == "union_tag_invalid" and union:
            loc += [_UNION_FIELDS[union][0]]
        reason, value, allowed = _describe(err)
        problems.append((loc, reason, value, allowed))
    full = [[*([prefix] if prefix else []), *loc] for loc, *_ in problems]
    paths = [_format_loc(loc) for loc in full]
    lines = _yaml_lines(path, full[:_LINES_LOOKED_UP]) if path is not None and full else []
    lines += [None] * (len(full) - len(lines))
    structured = [
        Problem(reason, file=file, line=line, field=p or None, value=value, allowed=allowed)
        for p, line, (_, reason, value, allowed) in zip(paths, lines, problems, strict=True)
    ]
    return InputError.from_problems(structured)


#: Problems of one file whose YAML line is looked up (each lookup is cheap, but files can be huge).
_LINES_LOOKED_UP = 20


@contextmanager
def _located(file: str, field: str) -> Iterator[None]:
    """Give InputErrors raised by the model classes the file and the spec field they come from."""
    try:
        yield
    except InputError as exc:

        def locate(p: Problem) -> Problem:
            if p.field and p.field.startswith(field):
                where, inner = p.field, ""  # already a spec path
            else:
                where, inner = field, f" ({p.field})" if p.field else ""
            return dataclasses.replace(p, reason=p.reason + inner, file=p.file or file, field=where)

        raise InputError.from_problems([locate(p) for p in exc.problems]) from exc


@contextmanager
def _prefixed(prefix: str) -> Iterator[None]:
    """Put ``prefix.`` before the field of InputErrors raised inside (inline train / route)."""
    try:
        yield
    except InputError as exc:
        raise prefixed_error(exc, prefix) from exc


def prefixed_error(exc: InputError, prefix: str, file: str | None = None) -> InputError:
    """The error with ``prefix.`` put before the field of each of its problems (and ``file`` given
    to problems that name none)."""
    return InputError.from_problems(
        [
            dataclasses.replace(p, field=f"{prefix}.{p.field}" if p.field else prefix, file=p.file or file)
            for p in exc.problems
        ]
    )


# ====================================================================== base spec
@dataclasses.dataclass(frozen=True)
class _UnknownField:
    """The value of an unknown field, with the closest known name and the known names."""

    value: Any
    suggestion: str | None
    allowed: str


class Spec(BaseModel):
    """Base of every spec (the pydantic model of a block of a trainsim file).

    Unknown fields are errors (with the closest known name); a field named with its unit suffix
    (``mass_t``) takes a plain number, and the same name without the suffix a text with a unit
    (``mass: "49.8 t"``); every number is checked against :mod:`trainsim.model.bounds` (no
    true/false, no quoted numbers, finite, plausible). Subclasses raise their own problems with
    :func:`fail`.
    """

    # Built when first validated, not when defined: a class nested in another is then never built on
    # its own (its schema is generated once, inside the document that holds it), and a command
    # builds only the documents it reads (issue 14: building every spec of the readers at import
    # was a fifth of a `trainsim run`). A document that holds others names them in
    # ``_built_first`` so that their schemas are generated once and reused (:func:`built`).
    model_config = ConfigDict(extra="forbid", populate_by_name=True, allow_inf_nan=False, defer_build=True)

    #: documents nested in this one that are also validated on their own: built before this one
    _built_first: ClassVar[tuple[type[Spec], ...]] = ()

    @classmethod
    def _field_names(
        cls,
    ) -> tuple[dict[str, str], dict[str, tuple[str, str]], dict[str, tuple[str, str]], dict[str, _Numeric]]:
        """(names by key, generic name -> (field, unit), field -> its (name, unit) split, numeric
        fields -> how to check them), per class."""
        cached = cls.__dict__.get("_names_cache")
        if cached is not None:
            return cached
        names: dict[str, str] = {}
        numeric: dict[str, _Numeric] = {}
        for name, info in cls.model_fields.items():
            key = info.alias or name
            names[key] = name
            depth = _numeric_depth(info.annotation)
            if depth is not None:
                split = split_suffix(key)
                unit = UNITS[split[1]] if split else None
                bound = bounds.bound_for(key, unit.dimension if unit else None)
                literal = typing.get_origin(info.annotation) is Literal
                choices = typing.get_args(info.annotation) if literal else ()
                numeric[key] = _Numeric(
                    depth, bound, unit.symbol if unit else None, unit.factor if unit else 1.0, choices
                )
        generic: dict[str, tuple[str, str]] = {}
        suffixed: dict[str, tuple[str, str]] = {}
        for key in names:
            split = split_suffix(key)
            if split:
                suffixed[key] = split
                if split[0] not in names:
                    generic.setdefault(split[0], (key, split[1]))
        cached = (names, generic, suffixed, numeric)
        type.__setattr__(cls, "_names_cache", cached)
        return cached

    @model_validator(mode="before")
    @classmethod
    def _fields_and_units(cls, data: Any) -> Any:
        if not isinstance(data, dict):
            return data
        names, generic, suffixed, numeric = cls._field_names()
        out: dict[str, Any] = {}
        unknown: list[str] = []
        for key, value in data.items():
            if not isinstance(key, str):
                fail("field names must be text", value=key)
            if key in names:
                split = suffixed.get(key)
                if split and isinstance(value, str) and not _is_number_text(value):
                    fail(
                        f"'{key}' takes a plain number in {split[1]}; to give a unit, write "
                        f"'{split[0]}: {shown_value(value, 40)[1:-1]}' instead",
                        field=key,
                        value=value,
                    )
                if key in numeric and value is not None:
                    _check_numbers(value, numeric[key], key)
                out[key] = value
            elif key in generic:
                target, unit = generic[key]
                if target in data:
                    fail(f"give either '{key}' or '{target}', not both", field=key)
                try:
                    if isinstance(value, list):
                        out[target] = [to_unit(v, unit, require_unit=True, field=key) for v in value]
                    else:
                        out[target] = to_unit(value, unit, require_unit=True, field=key)
                except InputError as exc:
                    reason = exc.reason
                    if "without unit" in reason:
                        shown = shown_value(value, 40)
                        reason = f"'{key}' needs a unit, e.g. '{key}: {shown} {unit}'"
                        reason += f"; or write '{target}: {shown}'"
                    fail(reason, field=key, value=value, allowed=exc.allowed)
                if target in numeric:
                    _check_numbers(out[target], numeric[target], key, written=value)
            else:
                unknown.append(key)
        for key in unknown:
            # Left in place for pydantic's extra="forbid", which reports each one at its own location
            # without stopping the validation of the other fields; the wrapper carries the hint.
            close = difflib.get_close_matches(key, [*names, *generic], n=1, cutoff=0.6)
            out[key] = _UnknownField(data[key], close[0] if close else None, ", ".join(names))
        return out


def _is_number_text(text: str) -> bool:
    """Whether a text is a plain number ("12", " 3.5 "), i.e. a quoted number."""
    try:
        float(text)
    except ValueError:
        return False
    return True


@dataclasses.dataclass(frozen=True)
class _Numeric:
    """How to check a numeric field: list nesting depth (0: a number), its bound and its unit."""

    depth: int
    bound: bounds.Bound
    unit: str | None
    factor: float
    choices: tuple[int, ...] = ()  # a Literal of whole numbers (version: 1)


def _numeric_depth(annotation: Any) -> int | None:
    """0 for a number (float or int, optional, constrained), 1 for a list of numbers...; None otherwise."""
    if annotation is float or annotation is int:
        return 0
    origin = typing.get_origin(annotation)
    args = typing.get_args(annotation)
    if origin is Annotated:
        return _numeric_depth(args[0])
    if origin is Literal and args and all(type(a) is int for a in args):
        return 0  # e.g. version: 1 (true is not 1)
    if origin is typing.Union or origin is types.UnionType:
        depths = {_numeric_depth(a) for a in args if a is not type(None)}
        return depths.pop() if len(depths) == 1 else None
    if origin in (list, tuple) and args:
        inner = {_numeric_depth(a) for a in args if a is not Ellipsis}
        depth = inner.pop() if len(inner) == 1 else None
        return None if depth is None else depth + 1
    return None


def _check_numbers(value: Any, numeric: _Numeric, field: str, written: Any = None) -> None:
    """Refuse text, true/false, non-finite and implausible values in a numeric field (one rule for
    every trainsim file: a number is written as a number, and inside :mod:`trainsim.model.bounds`)."""
    if numeric.depth > 0:
        if isinstance(value, list):
            for i, item in enumerate(value):
                if item is not None:
                    _check_numbers(
                        item,
                        _Numeric(numeric.depth - 1, numeric.bound, numeric.unit, numeric.factor),
                        f"{field}[{i}]",
                        written[i] if isinstance(written, list) and i < len(written) else None,
                    )
        return  # not a list: pydantic says "must be a list"
    shown = written if written is not None else value
    if numeric.choices:
        allowed = ", ".join(str(c) for c in numeric.choices)
    else:
        allowed = numeric.bound.allowed(numeric.unit, numeric.factor)
    if isinstance(value, bool):
        fail("must be a number, not true/false", field=field, value=value, allowed=allowed)
    if isinstance(value, str):
        fail(
            "must be a number, not text (write it without quotes)", field=field, value=value, allowed=allowed
        )
    if isinstance(value, int | float):
        bound = numeric.bound
        if bound.low == 0 and -bound.high / numeric.factor <= value < 0:
            return  # a sign error of a plausible magnitude: the field's own rule says what is allowed
        try:
            bounds.check(value, bound, unit=numeric.unit, factor=numeric.factor)
        except InputError as exc:
            fail(exc.reason, field=field, value=shown, allowed=exc.allowed)


def _check_increasing(
    values: Sequence[float] | np.ndarray, field: str, *, strict: bool = True, what: str = "values"
) -> None:
    """The first value that does not increase (strictly) is an error; checked on the whole array."""
    arr = np.asarray(values, dtype=float)
    if arr.size < 2:
        return
    step = np.diff(arr)
    bad = np.flatnonzero(~(step > 0) if strict else ~(step >= 0))
    if bad.size:
        i = int(bad[0]) + 1
        fail(
            f"{what} must {'increase strictly' if strict else 'not decrease'}",
            field=f"{field}[{i}]",
            value=values[i] if not isinstance(values, np.ndarray) else float(arr[i]),
            allowed=f"{'>' if strict else '>='} {float(arr[i - 1]):g}",
        )


# ====================================================================== long lists
#: Fewest entries of a list read column by column (:class:`SpecTable`); shorter lists are validated
#: one model per entry (pydantic costs about 10 us per entry; a 200,000-entry route took 2 s).
TABLE_MIN_ENTRIES = 1000

_CONSTRAINTS = {
    "Gt": ("gt", np.greater),
    "Ge": ("ge", np.greater_equal),
    "Lt": ("lt", np.less),
    "Le": ("le", np.less_equal),
}


class SpecTable(Sequence[Any]):
    """A long list of a :class:`Spec` whose fields are all numbers, held as columns (numpy arrays,
    NaN where a field is absent), after a column-wise check that accepts exactly what validating one
    model per entry accepts. Entries are built (unvalidated, with the fields that were written) only
    when indexed; :meth:`column` gives the arrays to code that checks or converts the whole list."""

    def __init__(self, cls: type[Spec], columns: dict[str, np.ndarray], n: int) -> None:
        self.cls, self.columns, self._n = cls, columns, n

    def column(self, name: str) -> np.ndarray:
        """The values of ``name`` [the field's unit], NaN where it was not written."""
        return self.columns[name]

    def __len__(self) -> int:
        return self._n

    def __getitem__(self, index: Any) -> Any:
        if isinstance(index, slice):
            return [self[i] for i in range(*index.indices(self._n))]
        if index < 0:
            index += self._n
        if not 0 <= index < self._n:
            raise IndexError(index)
        values = {k: float(c[index]) for k, c in self.columns.items() if not np.isnan(c[index])}
        return self.cls.model_construct(_fields_set=set(values), **values)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Sequence) and list(self) == list(other)

    __hash__ = None  # type: ignore[assignment]


def _table_checks(cls: type[Spec]) -> dict[str, tuple[bool, list[tuple[Any, float]]]] | None:
    """{field: (required, [(numpy comparison, limit)])} of a spec whose fields are all plain numbers
    with gt/ge/lt/le constraints only; None if it has any other kind of field."""
    cached = cls.__dict__.get("_table_cache", False)
    if cached is not False:
        return cached
    out: dict[str, tuple[bool, list[tuple[Any, float]]]] | None = {}
    numeric = cls._field_names()[3]
    for name, info in cls.model_fields.items():
        key = info.alias or name
        kind = numeric.get(key)
        plain = kind is not None and kind.depth == 0 and not kind.choices
        if not plain or (not info.is_required() and info.default is not None):
            out = None  # text, flags, lists, or a default other than None: one model per entry
            break
        compare = []
        for meta in info.metadata:
            rule = _CONSTRAINTS.get(type(meta).__name__)
            if rule is None:
                break
            compare.append((rule[1], float(getattr(meta, rule[0]))))
        else:
            out[key] = (info.is_required(), compare)
            continue
        out = None
        break
    type.__setattr__(cls, "_table_cache", out)
    return out


def spec_table(cls: type[Spec], data: Any) -> SpecTable | None:
    """``data`` (a list of mappings) as a :class:`SpecTable` of ``cls`` if every entry is valid, checked
    column by column; None if the list is short, ``cls`` has other than number fields, or any entry
    is not plainly valid (then one model per entry gives the exact problem, its index and range).

    ``cls`` defines ``_table_ok(columns) -> bool``, its model validators on whole columns; a class
    without it is not read as a table."""
    if not isinstance(data, list) or len(data) < TABLE_MIN_ENTRIES:
        return None
    table_ok = getattr(cls, "_table_ok", None)
    checks = _table_checks(cls)
    if not checks or table_ok is None:
        return None
    keys = checks.keys()
    required = {k for k, (req, _) in checks.items() if req}
    for entry in data:
        if entry.__class__ is not dict or not entry.keys() <= keys or not required <= entry.keys():
            return None  # unknown fields, units in text, missing fields: one model per entry
    numeric = cls._field_names()[3]
    columns: dict[str, np.ndarray] = {}
    number = {int, float, type(None)}
    for key, (req, compare) in checks.items():
        raw = [entry.get(key) for entry in data]
        if not set(map(type, raw)) <= number:
            return None  # true/false, text, mappings: pydantic and _check_numbers say what is wrong
        try:
            values = np.array(raw, dtype=float)
        except (OverflowError, ValueError):
            return None
        absent = raw.count(None)
        if (req and absent) or int(np.isnan(values).sum()) != absent:
            return None  # a null where a number is needed, or a NaN written
        present = values[~np.isnan(values)] if absent else values
        kind = numeric[key]
        bound = kind.bound
        with np.errstate(over="ignore", invalid="ignore"):
            si = present * kind.factor
            inside = np.isfinite(si) & (si <= bound.high)
            inside &= si > bound.low if bound.low_open else si >= bound.low
            if bound.low == 0:  # a negative of plausible size is left to the field's own rule
                inside |= (present < 0) & (present >= -bound.high / kind.factor)
        if not inside.all():
            return None
        for op, limit in compare:
            if not op(present, limit).all():
                return None
        columns[key] = values
    if not table_ok(columns):
        return None
    return SpecTable(cls, columns, len(data))


def table_or_models(cls: type[Spec]) -> Any:
    """Validator of a list field of ``cls``: a :class:`SpecTable` for long valid lists, else pydantic's
    list of models (same problems, same field paths ``gradients[12].gradient_permille``)."""

    def validate(value: Any, handler: Any) -> Any:
        table = spec_table(cls, value)
        return table if table is not None else handler(value)

    validate.table_of = cls  # type: ignore[attr-defined]  # read by the quick reader (_quick_value)
    return WrapValidator(validate)


def table_as_list(value: Any, handler: Any) -> Any:
    """Serializer of a list field that may hold a :class:`SpecTable` (dump_yaml, web)."""
    return handler(list(value) if isinstance(value, SpecTable) else value)


def column(items: Sequence[Any], name: str) -> np.ndarray:
    """The values of field ``name`` of a list of specs or a :class:`SpecTable` (NaN for None)."""
    if isinstance(items, SpecTable):
        return items.column(name)
    return np.array([getattr(x, name) for x in items], dtype=float)


NonNegative = Annotated[float, Field(ge=0)]
Positive = Annotated[float, Field(gt=0)]
Fraction = Annotated[float, Field(gt=0, le=1)]


def _check_header(data: Any, schema: str, file: str, *, required: bool = True) -> None:
    """Check ``schema`` / ``version`` before the rest, so that a wrong file gets one clear error."""
    if not isinstance(data, dict):
        raise InputError(
            "expected a mapping of fields (key: value lines) at the top level",
            file=file,
            value=type(data).__name__,
        )
    if "schema" not in data:
        if required:
            raise InputError("missing 'schema' line", file=file, field="schema", allowed=", ".join(SCHEMAS))
        return
    if data["schema"] != schema:
        raise InputError(
            f"this reader expects a '{schema}' file",
            file=file,
            field="schema",
            value=data["schema"],
            allowed=schema,
        )
    if "version" not in data:
        raise InputError("missing 'version' line", file=file, field="version", allowed="1")
    if data["version"] not in SCHEMAS[schema]:
        raise InputError(
            f"unsupported version of '{schema}'",
            file=file,
            field="version",
            value=data["version"],
            allowed=", ".join(str(v) for v in SCHEMAS[schema]),
        )


def built(cls: type[Spec]) -> type[Spec]:
    """``cls`` with its validator built, after the documents it names in ``_built_first``.

    A deferred model nested in another that is built first has its schema generated inside the
    other and not kept: validating the nested one on its own later generates it again. Building
    the nested documents first lets the outer one reuse their schemas (a scenario reads its train
    and route files with their own validators)."""
    if not cls.__pydantic_complete__:
        for first in cls._built_first:
            built(first)
        cls.model_rebuild(force=True)
    return cls


# ====================================================================== the quick reader
# Building a document's pydantic validator costs more than a whole fastest run of the metro (about
# 60 ms CPU for a scenario with its train and route, plus pydantic's first-use imports); the quick
# reader makes the spec of a plainly valid mapping without it, from the same field declarations,
# the same before/after model validators and model_construct. It accepts a subset of what pydantic
# accepts (exact types: a number where a float is declared, text where text is; no coercion) and
# leaves everything else, every problem included, to pydantic's validation: error messages come
# only from there. tests/io/test_startup_specs.py checks that both give equal specs.


class _LeftToPydanticError(Exception):
    """The quick reader leaves this mapping to pydantic."""


@dataclasses.dataclass(frozen=True)
class _Tagged:
    """A union discriminated by a field (``Field(discriminator="model")``)."""

    field: str


_BOUNDS = {"Gt": operator.gt, "Ge": operator.ge, "Lt": operator.lt, "Le": operator.le}
_LENGTHS = {"MinLen": operator.ge, "MaxLen": operator.le}
_NOTHING = object()
#: the largest integer every float holds exactly: larger ones are left to pydantic's conversion
_EXACT_INT = 2**53


def quick_spec(cls: type[Spec], data: Any) -> Spec | None:
    """The spec of ``data`` made without building ``cls``'s validator, or None when the quick reader
    leaves it to pydantic (any problem, or anything but plain values of the declared types)."""
    try:
        return _quick(cls, data)
    except Exception:  # every doubt goes to pydantic, which validates and reports
        return None


def _quick(cls: type[Spec], data: Any) -> Spec:
    if type(data) is not dict:
        raise _LeftToPydanticError
    decorators = cls.__pydantic_decorators__
    modes = {name: d.info.mode for name, d in decorators.model_validators.items()}
    if (
        [n for n, m in modes.items() if m != "after"] != ["_fields_and_units"]
        or decorators.field_validators
        or decorators.validators
        or decorators.root_validators
        or cls.__private_attributes__
    ):
        raise _LeftToPydanticError
    data = cls._fields_and_units(data)  # problems raise: left to pydantic
    fields = cls.model_fields
    names = {info.alias or name: name for name, info in fields.items()}
    values: dict[str, Any] = {}
    for key, value in data.items():
        name = names.get(key)
        if name is None or isinstance(value, _UnknownField):
            raise _LeftToPydanticError
        values[name] = _quick_value(fields[name].annotation, [fields[name]], value)
    if any(info.is_required() and name not in values for name, info in fields.items()):
        raise _LeftToPydanticError
    spec = cls.model_construct(_fields_set=set(values), **values)
    for name, mode in modes.items():
        if mode == "after" and getattr(spec, name)() is not spec:
            raise _LeftToPydanticError
    return spec


def _quick_value(tp: Any, meta: list[Any], value: Any) -> Any:
    """``value`` of declared type ``tp`` with the metadata ``meta`` (constraints, discriminators)."""
    while typing.get_origin(tp) is Annotated:
        tp, *more = typing.get_args(tp)
        meta = [*meta, *more]
    flat: list[Any] = []
    for m in meta:
        if isinstance(m, FieldInfo):
            flat += m.metadata
            if isinstance(m.discriminator, str):
                flat.append(_Tagged(m.discriminator))
            elif m.discriminator is not None:
                flat.append(m.discriminator)
        else:
            flat.append(m)
    result: Any = _NOTHING
    for m in flat:
        if isinstance(m, WrapValidator):
            table_of = getattr(m.func, "table_of", None)
            if table_of is None:
                raise _LeftToPydanticError
            table = spec_table(table_of, value)
            if table is not None:
                result = table
    tags = [m for m in flat if isinstance(m, _Tagged | Discriminator)]
    if result is _NOTHING:
        result = _quick_typed(tp, tags[0] if tags else None, value)
    for m in flat:
        kind = type(m).__name__
        if kind in _BOUNDS:
            if result is not None and not _BOUNDS[kind](result, getattr(m, kind.lower())):
                raise _LeftToPydanticError
        elif kind in _LENGTHS:
            limit = m.min_length if kind == "MinLen" else m.max_length
            if result is not None and not _LENGTHS[kind](len(result), limit):
                raise _LeftToPydanticError
        elif not isinstance(m, WrapValidator | WrapSerializer | _Tagged | Discriminator | Tag):
            raise _LeftToPydanticError
    return result


def _quick_typed(tp: Any, tag: Any, value: Any) -> Any:
    if tp is Any:
        return value
    if tp is float:
        if type(value) is float and math.isfinite(value):
            return value
        if type(value) is int and abs(value) <= _EXACT_INT:
            return float(value)
        raise _LeftToPydanticError
    if tp in (int, bool, str):
        if type(value) is tp:
            return value
        raise _LeftToPydanticError
    if tp is type(None):
        if value is None:
            return None
        raise _LeftToPydanticError
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if origin is Literal:
        for choice in args:
            if type(choice) is type(value) and choice == value:
                return choice
        raise _LeftToPydanticError
    if origin is typing.Union or origin is types.UnionType:
        if value is None and type(None) in args:
            return None
        members = [a for a in args if a is not type(None)]
        if tag is not None:
            return _quick_tagged(members, tag, value)
        if len(members) == 1:
            return _quick_value(members[0], [], value)
        raise _LeftToPydanticError
    if origin is list and type(value) is list:
        return [_quick_value(args[0], [], item) for item in value]
    if origin is dict and type(value) is dict:
        return {_quick_value(args[0], [], k): _quick_value(args[1], [], v) for k, v in value.items()}
    if isinstance(tp, type) and issubclass(tp, Spec):
        return _quick(tp, value)
    raise _LeftToPydanticError


def _quick_tagged(members: list[Any], tag: Any, value: Any) -> Any:
    """The member of a discriminated union that ``value`` names."""
    if isinstance(tag, _Tagged):
        if type(value) is not dict:
            raise _LeftToPydanticError
        for member in members:
            if isinstance(member, type) and issubclass(member, Spec):
                choices = typing.get_args(member.model_fields[tag.field].annotation)
                if any(type(c) is type(value.get(tag.field)) and c == value.get(tag.field) for c in choices):
                    return _quick(member, value)
        raise _LeftToPydanticError
    if not callable(tag.discriminator):
        raise _LeftToPydanticError
    name = tag.discriminator(value)
    for member in members:
        if typing.get_origin(member) is Annotated and Tag(name) in typing.get_args(member)[1:]:
            return _quick_value(member, [], value)
    raise _LeftToPydanticError


#: Plainly valid documents of one kind read by the quick reader before that kind's pydantic validator
#: is built [-]. The quick reader saves the build (tens of ms) for a command that reads a few files, but
#: a validation costs it about 3 x the built validator's (0.70 against 0.23 ms for the metro's train):
#: a batch worker that reads the same kind of document for every run amortises the build instead.
QUICK_READS_BEFORE_BUILD = 32
_quick_reads: collections.Counter[type] = collections.Counter()


def _validate(
    cls: type[Spec], data: Any, schema: str, source: str, path: str | Path | None, *, header: bool
) -> Any:
    _check_header(data, schema, source, required=header)
    if not cls.__pydantic_complete__ and _quick_reads[cls] < QUICK_READS_BEFORE_BUILD:
        quick = quick_spec(cls, data)
        if quick is not None:
            _quick_reads[cls] += 1
            return quick
    try:
        return built(cls).model_validate(data)
    except ValidationError as exc:
        raise validation_error(exc, source, path) from None
