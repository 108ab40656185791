"""The ``trainsim/scenario`` document: a train and a route (files or inline), stops, dwell times,
settings and how it is driven (docs/FORMAT.md, "Scenario")."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, ClassVar, Literal

from pydantic import Discriminator, Field, Tag, ValidationError

from trainsim.errors import InputError
from trainsim.io.spec import (
    Fraction,
    NonNegative,
    Spec,
    _prefixed,
    _validate,
    prefixed_error,
    read_yaml,
    validation_error,
)
from trainsim.io.yaml_route import RouteSpec, route_spec_from_dict
from trainsim.io.yaml_train import TrainSpec, train_spec_from_dict
from trainsim.model import (
    Route,
    Train,
)
from trainsim.model.scenario import RunSettings, Scenario

if TYPE_CHECKING:
    from trainsim.model.timetable import Timetable


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

    # a scenario names train and route files, read with their own validators (see spec.built)
    _built_first: ClassVar[tuple[type[Spec], ...]] = (TrainSpec, RouteSpec)

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
        from trainsim.io.timetable_file import read_timetable_yaml

        def read_timetable(name: str) -> Timetable:
            path = _resolve(base, name, file, "driving.timetable")
            read_yaml(path)  # the bounds of io.documents first: the timetable reader parses without them
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


def scenario_spec_from_dict(
    data: Any, source: str = "<scenario>", *, path: str | Path | None = None
) -> ScenarioSpec:
    """Validate a ``trainsim/scenario`` mapping (inline train and route may omit schema/version)."""
    return _validate(ScenarioSpec, data, "trainsim/scenario", source, path, header=True)
