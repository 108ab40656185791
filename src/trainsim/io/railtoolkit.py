"""railtoolkit / TrainRuns.jl YAML files: rolling stock, running paths and settings (schema 2022.05).

Files are checked as TrainRuns.jl 1.0.4 checks them: the ``schema`` and ``schema_version`` lines
first, then the JSON Schema of that version (shipped in ``trainsim/io/schemas``, ISC licence, see
``RAILTOOLKIT_LICENSE`` there). Every problem is an :class:`~trainsim.errors.InputError` naming the
file and the field (``paths``, ``trains[0].formation[3]``...).

Supported versions: rolling stock 2022.05 (the only one TrainRuns.jl 1.0.4 reads); running paths
2022.05 (rows ``[position m, speed km/h, resistance per mille]``) and 2024.07 (rows
``{position, speed, resistance}``, the current railtoolkit/schema).

How a train is built (TrainRuns.jl 1.0.4, ``Train(file)``, reproduced exactly for a formation with
one traction unit; deviations are marked):

* the first train of ``trains`` (or the one with ``train_id``), formation head first; every id of the
  formation must be a vehicle of the file;
* mass = sum of every vehicle's ``mass`` + ``load_limit`` (fully loaded) [t -> kg]; length = sum of
  ``length``; maximum speed = the smallest ``speed_limit`` (504 km/h, TrainRuns.jl's default, if no
  vehicle has one, with a note);
* the train is a passenger train if any vehicle is ``passenger`` or ``multiple unit``, else freight;
* the first vehicle of type ``traction unit`` or ``multiple unit`` is the loco. Its resistance is
  Wende's traction-unit law (:func:`trainsim.physics.resistance.wende_traction_unit`) on its EMPTY
  mass: ``base_resistance`` on ``mass_traction`` (default: the whole mass), ``rolling_resistance`` on
  the rest, ``air_resistance`` as ``F_t2 = air / 1000 x m_loco g``. Its ``tractive_effort``
  ``[[km/h, N]]`` is the train's traction, interpolated linearly. TrainRuns.jl uses only one traction
  unit: further traction units count in mass, length and rotating mass only (with a note);
* the other vehicles are the cars, with one law for all of them, on their FULL mass (empty +
  ``load_limit``): Strahl (freight: f_w0 = mean ``base_resistance``, f_w2 = mean ``air_resistance``)
  or Sauthoff (passenger: also f_w1 = mean ``rolling_resistance``); means are over the cars counted
  one by one, a missing coefficient counting as 0 (TrainRuns.jl's default, with a note);
* rotating mass factor = (xi_loco m_loco + sum xi_car m_car) / (sum of empty masses), with defaults
  xi = 1.09 for traction units and 1.06 for cars (``rotation_mass``). Deviation: trainsim sums over
  every vehicle, where TrainRuns.jl counts only one traction unit in the numerator;
* braking: a constant deceleration of ``|a_braking|`` of the loco, else TrainRuns.jl's defaults
  0.375 m/s^2 (passenger) / 0.225 m/s^2 (freight), after Bruenger & Dahlhaus (2014) p. 74, recorded
  as a note and, by :func:`load_railtoolkit_train`, as a :class:`RailtoolkitDefaultWarning`;
* no ``tractive_effort``: TrainRuns.jl 1.0.4 falls back on ``m_td g mu`` with an undefined ``mu``;
  trainsim raises an InputError asking for the table;
* no electrical data (the format has none): the train's ``electrical`` is None.

How a path is built: ``characteristic_sections`` sorted by position; each row starts a section that
runs to the next row, with that row's speed limit and path resistance ``f_Rp``; the last row only
marks the end. ``f_Rp`` [per mille] is a specific resistance standing for gradient, curves and
tunnels together, so trainsim carries it as a gradient-equivalent :class:`GradientSection` and sets
the curve and tunnel formulas to ``none`` (no double counting); ``small_angle`` reads it exactly as
TrainRuns.jl does (f_Rp / 1000 x m g). The route has a station at its first and at its last position
(dwell 0): TrainRuns.jl runs from start to end without intermediate stops. The points of interest are
returned for output. ``mass_model``: ``mass_point`` -> line resistance at the head,
``homogeneous_strip`` -> averaged over the train length.
"""

from __future__ import annotations

