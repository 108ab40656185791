"""trainsim's own YAML formats: ``trainsim/train``, ``trainsim/route`` and ``trainsim/scenario``.

The formats are documented for their writers in ``docs/FORMAT.md``. Each file starts with::

    schema: trainsim/train        # or trainsim/route, trainsim/scenario
    version: 1

Rules that hold everywhere:

* every quantity has its unit in its field name (``mass_t``, ``speed_kmh``, ``force_kn``,
  ``position_m``...); the same name without the suffix takes a string with a unit instead
  (``mass: "49800 kg"``), see :mod:`trainsim.io.units`;
* unknown fields are errors (a typo must not silently fall back to a default); so are duplicate keys;
* what changes the result and has no obvious value has no default (``table_is`` of a braking table,
  the line-resistance formulas, the rotating mass factor).

Files are validated by pydantic v2 models (the ``*Spec`` classes); every validation problem becomes
one :class:`~trainsim.errors.InputError` naming the file, the YAML line when known, the field path
(``formation[2].mass_t``), the value and what is allowed. The validated spec is kept available
(:func:`read_train_spec`, ``spec.to_train()``, :func:`dump_yaml`) so that an editor can round-trip it.
"""

from __future__ import annotations

import dataclasses
import difflib
import itertools
import math
import types
import typing
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, ClassVar, Literal, NoReturn

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, Discriminator, Field, Tag, ValidationError, model_validator
from pydantic_core import PydanticCustomError

from trainsim.constants import GRAVITY_RANGE_MPS2, KMH, KN, KW, STANDARD_GRAVITY, TONNE
from trainsim.errors import InputError, Problem, shown_value
from trainsim.io import documents
from trainsim.io.units import UNITS, split_suffix, to_unit
from trainsim.model import (
    Braking,
    Curve,
    EffortCurve,
    Electrical,
    ElectrificationSection,
    GradientSection,
    LineResistanceSettings,
    Quadratic,
    ResistanceTerm,
    Route,
    SpeedLimit,
    Station,
    Train,
    Tunnel,
    Vehicle,
    bounds,
)
from trainsim.model.route import ApplyOver, CurveFormula, GradientFormula, TunnelFormula
from trainsim.model.scenario import RunSettings, Scenario
from trainsim.physics import line_resistance
from trainsim.physics import resistance as res

if TYPE_CHECKING:  # trainsim.optimize is imported where a driving block is read, not by every reader
    from trainsim.optimize.timetable import Timetable

__all__ = [
    "SCHEMAS",
    "RouteSpec",
    "ScenarioSpec",
    "Spec",
    "TrainSpec",
    "driving_from_spec",
    "driving_spec_from_dict",
    "dump_yaml",
    "fail",
    "load_route_yaml",
    "load_scenario_yaml",
    "load_train_yaml",
    "read_route_spec",
    "read_scenario_spec",
    "read_train_spec",
    "read_yaml",
    "register_file_readers",
    "route_from_dict",
    "route_spec_from_dict",
    "scenario_from_dict",
    "scenario_spec_from_dict",
    "settings_from_dict",
    "train_from_dict",
    "train_spec_from_dict",
    "validation_error",
]

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

    model_config = ConfigDict(extra="forbid", populate_by_name=True, allow_inf_nan=False)

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
    values: Sequence[float], field: str, *, strict: bool = True, what: str = "values"
) -> None:
    for i in range(1, len(values)):
        if values[i] < values[i - 1] or (strict and values[i] == values[i - 1]):
            fail(
                f"{what} must {'increase strictly' if strict else 'not decrease'}",
                field=f"{field}[{i}]",
                value=values[i],
                allowed=f"{'>' if strict else '>='} {values[i - 1]:g}",
            )


NonNegative = Annotated[float, Field(ge=0)]
Positive = Annotated[float, Field(gt=0)]
Fraction = Annotated[float, Field(gt=0, le=1)]


# ====================================================================== force tables
class _ForceTable(Spec):
    """A table of speeds [km/h] and forces [kN or N], interpolated linearly (source 002 eq. 1, 8)."""

    speed_kmh: list[float] = Field(min_length=1)
    force_kn: list[float] | None = None
    force_n: list[float] | None = None

    signed: ClassVar[bool] = False  # braking tables may be written negative (source 002)

    @model_validator(mode="after")
    def _check_table(self) -> _ForceTable:
        if (self.force_kn is None) == (self.force_n is None):
            fail("give the forces as exactly one of 'force_kn' or 'force_n'", field="force_kn")
        forces = self.forces_n_signed()
        name = "force_kn" if self.force_kn is not None else "force_n"
        if len(forces) != len(self.speed_kmh):
            fail(
                f"'speed_kmh' has {len(self.speed_kmh)} values but '{name}' has {len(forces)}",
                field=name,
                allowed="as many forces as speeds",
            )
        if self.speed_kmh[0] < 0:
            fail("speeds must be >= 0", field="speed_kmh[0]", value=self.speed_kmh[0], allowed=">= 0")
        _check_increasing(self.speed_kmh, "speed_kmh", what="table speeds")
        if self.signed:
            if any(f > 0 for f in forces) and any(f < 0 for f in forces):
                fail(
                    "braking forces must all have the same sign (positive magnitudes, or all negative "
                    "as in source 002)",
                    field=name,
                    value=[self._shown(f) for f in forces],
                )
        else:
            for i, f in enumerate(forces):
                if f < 0:
                    fail("forces must be >= 0", field=f"{name}[{i}]", value=self._shown(f), allowed=">= 0")
        return self

    def _shown(self, force_n: float) -> float:
        return force_n / KN if self.force_kn is not None else force_n

    def forces_n_signed(self) -> list[float]:
        """Forces as written, in N."""
        if self.force_kn is not None:
            return [f * KN for f in self.force_kn]
        return list(self.force_n or [])

    def curve(self, label: str) -> EffortCurve:
        """The table as an effort curve [N over m/s]; braking forces as magnitudes."""
        return EffortCurve.from_table(
            np.asarray(self.speed_kmh) * KMH, np.abs(self.forces_n_signed()), label=label
        )


# ====================================================================== traction
class _Caps(Spec):
    max_force_kn: Positive | None = None
    max_power_kw: Positive | None = None

    def _capped(self, curve: EffortCurve) -> EffortCurve:
        return curve.capped(
            force_cap_n=self.max_force_kn * KN if self.max_force_kn is not None else None,
            power_cap_w=self.max_power_kw * KW if self.max_power_kw is not None else None,
        )


class TableTraction(_ForceTable, _Caps):
    """``model: table``: maximum tractive effort by speed; ``per_motor`` tables times ``motors``
    (source 002 eq. 2: W_x = n_m w_x)."""

    model: Literal["table"]
    per_motor: bool = False
    motors: int | None = Field(default=None, ge=1)

    @model_validator(mode="after")
    def _check_motors(self) -> TableTraction:
        if self.per_motor and self.motors is None:
            fail("a per-motor table needs 'motors' (the number of motors or motor cars)", field="motors")
        if not self.per_motor and self.motors is not None:
            fail("'motors' only applies with 'per_motor: true'", field="motors", value=self.motors)
        return self

    def build(self, train: TrainSpec) -> EffortCurve:
        curve = self.curve("traction table")
        if self.per_motor:
            curve = curve.scaled(float(self.motors or 1), label=f"{self.motors} x traction table per motor")
        return self._capped(curve)


