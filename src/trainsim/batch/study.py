"""The study file (``schema: trainsim/study``): a base scenario, axes, random samples, explicit runs.

A study is read and checked once, in the process that starts it: the base scenario and every explicit
run are validated by the normal scenario reader (an invalid base is an error of the study, not a
thousand failed runs), every field path is checked against the data it points into, and the set of
runs is expanded with its parameters and stable run ids (:mod:`trainsim.batch.expand`). What varies
from run to run is validated per run in the workers; a value the reader rejects makes that run a
failure row, never stops the study.

The format is documented in docs/BATCH.md.
"""

from __future__ import annotations

import copy
import difflib
import hashlib
import json
import math
import re
from dataclasses import dataclass
from pathlib import Path as FsPath
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from trainsim.batch.expand import MAX_RUNS, Expansion, expand
from trainsim.batch.paths import Path, get_values, parse_path, set_value
from trainsim.errors import InputError, Problem

__all__ = [
    "MULTI_POINT_KEYS",
    "PARTS",
    "STUDY_SCHEMA",
    "AxisSpec",
    "DistributionSpec",
    "Entry",
    "RunEntrySpec",
    "SamplesSpec",
    "Study",
    "StudySpec",
    "load_study",
    "parse_clock",
    "scenario_from_data",
    "study_from_dict",
]

STUDY_SCHEMA = "trainsim/study"
#: The top-level keys of a scenario a path may start with.
PARTS = ("train", "route", "settings", "stops", "dwell_s", "driving", "model", "multi_point")
#: Keys of a scenario file that choose the multi-point model and give its settings (docs/MULTIPOINT.md).
MULTI_POINT_KEYS = ("model", "multi_point")
#: Largest number of runs a study may expand to (its parameters are held in memory).


# ====================================================================== the file's model
class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", populate_by_name=True, allow_inf_nan=False)


class RangeSpec(_Model):
    """``{from, to, step}`` (``to`` included when it falls on a step) or ``{from, to, count}``."""

    from_: float = Field(alias="from")
    to: float
    step: Annotated[float, Field(gt=0)] | None = None
    count: Annotated[int, Field(ge=1, le=MAX_RUNS)] | None = None

    @model_validator(mode="after")
    def _check(self) -> RangeSpec:
        if (self.step is None) == (self.count is None):
            raise ValueError("give exactly one of 'step' or 'count'")
        if self.to < self.from_:
            raise ValueError(f"'to' ({self.to:g}) is below 'from' ({self.from_:g})")
        if self.step is not None and (self.to - self.from_) / self.step > MAX_RUNS:
            raise ValueError(f"the range has more than {MAX_RUNS} values")
        return self

    def values(self) -> list[float | int]:
        ints = all(float(x).is_integer() for x in (self.from_, self.to, self.step or 1.0))
        if self.count is not None:
            if self.count == 1:
                out = [self.from_]
            else:
                out = [self.from_ + (self.to - self.from_) * k / (self.count - 1) for k in range(self.count)]
            ints = ints and all(float(x).is_integer() for x in out)
        else:
            step = float(self.step or 1.0)
            n = math.floor((self.to - self.from_) / step + 1e-9)
            out = [self.from_ + k * step for k in range(n + 1)]
        # 0.1 + 2 * 0.05 is 0.20000000000000004: values are rounded to 12 significant digits
        return [round(x) if ints else float(f"{x:.12g}") for x in out]


class AxisSpec(_Model):
    """One axis of a sweep: a field (or several fields moved together) and its values."""

    field: str | None = None
    fields: list[str] | None = Field(default=None, min_length=1)
    values: list[Any] | None = Field(default=None, min_length=1)
    range: RangeSpec | None = None
    relative: bool = False

    @model_validator(mode="after")
    def _check(self) -> AxisSpec:
        if (self.field is None) == (self.fields is None):
            raise ValueError("give exactly one of 'field' (one path) or 'fields' (paths moved together)")
        if (self.values is None) == (self.range is None):
            raise ValueError("give exactly one of 'values' or 'range'")
        if self.fields is not None:
            if self.range is not None:
                raise ValueError("'range' is for one field; with 'fields' give 'values' as lists")
            for k, v in enumerate(self.values or []):
                if not isinstance(v, list) or len(v) != len(self.fields):
                    raise ValueError(
                        f"values[{k}] must be a list of {len(self.fields)} values, one per field (got {v!r})"
                    )
        return self

    def paths(self) -> list[str]:
        return list(self.fields) if self.fields is not None else [str(self.field)]

    def points(self) -> list[tuple[Any, ...]]:
        """The axis values, each as a tuple with one value per field."""
        if self.range is not None:
            return [(v,) for v in self.range.values()]
        if self.fields is not None:
            return [tuple(v) for v in self.values or []]
        return [(v,) for v in self.values or []]