import itertools
import json
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cache
from importlib import resources
from pathlib import Path
from statistics import fmean
from typing import TYPE_CHECKING, Any, Literal

from trainsim.constants import KMH, TONNE, TRAINRUNS_GRAVITY
from trainsim.errors import InputError, Problem
from trainsim.io.documents import read_document as read_yaml
from trainsim.io.railtoolkit_names import MASS_MODELS, PATH_SCHEMA_URL, ROLLING_STOCK_SCHEMA_URL
from trainsim.model import (
    Braking,
    EffortCurve,
    GradientSection,
    LineResistanceSettings,
    ResistanceTerm,
    Route,
    SpeedLimit,
    Station,
    Train,
    Vehicle,
    bounds,
)
from trainsim.physics import resistance as res

if TYPE_CHECKING:
    import jsonschema

__all__ = [
    "MASS_MODELS",
    "PATH_SCHEMA_URL",
    "ROLLING_STOCK_SCHEMA_URL",
    "PointOfInterest",
    "RailtoolkitDefaultWarning",
    "RailtoolkitPath",
    "RailtoolkitSettings",
    "RailtoolkitTrain",
    "load_railtoolkit_path",
    "load_railtoolkit_settings",
    "load_railtoolkit_train",
    "read_railtoolkit_path",
    "read_railtoolkit_train",
]

#: schema URL -> {supported schema_version: schema file in trainsim/io/schemas}
_SCHEMA_FILES: dict[str, dict[str, str]] = {
    ROLLING_STOCK_SCHEMA_URL: {"2022.05": "rolling-stock.json"},
    PATH_SCHEMA_URL: {"2022.05": "running-path.2022.05.json", "2024.07": "running-path.json"},
}


# TrainRuns.jl 1.0.4 defaults (src/constructors.jl, Train(file)).
_XI_LOCO = 1.09  # rotation mass factor of a traction unit
_XI_CAR = 1.06  # rotation mass factor of a car
_A_BRAKING_PASSENGER = 0.375  # m/s^2, Bruenger & Dahlhaus 2014 p. 74
_A_BRAKING_FREIGHT = 0.225  # m/s^2, same source
_V_LIMIT_DEFAULT_MPS = 140.0  # 504 km/h when no vehicle gives a speed limit

# TrainRuns.jl 1.0.4 settings schema (src/constructors.jl, Settings(file)), ISC licence.
_SETTINGS_SCHEMA: dict[str, Any] = {
    "type": "object",
    "properties": {
        "massModel": {"type": "string", "enum": ["mass_point", "homogeneous_strip"]},
        "stepVariable": {"type": "string", "enum": ["distance", "time", "velocity"]},
        "stepSize": {"type": "number", "exclusiveMinimum": 0},
        "approxLevel": {"type": "number"},
        "outputDetail": {
            "type": "string",
            "enum": ["running_time", "points_of_interest", "data_points", "driving_course"],
        },
        "outputFormat": {"type": "string", "enum": ["dataframe", "vector"]},
        "verbosity": {
            "type": "string",
            "enum": ["unset", "trace", "debug", "info", "warn", "error", "fatal"],
        },
    },
}


class RailtoolkitDefaultWarning(UserWarning):
    """A TrainRuns.jl default was applied to a value the railtoolkit file does not give."""


@dataclass(frozen=True)
class PointOfInterest:
    """A point where TrainRuns.jl reports the run.

    Attributes:
        name: label of the point.
        position_m: position [m].
        measure: which end of the train is measured there: ``front``, ``middle`` or ``rear``.
    """

    name: str
    position_m: float
    measure: str


@dataclass(frozen=True)
class RailtoolkitTrain:
    """A train read from a railtoolkit rolling-stock file, with what was assumed to build it."""

    train: Train
    train_id: str
    schema_version: str
    notes: tuple[str, ...] = ()


@dataclass(frozen=True)
class RailtoolkitPath:
    """A route read from a railtoolkit running-path file, with its points of interest."""

    route: Route
    path_id: str
    schema_version: str
    points_of_interest: tuple[PointOfInterest, ...] = ()
    notes: tuple[str, ...] = ()