class PiecewiseInterval(Spec):
    """One interval of a piecewise law from ``from_kmh`` to the next interval's start (source 000):
    ``F = c0 + c1 V + c2 V^2 + ch / v`` with V in km/h and F in kN; ``ch_kw`` is the constant power
    P of a hyperbolic law ``F = P / v``."""

    from_kmh: float = Field(ge=0)
    c0_kn: float = 0.0
    c1_kn_per_kmh: float = 0.0
    c2_kn_per_kmh2: float = 0.0
    ch_kw: float = 0.0

    def row(self) -> tuple[float, float, float, float]:
        # V [km/h] = v [m/s] / KMH: the linear term scales by 1/KMH, the quadratic one by 1/KMH^2.
        return (
            self.c0_kn * KN,
            self.c1_kn_per_kmh * KN / KMH,
            self.c2_kn_per_kmh2 * KN / KMH**2,
            self.ch_kw * KW,
        )


class PiecewiseTraction(_Caps):
    """``model: piecewise``: quadratic or hyperbolic law per speed interval (source 000)."""

    model: Literal["piecewise"]
    intervals: list[PiecewiseInterval] = Field(min_length=1)

    @model_validator(mode="after")
    def _check_intervals(self) -> PiecewiseTraction:
        if self.intervals[0].from_kmh != 0:
            fail(
                "the first interval must start at 0 km/h",
                field="intervals[0].from_kmh",
                value=self.intervals[0].from_kmh,
                allowed="0",
            )
        starts = [i.from_kmh for i in self.intervals]
        for i in range(1, len(starts)):
            if starts[i] <= starts[i - 1]:
                fail(
                    "interval starts must increase strictly",
                    field=f"intervals[{i}].from_kmh",
                    value=starts[i],
                    allowed=f"> {starts[i - 1]:g}",
                )
        if self.intervals[0].ch_kw != 0 and self.max_force_kn is None:
            fail(
                "a hyperbolic law (ch_kw) from 0 km/h is infinite at standstill: give 'max_force_kn' "
                "(e.g. the adhesion limit) or start it at a speed above 0",
                field="max_force_kn",
            )
        return self

    def build(self, train: TrainSpec) -> EffortCurve:
        curve = EffortCurve.piecewise(
            np.array([i.from_kmh * KMH for i in self.intervals]),
            np.array([i.row() for i in self.intervals]),
            force_cap_n=self.max_force_kn * KN if self.max_force_kn is not None else float("inf"),
            label="piecewise traction law",
        )
        return self._capped(curve)


class PowerLimitedTraction(Spec):
    """``model: power_limited``: ``F = min(F_cap, eta P / v)`` (source 001: P_available = eta P_nom).

    The force cap is ``max_force_kn`` and/or the adhesion limit ``mu m_adh g`` (the smaller if both).
    ``efficiency`` is nominal power -> wheel, not the line-to-wheel efficiency of ``electrical``.
    """

    model: Literal["power_limited"]
    power_kw: Positive
    efficiency: Fraction
    max_force_kn: Positive | None = None
    adhesion_coefficient: Annotated[float, Field(gt=0, le=0.6)] | None = None
    adhesion_mass_t: Positive | None = None

    @model_validator(mode="after")
    def _check_cap(self) -> PowerLimitedTraction:
        if self.max_force_kn is None and self.adhesion_coefficient is None:
            fail(
                "power-limited traction needs a force limit at low speed: 'max_force_kn' and/or "
                "'adhesion_coefficient'",
                field="max_force_kn",
            )
        if self.adhesion_mass_t is not None and self.adhesion_coefficient is None:
            fail("'adhesion_mass_t' needs 'adhesion_coefficient'", field="adhesion_mass_t")
        return self

    def build(self, train: TrainSpec) -> EffortCurve:
        cap = math.inf
        if self.max_force_kn is not None:
            cap = self.max_force_kn * KN
        adhesion_kg = math.inf
        if self.adhesion_coefficient is not None:
            mass_kg = (
                self.adhesion_mass_t * TONNE if self.adhesion_mass_t is not None else train.adhesion_mass_kg()
            )
            if mass_kg is None:
                raise InputError(
                    "the adhesion limit needs the mass on driven axles: give 'adhesion_mass_t', or mark the "
                    "driving vehicles 'powered: true', or give the train's 'adhesion_mass_t'",
                    field="traction.adhesion_mass_t",
                )
            adhesion_kg = self.adhesion_coefficient * mass_kg
        # the law's constant bounds the force at the largest g a route may have; the adhesion limit
        # mu m_adh g itself is applied with the route's gravity when the run starts
        law_cap = min(cap, adhesion_kg * GRAVITY_RANGE_MPS2[1])
        curve = EffortCurve.power_limited(
            self.power_kw * KW, law_cap, self.efficiency, label=f"{self.power_kw:g} kW power-limited"
        )
        return dataclasses.replace(curve, force_cap_n=cap, adhesion_limit_kg=adhesion_kg)


TractionSpec = Annotated[
    TableTraction | PiecewiseTraction | PowerLimitedTraction,
    Field(discriminator="model"),
]


# ====================================================================== braking
class RegenerativeFraction(Spec):
    """``model: fraction_of_traction``: regenerative force = fraction x maximum traction
    (source 004: f_ru = 0.8 f_u(V))."""

    model: Literal["fraction_of_traction"]
    fraction: Fraction
    max_power_kw: Positive | None = None

    def build(self, traction: EffortCurve) -> EffortCurve:
        curve = traction.scaled(self.fraction, label=f"{self.fraction:g} x traction (regenerative)")
        return curve.capped(power_cap_w=self.max_power_kw * KW) if self.max_power_kw else curve


class RegenerativeTable(_ForceTable):
    """``model: table``: maximum regenerative braking force by speed (magnitudes; signs ignored)."""

    model: Literal["table"]
    max_power_kw: Positive | None = None
    signed: ClassVar[bool] = True

    def build(self, traction: EffortCurve) -> EffortCurve:
        curve = self.curve("regenerative braking table")
        return curve.capped(power_cap_w=self.max_power_kw * KW) if self.max_power_kw else curve


def _regen_tag(value: Any) -> str | None:
    if value is None or value == "none":
        return "none"
    if isinstance(value, dict):
        return value.get("model")
    return None


RegenerativeSpec = Annotated[
    Annotated[Literal["none"], Tag("none")]
    | Annotated[RegenerativeFraction, Tag("fraction_of_traction")]
    | Annotated[RegenerativeTable, Tag("table")],
    Discriminator(_regen_tag),
]


class _BrakingBase(Spec):
    regenerative: RegenerativeSpec | None = None

    def _regen(self, traction: EffortCurve) -> EffortCurve | None:
        if self.regenerative is None or self.regenerative == "none":
            return None
        return self.regenerative.build(traction)