#: The parameters each distribution needs.
_NEEDS: dict[str, tuple[str, ...]] = {
    "uniform": ("low", "high"),
    "normal": ("mean", "std"),
    "triangular": ("low", "mode", "high"),
    "choice": ("values",),
}


class DistributionSpec(_Model):
    """A random distribution of one field (Monte Carlo)."""

    distribution: Literal["uniform", "normal", "triangular", "choice"]
    low: float | None = None
    high: float | None = None
    mode: float | None = None
    mean: float | None = None
    std: Annotated[float, Field(ge=0)] | None = None
    min: float | None = None
    max: float | None = None
    values: list[Any] | None = Field(default=None, min_length=1)
    weights: list[Annotated[float, Field(ge=0)]] | None = None
    relative: bool = False

    @model_validator(mode="after")
    def _check(self) -> DistributionSpec:
        needs = _NEEDS[self.distribution]
        missing = [k for k in needs if getattr(self, k) is None]
        if missing:
            raise ValueError(f"a {self.distribution} distribution needs {', '.join(missing)}")
        allowed = {*needs, "distribution", "relative"}
        allowed |= {"min", "max"} if self.distribution == "normal" else set()
        allowed |= {"weights"} if self.distribution == "choice" else set()
        extra = sorted(k for k in self.model_fields_set if k not in allowed)
        if extra:
            raise ValueError(
                f"{', '.join(extra)} not used by a {self.distribution} distribution "
                f"(it takes {', '.join(sorted(allowed - {'distribution'}))})"
            )
        if self.distribution in ("uniform", "triangular") and not self.low <= self.high:  # type: ignore[operator]
            raise ValueError("'low' must not exceed 'high'")
        if self.distribution == "triangular" and not self.low <= self.mode <= self.high:  # type: ignore[operator]
            raise ValueError("'mode' must lie between 'low' and 'high'")
        if self.min is not None and self.max is not None and self.min >= self.max:
            raise ValueError("'min' must be below 'max'")
        if self.weights is not None:
            if len(self.weights) != len(self.values or []):
                raise ValueError("'weights' needs one weight per value")
            if sum(self.weights) <= 0:
                raise ValueError("the weights must not all be 0")
        numbers = all(isinstance(v, int | float) and not isinstance(v, bool) for v in self.values or [])
        if self.relative and self.distribution == "choice" and not numbers:
            raise ValueError("relative choices must be numbers (factors)")
        return self


class SamplesSpec(_Model):
    """Seeded random samples (Monte Carlo): ``count`` runs, each with a value drawn for every field."""

    count: Annotated[int, Field(ge=1, le=MAX_RUNS)]
    seed: Annotated[int, Field(ge=0)]
    fields: dict[str, DistributionSpec] = Field(min_length=1)


#: Departures one run entry may expand to (a day at one per second is 86,400).
MAX_DEPARTURES = 100_000


class DeparturesSpec(_Model):
    """Departures at a regular interval: ``first``, ``last`` (included) and ``every_min``."""

    first: str | float
    last: str | float
    # a second at least: a finer interval is no timetable (and 1e-5 min would expand to millions of runs)
    every_min: Annotated[float, Field(ge=1.0 / 60.0)]


class RunEntrySpec(_Model):
    """One explicit run (or several, one per departure): its train, route, stops and times."""

    name: str = Field(min_length=1)
    train: str | dict[str, Any] | None = None
    route: str | dict[str, Any] | None = None
    stops: list[str] | None = None
    dwell_s: dict[str, Annotated[float, Field(ge=0)]] | None = None
    settings: dict[str, Any] | None = None
    driving: dict[str, Any] | None = None
    set: dict[str, Any] | None = None
    departure: str | float | None = None
    departures: list[str | float] | DeparturesSpec | None = None

    @model_validator(mode="after")
    def _check(self) -> RunEntrySpec:
        if self.departure is not None and self.departures is not None:
            raise ValueError("give 'departure' (one run) or 'departures' (several), not both")
        return self


class StudySpec(_Model):
    """A ``trainsim/study`` file (docs/BATCH.md)."""

    schema_id: Literal["trainsim/study"] = Field(alias="schema")
    version: Literal[1]
    name: str = Field(min_length=1)
    description: str | None = None
    base: str | dict[str, Any] | None = None
    runs: list[RunEntrySpec] | None = Field(default=None, min_length=1)
    axes: list[AxisSpec] = Field(default_factory=list)
    combine: Literal["product", "zip"] = "product"
    samples: SamplesSpec | None = None
    chunk_size: Annotated[int, Field(ge=1, le=100_000)] | None = None

    @model_validator(mode="after")
    def _check(self) -> StudySpec:
        if self.base is None and self.runs is None:
            raise ValueError("a study needs a 'base' scenario, a list of 'runs', or both")
        return self