@dataclass(frozen=True)
class RailtoolkitSettings:
    """A TrainRuns.jl settings file.

    Attributes:
        mass_model: ``mass_point`` or ``homogeneous_strip``.
        apply_over: the matching :class:`LineResistanceSettings` ``apply_over``.
        ignored: settings trainsim does not use (its own integrator and outputs), by key.
        notes: what was ignored and why.
    """

    mass_model: str = "mass_point"
    apply_over: Literal["head", "train_length"] = "head"
    ignored: dict[str, Any] = field(default_factory=dict)
    notes: tuple[str, ...] = ()


# ====================================================================== schema checks
@cache
def _schema(name: str) -> dict[str, Any]:
    text = resources.files("trainsim.io").joinpath("schemas", name).read_text(encoding="utf-8")
    return json.loads(text)


@cache
def _validator(name: str) -> jsonschema.Draft202012Validator:
    """The JSON Schema validator of a schema file (built once)."""
    # imported here: jsonschema costs about 45 ms of every start-up, and only railtoolkit files need it
    import jsonschema

    return jsonschema.Draft202012Validator(_schema(name))


def _path_text(parts: Sequence[str | int]) -> str:
    text = ""
    for part in parts:
        text += f"[{part}]" if isinstance(part, int) else ("." if text else "") + str(part)
    return text


def _describe_schema_error(error: jsonschema.ValidationError) -> tuple[str, str, Any, str | None]:
    """(field path, reason, value, allowed) of a JSON Schema error, in words."""
    where = list(error.absolute_path)
    kind = error.validator
    instance = error.instance
    value = instance if not isinstance(instance, dict | list) else None
    arg = error.validator_value
    json_types = {"array": "a list", "object": "a mapping", "number": "a number", "string": "text"}
    if kind == "required":
        missing = next((name for name in arg if isinstance(instance, dict) and name not in instance), "?")
        return _path_text([*where, missing]), f"'{missing}' is missing", None, None
    if kind == "type":
        kinds = arg if isinstance(arg, list) else [arg]
        got = type(instance).__name__ if isinstance(instance, dict | list) else None
        reason = "must be " + " or ".join(json_types.get(k, k) for k in kinds)
        if got:
            reason += f", not a {'mapping' if got == 'dict' else 'list'}"
        return _path_text(where), reason, value, None
    if kind in ("enum", "const"):
        allowed = ", ".join(map(str, arg if isinstance(arg, list) else [arg]))
        return _path_text(where), "not an allowed value", value, allowed
    if kind in ("exclusiveMinimum", "minimum", "maximum", "exclusiveMaximum"):
        op = {"exclusiveMinimum": ">", "minimum": ">=", "maximum": "<=", "exclusiveMaximum": "<"}[kind]
        return _path_text(where), "out of range", value, f"{op} {arg}"
    if kind == "minItems":
        return _path_text(where), f"needs at least {arg} item(s)", None, None
    if kind == "maxItems":
        return _path_text(where), f"has more than {arg} items", None, None
    if kind == "uniqueItems":
        return _path_text(where), "has duplicate items", None, None
    if kind == "anyOf" and isinstance(instance, dict) and not where:
        return "trains", "needs 'trains' or 'vehicles'", None, None
    if kind == "pattern":
        return _path_text(where), "wrong format", value, f"pattern {arg}"
    return _path_text(where), error.message, None, None


def _lines(file: str, locs: list[list[str | int]]) -> list[int | None]:
    """The YAML lines of the values at ``locs`` in the file (None where unknown)."""
    from trainsim.io import documents

    try:
        text = documents.read_text(file)
    except InputError:
        return [None] * len(locs)
    return documents.yaml_lines(text, locs)


#: railtoolkit keys -> (quantity of trainsim.model.bounds, unit, SI value of one unit); other numbers
#: are bounded as coefficients.
_KEY_BOUNDS: dict[str, tuple[str, str, float]] = {
    "mass": ("mass", "t", TONNE),
    "load_limit": ("mass", "t", TONNE),
    "mass_traction": ("mass", "t", TONNE),
    "length": ("length", "m", 1.0),
    "position": ("length", "m", 1.0),
    "speed_limit": ("speed", "km/h", KMH),
    "speed": ("speed", "km/h", KMH),
    "resistance": ("ratio", "per mille", 1e-3),
    "base_resistance": ("ratio", "per mille", 1e-3),
    "rolling_resistance": ("ratio", "per mille", 1e-3),
    "air_resistance": ("ratio", "per mille", 1e-3),
    "a_braking": ("acceleration", "m/s^2", 1.0),
    "rotation_mass": ("coefficient", "", 1.0),
}