class TableBraking(_ForceTable, _BrakingBase):
    """``model: table`` (``table_is`` required) or ``model: fraction_of_full`` (a table of the full
    braking force). Service force = ``service_fraction`` x table; ``service_fraction`` defaults to
    0.75 for a full-braking table (source 000: service braking is 0.75 x full braking, the rest is
    kept for emergencies) and to 1.0 for a service table. Negative forces (source 002 table 4) are
    read as magnitudes."""

    model: Literal["table", "fraction_of_full"]
    table_is: Literal["service", "full"] | None = None
    service_fraction: Fraction | None = None
    signed: ClassVar[bool] = True

    @model_validator(mode="after")
    def _check_kind(self) -> TableBraking:
        if self.model == "table" and self.table_is is None:
            fail(
                "say what the braking table is: 'table_is: service' (the force the train brakes with) or "
                "'table_is: full' (full/emergency force; service = 0.75 x full unless 'service_fraction')",
                field="table_is",
                allowed="service, full",
            )
        if self.model == "fraction_of_full" and self.table_is == "service":
            fail(
                "'fraction_of_full' scales a table of the full braking force",
                field="table_is",
                value=self.table_is,
                allowed="full",
            )
        return self

    @property
    def is_full(self) -> bool:
        return self.model == "fraction_of_full" or self.table_is == "full"

    @property
    def fraction(self) -> float:
        if self.service_fraction is not None:
            return self.service_fraction
        return 0.75 if self.is_full else 1.0

    def build(self, traction: EffortCurve) -> Braking:
        table = self.curve("braking table")
        if self.is_full:
            service = table.scaled(self.fraction, label=f"{self.fraction:g} x full braking table")
            return Braking(service_force=service, full_force=table, regenerative=self._regen(traction))
        service = table if self.fraction == 1.0 else table.scaled(self.fraction)
        return Braking(service_force=service, regenerative=self._regen(traction))


class DecelerationBraking(_BrakingBase):
    """``model: deceleration``: constant service deceleration [m/s^2], whatever resistance and grade
    (TrainRuns.jl convention); the sign is ignored because sources write it negative."""

    model: Literal["deceleration"]
    deceleration_mps2: float

    @model_validator(mode="after")
    def _check_value(self) -> DecelerationBraking:
        if not 0 < abs(self.deceleration_mps2) <= 5:
            fail(
                "the deceleration must be non-zero and realistic",
                field="deceleration_mps2",
                value=self.deceleration_mps2,
                allowed="0 < |a| <= 5 m/s^2",
            )
        return self

    def build(self, traction: EffortCurve) -> Braking:
        return Braking(deceleration_mps2=abs(self.deceleration_mps2), regenerative=self._regen(traction))


BrakingSpec = Annotated[TableBraking | DecelerationBraking, Field(discriminator="model")]


# ====================================================================== resistance
class _Term(Spec):
    """A running-resistance term; ``applies_to`` is ``train`` or the name of a vehicle of the
    formation (the term is then evaluated with that vehicle's mass, empty + load, and multiplied by
    its count)."""

    applies_to: str | None = None

    def law(self, mass_kg: float, axles: int | None) -> Quadratic:
        raise NotImplementedError

    @staticmethod
    def _axles(own: int | None, fallback: int | None, family: str) -> int:
        axles = own if own is not None else fallback
        if axles is None:
            raise InputError(
                f"'{family}' needs the number of axles: give 'axles' in the term or in the vehicle",
                field="axles",
            )
        return axles


class DavisTerm(_Term):
    """``R = A + B v + C v^2`` in SI (N, v in m/s) (Davis 1926; source 002 eq. 4)."""

    family: Literal["davis"]
    a_n: NonNegative
    b_n_s_per_m: float
    c_n_s2_per_m2: NonNegative

    def law(self, mass_kg: float, axles: int | None) -> Quadratic:
        return res.davis(self.a_n, self.b_n_s_per_m, self.c_n_s2_per_m2)


class DavisKnKmhTerm(_Term):
    """``R = A + B V + C V^2`` in kN with V in km/h (source 002 table 2 reading)."""

    family: Literal["davis_kn_kmh"]
    a_kn: NonNegative
    b_kn_per_kmh: float
    c_kn_per_kmh2: NonNegative

    def law(self, mass_kg: float, axles: int | None) -> Quadratic:
        return res.davis_kn_kmh(self.a_kn, self.b_kn_per_kmh, self.c_kn_per_kmh2)


class PerMassTerm(_Term):
    """``R_b = m (a1 + a2 v^2)`` (source 000), a1 [N/kg], a2 [N s^2/(kg m^2)], v in m/s."""

    family: Literal["per_mass"]
    a1_n_per_kg: NonNegative
    a2_n_s2_per_kg_m2: NonNegative

    def law(self, mass_kg: float, axles: int | None) -> Quadratic:
        return res.per_mass(mass_kg, self.a1_n_per_kg, self.a2_n_s2_per_kg_m2)


class SpecificTerm(_Term):
    """``w = a + b V + c V^2`` [N/kN] with V in km/h, force ``w m g / 1000`` (TB/T 1407, PTR)."""

    family: Literal["specific_n_per_kn"]
    a_n_per_kn: NonNegative
    b_n_per_kn_per_kmh: float
    c_n_per_kn_per_kmh2: NonNegative

    def law(self, mass_kg: float, axles: int | None) -> Quadratic:
        return res.specific_n_per_kn(
            mass_kg, self.a_n_per_kn, self.b_n_per_kn_per_kmh, self.c_n_per_kn_per_kmh2
        )


class RavTerm(_Term):
    """French ``RAV = A + B V + C V^2`` in N with V in km/h (source 001)."""

    family: Literal["rav"]
    a_n: NonNegative
    b_n_per_kmh: float
    c_n_per_kmh2: NonNegative

    def law(self, mass_kg: float, axles: int | None) -> Quadratic:
        return res.rav(self.a_n, self.b_n_per_kmh, self.c_n_per_kmh2)


class RavLocomotiveTerm(_Term):
    """BB 60000 locomotive RAV ``6.5 M + 130 N_e + 0.1 M V + 0.3 V^2`` (source 001)."""

    family: Literal["rav_locomotive_bb60000"]
    axles: int | None = Field(default=None, ge=1)

    def law(self, mass_kg: float, axles: int | None) -> Quadratic:
        return res.rav_locomotive_bb60000(mass_kg, self._axles(self.axles, axles, self.family))


class RavCarriageTerm(_Term):
    """Standard 4-axle carriage RAV ``12 M + 0.09 M V + 0.0044 M V^2`` (source 001)."""

    family: Literal["rav_carriage_4axle"]

    def law(self, mass_kg: float, axles: int | None) -> Quadratic:
        return res.rav_carriage_4axle(mass_kg)


class StrahlTerm(_Term):
    """Strahl (freight wagons): ``m g (f0 + f2 (v/v00)^2) / 1000`` (Wende 2003)."""

    family: Literal["strahl"]
    f0_permille: NonNegative
    f2_permille: NonNegative

    def law(self, mass_kg: float, axles: int | None) -> Quadratic:
        return res.strahl(mass_kg, self.f0_permille, self.f2_permille)


class SauthoffTerm(_Term):
    """Sauthoff (passenger coaches): ``m g (f0 + f1 v/v00 + f2 ((v+dv)/v00)^2) / 1000`` (Wende 2003)."""

    family: Literal["sauthoff"]
    f0_permille: NonNegative
    f1_permille: NonNegative
    f2_permille: NonNegative

    def law(self, mass_kg: float, axles: int | None) -> Quadratic:
        return res.sauthoff(mass_kg, self.f0_permille, self.f1_permille, self.f2_permille)


class WendeTerm(_Term):
    """Traction unit after Wende (2003) p. 151; ``driven_mass_t`` defaults to the whole mass."""

    family: Literal["wende"]
    f_driven_permille: NonNegative
    f_carrying_permille: NonNegative
    f_air_permille: NonNegative
    driven_mass_t: Positive | None = None

    def law(self, mass_kg: float, axles: int | None) -> Quadratic:
        driven = self.driven_mass_t * TONNE if self.driven_mass_t is not None else mass_kg
        return res.wende_traction_unit(
            mass_kg, driven, self.f_driven_permille, self.f_carrying_permille, self.f_air_permille
        )