_MODELS: tuple[type[BaseModel], ...] = (
    StudySpec,
    RunEntrySpec,
    AxisSpec,
    RangeSpec,
    SamplesSpec,
    DistributionSpec,
    DeparturesSpec,
)
_KNOWN_FIELDS = sorted({info.alias or name for m in _MODELS for name, info in m.model_fields.items()})


def _loc_text(loc: tuple[Any, ...]) -> str:
    text = ""
    for part in loc:
        if isinstance(part, int):
            text += f"[{part}]"
        elif part in ("str", "dict[str,any]", "list[union[str,float]]", "DeparturesSpec", "float"):
            continue  # pydantic's union branch names are not fields of the file
        else:
            text += ("." if text else "") + str(part)
    return text


def _study_error(exc: ValidationError, file: str) -> InputError:
    """One InputError naming every problem of the study file, with did-you-mean hints."""
    problems: dict[str, str] = {}
    for err in exc.errors(include_url=False):
        loc = tuple(err["loc"])
        field = _loc_text(loc)
        kind = err["type"]
        if kind == "extra_forbidden":
            key = str(loc[-1]) if loc else ""
            close = difflib.get_close_matches(key, _KNOWN_FIELDS, n=1, cutoff=0.6)
            text = "unknown field" + (f" (did you mean '{close[0]}'?)" if close else "")
        elif kind == "missing":
            text = "required field is missing"
        elif kind in ("value_error", "assertion_error"):
            text = err["msg"].removeprefix("Value error, ")
        else:
            value = err.get("input")
            shown = "" if isinstance(value, dict | list) else f" (got {value!r})"
            text = err["msg"][0].lower() + err["msg"][1:] + shown
        # a union reports one error per branch: keep the first of each field
        problems.setdefault(field, text)
    items = list(problems.items())
    if len(items) == 1:
        field, text = items[0]
        return InputError(text, file=file, field=field or None)
    joined = "; ".join(f"({i}) {f or '(top level)'}: {t}" for i, (f, t) in enumerate(items, 1))
    error = InputError(f"{len(items)} problems: {joined}", file=file)
    error.field = items[0][0] or None
    return error


# ====================================================================== clock times
_CLOCK = re.compile(r"^\s*(\d{1,3}):([0-5]\d)(?::([0-5]\d(?:\.\d+)?))?\s*$")


def parse_clock(value: str | float | int, *, field: str = "departure", file: str | None = None) -> float:
    """Seconds since midnight from ``"HH:MM"``, ``"HH:MM:SS"`` (hours may pass 24) or a number of
    seconds."""
    if isinstance(value, bool):
        raise InputError("not a time", file=file, field=field, value=value, allowed="HH:MM[:SS] or seconds")
    if isinstance(value, int | float):
        if not math.isfinite(value) or value < 0:
            raise InputError("not a time", file=file, field=field, value=value, allowed=">= 0 s")
        return float(value)
    m = _CLOCK.match(str(value))
    if not m:
        raise InputError(
            "not a time", file=file, field=field, value=value, allowed="HH:MM or HH:MM:SS, or seconds"
        )
    return int(m.group(1)) * 3600.0 + int(m.group(2)) * 60.0 + float(m.group(3) or 0.0)


# ====================================================================== resolved study
@dataclass(frozen=True)
class Entry:
    """A scenario every run of the study starts from: the base, or one explicit run.

    Attributes:
        name: the explicit run's name (None for the base of a sweep).
        data: scenario data; ``train`` and ``route`` are inline mappings (trainsim files are read and
            inlined) or the absolute path of a file of another format (railtoolkit...), which cannot be
            varied.
        departures: departure times [s since midnight], or None.
    """

    name: str | None
    data: dict[str, Any]
    departures: tuple[float, ...] | None


@dataclass(frozen=True)
class ParamColumn:
    """A parameter column of the results: the run name, departure, sample index or a varied field.

    ``path`` is the field written by the column's values (None for run / departure_s / sample);
    ``relative`` columns hold factors applied to the value already there.
    """

    name: str
    path: str | None = None
    relative: bool = False
    where: str = ""  # where the study file sets it, for error messages
    kind: str = "axis"  # run, departure, sample_index, axis or sampled


def _canonical(obj: Any) -> str:
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), ensure_ascii=False, default=str)