def _check_magnitudes(data: Any, file: str) -> None:
    """Every number of the file finite and inside the plausible range of its quantity
    (:mod:`trainsim.model.bounds`); all problems reported together, with their lines."""
    problems: list[tuple[list[str | int], str, Any, str | None]] = []
    todo: list[tuple[list[str | int], Any, str | None]] = [([], data, None)]
    while todo and len(problems) < 50:
        loc, value, key = todo.pop()
        if isinstance(value, dict):
            todo.extend(([*loc, k], v, k if isinstance(k, str) else None) for k, v in value.items())
        elif isinstance(value, list):
            todo.extend(([*loc, i], v, key) for i, v in enumerate(value))
        elif isinstance(value, int | float) and not isinstance(value, bool):
            quantity, unit, factor = _KEY_BOUNDS.get(key or "", ("coefficient", "", 1.0))
            try:
                bounds.check(value, quantity, unit=unit, factor=factor)
            except InputError as exc:
                problems.append((loc, exc.reason, value, exc.allowed))
    if problems:
        problems.sort(key=lambda p: [str(x) for x in p[0]])
        lines = _lines(file, [p[0] for p in problems[:20]])
        raise InputError.from_problems(
            [
                Problem(
                    reason,
                    file=file,
                    line=lines[i] if i < len(lines) else None,
                    field=_path_text(loc) or None,
                    value=value,
                    allowed=allowed,
                )
                for i, (loc, reason, value, allowed) in enumerate(problems)
            ]
        )


def _check(data: Any, file: str, expected_url: str, kind: str) -> str:
    """Check header and JSON Schema; returns the schema version."""
    if not isinstance(data, dict):
        raise InputError(f"expected a railtoolkit {kind} file (a YAML mapping)", file=file)
    if "schema" not in data:
        raise InputError(
            "no 'schema' line: not a railtoolkit file (TrainRuns.jl: \"No attribute with 'schema' found\")",
            file=file,
            field="schema",
            allowed=expected_url,
        )
    if data["schema"] != expected_url:
        other = "rolling stock" if data["schema"] == ROLLING_STOCK_SCHEMA_URL else "running path"
        known = data["schema"] in _SCHEMA_FILES
        raise InputError(
            f"this is a railtoolkit {other} file, not a {kind} file"
            if known
            else f"not a railtoolkit {kind} file",
            file=file,
            field="schema",
            value=data["schema"],
            allowed=expected_url,
        )
    if "schema_version" not in data:
        raise InputError(
            "no 'schema_version' line (TrainRuns.jl: \"No attribute with 'schema_version' found\")",
            file=file,
            field="schema_version",
            allowed=", ".join(_SCHEMA_FILES[expected_url]),
        )
    version = str(data["schema_version"])
    if version not in _SCHEMA_FILES[expected_url]:
        raise InputError(
            f"unsupported railtoolkit {kind} schema version",
            file=file,
            field="schema_version",
            value=data["schema_version"],
            allowed=", ".join(_SCHEMA_FILES[expected_url]),
        )
    if kind == "running path" and "paths" not in data:
        raise InputError(
            "no 'paths' in the file (TrainRuns.jl: \"No collection with 'paths' found\")",
            file=file,
            field="paths",
        )
    validator = _validator(_SCHEMA_FILES[expected_url][version])
    errors = sorted(validator.iter_errors(data), key=lambda e: (list(map(str, e.absolute_path)), e.validator))
    if errors:
        described = [_describe_schema_error(e) for e in errors]
        lines = _lines(file, [list(e.absolute_path) for e in errors[:20]])
        raise InputError.from_problems(
            [
                Problem(
                    f"{reason} (railtoolkit {kind} schema {version})",
                    file=file,
                    line=lines[i] if i < len(lines) else None,
                    field=path or None,
                    value=value,
                    allowed=allowed,
                )
                for i, (path, reason, value, allowed) in enumerate(described)
            ]
        )
    _check_magnitudes(data, file)
    return version


# ====================================================================== trains
@dataclass
class _Group:
    """A vehicle type of the formation and how often it appears."""

    index: int  # position in 'vehicles'
    data: dict[str, Any]
    count: int

    @property
    def id(self) -> str:
        return str(self.data["id"])

    @property
    def propulsion(self) -> bool:
        return self.data["vehicle_type"] in ("traction unit", "multiple unit")