class AltriosTerm(_Term):
    """US freight style (ALTRIOS): bearing per axle + rolling ratio x W + davis_b v W + rho cd_area v^2."""

    family: Literal["altrios"]
    bearing_force_per_axle_n: NonNegative
    rolling_ratio: NonNegative
    davis_b_s_per_m: NonNegative
    cd_area_m2: NonNegative
    axles: int | None = Field(default=None, ge=1)

    def law(self, mass_kg: float, axles: int | None) -> Quadratic:
        return res.altrios(
            mass_kg,
            self._axles(self.axles, axles, self.family),
            self.bearing_force_per_axle_n,
            self.rolling_ratio,
            self.davis_b_s_per_m,
            self.cd_area_m2,
        )


_TERMS = (
    DavisTerm,
    DavisKnKmhTerm,
    PerMassTerm,
    SpecificTerm,
    RavTerm,
    RavLocomotiveTerm,
    RavCarriageTerm,
    StrahlTerm,
    SauthoffTerm,
    WendeTerm,
    AltriosTerm,
)
RESISTANCE_FAMILY_NAMES = tuple(t.model_fields["family"].annotation.__args__[0] for t in _TERMS)
_UNION_FIELDS["resistance"] = ("family", ", ".join(RESISTANCE_FAMILY_NAMES))

ResistanceSpec = Annotated[
    DavisTerm
    | DavisKnKmhTerm
    | PerMassTerm
    | SpecificTerm
    | RavTerm
    | RavLocomotiveTerm
    | RavCarriageTerm
    | StrahlTerm
    | SauthoffTerm
    | WendeTerm
    | AltriosTerm,
    Field(discriminator="family"),
]


# ====================================================================== train
class VehicleSpec(Spec):
    """One vehicle type of the formation, ``count`` times."""

    name: str = Field(min_length=1)
    count: int = Field(default=1, ge=1)
    mass_t: Annotated[float, Field(gt=0, le=1000)]
    load_t: NonNegative = 0.0
    length_m: Annotated[float, Field(gt=0, le=500)]
    axles: int | None = Field(default=None, ge=1, le=64)
    rotating_mass_factor: Annotated[float, Field(ge=1, le=2)] | None = None
    powered: bool = False
    max_speed_kmh: Positive | None = None
    resistance: list[ResistanceSpec] | None = None

    @model_validator(mode="after")
    def _check_terms(self) -> VehicleSpec:
        for i, term in enumerate(self.resistance or []):
            if term.applies_to not in (None, self.name):
                fail(
                    "a term inside a vehicle applies to that vehicle; leave 'applies_to' out",
                    field=f"resistance[{i}].applies_to",
                    value=term.applies_to,
                    allowed=self.name,
                )
        return self

    @property
    def total_mass_kg(self) -> float:
        return (self.mass_t + self.load_t) * TONNE


class ElectricalSpec(Spec):
    """Electrical data; ``regenerative_efficiency`` defaults to ``traction_efficiency``."""

    line_voltage_v: Positive
    traction_efficiency: Fraction
    regenerative_efficiency: Annotated[float, Field(ge=0, le=1)] | None = None
    power_factor: Fraction = 1.0
    auxiliary_power_kw: NonNegative = 0.0
    receptivity: Annotated[float, Field(ge=0, le=1)] = 1.0

    def build(self) -> Electrical:
        return Electrical(
            line_voltage_v=self.line_voltage_v,
            traction_efficiency=self.traction_efficiency,
            regenerative_efficiency=(
                self.regenerative_efficiency
                if self.regenerative_efficiency is not None
                else self.traction_efficiency
            ),
            power_factor=self.power_factor,
            auxiliary_power_w=self.auxiliary_power_kw * KW,
            receptivity=self.receptivity,
        )


