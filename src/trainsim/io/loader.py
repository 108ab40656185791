"""Reading any input file trainsim knows, whatever its format, and checking it.

The format is detected from the file's content, never from its name:

* ``schema: trainsim/train`` | ``trainsim/route`` | ``trainsim/scenario``: trainsim's own formats
  (:mod:`trainsim.io.trainsim_yaml`, docs/FORMAT.md);
* ``schema: https://railtoolkit.org/schema/rolling-stock.json`` or ``.../running-path.json``:
  railtoolkit / TrainRuns.jl files (:mod:`trainsim.io.railtoolkit`);
* a file with only a ``settings`` mapping: a TrainRuns.jl settings file.

A missing file, malformed YAML (with its line) and an unknown format are InputErrors; the last one
lists the formats trainsim knows.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any, Literal, ParamSpec, TypeVar

from trainsim.errors import InputError
from trainsim.io import documents, interchange
from trainsim.io import trainsim_yaml as tsy
from trainsim.io.railtoolkit_names import MASS_MODELS, PATH_SCHEMA_URL, ROLLING_STOCK_SCHEMA_URL
from trainsim.io.report import CheckReport
from trainsim.io.report import route_figures as _route_figures
from trainsim.io.report import train_figures as _train_figures
from trainsim.model import Route, Train
from trainsim.model.scenario import RunSettings, Scenario

P = ParamSpec("P")
R = TypeVar("R")

__all__ = [
    "KNOWN_FORMATS",
    "CheckReport",
    "Detected",
    "check_file",
    "detect_format",
    "load_route",
    "load_scenario",
    "load_train",
    "scenario_from_files",
]

Kind = Literal["train", "route", "scenario", "settings", "timetable"]

#: format name -> (kind, how a file of that format is recognised)
KNOWN_FORMATS: dict[str, tuple[Kind, str]] = {
    "trainsim/train": ("train", "schema: trainsim/train"),
    "trainsim/route": ("route", "schema: trainsim/route"),
    "trainsim/scenario": ("scenario", "schema: trainsim/scenario"),
    "railtoolkit/rolling-stock": ("train", f"schema: {ROLLING_STOCK_SCHEMA_URL}"),
    "railtoolkit/running-path": ("route", f"schema: {PATH_SCHEMA_URL}"),
    "trainruns/settings": ("settings", "a top-level 'settings' mapping (TrainRuns.jl settings)"),
    "ttobench/train": ("train", "TTOBench JSON with 'metadata' and 'mass'"),
    "ttobench/track": ("route", "TTOBench JSON with 'metadata' and 'stops'"),
    "ttobench/journey": ("timetable", "TTOBench JSON with 'metadata' and 'timing points'"),
    "trainsim/timetable": ("timetable", "schema: trainsim/timetable"),
}

_BY_SCHEMA = {
    "trainsim/train": "trainsim/train",
    "trainsim/route": "trainsim/route",
    "trainsim/scenario": "trainsim/scenario",
    ROLLING_STOCK_SCHEMA_URL: "railtoolkit/rolling-stock",
    PATH_SCHEMA_URL: "railtoolkit/running-path",
}


def _railtoolkit() -> ModuleType:
    """The railtoolkit reader, imported when a railtoolkit file is read (not by every run)."""
    from trainsim.io import railtoolkit

    return railtoolkit


def _errors_name_the_file(func: Callable[P, R]) -> Callable[P, R]:
    """Decorator of the loaders: an InputError raised below the file layer (a model class, a
    reader that does not know the file name) names the file read (the first argument)."""

    @functools.wraps(func)
    def wrapper(*args: P.args, **kwargs: P.kwargs) -> R:
        try:
            return func(*args, **kwargs)
        except InputError as exc:
            if args and isinstance(args[0], str | Path):
                located = exc.located(str(args[0]))
                if located is not exc:
                    raise located from exc
            raise

    return wrapper


@dataclass(frozen=True)
class Detected:
    """What a file is.

    Attributes:
        kind: ``train``, ``route``, ``scenario`` or ``settings``.
        format: a key of :data:`KNOWN_FORMATS`.
        version: the format version written in the file ("" for settings files).
    """

    kind: Kind
    format: str
    version: str


def _known_formats() -> str:
    return "; ".join(f"{name} ({how})" for name, (_, how) in KNOWN_FORMATS.items())


def _detect(data: Any, file: str) -> Detected:
    if not isinstance(data, dict):
        raise InputError(
            "not a trainsim or railtoolkit file: expected a YAML mapping at the top level",
            file=file,
            value=type(data).__name__,
            allowed=_known_formats(),
        )
    schema = data.get("schema")
    if schema is None and "metadata" in data:
        for key, name in (
            ("timing points", "ttobench/journey"),
            ("stops", "ttobench/track"),
            ("mass", "ttobench/train"),
        ):
            if key in data:
                version = (
                    data["metadata"].get("library version", "") if isinstance(data["metadata"], dict) else ""
                )
                return Detected(KNOWN_FORMATS[name][0], name, str(version))
    if schema == "trainsim/timetable":
        return Detected("timetable", "trainsim/timetable", str(data.get("version", "")))
    if schema is None:
        # Files that lost their schema line still get the error of their own reader.
        if "version" in data:
            raise InputError(
                "missing 'schema' line", file=file, field="schema", allowed=", ".join(tsy.SCHEMAS)
            )
        if "schema_version" in data or "paths" in data:
            return Detected("route", "railtoolkit/running-path", str(data.get("schema_version", "")))
        if "trains" in data or "vehicles" in data:
            return Detected("train", "railtoolkit/rolling-stock", str(data.get("schema_version", "")))
        if set(data) == {"settings"}:
            return Detected("settings", "trainruns/settings", "")
        raise InputError(
            "unknown file format: no 'schema' line", file=file, field="schema", allowed=_known_formats()
        )
    if not isinstance(schema, str) or schema not in _BY_SCHEMA:
        raise InputError(
            "unknown file format", file=file, field="schema", value=schema, allowed=_known_formats()
        )
    name = _BY_SCHEMA[schema]
    version = data.get("version") if name.startswith("trainsim/") else data.get("schema_version")
    return Detected(KNOWN_FORMATS[name][0], name, "" if version is None else str(version))


def detect_format(path: str | Path) -> Detected:
    """The format of a file, from its content."""
    return _detect(tsy.read_yaml(path), str(path))


def _expect(detected: Detected, kind: Kind, file: str) -> None:
    if detected.kind != kind:
        raise InputError(
            f"this is a {detected.kind} file ({detected.format}), expected a {kind} file",
            file=file,
            field="schema",
            allowed=", ".join(n for n, (k, _) in KNOWN_FORMATS.items() if k == kind),
        )


@documents.gc_paused
@_errors_name_the_file
def load_train(path: str | Path, train_id: str | None = None) -> Train:
    """A train from a ``trainsim/train`` or railtoolkit rolling-stock file.

    Args:
        path: the file.
        train_id: for railtoolkit files with several trains, the ``id`` of the one to read
            (default: the first, as TrainRuns.jl).
    """
    file = str(path)
    if (train := interchange.detect_and_load(path, "train")) is not None:
        return train
    data = tsy.read_yaml(path)  # read once, handed to the reader
    detected = _detect(data, file)
    _expect(detected, "train", file)
    if detected.format == "trainsim/train":
        if train_id is not None:
            raise InputError(
                "a trainsim train file holds one train; 'train_id' is for railtoolkit files", file=file
            )
        return tsy.train_spec_from_dict(data, file, path=path).to_train(file)
    if detected.format == "ttobench/train":
        from trainsim.io.ttobench import read_ttobench_train

        return read_ttobench_train(path).train
    return _railtoolkit().load_railtoolkit_train(path, train_id, data=data)


@documents.gc_paused
@_errors_name_the_file
def load_route(path: str | Path, mass_model: str | None = None, path_id: str | None = None) -> Route:
    """A route from a ``trainsim/route`` or railtoolkit running-path file.

    Args:
        path: the file.
        mass_model: for railtoolkit paths, TrainRuns.jl's ``massModel``: ``mass_point`` (default) or
            ``homogeneous_strip``. A trainsim route says it in ``line_resistance.apply_over``; giving
            a different ``mass_model`` with it is an error rather than a silent override.
        path_id: for railtoolkit files with several paths, the ``id`` of the one to read.
    """
    file = str(path)
    if (route := interchange.detect_and_load(path, "route", mass_model=mass_model)) is not None:
        return route
    data = tsy.read_yaml(path)  # read once, handed to the reader
    detected = _detect(data, file)
    _expect(detected, "route", file)
    if detected.format == "trainsim/route":
        route = tsy.route_spec_from_dict(data, file, path=path).to_route(file)
        if mass_model is not None and MASS_MODELS.get(mass_model) != route.line_resistance.apply_over:
            raise InputError(
                "the mass model contradicts the route's line_resistance.apply_over",
                file=file,
                field="line_resistance.apply_over",
                value=mass_model,
                allowed=f"{route.line_resistance.apply_over} (or change the route file)",
            )
        return route
    if detected.format == "ttobench/track":
        from trainsim.io.ttobench import read_ttobench_track

        return read_ttobench_track(path)
    return _railtoolkit().load_railtoolkit_path(path, path_id, mass_model or "mass_point", data=data)


@documents.gc_paused
@_errors_name_the_file
def load_scenario(path: str | Path) -> Scenario:
    """A scenario from a ``trainsim/scenario`` file (train and route files relative to it)."""
    if (scenario := interchange.detect_and_load(path, "scenario")) is not None:
        return scenario
    detected = detect_format(path)
    _expect(detected, "scenario", str(path))
    data = tsy.read_yaml(path)
    if isinstance(data, dict) and ("model" in data or "multi_point" in data):
        # the multi-point model's own reader validates its block; imported here (it imports us)
        import dataclasses

        from trainsim.io.multipoint_spec import load_multipoint_scenario

        scenario, spec = load_multipoint_scenario(path)
        if spec is None:
            return scenario
        return dataclasses.replace(scenario, model="multi_point", multi_point=spec)
    return tsy.load_scenario_yaml(path)


def scenario_from_files(
    train_path: str | Path,
    route_path: str | Path,
    settings: RunSettings | Mapping[str, Any] | str | Path | None = None,
    *,
    name: str | None = None,
    train_id: str | None = None,
    path_id: str | None = None,
) -> Scenario:
    """A scenario from a train file and a route file of any known format.

    Args:
        train_path: trainsim train or railtoolkit rolling-stock file.
        route_path: trainsim route or railtoolkit running-path file.
        settings: :class:`RunSettings`, a mapping of the scenario ``settings`` keys (``max_step_m``,
            ``braking_fraction``, ``record_dwell``), or a TrainRuns.jl settings file whose
            ``massModel`` is used for the route (its other keys are ignored: see
            :func:`check_file`).
        name: scenario name (default "<train> on <route>").
        train_id, path_id: which train / path of a railtoolkit file.
    """
    mass_model = None
    run_settings = RunSettings()
    if isinstance(settings, RunSettings):
        run_settings = settings
    elif isinstance(settings, str | Path):
        mass_model = _railtoolkit().load_railtoolkit_settings(settings).mass_model
    elif settings is not None:
        run_settings = tsy.settings_from_dict(dict(settings))
    train = load_train(train_path, train_id)
    route = load_route(route_path, mass_model, path_id)
    return Scenario(
        name=name or f"{train.name} on {route.name}", train=train, route=route, settings=run_settings
    )


# ====================================================================== check
# Fields of railtoolkit files that trainsim reads; the others are reported as ignored.
_RTK_VEHICLE_FIELDS = {
    "name",
    "id",
    "vehicle_type",
    "length",
    "mass",
    "load_limit",
    "mass_traction",
    "speed_limit",
    "rotation_mass",
    "base_resistance",
    "rolling_resistance",
    "air_resistance",
    "tractive_effort",
    "a_braking",
}


def _ignored_rtk_fields(data: dict[str, Any]) -> list[str]:
    ignored: set[str] = set()
    for v in data.get("vehicles") or []:
        ignored |= {f"vehicles.{k}" for k in v if k not in _RTK_VEHICLE_FIELDS}
    for t in data.get("trains") or []:
        ignored |= {f"trains.{k}" for k in t if k not in {"name", "id", "formation"}}
    paths = data.get("paths")
    for p in paths if isinstance(paths, list) else []:
        ignored |= {
            f"paths.{k}"
            for k in p
            if k not in {"name", "id", "description", "characteristic_sections", "points_of_interest"}
        }
    return sorted(ignored)


@documents.gc_paused
@_errors_name_the_file
def check_file(path: str | Path) -> CheckReport:
    """Read and check a file of any known format; InputError if it is not valid.

    The report gives the format, the name, key figures (mass, length, route length, stations...)
    and notes: defaults applied, readings made, fields ignored.
    """
    file = str(path)
    if (report := interchange.check_file(path)) is not None:
        return report
    data = tsy.read_yaml(path)
    schema = data.get("schema") if isinstance(data, dict) else None
    if isinstance(schema, str) and schema in CHECKERS:
        return CHECKERS[schema](Path(path))
    detected = _detect(data, file)
    if detected.format.startswith("ttobench/"):
        return _check_ttobench(path, detected)
    if detected.format == "trainsim/timetable":
        return _check_timetable(path, detected)
    if detected.format == "trainsim/scenario" and ("model" in data or "multi_point" in data):
        return _check_multipoint(path, detected)
    fmt = detected.format + (f" v{detected.version}" if detected.format.startswith("trainsim/") else "")
    if detected.format.startswith("railtoolkit/"):
        fmt += f" {detected.version}"
    if detected.format == "trainsim/train":
        spec = tsy.train_spec_from_dict(data, file, path=path)  # the file read once, above
        train = spec.to_train(file)
        return CheckReport(
            file, "train", fmt, train.name, _train_figures(train), spec.notes(), spec.warnings()
        )
    if detected.format == "trainsim/route":
        spec_r = tsy.route_spec_from_dict(data, file, path=path)  # the file read once, above
        route = spec_r.to_route(file)
        return CheckReport(file, "route", fmt, route.name, _route_figures(route), spec_r.notes())
    if detected.format == "trainsim/scenario":
        spec_s = tsy.read_scenario_spec(path)
        scenario = spec_s.to_scenario(file, Path(path).parent)
        figures = {f"train {k}": v for k, v in _train_figures(scenario.train).items()}
        figures.update({f"route {k}": v for k, v in _route_figures(scenario.route).items()})
        figures["stops"] = ", ".join(s.name for s in scenario.route.stops)
        run = scenario.settings
        figures["settings"] = f"max step {run.max_step_m:g} m, braking fraction {run.braking_fraction:g}"
        notes = []
        for label, sub in (("train", spec_s.train), ("route", spec_s.route)):
            if isinstance(sub, str):
                notes.append(f"{label} from {sub}")
                sub_path = Path(sub) if Path(sub).is_absolute() else Path(path).parent / sub
                notes += [f"{label}: {n}" for n in check_file(sub_path).notes]
            else:
                notes += [f"{label}: {n}" for n in sub.notes()]
        return CheckReport(file, "scenario", fmt, scenario.name, figures, notes)
    if detected.format == "railtoolkit/rolling-stock":
        loaded = _railtoolkit().read_railtoolkit_train(path)
        notes = list(loaded.notes)
        ignored = _ignored_rtk_fields(data)
        if ignored:
            notes.append("fields not used by trainsim: " + ", ".join(ignored))
        figures = {"train id": loaded.train_id, **_train_figures(loaded.train)}
        return CheckReport(file, "train", fmt, loaded.train.name, figures, notes)
    if detected.format == "railtoolkit/running-path":
        loaded_p = _railtoolkit().read_railtoolkit_path(path)
        notes = list(loaded_p.notes)
        ignored = _ignored_rtk_fields(data)
        if ignored:
            notes.append("fields not used by trainsim: " + ", ".join(ignored))
        notes.append(
            "path resistance f_Rp carried as gradient-equivalent sections; curves and tunnels: none "
            "(already in f_Rp); mass_point unless a settings file says homogeneous_strip"
        )
        figures = {"path id": loaded_p.path_id, **_route_figures(loaded_p.route)}
        pois = loaded_p.points_of_interest
        figures["points of interest"] = (
            f"{len(pois)}: " + ", ".join(f"{p.name} @ {p.position_m:g} m ({p.measure})" for p in pois)
            if pois
            else "none"
        )
        return CheckReport(file, "route", fmt, loaded_p.route.name, figures, notes)
    settings = _railtoolkit().load_railtoolkit_settings(path)
    figures = {"mass model": settings.mass_model, "line resistance applied over": settings.apply_over}
    return CheckReport(file, "settings", fmt, Path(file).stem, figures, list(settings.notes))


#: Checkers of document kinds read by higher layers (``schema`` -> function returning the report);
#: e.g. the CLI registers ``trainsim/study`` (the batch layer sits above this one).
CHECKERS: dict[str, Callable[[Path], CheckReport]] = {}


def register_checker(schema: str, checker: Callable[[Path], CheckReport]) -> None:
    """Let :func:`check_file` check files whose ``schema`` is read by a layer above ``io``."""
    CHECKERS[schema] = checker


def _check_ttobench(path: str | Path, detected: Detected) -> CheckReport:
    """A TTOBench train, track or journey file, read by the reader ``run`` and ``optimize`` use."""
    from trainsim.io import ttobench

    file = str(path)
    fmt = f"{detected.format} {detected.version}".strip()
    if detected.format == "ttobench/train":
        loaded = ttobench.read_ttobench_train(path)
        figures = _train_figures(loaded.train)
        if loaded.tunnel_drag:
            figures["tunnel drag"] = f"{len(loaded.tunnel_drag)} cross-section(s)"
        return CheckReport(file, "train", fmt, loaded.train.name, figures, list(loaded.notes))
    if detected.format == "ttobench/track":
        route = ttobench.read_ttobench_track(path)
        return CheckReport(file, "route", fmt, route.name, _route_figures(route))
    journey = ttobench.read_ttobench_journey(path)
    points = journey.points
    windows = [p for p in points if p.earliest_s is not None or p.latest_s is not None]
    figures = {
        "track": journey.track_id or "(not named)",
        "timing points": f"{len(points)} from {points[0].position_m:g} m to {points[-1].position_m:g} m",
        "stops": str(sum(p.is_stop for p in points)),
        "time windows": str(len(windows)),
    }
    return CheckReport(file, "timetable", fmt, journey.name, figures, list(journey.notes))


def _check_timetable(path: str | Path, detected: Detected) -> CheckReport:
    """A ``trainsim/timetable`` file (the schedule of ``optimize``)."""
    from trainsim.io.timetable_file import read_timetable_yaml

    timetable = read_timetable_yaml(path)
    figures = {k: str(v) for k, v in _public_figures(timetable).items()}
    return CheckReport(
        str(path), "timetable", f"trainsim/timetable v{detected.version}", Path(path).stem, figures
    )


def _public_figures(obj: Any) -> dict[str, Any]:
    """The public dataclass fields of an object, shortened for a report."""
    import dataclasses as dc

    if not dc.is_dataclass(obj):
        return {"value": obj}
    out: dict[str, Any] = {}
    for f in dc.fields(obj):
        if f.name.startswith("_"):
            continue
        value = getattr(obj, f.name)
        text = repr(value)
        out[f.name.replace("_", " ")] = text if len(text) <= 100 else text[:97] + "..."
    return out


def _check_multipoint(path: str | Path, detected: Detected) -> CheckReport:
    """A scenario with ``model: multi_point``: read as ``run`` and ``multipoint`` read it."""
    scenario = load_scenario(path)
    figures = {f"train {k}": v for k, v in _train_figures(scenario.train).items()}
    figures.update({f"route {k}": v for k, v in _route_figures(scenario.route).items()})
    figures["model"] = scenario.model
    spec = scenario.multi_point
    if spec is not None:
        figures.update({f"multi-point {k}": str(v) for k, v in _public_figures(spec).items()})
    return CheckReport(
        str(path), "scenario", f"{detected.format} v{detected.version}", scenario.name, figures
    )


# scenarios name train and route files of any format: the trainsim YAML reader reads them with these
tsy.register_file_readers(train=load_train, route=load_route)