def read_railtoolkit_train(
    path: str | Path, train_id: str | None = None, *, data: Any = None
) -> RailtoolkitTrain:
    """A train from a railtoolkit rolling-stock file, with the notes of what was assumed.

    Args:
        path: the YAML file.
        train_id: ``id`` of the train to read; None for the first one (as TrainRuns.jl).
        data: the file's content when the caller has read it already (the file is read once).
    """
    file = str(path)
    data = read_yaml(path) if data is None else data
    version = _check(data, file, ROLLING_STOCK_SCHEMA_URL, "rolling stock")
    notes: list[str] = []
    trains = data.get("trains")
    if not trains:
        raise InputError(
            "no 'trains' in the file: a file with vehicles only describes no train to run",
            file=file,
            field="trains",
        )
    vehicles_data = data.get("vehicles") or []
    if not vehicles_data:
        raise InputError("no 'vehicles' in the file", file=file, field="vehicles")
    ids = [str(t["id"]) for t in trains]
    if train_id is None:
        t_index = 0
        if len(trains) > 1:
            notes.append(f"{len(trains)} trains in the file; using the first, '{ids[0]}' (as TrainRuns.jl)")
    elif train_id in ids:
        t_index = ids.index(train_id)
    else:
        raise InputError(
            "no train with that id", file=file, field="trains.id", value=train_id, allowed=", ".join(ids)
        )
    train = trains[t_index]
    formation = [str(x) for x in train["formation"]]
    by_id: dict[str, int] = {}
    for i, v in enumerate(vehicles_data):
        by_id.setdefault(str(v["id"]), i)
    for k, vid in enumerate(formation):
        if vid not in by_id:
            raise InputError(
                "the formation names a vehicle that is not in the file's 'vehicles'",
                file=file,
                field=f"trains[{t_index}].formation[{k}]",
                value=vid,
                allowed=", ".join(by_id),
            )
    # Vehicle types in the order of 'vehicles', as TrainRuns.jl walks them.
    groups = [
        _Group(i, vehicles_data[i], formation.count(vid))
        for vid, i in sorted(by_id.items(), key=lambda kv: kv[1])
        if vid in formation
    ]
    passenger = any(g.data["vehicle_type"] in ("passenger", "multiple unit") for g in groups)
    locos = [g for g in groups if g.propulsion]
    if not locos:
        raise InputError(
            "no traction unit or multiple unit in the formation (TrainRuns.jl needs one to pull the train)",
            file=file,
            field=f"trains[{t_index}].formation",
            value=formation,
        )
    loco = locos[0]
    cars = [g for g in groups if not g.propulsion]
    extra_units = sum(g.count for g in locos) - 1
    if extra_units:
        notes.append(
            f"{extra_units} more traction unit(s) in the formation: as TrainRuns.jl, only one '{loco.id}' "
            "pulls and has running resistance; the others count in mass, length and rotating mass only"
        )
    where = f"vehicles[{loco.index}]"

    # ---- masses, length, speed
    mass_full_kg = sum(g.count * (g.data["mass"] + g.data.get("load_limit", 0.0)) * TONNE for g in groups)
    mass_empty_kg = sum(g.count * g.data["mass"] * TONNE for g in groups)
    length_m = sum(g.count * g.data["length"] for g in groups)
    limits = [g.data["speed_limit"] for g in groups if "speed_limit" in g.data]
    if limits:
        v_max = min(limits) * KMH
    else:
        v_max = _V_LIMIT_DEFAULT_MPS
        notes.append("no vehicle has a speed_limit: TrainRuns.jl's default 504 km/h used")

    # ---- the loco
    m_loco = loco.data["mass"] * TONNE
    m_td = loco.data.get("mass_traction", loco.data["mass"]) * TONNE
    if "mass_traction" not in loco.data:
        notes.append(
            f"'{loco.id}' has no mass_traction: all of its mass taken as on driven axles (default; "
            "TrainRuns.jl 1.0.4 refers to an undefined variable here)"
        )
    if m_td > m_loco:
        raise InputError(
            "the mass on driven axles exceeds the vehicle's mass",
            file=file,
            field=f"{where}.mass_traction",
            value=loco.data["mass_traction"],
            allowed=f"<= {loco.data['mass']} t",
        )
    for key, needed in (
        ("base_resistance", m_td > 0),
        ("rolling_resistance", m_loco - m_td > 0),
        ("air_resistance", True),
    ):
        if needed and key not in loco.data:
            notes.append(f"'{loco.id}' has no {key}: 0 per mille (TrainRuns.jl default)")
    try:
        loco_law = res.wende_traction_unit(
            m_loco,
            m_td,
            loco.data.get("base_resistance", 0.0),
            loco.data.get("rolling_resistance", 0.0),
            loco.data.get("air_resistance", 0.0),
            gravity_mps2=TRAINRUNS_GRAVITY,
        )
    except InputError as exc:
        raise InputError(exc.reason, file=file, field=where, value=exc.value, allowed=exc.allowed) from exc
    terms = [ResistanceTerm(f"wende: traction unit {loco.id} (empty mass)", loco_law)]

    if "tractive_effort" not in loco.data:
        raise InputError(
            "the traction unit has no tractive_effort; trainsim needs the table [[km/h, N], ...] "
            "(TrainRuns.jl 1.0.4 would fall back on an undefined adhesion coefficient)",
            file=file,
            field=f"{where}.tractive_effort",
        )
    table = loco.data["tractive_effort"]
    try:
        traction = EffortCurve.from_table(
            [row[0] * KMH for row in table], [row[1] for row in table], label=f"tractive effort of {loco.id}"
        )
    except InputError as exc:
        raise InputError(
            exc.reason, file=file, field=f"{where}.tractive_effort", value=exc.value, allowed=exc.allowed
        ) from exc

    # ---- the cars: one law for all, on their full mass
    if cars:
        family = "sauthoff" if passenger else "strahl"
        used = ["base_resistance", "air_resistance"] + (["rolling_resistance"] if passenger else [])
        coefficients: dict[str, float] = {}
        for key in used:
            values: list[float] = []
            for g in cars:
                if key not in g.data:
                    notes.append(f"car '{g.id}' has no {key}: 0 per mille in the mean (TrainRuns.jl default)")
                values += [float(g.data.get(key, 0.0))] * g.count
            coefficients[key] = fmean(values)
        m_cars_full = sum(g.count * (g.data["mass"] + g.data.get("load_limit", 0.0)) * TONNE for g in cars)
        n_cars = sum(g.count for g in cars)
        if passenger:
            law = res.sauthoff(
                m_cars_full,
                coefficients["base_resistance"],
                coefficients["rolling_resistance"],
                coefficients["air_resistance"],
                gravity_mps2=TRAINRUNS_GRAVITY,
            )
        else:
            law = res.strahl(
                m_cars_full,
                coefficients["base_resistance"],
                coefficients["air_resistance"],
                gravity_mps2=TRAINRUNS_GRAVITY,
            )
        shown = ", ".join(f"{k} {v:g}" for k, v in coefficients.items())
        terms.append(ResistanceTerm(f"{family}: {n_cars} cars, full mass ({shown} per mille)", law))

    # ---- rotating mass: weights are the empty masses (TrainRuns.jl)
    def xi(g: _Group) -> float:
        return float(g.data.get("rotation_mass", _XI_LOCO if g.propulsion else _XI_CAR))

    rho = sum(g.count * xi(g) * g.data["mass"] * TONNE for g in groups) / mass_empty_kg

    # ---- braking
    if "a_braking" in loco.data:
        a_braking = abs(float(loco.data["a_braking"]))
    else:
        a_braking = _A_BRAKING_PASSENGER if passenger else _A_BRAKING_FREIGHT
        notes.append(
            f"default: no a_braking given; constant deceleration {a_braking} m/s^2 for a "
            f"{'passenger' if passenger else 'freight'} train (TrainRuns.jl default after Bruenger & "
            "Dahlhaus 2014, p. 74)"
        )
    try:
        braking = Braking(deceleration_mps2=a_braking)
    except InputError as exc:
        raise InputError(exc.reason, file=file, field=f"{where}.a_braking", value=exc.value) from exc

    vehicles = []
    for vid in formation:
        g = next(x for x in groups if x.id == vid)
        vehicles.append(
            Vehicle(
                name=vid,
                mass_kg=g.data["mass"] * TONNE,
                length_m=g.data["length"],
                load_kg=g.data.get("load_limit", 0.0) * TONNE,
                rotating_mass_factor=xi(g),
                powered=g.propulsion,
            )
        )
    if loco.data.get("power_type") == "electric":
        notes.append(
            "electric traction unit, but the railtoolkit format has no electrical data: energy at the wheel"
        )
    try:
        result = Train(
            name=str(train.get("name") or train["id"]),
            mass_kg=mass_full_kg,
            rotating_mass_factor=rho,
            length_m=length_m,
            max_speed_mps=v_max,
            traction=traction,
            braking=braking,
            resistance=tuple(terms),
            electrical=None,
            vehicles=tuple(vehicles),
            adhesion_mass_kg=m_td,
        )
    except InputError as exc:
        raise exc.located(file) from exc
    return RailtoolkitTrain(result, ids[t_index], version, tuple(notes))