class TrainSpec(Spec):
    """A ``trainsim/train`` file (see docs/FORMAT.md)."""

    schema_id: Literal["trainsim/train"] = Field(default="trainsim/train", alias="schema")
    version: Literal[1] = 1
    name: str = Field(min_length=1)
    description: str | None = None
    formation: list[VehicleSpec] | None = Field(default=None, min_length=1)
    mass_t: Annotated[float, Field(gt=0, le=50000)] | None = None
    load_t: NonNegative | None = None
    length_m: Annotated[float, Field(gt=0, le=5000)] | None = None
    adhesion_mass_t: Positive | None = None
    rotating_mass_factor: Annotated[float, Field(ge=1, le=2)] | None = None
    gamma: Annotated[float, Field(ge=0, le=1)] | None = None
    max_speed_kmh: Annotated[float, Field(gt=0, lt=720)] | None = None
    traction: TractionSpec
    braking: BrakingSpec
    resistance: list[ResistanceSpec] = Field(default_factory=list)
    electrical: ElectricalSpec | None = None

    @model_validator(mode="after")
    def _check_train(self) -> TrainSpec:
        if not self.resistance and not any(v.resistance for v in self.formation or []):
            fail(
                "the train needs running resistance: a 'resistance' list (or 'resistance' in its vehicles)",
                field="resistance",
                allowed=", ".join(RESISTANCE_FAMILY_NAMES),
            )
        if self.formation is None:
            if self.mass_t is None:
                fail("give the train's 'formation' (list of vehicles) or its 'mass_t'", field="formation")
            if self.length_m is None:
                fail("a train given by 'mass_t' needs 'length_m'", field="length_m")
            vehicles: list[VehicleSpec] = []
        else:
            for key in ("mass_t", "load_t", "length_m"):
                if getattr(self, key) is not None:
                    fail(
                        f"'{key}' comes from the formation; give it per vehicle, not for the train",
                        field=key,
                        value=getattr(self, key),
                    )
            vehicles = self.formation
            seen: dict[str, int] = {}
            for i, v in enumerate(vehicles):
                if v.name == "train":
                    fail(
                        "'train' is reserved ('applies_to: train' means the whole train)",
                        field=f"formation[{i}].name",
                        value=v.name,
                    )
                if v.name in seen:
                    fail(
                        f"vehicle name already used by formation[{seen[v.name]}]",
                        field=f"formation[{i}].name",
                        value=v.name,
                    )
                seen[v.name] = i
        if self.rotating_mass_factor is not None and self.gamma is not None:
            fail("give 'rotating_mass_factor' or 'gamma' (= factor - 1), not both", field="gamma")
        if self.rotating_mass_factor is None and self.gamma is None:
            missing = [f"formation[{i}]" for i, v in enumerate(vehicles) if v.rotating_mass_factor is None]
            if not vehicles or missing:
                fail(
                    "the rotating mass factor is needed: give the train's 'rotating_mass_factor' "
                    "(rho >= 1) or 'gamma' (= rho - 1, source 002), or 'rotating_mass_factor' for every "
                    "vehicle" + (f" (missing in {', '.join(missing)})" if vehicles else ""),
                    field="rotating_mass_factor",
                )
        if self.max_speed_kmh is None and (not vehicles or any(v.max_speed_kmh is None for v in vehicles)):
            fail(
                "give the train's 'max_speed_kmh' (or 'max_speed_kmh' for every vehicle)",
                field="max_speed_kmh",
            )
        names = [v.name for v in vehicles]
        for i, term in enumerate(self.resistance):
            if term.applies_to is None:
                fail(
                    "say what the term applies to: 'train' or a vehicle name",
                    field=f"resistance[{i}].applies_to",
                    allowed=", ".join(["train", *names]),
                )
            if term.applies_to != "train" and term.applies_to not in names:
                fail(
                    "no vehicle of that name in the formation",
                    field=f"resistance[{i}].applies_to",
                    value=term.applies_to,
                    allowed=", ".join(["train", *names]),
                )
        return self

    # ------------------------------------------------------------------ derived figures
    def vehicles(self) -> list[VehicleSpec]:
        """The vehicle types of the formation (empty for a train given by its mass)."""
        return list(self.formation or [])

    def mass_kg(self) -> float:
        """Train mass including load [kg]."""
        if self.formation is None:
            return ((self.mass_t or 0.0) + (self.load_t or 0.0)) * TONNE
        return sum(v.count * v.total_mass_kg for v in self.formation)

    def adhesion_mass_kg(self) -> float | None:
        """Mass on driven axles [kg]: the train's ``adhesion_mass_t``, else the powered vehicles'
        mass (empty + load), else None."""
        if self.adhesion_mass_t is not None:
            return self.adhesion_mass_t * TONNE
        powered = [v for v in self.vehicles() if v.powered]
        return sum(v.count * v.total_mass_kg for v in powered) if powered else None

    def rho(self) -> float:
        """Rotating mass factor of the train [-].

        From the vehicles: each vehicle's rotating parts add ``(xi - 1) x empty mass`` of inertia
        (they do not grow with the load), so ``rho = 1 + sum n (xi - 1) m_empty / m_total``.
        """
        if self.rotating_mass_factor is not None:
            return self.rotating_mass_factor
        if self.gamma is not None:
            return 1.0 + self.gamma
        extra = sum(
            v.count * ((v.rotating_mass_factor or 1.0) - 1.0) * v.mass_t * TONNE for v in self.vehicles()
        )
        return 1.0 + extra / self.mass_kg()

    def max_speed_mps(self) -> float:
        if self.max_speed_kmh is not None:
            return self.max_speed_kmh * KMH
        return min(v.max_speed_kmh or math.inf for v in self.vehicles()) * KMH

    def resistance_terms(self, file: str = "") -> list[ResistanceTerm]:
        """The running-resistance terms, vehicle terms evaluated per vehicle and times its count."""
        vehicles = {v.name: v for v in self.vehicles()}
        terms: list[tuple[str, _Term, VehicleSpec | None]] = []
        for i, term in enumerate(self.resistance):
            terms.append((f"resistance[{i}]", term, vehicles.get(term.applies_to or "train")))
        for j, v in enumerate(self.vehicles()):
            for i, term in enumerate(v.resistance or []):
                terms.append((f"formation[{j}].resistance[{i}]", term, v))
        out = []
        all_axles = [v.axles for v in self.vehicles()]
        train_axles = (
            sum((v.axles or 0) * v.count for v in self.vehicles())
            if all_axles and all(a is not None for a in all_axles)
            else None
        )
        for field, term, vehicle in terms:
            family = getattr(term, "family", "?")
            with _located(file, field):
                if vehicle is None:
                    law = term.law(self.mass_kg(), train_axles)
                    label = f"{family} (whole train)"
                else:
                    if isinstance(term, RavCarriageTerm) and vehicle.axles not in (None, 4):
                        raise InputError(
                            "'rav_carriage_4axle' is the law of 4-axle carriages",
                            field="axles",
                            value=vehicle.axles,
                            allowed="4",
                        )
                    law = term.law(vehicle.total_mass_kg, vehicle.axles).scaled(float(vehicle.count))
                    label = f"{family}: {vehicle.count} x {vehicle.name}"
            out.append(ResistanceTerm(label, law))
        return out

    def notes(self) -> list[str]:
        """Defaults applied and readings made when building the train, for ``trainsim check``."""
        notes: list[str] = []
        if self.formation is not None and self.rotating_mass_factor is None and self.gamma is None:
            notes.append(f"rotating mass factor {self.rho():.4f} combined from the vehicles' factors")
        t = self.traction
        if isinstance(t, PowerLimitedTraction) and t.adhesion_coefficient and t.adhesion_mass_t is None:
            mass = self.adhesion_mass_kg()
            if mass is not None:
                notes.append(
                    f"adhesion mass {mass / TONNE:g} t (powered vehicles or the train's adhesion_mass_t)"
                )
        b = self.braking
        if isinstance(b, TableBraking):
            if b.is_full and b.service_fraction is None:
                notes.append("service braking = 0.75 x the full braking table (source 000 default)")
            if any(f < 0 for f in b.forces_n_signed()):
                notes.append("braking table given as negative forces: read as magnitudes")
        if b.regenerative is None:
            notes.append("no regenerative braking (the 'regenerative' key is absent: friction brakes only)")
        if self.electrical is not None:
            if self.electrical.regenerative_efficiency is None:
                notes.append("regenerative efficiency = traction efficiency (not given)")
        else:
            notes.append("no electrical data: energy at the wheel only")
        return notes

    def warnings(self) -> list[str]:
        """Inconsistencies that are not errors, for ``trainsim check``."""
        out = []
        if self.max_speed_kmh is not None and self.formation:
            for v in self.formation:
                if v.max_speed_kmh is not None and v.max_speed_kmh < self.max_speed_kmh:
                    out.append(
                        f"train max speed {self.max_speed_kmh:g} km/h exceeds the limit of vehicle "
                        f"'{v.name}' ({v.max_speed_kmh:g} km/h)"
                    )
        return out

    # ------------------------------------------------------------------ the model object
    def to_train(self, file: str = "<train>") -> Train:
        """The :class:`~trainsim.model.Train` in SI units."""
        with _located(file, "traction"):
            traction = self.traction.build(self)
        with _located(file, "braking"):
            braking = self.braking.build(traction)
        resistance = self.resistance_terms(file)
        electrical = None
        if self.electrical is not None:
            with _located(file, "electrical"):
                electrical = self.electrical.build()
        vehicles: list[Vehicle] = []
        for v in self.vehicles():
            vehicles += [
                Vehicle(
                    name=v.name,
                    mass_kg=v.mass_t * TONNE,
                    length_m=v.length_m,
                    load_kg=v.load_t * TONNE,
                    axles=v.axles,
                    rotating_mass_factor=v.rotating_mass_factor or self.rho(),
                    powered=v.powered,
                )
            ] * v.count
        length = (
            self.length_m if self.formation is None else sum(v.count * v.length_m for v in self.vehicles())
        )
        with _located(file, "train"):
            return Train(
                name=self.name,
                mass_kg=self.mass_kg(),
                rotating_mass_factor=self.rho(),
                length_m=float(length or 0.0),
                max_speed_mps=self.max_speed_mps(),
                traction=traction,
                braking=braking,
                resistance=tuple(resistance),
                electrical=electrical,
                vehicles=tuple(vehicles),
                adhesion_mass_kg=self.adhesion_mass_kg(),
            )


# ====================================================================== route
class StationSpec(Spec):
    name: str = Field(min_length=1)
    position_m: float
    dwell_s: NonNegative = 0.0
    stop: bool = True


class _Section(Spec):
    """A section from ``from_m`` to ``to_m`` (or ``from_m + length_m``)."""

    from_m: float
    to_m: float | None = None

    def stop(self) -> float:
        """End of a section that must have one (curves, tunnels) [m]."""
        end = self.end()
        return self.from_m if end is None else end

    def end(self) -> float | None:
        """End [m] from ``to_m`` or ``from_m + length_m``; None if neither is given."""
        length = self.__dict__.get("length_m")
        if self.to_m is not None:
            return self.to_m
        return self.from_m + length if length is not None else None

    @model_validator(mode="after")
    def _check_extent(self) -> _Section:
        length = self.__dict__.get("length_m")
        if self.to_m is not None and length is not None:
            fail("give 'to_m' or 'length_m', not both", field="length_m")
        end = self.end()
        if end is not None and not end > self.from_m:
            fail("a section must end after it starts", field="to_m", value=end, allowed=f"> {self.from_m:g}")
        return self


