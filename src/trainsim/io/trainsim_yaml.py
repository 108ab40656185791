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

The reader is split by document kind: :mod:`trainsim.io.spec` (reading, the :class:`Spec` base,
problems in words), :mod:`trainsim.io.yaml_train`, :mod:`trainsim.io.yaml_route` and
:mod:`trainsim.io.yaml_scenario`. This module gathers their names (every name other modules
import from here stays importable) and holds the functions reading whole files.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import yaml
from pydantic import BaseModel, ValidationError

from trainsim.io.spec import (  # noqa: F401 (the document kinds' names, gathered here)
    _LINES_LOOKED_UP,
    _UNION_FIELDS,
    SCHEMAS,
    Fraction,
    NonNegative,
    Positive,
    Spec,
    _check_header,
    _check_increasing,
    _check_numbers,
    _clean_loc,
    _describe,
    _format_loc,
    _is_number_text,
    _located,
    _Numeric,
    _numeric_depth,
    _parse_field,
    _prefixed,
    _union_field,
    _UnknownField,
    _validate,
    _yaml_line,
    _yaml_lines,
    fail,
    prefixed_error,
    read_yaml,
    validation_error,
)
from trainsim.io.yaml_route import (  # noqa: F401 (the document kinds' names, gathered here)
    CurveSpec,
    ElectrificationSpec,
    ElevationPointSpec,
    GradientSpec,
    LineResistanceSpec,
    RouteSpec,
    SpeedLimitSpec,
    StationSpec,
    TunnelSpec,
    _Section,
    route_spec_from_dict,
)
from trainsim.io.yaml_scenario import (  # noqa: F401 (the document kinds' names, gathered here)
    _FILE_READERS,
    DrivingSpec,
    ScenarioSpec,
    SettingsSpec,
    _file_or_inline,
    _load_referenced,
    _resolve,
    apply_stops,
    driving_from_spec,
    driving_spec_from_dict,
    register_file_readers,
    scenario_spec_from_dict,
)
from trainsim.io.yaml_train import (  # noqa: F401 (the document kinds' names, gathered here)
    _TERMS,
    RESISTANCE_FAMILY_NAMES,
    AltriosTerm,
    BrakingSpec,
    DavisKnKmhTerm,
    DavisTerm,
    DecelerationBraking,
    ElectricalSpec,
    PerMassTerm,
    PiecewiseInterval,
    PiecewiseTraction,
    PowerLimitedTraction,
    RavCarriageTerm,
    RavLocomotiveTerm,
    RavTerm,
    RegenerativeFraction,
    RegenerativeSpec,
    RegenerativeTable,
    ResistanceSpec,
    SauthoffTerm,
    SpecificTerm,
    StrahlTerm,
    TableBraking,
    TableTraction,
    TractionSpec,
    TrainSpec,
    VehicleSpec,
    WendeTerm,
    _BrakingBase,
    _Caps,
    _ForceTable,
    _regen_tag,
    _Term,
    train_spec_from_dict,
)
from trainsim.model import (
    Route,
    Train,
)
from trainsim.model.scenario import RunSettings, Scenario

if TYPE_CHECKING:  # trainsim.optimize is imported where a driving block is read, not by every reader
    pass

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


# Former private names, kept for modules that used them (io/multipoint_spec.py): use Spec, fail and
# validation_error instead.
_Spec = Spec
_fail = fail
_validation_error = validation_error