def load_railtoolkit_train(path: str | Path, train_id: str | None = None, *, data: Any = None) -> Train:
    """A :class:`~trainsim.model.Train` from a railtoolkit rolling-stock file (TrainRuns.jl conventions).

    Defaults applied for missing data (braking deceleration, resistance coefficients, ...) are
    reported as :class:`RailtoolkitDefaultWarning`; :func:`read_railtoolkit_train` returns them as notes.
    """
    loaded = read_railtoolkit_train(path, train_id, data=data)
    for note in loaded.notes:
        if "default" in note:
            warnings.warn(f"{path}: {note}", RailtoolkitDefaultWarning, stacklevel=2)
    return loaded.train


# ====================================================================== paths
def _rows_2022(path_data: dict[str, Any]) -> list[tuple[float, float, float]]:
    return [(float(r[0]), float(r[1]), float(r[2])) for r in path_data["characteristic_sections"]]


def _rows_2024(
    path_data: dict[str, Any], file: str, where: str, notes: list[str]
) -> list[tuple[float, float, float]]:
    rows = sorted(path_data["characteristic_sections"], key=lambda r: r["position"])
    out: list[tuple[float, float, float]] = []
    speed: float | None = None
    resistance = 0.0
    for i, row in enumerate(rows):
        if "speed" in row:
            speed = float(row["speed"])
        if "resistance" in row:
            resistance = float(row["resistance"])
        elif i == 0:
            notes.append("first characteristic section has no resistance: 0 per mille")
        if speed is None:
            raise InputError(
                "the first characteristic section needs a speed",
                file=file,
                field=f"{where}.characteristic_sections[0].speed",
            )
        out.append((float(row["position"]), speed, resistance))
    return out