class SpeedLimitSpec(_Section):
    limit_kmh: Annotated[float, Field(gt=0, lt=720)]


class GradientSpec(_Section):
    gradient_permille: Annotated[float, Field(gt=-200, lt=200)]


class ElevationPointSpec(Spec):
    position_m: float
    elevation_m: float


class CurveSpec(_Section):
    """A curve: extent by ``to_m`` or ``length_m``; ``radius_m`` or ``central_angle_deg`` (source 002:
    R = (360 / 2 pi) L_r / alpha)."""

    length_m: Positive | None = None
    radius_m: Positive | None = None
    central_angle_deg: Annotated[float, Field(gt=0, lt=360)] | None = None

    @model_validator(mode="after")
    def _check_curve(self) -> CurveSpec:
        if self.end() is None:
            fail("a curve needs 'to_m' or 'length_m'", field="to_m")
        if (self.radius_m is None) == (self.central_angle_deg is None):
            fail("give exactly one of 'radius_m' or 'central_angle_deg'", field="radius_m")
        return self

    def radius(self) -> float:
        if self.radius_m is not None:
            return self.radius_m
        return line_resistance.curve_radius_from_angle(
            self.stop() - self.from_m, self.central_angle_deg or 0.0
        )


class TunnelSpec(_Section):
    length_m: Positive | None = None
    limiting_gradient: bool = False

    @model_validator(mode="after")
    def _check_tunnel(self) -> TunnelSpec:
        if self.end() is None:
            fail("a tunnel needs 'to_m' or 'length_m'", field="length_m")
        return self


class ElectrificationSpec(_Section):
    voltage_v: NonNegative


class LineResistanceSpec(Spec):
    """Formula choices; ``curve_formula`` and ``tunnel_formula`` are required (they change the result
    and no choice is neutral); ``gradient_formula`` defaults to ``small_angle`` (differs from ``exact``
    by < 0.01 % below 10 per mille) and ``apply_over`` to ``head`` (mass-point train)."""

    curve_formula: CurveFormula
    tunnel_formula: TunnelFormula
    gradient_formula: GradientFormula = "small_angle"
    apply_over: ApplyOver = "head"

    def build(self) -> LineResistanceSettings:
        return LineResistanceSettings(
            curve_formula=self.curve_formula,
            tunnel_formula=self.tunnel_formula,
            gradient_formula=self.gradient_formula,
            apply_over=self.apply_over,
        )


class RouteSpec(Spec):
    """A ``trainsim/route`` file (see docs/FORMAT.md)."""

    schema_id: Literal["trainsim/route"] = Field(default="trainsim/route", alias="schema")
    version: Literal[1] = 1
    name: str = Field(min_length=1)
    description: str | None = None
    start_m: float = 0.0
    length_m: Positive | None = None
    end_m: float | None = None
    stations: list[StationSpec] = Field(min_length=2)
    speed_limits: list[SpeedLimitSpec] = Field(min_length=1)
    gradients: list[GradientSpec] | None = None
    elevation: list[ElevationPointSpec] | None = None
    curves: list[CurveSpec] = Field(default_factory=list)
    tunnels: list[TunnelSpec] = Field(default_factory=list)
    electrification: list[ElectrificationSpec] = Field(default_factory=list)
    line_resistance: LineResistanceSpec
    #: g for every weight force on the route [m/s^2]; default the standard 9.80665 (sources differ:
    #: TTOBench 9.81, ALTRIOS 9.80155; see trainsim.constants)
    gravity_mps2: float = STANDARD_GRAVITY

    @model_validator(mode="after")
    def _check_route(self) -> RouteSpec:
        if (self.length_m is None) == (self.end_m is None):
            fail("give exactly one of 'length_m' or 'end_m'", field="length_m")
        end = self.end()
        if not end > self.start_m:
            fail(
                "the route must end after it starts", field="end_m", value=end, allowed=f"> {self.start_m:g}"
            )
        if self.gradients is not None and self.elevation is not None:
            fail("give 'gradients' or 'elevation', not both", field="elevation")
        self._check_stations(end)
        self._check_changes("speed_limits", self.speed_limits, end, cover=True)
        self._check_changes("gradients", self.gradients or [], end, cover=False)
        self._check_changes("electrification", self.electrification, end, cover=False)
        self._check_spans("curves", self.curves, end)
        self._check_spans("tunnels", self.tunnels, end)
        if self.elevation is not None:
            if len(self.elevation) < 2:
                fail("an elevation profile needs at least 2 points", field="elevation")
            _check_increasing([p.position_m for p in self.elevation], "elevation", what="positions")
        return self

    def end(self) -> float:
        return self.end_m if self.end_m is not None else self.start_m + (self.length_m or 0.0)

    def _check_stations(self, end: float) -> None:
        names: dict[str, int] = {}
        for i, s in enumerate(self.stations):
            if not self.start_m <= s.position_m <= end:
                fail(
                    "station outside the route",
                    field=f"stations[{i}].position_m",
                    value=s.position_m,
                    allowed=f"{self.start_m:g} .. {end:g} m",
                )
            if s.name in names:
                fail(
                    f"station name already used by stations[{names[s.name]}]",
                    field=f"stations[{i}].name",
                    value=s.name,
                )
            names[s.name] = i
        _check_increasing([s.position_m for s in self.stations], "stations", what="station positions")

    def _check_changes(self, name: str, items: Sequence[_Section], end: float, *, cover: bool) -> None:
        """Lists of changes: each entry runs to its own ``to_m`` or to the next entry's start."""
        for i, item in enumerate(items):
            if not self.start_m <= item.from_m < end:
                fail(
                    "section starts outside the route",
                    field=f"{name}[{i}].from_m",
                    value=item.from_m,
                    allowed=f"{self.start_m:g} <= from_m < {end:g} m",
                )
        _check_increasing([x.from_m for x in items], name, what="'from_m' positions")
        if cover and items and items[0].from_m != self.start_m:
            fail(
                f"{name} must start at the route start",
                field=f"{name}[0].from_m",
                value=items[0].from_m,
                allowed=f"{self.start_m:g}",
            )
        for i, item in enumerate(items):
            nxt = items[i + 1].from_m if i + 1 < len(items) else end
            if item.to_m is None:
                continue
            if item.to_m > nxt + 1e-9:
                fail(
                    "section runs into the next one"
                    if i + 1 < len(items)
                    else "section runs past the route end",
                    field=f"{name}[{i}].to_m",
                    value=item.to_m,
                    allowed=f"<= {nxt:g}",
                )
            if cover and item.to_m < nxt - 1e-9:
                fail(
                    f"gap in {name}: every position needs a value (leave 'to_m' out to run to the next one)",
                    field=f"{name}[{i}].to_m",
                    value=item.to_m,
                    allowed=f"{nxt:g}",
                )

    def _check_spans(self, name: str, items: Sequence[_Section], end: float) -> None:
        for i, item in enumerate(items):
            stop = item.stop()
            if item.from_m < self.start_m or stop > end + 1e-9:
                fail(
                    "section outside the route",
                    field=f"{name}[{i}]",
                    value=(item.from_m, stop),
                    allowed=f"{self.start_m:g} .. {end:g} m",
                )
            if i > 0:
                prev_end = items[i - 1].stop()
                if item.from_m < prev_end - 1e-9:
                    fail(
                        f"{name} must be listed in order and must not overlap",
                        field=f"{name}[{i}].from_m",
                        value=item.from_m,
                        allowed=f">= {prev_end:g}",
                    )

    @staticmethod
    def _ends(items: Sequence[_Section], end: float) -> list[tuple[float, float]]:
        return [
            (x.from_m, x.to_m if x.to_m is not None else (items[i + 1].from_m if i + 1 < len(items) else end))
            for i, x in enumerate(items)
        ]

    def notes(self) -> list[str]:
        notes = []
        fields_set = self.line_resistance.model_fields_set
        if "gradient_formula" not in fields_set:
            notes.append("line_resistance.gradient_formula not given: small_angle")
        if "apply_over" not in fields_set:
            notes.append("line_resistance.apply_over not given: head (mass-point train)")
        if not self.gradients and not self.elevation:
            notes.append("no gradients: level line")
        return notes

    def to_route(self, file: str = "<route>") -> Route:
        """The :class:`~trainsim.model.Route` in SI units."""
        end = self.end()
        limits = [
            SpeedLimit(a, b, x.limit_kmh * KMH)
            for (a, b), x in zip(self._ends(self.speed_limits, end), self.speed_limits, strict=True)
        ]
        gradients: list[GradientSection] = []
        if self.gradients:
            gradients = [
                GradientSection(a, b, x.gradient_permille)
                for (a, b), x in zip(self._ends(self.gradients, end), self.gradients, strict=True)
                if x.gradient_permille != 0
            ]
        elif self.elevation:
            pts = self.elevation
            for p, q in itertools.pairwise(pts):
                a, b = max(p.position_m, self.start_m), min(q.position_m, end)
                grade = (q.elevation_m - p.elevation_m) / (q.position_m - p.position_m) * 1000.0
                if b > a and grade != 0:
                    gradients.append(GradientSection(a, b, grade))
        with _located(file, "curves"):
            curves = [Curve(c.from_m, c.stop(), c.radius()) for c in self.curves]
        tunnels = [Tunnel(t.from_m, t.stop(), t.limiting_gradient) for t in self.tunnels]
        electrification = [
            ElectrificationSection(a, b, x.voltage_v)
            for (a, b), x in zip(self._ends(self.electrification, end), self.electrification, strict=True)
        ]
        stations = [Station(s.name, s.position_m, s.dwell_s, s.stop) for s in self.stations]
        with _located(file, "route"):
            return Route(
                name=self.name,
                start_m=self.start_m,
                end_m=end,
                stations=tuple(stations),
                speed_limits=tuple(limits),
                gradients=tuple(gradients),
                curves=tuple(curves),
                tunnels=tuple(tunnels),
                electrification=tuple(electrification),
                line_resistance=self.line_resistance.build(),
                gravity_mps2=self.gravity_mps2,
            )