def _read_part(value: Any, kind: str, base_dir: FsPath, file: str, field: str) -> Any:
    """Inline a trainsim train/route file as data; keep a file of another format (railtoolkit...) as
    its absolute path, read by the loader in the workers."""
    from trainsim.io import loader
    from trainsim.io import trainsim_yaml as tsy

    if isinstance(value, dict):
        data = copy.deepcopy(value)
        data.setdefault("schema", f"trainsim/{kind}")
        data.setdefault("version", 1)
        return data
    if not isinstance(value, str):
        raise InputError(f"'{field}' must be a file name or a mapping", file=file, field=field, value=value)
    path = FsPath(value)
    path = path if path.is_absolute() else base_dir / path
    if not _exists(path, file, field):
        raise InputError("referenced file not found", file=file, field=field, value=str(path))
    detected = loader.detect_format(path)
    if detected.kind != kind:
        raise InputError(
            f"this is a {detected.kind} file ({detected.format}), expected a {kind} file",
            file=file,
            field=field,
            value=str(path),
        )
    if detected.format == f"trainsim/{kind}":
        return tsy.read_yaml(path)
    return str(path.resolve())


def _exists(path: FsPath, file: str, field: str) -> bool:
    """Whether ``path`` exists; InputError for a name the system refuses to look up (too long, a
    NUL byte...): ``Path.exists`` raises OSError or ValueError for those instead of answering."""
    try:
        return path.exists()
    except (OSError, ValueError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise InputError(
            f"not a usable file name ({reason})",
            file=file,
            field=field,
            value=str(path),
            allowed=f"an existing file's name (at most {_MAX_NAME_BYTES} bytes per path component)",
        ) from None


#: Longest file name (one path component) of common file systems [bytes].
_MAX_NAME_BYTES = 255


def _file_digest(path: str) -> str:
    return hashlib.sha256(FsPath(path).read_bytes()).hexdigest()


class Study:
    """A checked study: its entries (base or explicit runs), axes and samples.

    Build it with :func:`load_study` or :func:`study_from_dict`; :meth:`expand` gives the runs.
    """

    def __init__(self, spec: StudySpec, file: str, base_dir: FsPath) -> None:
        self.spec = spec
        self.file = file
        self.base_dir = base_dir
        self.name = spec.name
        self.entries = self._entries()
        self.columns = self._columns()
        self._check_paths()
        #: whether runs are driven by a ``driving`` block (base, explicit runs or a varied path): the
        #: results then have the driving columns (strategy, schedule deviation, energy saved...)
        self.driving = any("driving" in e.data for e in self.entries) or any(
            c.path is not None and parse_path(c.path).root == "driving" for c in self.columns
        )
        #: whether some runs use the multi-point model: the results then have the coupler-force columns
        self.multi_point = self._check_models()
        self.timetables, self._timetable_digests = self._read_timetables()
        self.profiles, self._profile_digests = self._read_profiles()
        self.fingerprint = self._fingerprint()

    # ------------------------------------------------------------------ entries
    def _base_data(self) -> dict[str, Any] | None:
        from trainsim.io import loader
        from trainsim.io import trainsim_yaml as tsy

        base = self.spec.base
        if base is None:
            return None
        if isinstance(base, str):
            path = FsPath(base)
            path = path if path.is_absolute() else self.base_dir / path
            if not _exists(path, self.file, "base"):
                raise InputError(
                    "base scenario file not found", file=self.file, field="base", value=str(path)
                )
            detected = loader.detect_format(path)
            if detected.kind != "scenario":
                raise InputError(
                    f"the base must be a scenario; this is a {detected.kind} file ({detected.format})",
                    file=self.file,
                    field="base",
                    value=str(path),
                )
            data = tsy.read_yaml(path)
            where, origin = str(path), path.parent
        else:
            data = copy.deepcopy(base)
            data.setdefault("schema", "trainsim/scenario")
            data.setdefault("version", 1)
            data.setdefault("name", self.spec.name)
            where, origin = f"{self.file}: base", self.base_dir
        # the scenario reader reports everything else (unknown fields, bad values) with the file
        for kind in ("train", "route"):
            if kind in data:
                data[kind] = _read_part(data[kind], kind, origin, where, kind)
        _resolve_files(data, origin)
        if isinstance(base, str):
            _validate_scenario(data, where, file=where)
        else:
            _validate_scenario(data, where, file=self.file, where="base")
        return data

    def _entries(self) -> list[Entry]:
        base = self._base_data()
        if self.spec.runs is None:
            assert base is not None
            return [Entry(None, base, None)]
        entries = []
        names: set[str] = set()
        for i, run in enumerate(self.spec.runs):
            where = f"runs[{i}]"
            if run.name in names:
                raise InputError(
                    "two runs have the same name", file=self.file, field=f"{where}.name", value=run.name
                )
            names.add(run.name)
            # the parts of the base are shared by the entries that do not change them (one copy in the
            # payload sent to the workers, one train built per worker); nothing below writes into them
            data = dict(base) if base is not None else {"schema": "trainsim/scenario", "version": 1}
            data["name"] = run.name
            for kind in ("train", "route"):
                value = getattr(run, kind)
                if value is not None:
                    data[kind] = _read_part(value, kind, self.base_dir, self.file, f"{where}.{kind}")
                elif kind not in data:
                    raise InputError(
                        f"the run has no {kind}: give one here or a 'base' scenario",
                        file=self.file,
                        field=f"{where}.{kind}",
                    )
            if run.stops is not None:
                data["stops"] = list(run.stops)
            if run.dwell_s is not None:
                data["dwell_s"] = {**(data.get("dwell_s") or {}), **run.dwell_s}
            if run.settings is not None:
                data["settings"] = {**(data.get("settings") or {}), **run.settings}
            if run.driving is not None:
                driving = dict(data.get("driving") or {})
                if {"supplement", "timetable"} & set(run.driving):
                    # the run's schedule replaces the base's (a supplement and a timetable never mix)
                    driving.pop("supplement", None)
                    driving.pop("timetable", None)
                data["driving"] = {**driving, **run.driving}
            copied: set[str] = set()
            model_set = False
            for path, value in (run.set or {}).items():
                root = self._check_root(path, f"{where}.set.{path}").root
                if root not in copied and root in data:
                    data[root] = copy.deepcopy(data[root])
                    copied.add(root)
                try:
                    set_value(data, path, value)
                except InputError as exc:
                    raise _at(exc, self.file, f"{where}.set.{path}") from None
                model_set = model_set or root == "model"
            if model_set:
                drop_unused_block(data)
            _resolve_files(data, self.base_dir)
            _validate_scenario(
                data, f"{self.file}: {where} ({run.name})", file=self.file, where=f"{where} ({run.name})"
            )
            departures: tuple[float, ...] | None = None
            if run.departure is not None:
                departures = (parse_clock(run.departure, field=f"{where}.departure", file=self.file),)
            elif isinstance(run.departures, DeparturesSpec):
                d = run.departures
                first = parse_clock(d.first, field=f"{where}.departures.first", file=self.file)
                last = parse_clock(d.last, field=f"{where}.departures.last", file=self.file)
                if last < first:
                    raise InputError(
                        "the last departure is before the first",
                        file=self.file,
                        field=f"{where}.departures.last",
                        value=d.last,
                    )
                n = math.floor((last - first) / (d.every_min * 60.0) + 1e-9)
                if n + 1 > MAX_DEPARTURES:
                    raise InputError(
                        f"{n + 1} departures, more than the {MAX_DEPARTURES} one run entry may have",
                        file=self.file,
                        field=f"{where}.departures.every_min",
                        value=d.every_min,
                        allowed=f"an interval giving at most {MAX_DEPARTURES} departures between first and last",
                    )
                departures = tuple(round(first + k * d.every_min * 60.0, 6) for k in range(n + 1))
            elif run.departures is not None:
                departures = tuple(
                    parse_clock(t, field=f"{where}.departures[{k}]", file=self.file)
                    for k, t in enumerate(run.departures)
                )
                if len(set(departures)) != len(departures):
                    raise InputError(
                        "the same departure is given twice", file=self.file, field=f"{where}.departures"
                    )
            entries.append(Entry(run.name, data, departures))
        return entries

    # ------------------------------------------------------------------ columns and paths
    def _check_root(self, path: str, field: str) -> Path:
        try:
            parsed = parse_path(path)
        except InputError as exc:
            raise _at(exc, self.file, field) from None
        if parsed.root not in PARTS:
            raise InputError(
                "a field path starts with the part of the scenario it changes",
                file=self.file,
                field=field,
                value=path,
                allowed=", ".join(PARTS),
            )
        return parsed

    def _columns(self) -> list[ParamColumn]:
        cols: list[ParamColumn] = []
        if self.spec.runs is not None:
            cols.append(ParamColumn("run", kind="run"))
        if any(e.departures is not None for e in self.entries):
            cols.append(ParamColumn("departure_s", kind="departure"))
        if self.spec.samples is not None:
            cols.append(ParamColumn("sample", kind="sample_index"))
        for i, axis in enumerate(self.spec.axes):
            for k, path in enumerate(axis.paths()):
                where = f"axes[{i}].field" if axis.field is not None else f"axes[{i}].fields[{k}]"
                self._check_root(path, where)
                name = f"{path}:factor" if axis.relative else path
                cols.append(ParamColumn(name, path, axis.relative, where))
        if self.spec.samples is not None:
            for path, dist in self.spec.samples.fields.items():
                where = f"samples.fields.{path}"
                self._check_root(path, where)
                name = f"{path}:factor" if dist.relative else path
                cols.append(ParamColumn(name, path, dist.relative, where, kind="sampled"))
        seen: dict[str, str] = {}
        for c in cols:
            if c.path is None:
                continue
            key = parse_path(c.path).text
            if key in seen:
                raise InputError(
                    f"'{c.path}' is varied twice (by two axes, or by an axis and the samples)",
                    file=self.file,
                    field=c.where,
                )
            seen[key] = c.name
        return cols

    def _first_values(self) -> dict[str, Any]:
        """A value of every varied field, to try each path on the data."""
        out: dict[str, Any] = {}
        for axis in self.spec.axes:
            for path, v in zip(axis.paths(), axis.points()[0], strict=True):
                out[path] = v
        if self.spec.samples is not None:
            for path, dist in self.spec.samples.fields.items():
                if dist.distribution == "choice":
                    out[path] = (dist.values or [None])[0]
                elif dist.distribution == "normal":
                    out[path] = dist.mean
                elif dist.distribution == "triangular":
                    out[path] = dist.mode
                else:
                    out[path] = 0.5 * (float(dist.low) + float(dist.high))  # type: ignore[arg-type]
        return out

    def _check_paths(self) -> None:
        """Every varied path must lead into every entry's data, relative ones to numbers; a path that
        adds a field must name a field the reader knows (a typo would fail every run)."""
        first = self._first_values()
        for col in self.columns:
            if col.path is None:
                continue
            for entry in self.entries:
                what = f"'{col.path}'" + (f" (run '{entry.name}')" if entry.name else "")

                def fail(reason: str, allowed: str | None = None, what: str = what, col=col) -> InputError:
                    return InputError(f"{what}: {reason}", file=self.file, field=col.where, allowed=allowed)

                part = parse_path(col.path).root
                if part in ("train", "route") and isinstance(entry.data.get(part), str):
                    raise fail(
                        f"the {part} comes from a file that is not a trainsim file ({entry.data[part]}, "
                        "e.g. railtoolkit), whose fields cannot be varied; use a trainsim file"
                    )
                trial = copy.deepcopy(entry.data)
                try:
                    existing = get_values(trial, col.path)
                except InputError:
                    existing = None
                if col.relative:
                    if existing is None or not all(
                        isinstance(v, int | float) and not isinstance(v, bool) for v in existing
                    ):
                        raise fail(
                            f"a relative value scales a number, and there is none there (found {existing!r})"
                        )
                    continue
                try:
                    set_value(trial, col.path, first[col.path])
                except InputError as exc:
                    raise fail(exc.reason, exc.allowed) from None
                if part == "model":
                    drop_unused_block(trial)
                if existing is not None:
                    continue
                try:
                    _validate_scenario(trial, "trial", self.base_dir)
                except InputError as exc:
                    problems = [(p.field, p.reason) if isinstance(p, Problem) else p for p in exc.problems]
                    for field, reason in problems:
                        if str(reason).startswith(("unknown field", "no station of that name")):
                            raise fail(
                                f"no such field in the scenario: '{field}': {reason}", exc.allowed
                            ) from None

    # ------------------------------------------------------------------ models
    def _model_values(self) -> tuple[list[Any], str | None]:
        """The values the study writes at ``model`` (axes, samples) and where it writes them."""
        for i, axis in enumerate(self.spec.axes):
            for k, path in enumerate(axis.paths()):
                if parse_path(path).text == "model":
                    where = f"axes[{i}].field" if axis.field is not None else f"axes[{i}].fields[{k}]"
                    return [point[k] for point in axis.points()], where
        if self.spec.samples is not None:
            for path, dist in self.spec.samples.fields.items():
                if parse_path(path).text == "model":
                    return list(dist.values or []), f"samples.fields.{path}"
        return [], None

    def _check_models(self) -> bool:
        """Whether some runs use the multi-point model; InputError for combinations no run can compute.

        ``trainsim.run`` ignores a ``driving`` block with ``model: multi_point`` (it computes the
        multi-point fastest run): a study refuses the combination rather than reporting runs that were
        not driven as asked. A varied ``multi_point`` field needs runs that use the model.
        """
        values, model_where = self._model_values()
        varied = {c.path and parse_path(c.path).root for c in self.columns}
        driving_where = next(
            (c.where for c in self.columns if c.path and parse_path(c.path).root == "driving"), None
        )
        any_multi = False
        for i, entry in enumerate(self.entries):
            models = set(values) | {entry.data.get("model", "single_point")}
            multi = "multi_point" in models
            any_multi = any_multi or multi
            where = f"runs[{i}] ({entry.name})" if entry.name else "base"
            if multi and ("driving" in entry.data or driving_where):
                raise InputError(
                    "the multi-point model is not driven by a 'driving' block (trainsim.run ignores it "
                    "for model: multi_point and computes the fastest run); remove 'driving' or use the "
                    f"single-point model (multi-point runs from {model_where or where})",
                    file=self.file,
                    field=driving_where or f"{where}: driving",
                    allowed="driving with model: single_point only",
                )
            if "multi_point" in varied and not multi:
                col = next(c for c in self.columns if c.path and parse_path(c.path).root == "multi_point")
                raise InputError(
                    f"'{col.path}' is a setting of the multi-point model, and the runs of {where} use the "
                    "single-point model: give the scenario 'model: multi_point' (or vary 'model')",
                    file=self.file,
                    field=col.where,
                )
        return any_multi

    # ------------------------------------------------------------------ referenced files
    def _read_timetables(self) -> tuple[dict[str, Any], dict[str, str | None]]:
        """Every timetable file (``driving.timetable``) the runs may use: see :meth:`_read_files`."""
        from trainsim.io.timetable_file import read_timetable_yaml

        return self._read_files("driving", "timetable", read_timetable_yaml, (OSError,))

    def _read_profiles(self) -> tuple[dict[str, Any], dict[str, str | None]]:
        """Every speed-profile file (``multi_point.profile``) the runs may use: see :meth:`_read_files`."""
        if not self.multi_point:
            return {}, {}
        from trainsim.io.multipoint_spec import read_profile

        # pandas raises ValueError on a malformed CSV file
        return self._read_files(
            "multi_point", "profile", lambda p: read_profile(p, str(p)), (OSError, ValueError)
        )

    def _read_files(
        self, block: str, key: str, read: Any, unreadable: tuple[type[Exception], ...]
    ) -> tuple[dict[str, Any], dict[str, str | None]]:
        """Every file named by ``<block>.<key>`` that the runs may use, read here: the workers need no
        shared file system.

        Returns (written name -> what ``read`` makes of it, or the reader's error as ``(reason, file,
        field, value, allowed)`` for the runs using it to fail with; written name -> SHA-256 of the
        file, None if unreadable). The names are as written in the entries' data (absolute) and in
        axis or sample values (relative to the study file).
        """
        names: set[str] = set()
        for entry in self.entries:
            names.update(_file_names(block, key, block, entry.data.get(block)))
        values: list[tuple[str, Any]] = []
        for axis in self.spec.axes:
            for k, path in enumerate(axis.paths()):
                values += [(path, point[k]) for point in axis.points()]
        if self.spec.samples is not None:
            for path, dist in self.spec.samples.fields.items():
                values += [(path, v) for v in dist.values or []]
        for path, value in values:
            names.update(_file_names(block, key, parse_path(path).text, value))
        contents: dict[str, Any] = {}
        digests: dict[str, str | None] = {}
        for name in sorted(names):
            path = FsPath(name)
            path = path if path.is_absolute() else self.base_dir / path
            digests[name] = None
            try:
                contents[name] = read(path)
                digests[name] = _file_digest(str(path))
            except InputError as exc:
                contents[name] = (exc.reason, exc.file, exc.field, exc.value, exc.allowed)
            except unreadable as exc:
                contents[name] = (f"unreadable {key} file: {exc}", str(path), None, None, None)
        return contents, digests

    # ------------------------------------------------------------------ fingerprint
    def _fingerprint(self) -> str:
        files = {}
        for entry in self.entries:
            for kind in ("train", "route"):
                value = entry.data.get(kind)
                if isinstance(value, str):
                    files[value] = _file_digest(value)
        blob = {
            "entries": [(e.name, e.data, e.departures) for e in self.entries],
            "files": files,
            "axes": [a.model_dump(mode="json") for a in self.spec.axes],
            "combine": self.spec.combine,
            "samples": self.spec.samples.model_dump(mode="json") if self.spec.samples else None,
        }
        if self._timetable_digests:
            # only when there are any, so that the fingerprints of other studies stay as they were
            blob["timetables"] = self._timetable_digests
        if self._profile_digests:
            blob["profiles"] = self._profile_digests
        return hashlib.sha256(_canonical(blob).encode()).hexdigest()[:32]

    def expand(self) -> Expansion:
        """Every run of the study with its parameters and run id (computed once per study: the run ids
        cost 0.1-0.25 ms per metro run, a few per cent of the run, and a study is read-only once
        built). The expansion is shared by every caller: do not modify it."""
        cached = self.__dict__.get("_expansion")
        if cached is None:
            cached = self.__dict__["_expansion"] = expand(self)
        return cached


def _at(exc: InputError, file: str, field: str) -> InputError:
    return InputError(exc.reason, file=file, field=field, value=exc.value, allowed=exc.allowed)


def _validate_scenario(
    data: dict[str, Any],
    source: str,
    base_dir: FsPath | None = None,
    *,
    file: str | None = None,
    where: str | None = None,
) -> None:
    """Build the scenario once: InputError if the reader rejects it. Relative file names (a driving
    timetable written in an axis) are relative to ``base_dir``.

    The model classes check values after the reader (a dwell of 1e308 set by a run entry) and know no
    file: their problems are given ``file`` (the study file) and fields prefixed with ``where`` (the
    run entry that made the scenario), so that the user finds the value in the file he wrote.
    """
    try:
        scenario_from_data(data, source, base_dir)
    except InputError as exc:
        if file is None or all(p.file for p in exc.problems):
            raise
        problems = [
            p
            if p.file
            else Problem(
                p.reason,
                file=file,
                line=p.line,
                field=f"{where}: {p.field}" if where and p.field else (p.field or where),
                value=p.value,
                allowed=p.allowed,
            )
            for p in exc.problems
        ]
        raise InputError.from_problems(problems) from None


def scenario_from_data(data: dict[str, Any], source: str = "<scenario>", base_dir: FsPath | None = None):
    """The :class:`~trainsim.model.scenario.Scenario` of a scenario's data, as ``trainsim.load_scenario``
    reads the same file: without ``model``/``multi_point`` the scenario reader's; else as
    ``trainsim.io.multipoint_spec.load_multipoint_scenario`` (same checks, same public functions), with
    ``model="multi_point"`` and the validated block as ``trainsim.io.loader.load_scenario`` returns it.
    """
    from trainsim.io import trainsim_yaml as tsy

    if not isinstance(data, dict) or not ({"model", "multi_point"} & set(data)):
        return tsy.scenario_from_dict(data, source, base_dir)
    import dataclasses

    from trainsim.io.multipoint_spec import multipoint_scenario_from_dict

    scenario, spec = multipoint_scenario_from_dict(data, source, base_dir)
    if spec is None:
        return scenario
    return dataclasses.replace(scenario, model="multi_point", multi_point=spec)


def drop_unused_block(data: dict[str, Any]) -> None:
    """A run the study sets to ``model: single_point`` does not use the scenario's ``multi_point``
    block (kept for the study's multi-point runs; the reader would refuse the pair in one file)."""
    if data.get("model") == "single_point":
        data.pop("multi_point", None)


#: The files a scenario's data may name, as (block, key): ``driving.timetable``, ``multi_point.profile``.
REFERENCED_FILES = (("driving", "timetable"), ("multi_point", "profile"))


def _resolve_files(data: dict[str, Any], origin: FsPath) -> None:
    """Make the file names of :data:`REFERENCED_FILES` in a scenario's data absolute (relative to
    ``origin``, the directory of the file that wrote them), in new block mappings (the old ones may be
    shared)."""
    for block, key in REFERENCED_FILES:
        mapping = data.get(block)
        if isinstance(mapping, dict) and isinstance(mapping.get(key), str):
            path = FsPath(mapping[key])
            if not path.is_absolute():
                data[block] = {**mapping, key: str((origin / path).resolve())}


def _file_names(block: str, key: str, path: str, value: Any) -> list[str]:
    """The file named by a value written at ``path`` (``<block>.<key>`` or a whole ``<block>``
    mapping), if any."""
    if path == f"{block}.{key}" and isinstance(value, str):
        return [value]
    if path == block and isinstance(value, dict) and isinstance(value.get(key), str):
        return [value[key]]
    return []


def _check_header(data: Any, file: str) -> None:
    if not isinstance(data, dict):
        raise InputError(
            "expected a mapping of fields (key: value lines) at the top level",
            file=file,
            value=type(data).__name__,
        )
    if data.get("schema") != STUDY_SCHEMA:
        raise InputError(
            "not a study file" if "schema" in data else "missing 'schema' line",
            file=file,
            field="schema",
            value=data.get("schema"),
            allowed=STUDY_SCHEMA,
        )
    if data.get("version") != 1:
        raise InputError(
            "unsupported study version", file=file, field="version", value=data.get("version"), allowed="1"
        )


def study_from_dict(data: Any, source: str = "<study>", base_dir: str | FsPath | None = None) -> Study:
    """A checked :class:`Study` from a ``trainsim/study`` mapping; file names relative to ``base_dir``."""
    _check_header(data, source)
    try:
        spec = StudySpec.model_validate(data)
    except ValidationError as exc:
        raise _study_error(exc, source) from None
    return Study(spec, source, FsPath(base_dir) if base_dir is not None else FsPath("."))


def load_study(path: str | FsPath) -> Study:
    """A checked :class:`Study` from a study file; scenario, train and route files relative to it."""
    from trainsim.io import trainsim_yaml as tsy

    return study_from_dict(tsy.read_yaml(path), str(path), FsPath(path).parent)