def read_railtoolkit_path(
    path: str | Path, path_id: str | None = None, mass_model: str = "mass_point", *, data: Any = None
) -> RailtoolkitPath:
    """A route from a railtoolkit running-path file, with its points of interest and notes.

    Args:
        path: the YAML file.
        path_id: ``id`` of the path to read; None for the first (as TrainRuns.jl).
        mass_model: ``mass_point`` (line resistance at the head) or ``homogeneous_strip`` (averaged
            over the train length), TrainRuns.jl's ``massModel`` setting.
        data: the file's content when the caller has read it already (the file is read once).
    """
    file = str(path)
    if mass_model not in MASS_MODELS:
        raise InputError(
            "unknown mass model", field="mass_model", value=mass_model, allowed=", ".join(MASS_MODELS)
        )
    data = read_yaml(path) if data is None else data
    version = _check(data, file, PATH_SCHEMA_URL, "running path")
    notes: list[str] = []
    paths = data["paths"]
    ids = [str(p["id"]) for p in paths]
    if path_id is None:
        index = 0
        if len(paths) > 1:
            notes.append(f"{len(paths)} paths in the file; using the first, '{ids[0]}' (as TrainRuns.jl)")
    elif path_id in ids:
        index = ids.index(path_id)
    else:
        raise InputError(
            "no path with that id", file=file, field="paths.id", value=path_id, allowed=", ".join(ids)
        )
    p = paths[index]
    where = f"paths[{index}]"
    if version == "2022.05":
        rows = _rows_2022(p)
        raw_positions = [r[0] for r in rows]
        name = str(p.get("name") or p["id"])
    else:
        rows = _rows_2024(p, file, where, notes)
        raw_positions = [float(r["position"]) for r in p["characteristic_sections"]]
        name = str(p.get("description") or p["id"])
    if raw_positions != sorted(raw_positions):
        notes.append("characteristic sections not in order of position: sorted (as TrainRuns.jl)")
    rows.sort(key=lambda r: r[0])
    for i in range(1, len(rows)):
        if rows[i][0] == rows[i - 1][0]:
            raise InputError(
                "two characteristic sections start at the same position",
                file=file,
                field=f"{where}.characteristic_sections",
                value=rows[i][0],
            )
    start, end = rows[0][0], rows[-1][0]
    limits: list[SpeedLimit] = []
    gradients: list[GradientSection] = []
    for (s0, v, f), (s1, _, _) in itertools.pairwise(rows):
        if limits and limits[-1].limit_mps == v * KMH and limits[-1].end_m == s0:
            limits[-1] = SpeedLimit(limits[-1].start_m, s1, v * KMH)
        else:
            limits.append(SpeedLimit(s0, s1, v * KMH))
        if f == 0:
            continue
        if gradients and gradients[-1].gradient_permille == f and gradients[-1].end_m == s0:
            gradients[-1] = GradientSection(gradients[-1].start_m, s1, f)
        else:
            gradients.append(GradientSection(s0, s1, f))
    pois: list[PointOfInterest] = []
    for item in p.get("points_of_interest") or []:
        if isinstance(item, dict):
            pois.append(PointOfInterest(str(item["label"]), float(item["position"]), str(item["measure"])))
        else:
            pois.append(PointOfInterest(str(item[1]), float(item[0]), str(item[2])))
    pois.sort(key=lambda x: x.position_m)
    try:
        route = Route(
            name=name,
            start_m=start,
            end_m=end,
            stations=(Station("start", start, 0.0, True), Station("end", end, 0.0, True)),
            speed_limits=tuple(limits),
            gradients=tuple(gradients),
            line_resistance=LineResistanceSettings(
                curve_formula="none",
                tunnel_formula="none",
                gradient_formula="small_angle",
                apply_over=MASS_MODELS[mass_model],
            ),
            gravity_mps2=TRAINRUNS_GRAVITY,  # TrainRuns.jl's g (its formulary: 9.80665 m/s^2)
        )
    except InputError as exc:
        raise InputError(
            exc.reason,
            file=file,
            field=f"{where}.characteristic_sections",
            value=exc.value,
            allowed=exc.allowed,
        ) from exc
    return RailtoolkitPath(route, ids[index], version, tuple(pois), tuple(notes))