# ====================================================================== scenario
class SettingsSpec(Spec):
    max_step_m: Annotated[float, Field(ge=0.01, le=1000)] = 10.0
    braking_fraction: Fraction = 1.0
    record_dwell: bool = True

    def build(self) -> RunSettings:
        return RunSettings(
            max_step_m=self.max_step_m, braking_fraction=self.braking_fraction, record_dwell=self.record_dwell
        )


def _file_or_inline(value: Any) -> str | None:
    if isinstance(value, str):
        return "file"
    if isinstance(value, dict):
        return "inline"
    return None


class DrivingSpec(Spec):
    """How the scenario is driven: the fastest run, or a strategy to a timetable (docs/OPTIMIZATION.md)."""

    strategy: Literal["fastest", "optimal", "lesov", "reference"] = "fastest"
    supplement: str | None = None
    timetable: str | None = None


class ScenarioSpec(Spec):
    """A ``trainsim/scenario`` file (see docs/FORMAT.md)."""

    schema_id: Literal["trainsim/scenario"] = Field(default="trainsim/scenario", alias="schema")
    version: Literal[1] = 1
    name: str = Field(min_length=1)
    description: str | None = None
    train: Annotated[
        Annotated[str, Tag("file")] | Annotated[TrainSpec, Tag("inline")], Discriminator(_file_or_inline)
    ]
    route: Annotated[
        Annotated[str, Tag("file")] | Annotated[RouteSpec, Tag("inline")], Discriminator(_file_or_inline)
    ]
    stops: list[str] | None = None
    dwell_s: dict[str, NonNegative] | None = None
    settings: SettingsSpec = Field(default_factory=SettingsSpec)
    driving: DrivingSpec | None = None

    def to_scenario(self, file: str = "<scenario>", base_dir: str | Path | None = None) -> Scenario:
        """The :class:`~trainsim.model.scenario.Scenario`; file names are relative to ``base_dir``."""
        base = Path(base_dir) if base_dir is not None else Path(".")
        if isinstance(self.train, str):
            train = _load_referenced("train", _resolve(base, self.train, file, "train"), file)
        else:
            with _prefixed("train"):
                train = self.train.to_train(file)
        if isinstance(self.route, str):
            route = _load_referenced("route", _resolve(base, self.route, file, "route"), file)
        else:
            with _prefixed("route"):
                route = self.route.to_route(file)
        route = apply_stops(route, self.stops, self.dwell_s, file=file)
        scenario = Scenario(name=self.name, train=train, route=route, settings=self.settings.build())
        if self.driving is None:
            return scenario
        from trainsim.optimize.timetable import read_timetable_yaml

        def read_timetable(name: str) -> Timetable:
            path = _resolve(base, name, file, "driving.timetable")
            return read_timetable_yaml(path, len(route.stops) - 1)

        strategy, timetable = driving_from_spec(self.driving, file, read_timetable)
        return dataclasses.replace(scenario, strategy=strategy, timetable=timetable)


def driving_spec_from_dict(data: Any, source: str = "<scenario>") -> DrivingSpec:
    """Validate a scenario's ``driving`` mapping; InputError naming ``source`` and ``driving.<field>``."""
    try:
        return DrivingSpec.model_validate(data)
    except ValidationError as exc:
        raise validation_error(exc, source, None, prefix="driving") from None


def driving_from_spec(
    spec: DrivingSpec, file: str, read_timetable: Callable[[str], Timetable]
) -> tuple[str, Timetable | None]:
    """The strategy and the timetable of a scenario's ``driving`` block.

    A timetable file comes before a supplement; a strategy other than ``fastest`` needs one of them.

    Args:
        spec: the validated block (:func:`driving_spec_from_dict`).
        file: the scenario's file (or run) named by the errors.
        read_timetable: the ``Timetable`` of a timetable file name as written in the block (the
            caller resolves it and checks its sections; its errors pass through).

    Returns:
        (strategy name, ``Timetable``, None for a fastest run without a schedule).

    Raises:
        InputError: an unreadable supplement (field ``driving.supplement``) or an energy-efficient
            strategy without a schedule (field ``driving``), naming ``file``.
    """
    from trainsim.optimize.timetable import line_supplement

    if spec.timetable is not None:
        timetable = read_timetable(spec.timetable)
    elif spec.supplement is not None:
        try:
            timetable = line_supplement(spec.supplement)
        except InputError as exc:
            raise prefixed_error(exc, "driving", file) from None
    else:
        timetable = None
    if spec.strategy != "fastest" and timetable is None:
        raise InputError(
            "an energy-efficient strategy needs a supplement or a timetable",
            file=file,
            field="driving",
            allowed="driving: {strategy: optimal, supplement: '10%'} or {timetable: FILE}",
        )
    return spec.strategy, timetable


#: Readers of the train and route files a scenario names, of every format ("train", "route" ->
#: function of the path): :mod:`trainsim.io.loader` installs its ``load_train`` and ``load_route``
#: when it is imported (it reads every format, and imports this module: it cannot be imported here).
_FILE_READERS: dict[str, Callable[[Path], Any]] = {}


def register_file_readers(*, train: Callable[[Path], Train], route: Callable[[Path], Route]) -> None:
    """Let scenarios name train and route files of any format (see :data:`_FILE_READERS`)."""
    _FILE_READERS.update(train=train, route=route)


def _load_referenced(kind: Literal["train", "route"], path: Path, file: str) -> Any:
    """The train or route of a file a scenario names: by the installed readers (every format), else
    a trainsim file read here."""
    reader = _FILE_READERS.get(kind)
    if reader is not None:
        return reader(path)
    data = read_yaml(path)
    if isinstance(data, dict) and data.get("schema") == f"trainsim/{kind}":
        if kind == "train":
            return train_spec_from_dict(data, str(path), path=path).to_train(str(path))
        return route_spec_from_dict(data, str(path), path=path).to_route(str(path))
    raise InputError(
        f"this {kind} file is not a trainsim file: files of other formats are read through "
        "trainsim.io.loader (trainsim.load_scenario)",
        file=file,
        field=kind,
        value=str(path),
    )


def _resolve(base: Path, name: str, file: str, field: str) -> Path:
    path = Path(name)
    path = path if path.is_absolute() else base / path
    try:
        exists = path.exists()
    except (OSError, ValueError):  # a name too long, a NUL byte in it...
        raise InputError("not a usable file name", file=file, field=field, value=name) from None
    if not exists:
        raise InputError("referenced file not found", file=file, field=field, value=str(path))
    return path


def apply_stops(
    route: Route,
    stops: Sequence[str] | None,
    dwell_s: dict[str, float] | None,
    *,
    file: str | None = None,
) -> Route:
    """The route with the scenario's stop pattern: with ``stops`` only the named stations are stops;
    ``dwell_s`` overrides dwell times by station name."""
    names = [s.name for s in route.stations]
    for i, name in enumerate(stops or []):
        if name not in names:
            raise InputError(
                "no station of that name on the route",
                file=file,
                field=f"stops[{i}]",
                value=name,
                allowed=", ".join(names),
            )
    for name in dwell_s or {}:
        if name not in names:
            raise InputError(
                "no station of that name on the route",
                file=file,
                field=f"dwell_s.{name}",
                value=name,
                allowed=", ".join(names),
            )
    if stops is None and not dwell_s:
        return route
    stations = []
    for s in route.stations:
        stop = s.stop if stops is None else s.name in stops
        dwell = (dwell_s or {}).get(s.name, s.dwell_s)
        stations.append(dataclasses.replace(s, stop=stop, dwell_s=dwell))
    return dataclasses.replace(route, stations=tuple(stations))


# ====================================================================== public functions
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


def _validate(
    cls: type[Spec], data: Any, schema: str, source: str, path: str | Path | None, *, header: bool
) -> Any:
    _check_header(data, schema, source, required=header)
    try:
        return cls.model_validate(data)
    except ValidationError as exc:
        raise validation_error(exc, source, path) from None


def train_spec_from_dict(data: Any, source: str = "<train>", *, path: str | Path | None = None) -> TrainSpec:
    """Validate a ``trainsim/train`` mapping; InputError naming ``source`` and the field on failure."""
    return _validate(TrainSpec, data, "trainsim/train", source, path, header=True)


def route_spec_from_dict(data: Any, source: str = "<route>", *, path: str | Path | None = None) -> RouteSpec:
    """Validate a ``trainsim/route`` mapping."""
    return _validate(RouteSpec, data, "trainsim/route", source, path, header=True)


def scenario_spec_from_dict(
    data: Any, source: str = "<scenario>", *, path: str | Path | None = None
) -> ScenarioSpec:
    """Validate a ``trainsim/scenario`` mapping (inline train and route may omit schema/version)."""
    return _validate(ScenarioSpec, data, "trainsim/scenario", source, path, header=True)


def settings_from_dict(data: Any, source: str = "<settings>") -> RunSettings:
    """RunSettings from a mapping of the scenario ``settings`` keys."""
    try:
        return SettingsSpec.model_validate(data).build()
    except ValidationError as exc:
        raise validation_error(exc, source, None, prefix="settings") from None


def train_from_dict(data: Any, source: str = "<train>") -> Train:
    """A Train from a ``trainsim/train`` mapping (web layer)."""
    return train_spec_from_dict(data, source).to_train(source)


def route_from_dict(data: Any, source: str = "<route>") -> Route:
    """A Route from a ``trainsim/route`` mapping (web layer)."""
    return route_spec_from_dict(data, source).to_route(source)


def scenario_from_dict(data: Any, source: str = "<scenario>", base_dir: str | Path | None = None) -> Scenario:
    """A Scenario from a ``trainsim/scenario`` mapping; train/route file names relative to ``base_dir``."""
    return scenario_spec_from_dict(data, source).to_scenario(source, base_dir)


def _read(path: str | Path, reader: Callable[..., Any]) -> Any:
    return reader(read_yaml(path), str(path), path=path)


def read_train_spec(path: str | Path) -> TrainSpec:
    """The validated spec of a ``trainsim/train`` file (for editors: ``dump_yaml(spec)`` round-trips)."""
    return _read(path, train_spec_from_dict)


def read_route_spec(path: str | Path) -> RouteSpec:
    """The validated spec of a ``trainsim/route`` file."""
    return _read(path, route_spec_from_dict)


def read_scenario_spec(path: str | Path) -> ScenarioSpec:
    """The validated spec of a ``trainsim/scenario`` file."""
    return _read(path, scenario_spec_from_dict)


def load_train_yaml(path: str | Path) -> Train:
    """A Train from a ``trainsim/train`` file."""
    return read_train_spec(path).to_train(str(path))


def load_route_yaml(path: str | Path) -> Route:
    """A Route from a ``trainsim/route`` file."""
    return read_route_spec(path).to_route(str(path))


def load_scenario_yaml(path: str | Path) -> Scenario:
    """A Scenario from a ``trainsim/scenario`` file; train and route files relative to it."""
    return read_scenario_spec(path).to_scenario(str(path), Path(path).parent)


def dump_yaml(spec: BaseModel) -> str:
    """A spec as YAML text that reads back to an equal spec (fields left at their default omitted,
    except ``schema`` and ``version``)."""
    data = spec.model_dump(mode="json", by_alias=True, exclude_unset=True)
    for key, value in (
        ("schema", getattr(spec, "schema_id", None)),
        ("version", getattr(spec, "version", None)),
    ):
        if value is not None:
            data[key] = value
    order = ["schema", "version", "name"]
    data = {**{k: data[k] for k in order if k in data}, **{k: v for k, v in data.items() if k not in order}}
    return yaml.safe_dump(data, sort_keys=False, allow_unicode=True)


# Former private names, kept for modules that used them (multipoint/spec.py): use Spec, fail and
# validation_error instead.
_Spec = Spec
_fail = fail
_validation_error = validation_error