def load_railtoolkit_path(
    path: str | Path, path_id: str | None = None, mass_model: str = "mass_point", *, data: Any = None
) -> Route:
    """A :class:`~trainsim.model.Route` from a railtoolkit running-path file (see the module docstring)."""
    return read_railtoolkit_path(path, path_id, mass_model, data=data).route


# ====================================================================== settings
def load_railtoolkit_settings(path: str | Path) -> RailtoolkitSettings:
    """A TrainRuns.jl settings file: the ``massModel`` trainsim uses, and the keys it ignores.

    TrainRuns.jl falls back on its defaults for an invalid file; trainsim refuses it with an
    InputError instead, so that a typo is not silently ignored.
    """
    file = str(path)
    data = read_yaml(path)
    if not isinstance(data, dict) or "settings" not in data:
        raise InputError(
            "no 'settings' in the file (TrainRuns.jl settings files have one)", file=file, field="settings"
        )
    settings = data["settings"]
    if not isinstance(settings, dict):
        raise InputError("'settings' must be a mapping", file=file, field="settings", value=settings)
    import jsonschema

    errors = list(jsonschema.Draft202012Validator(_SETTINGS_SCHEMA).iter_errors(settings))
    if errors:
        where, reason, value, allowed = _describe_schema_error(errors[0])
        raise InputError(reason, file=file, field=f"settings.{where}", value=value, allowed=allowed)
    mass_model = str(settings.get("massModel", "mass_point"))
    ignored = {k: v for k, v in settings.items() if k != "massModel"}
    notes = []
    known = _SETTINGS_SCHEMA["properties"]
    for key, value in ignored.items():
        if key in known:
            notes.append(f"settings.{key} = {value!r} ignored: trainsim uses its own integrator and outputs")
        else:
            notes.append(f"settings.{key} ignored: unknown to TrainRuns.jl 1.0.4")
    if "massModel" not in settings:
        notes.append("no massModel: mass_point (TrainRuns.jl default)")
    return RailtoolkitSettings(mass_model, MASS_MODELS[mass_model], ignored, tuple(notes))
