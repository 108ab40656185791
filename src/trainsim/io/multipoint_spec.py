"""The ``multi_point`` block of a scenario file and running a scenario with the multi-point model.

A scenario chooses the model with ``model: multi_point`` and gives the model's settings in a
``multi_point`` block (all optional; see docs/MULTIPOINT.md)::

    model: multi_point
    multi_point:
      locomotive_positions: [0, 53]        # head + middle (distributed power)
      time_step_s: 0.05
      couplers: {draft_stiffness_n_per_m: 1.4e7, slack_m: 0.025, buff_capacity_kn: 2270}
      coupler_overrides: [{coupler: 0, slack_m: 0}]
      brakes: {propagation_speed_mps: 250, propagation_from: locomotives, build_up_s: 3}
      strategy: fastest                    # or: follow (with profile: a CSV of position_m, speed_kmh)

Until the scenario reader knows these keys, :func:`load_multipoint_scenario` reads such a file: it
takes ``model`` and ``multi_point`` out and hands the rest to the scenario reader.
"""

from __future__ import annotations

import csv
import io
import re
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import Field, ValidationError, model_validator

from trainsim.constants import KMH
from trainsim.errors import InputError, shown_value
from trainsim.io.documents import read_text
from trainsim.io.spec import Spec as _Spec
from trainsim.io.spec import fail as _fail
from trainsim.io.spec import validation_error as _validation_error
from trainsim.model import bounds
from trainsim.model.scenario import Scenario
from trainsim.multipoint.model import (
    FREIGHT_CAPACITY_N,
    BrakePropagation,
    CouplerModel,
    Locomotive,
    MultiPointSettings,
)
from trainsim.multipoint.result import MultiPointResult
from trainsim.multipoint.simulate import SpeedProfile, follow_profile, run_multipoint_fastest

__all__ = [
    "MultiPointSpec",
    "load_multipoint_scenario",
    "multipoint_scenario_from_dict",
    "multipoint_settings_from_dict",
    "read_profile",
    "run_multipoint_scenario",
]

Positive = Annotated[float, Field(gt=0)]
NonNegative = Annotated[float, Field(ge=0)]
#: a coupler's rated force [kN]: up to 100 MN (ten times the strongest couplers in service)
Capacity = Annotated[float, Field(gt=0, le=1e5)]
_DEFAULT = CouplerModel()


class CouplerSpec(_Spec):
    """Coupler parameters; every field defaults to the freight draft-gear values of docs/MULTIPOINT.md."""

    draft_stiffness_n_per_m: Positive = _DEFAULT.draft_stiffness_n_per_m
    buff_stiffness_n_per_m: Positive = _DEFAULT.buff_stiffness_n_per_m
    draft_damping_n_s_per_m: NonNegative = _DEFAULT.draft_damping_n_s_per_m
    buff_damping_n_s_per_m: NonNegative = _DEFAULT.buff_damping_n_s_per_m
    slack_m: NonNegative = _DEFAULT.slack_m
    draft_travel_m: Positive = _DEFAULT.draft_travel_m
    buff_travel_m: Positive = _DEFAULT.buff_travel_m
    solid_stiffness_n_per_m: Positive = _DEFAULT.solid_stiffness_n_per_m
    smoothing_m: Positive = _DEFAULT.smoothing_m
    friction_ratio: Annotated[float, Field(ge=0, lt=1)] = _DEFAULT.friction_ratio
    friction_velocity_mps: Annotated[float, Field(ge=1e-5, le=1.0)] = _DEFAULT.friction_velocity_mps
    #: rated draft and buff force of the coupling [kN] (default: the MT-2 gear's 2,270 kN); null: not
    #: checked. A run whose coupler force passes it gets a warning.
    draft_capacity_kn: Capacity | None = FREIGHT_CAPACITY_N / 1e3
    buff_capacity_kn: Capacity | None = FREIGHT_CAPACITY_N / 1e3

    @staticmethod
    def model_values(values: dict[str, Any]) -> dict[str, Any]:
        """The :class:`CouplerModel` arguments (SI) of the file's values."""
        out = dict(values)
        for mode in ("draft", "buff"):
            kn = out.pop(f"{mode}_capacity_kn")
            out[f"{mode}_capacity_n"] = None if kn is None else kn * 1e3
        return out

    def build(self) -> CouplerModel:
        return CouplerModel(**self.model_values({k: getattr(self, k) for k in CouplerSpec.model_fields}))


class CouplerOverrideSpec(CouplerSpec):
    """Other parameters for one coupling (index 0 = between vehicles 0 and 1); fields not given are
    those of the ``couplers`` block."""

    coupler: Annotated[int, Field(ge=0)]

    def build_over(self, base: CouplerSpec) -> CouplerModel:
        values = {k: getattr(base, k) for k in CouplerSpec.model_fields}
        values.update({k: getattr(self, k) for k in self.model_fields_set if k != "coupler"})
        return CouplerModel(**self.model_values(values))


class LocomotiveSpec(_Spec):
    """A powered vehicle: its index in the (arranged) formation and its share of the train's effort."""

    vehicle: Annotated[int, Field(ge=0)]
    share: Annotated[float, Field(ge=0, le=1)] | None = None


class BrakesSpec(_Spec):
    """How the brakes act along the train (named ``brakes``: ``braking`` is the train file's block)."""

    distribution: Literal["mass", "equal"] = "mass"
    electric_at: Literal["locomotives", "train"] = "locomotives"
    propagation_speed_mps: Positive | None = None
    propagation_from: Literal["head", "locomotives"] = "head"
    build_up_s: NonNegative = 0.0


class MultiPointSpec(_Spec):
    """The ``multi_point`` block of a scenario (see the module doc and docs/MULTIPOINT.md)."""

    strategy: Literal["fastest", "follow"] = "fastest"
    profile: str | None = None
    locomotive_positions: list[Annotated[int, Field(ge=0)]] | None = None
    locomotives: list[LocomotiveSpec] | None = None
    couplers: CouplerSpec = Field(default_factory=CouplerSpec)
    coupler_overrides: list[CouplerOverrideSpec] = Field(default_factory=list)
    brakes: BrakesSpec = Field(default_factory=BrakesSpec)
    resistance_split: Literal["terms", "mass"] = "terms"
    initial_couplers: Literal["neutral", "stretched", "bunched"] = "neutral"
    time_step_s: Annotated[float, Field(ge=1e-4, le=1.0)] = 0.05
    record_interval_s: Positive = 1.0
    speed_time_constant_s: Positive = 1.0
    standstill_speed_mps: Annotated[float, Field(ge=1e-4, le=0.1)] = 0.001
    stop_window_m: Positive = 2.0
    lookahead: bool = True
    traction_ramp_s: Annotated[float, Field(ge=0, le=600)] = 0.0

    @model_validator(mode="after")
    def _check(self) -> MultiPointSpec:
        if self.strategy == "follow" and not self.profile:
            _fail(
                "strategy 'follow' needs a 'profile' (CSV file of position_m and speed_kmh)", field="profile"
            )
        if self.strategy == "fastest" and self.profile:
            _fail("a 'profile' is only read with strategy: follow", field="profile")
        seen: set[int] = set()
        for i, o in enumerate(self.coupler_overrides):
            if o.coupler in seen:
                _fail("coupler given twice", field=f"coupler_overrides[{i}].coupler", value=o.coupler)
            seen.add(o.coupler)
        return self

    def build(self) -> MultiPointSettings:
        """The :class:`MultiPointSettings` (SI)."""
        b = self.brakes
        return MultiPointSettings(
            couplers=self.couplers.build(),
            coupler_overrides={o.coupler: o.build_over(self.couplers) for o in self.coupler_overrides},
            locomotive_positions=tuple(self.locomotive_positions) if self.locomotive_positions else None,
            locomotives=(
                tuple(Locomotive(lo.vehicle, lo.share) for lo in self.locomotives)
                if self.locomotives
                else None
            ),
            braking_distribution=b.distribution,
            electric_braking_at=b.electric_at,
            brake_propagation=BrakePropagation(b.propagation_speed_mps, b.propagation_from, b.build_up_s),
            resistance_split=self.resistance_split,
            initial_couplers=self.initial_couplers,
            time_step_s=self.time_step_s,
            record_interval_s=self.record_interval_s,
            speed_time_constant_s=self.speed_time_constant_s,
            standstill_speed_mps=self.standstill_speed_mps,
            stop_window_m=self.stop_window_m,
            lookahead=self.lookahead,
            traction_ramp_s=self.traction_ramp_s,
        )


def multipoint_settings_from_dict(data: Any, source: str = "<scenario>", *, path: str | Path | None = None):
    """Validate a ``multi_point`` block; returns the :class:`MultiPointSpec`. Errors name the file and
    ``multi_point.<field>``."""
    try:
        spec = MultiPointSpec.model_validate(data if data is not None else {})
    except ValidationError as exc:
        raise _validation_error(exc, source, path, prefix="multi_point") from None
    try:
        spec.build()
    except InputError as exc:
        raise InputError(
            exc.reason,
            file=source,
            field=f"multi_point.{exc.field}" if exc.field else "multi_point",
            value=exc.value,
            allowed=exc.allowed,
        ) from None
    return spec


#: Most data rows of a speed-profile file (a 1,000 km trace at 1 m steps is 1e6 rows).
MAX_PROFILE_ROWS = 2_000_000
#: Most columns of a speed-profile file (a trace.csv of trainsim has about 30).
MAX_PROFILE_COLUMNS = 200
#: A number as written in a CSV cell: no thousands separator, no '_', no NaN/inf.
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
#: The numeric columns of a profile: (unit factor to SI, quantity of :mod:`trainsim.model.bounds`).
_PROFILE_COLUMNS = {
    "position_m": (1.0, "length"),
    "speed_mps": (1.0, "speed"),
    "speed_kmh": (KMH, "speed"),
    "time_s": (1.0, "time"),
}


def read_profile(path: Path, source: str) -> SpeedProfile:
    """A speed profile from a CSV file with columns ``position_m`` and ``speed_kmh`` (or ``speed_mps``),
    optionally ``regime`` (names as in trainsim traces) and ``time_s``; a ``trace.csv`` written by
    ``trainsim run`` qualifies. Other columns are ignored.

    The file is read within bounds (size as every document, :data:`MAX_PROFILE_ROWS` rows,
    :data:`MAX_PROFILE_COLUMNS` columns); every cell of the columns used must be a finite number in the
    plausible range of its quantity, positions and times must not decrease. Errors name the file
    (``source`` if the file is missing: the scenario that names it), the line and the column.
    """
    from trainsim.sim.codes import REGIME_NAMES

    file = str(path)
    try:
        exists = path.exists()
    except (OSError, ValueError):
        exists = False  # a name the system cannot look up is a file that is not there
    if not exists:
        raise InputError(
            "profile file not found", file=source, field="multi_point.profile", value=shown_value(file)
        )
    rows = csv.reader(io.StringIO(read_text(path), newline=""))
    try:
        header = [h.strip() for h in next(rows)]
    except StopIteration:
        raise InputError("empty profile file", file=file, allowed="a header line and rows") from None
    except csv.Error as exc:
        raise InputError(f"not a CSV file ({exc})", file=file, line=1) from None
    if len(header) > MAX_PROFILE_COLUMNS:
        raise InputError(
            "too many columns", file=file, line=1, value=len(header), allowed=f"at most {MAX_PROFILE_COLUMNS}"
        )
    speed_name = "speed_mps" if "speed_mps" in header else "speed_kmh"
    if "position_m" not in header or speed_name not in header:
        raise InputError(
            "a profile needs the columns position_m and speed_kmh (or speed_mps)",
            file=file,
            line=1,
            value=header,
            allowed="a header with position_m and speed_kmh or speed_mps (regime and time_s optional)",
        )
    if len(set(header)) != len(header):
        twice = sorted({h for h in header if header.count(h) > 1})
        raise InputError("a column is named twice", file=file, line=1, value=twice)
    wanted = [n for n in ("position_m", speed_name, "time_s", "regime") if n in header]
    index = {n: header.index(n) for n in wanted}
    codes = {name: k for k, name in enumerate(REGIME_NAMES)}
    columns: dict[str, list[float]] = {n: [] for n in wanted}
    try:
        for row in rows:
            if not row or all(not c.strip() for c in row):
                continue
            line = rows.line_num
            if len(columns["position_m"]) >= MAX_PROFILE_ROWS:
                raise InputError(
                    "too many rows", file=file, line=line, allowed=f"at most {MAX_PROFILE_ROWS} rows"
                )
            for name in wanted:
                k = index[name]
                cell = row[k].strip() if k < len(row) else ""
                if name == "regime":
                    if cell not in codes:
                        raise InputError(
                            "unknown regime",
                            file=file,
                            line=line,
                            field="regime",
                            value=cell,
                            allowed=", ".join(REGIME_NAMES),
                        )
                    columns[name].append(codes[cell])
                else:
                    columns[name].append(_profile_number(cell, name, file, line))
    except csv.Error as exc:
        raise InputError(f"not a CSV file ({exc})", file=file, line=rows.line_num) from None
    if len(columns["position_m"]) < 2:
        raise InputError(
            "a profile needs at least two rows",
            file=file,
            value=len(columns["position_m"]),
            allowed=">= 2 rows of position_m and speed",
        )
    for name in ("position_m", "time_s"):
        if name in columns:
            _non_decreasing(columns[name], name, file)
    return SpeedProfile(
        np.array(columns["position_m"]),
        np.array(columns[speed_name]),
        np.array(columns["regime"], dtype="int8") if "regime" in columns else None,
        np.array(columns["time_s"]) if "time_s" in columns else None,
    )


def _profile_number(cell: str, name: str, file: str, line: int) -> float:
    """The value [SI] of a numeric cell of column ``name``; InputError naming line and column."""
    factor, quantity = _PROFILE_COLUMNS[name]
    unit = name.rsplit("_", 1)[1].replace("mps", "m/s").replace("kmh", "km/h")
    if not _NUMBER.fullmatch(cell):
        raise InputError(
            "not a number",
            file=file,
            line=line,
            field=name,
            value=cell,
            allowed=f"a decimal number ({bounds.BOUNDS[quantity].allowed(unit, factor)}), no thousands "
            "separator",
        )
    return bounds.check(float(cell), quantity, field=name, file=file, line=line, unit=unit, factor=factor)


def _non_decreasing(values: list[float], name: str, file: str) -> None:
    diffs = np.diff(np.asarray(values))
    bad = np.flatnonzero(diffs < 0)
    if bad.size:
        k = int(bad[0]) + 1
        raise InputError(
            f"{name} decreases (data row {k + 1})",
            file=file,
            field=name,
            value=values[k],
            allowed=f">= the previous row's {values[k - 1]:g}",
        )


def run_multipoint_scenario(
    scenario: Scenario,
    settings: MultiPointSpec | MultiPointSettings | dict | None = None,
    *,
    base_dir: str | Path | None = None,
    profile: SpeedProfile | None = None,
) -> MultiPointResult:
    """Run a scenario with the multi-point model.

    Args:
        scenario: the scenario (train with its formation, route, run settings).
        settings: the ``multi_point`` block (a mapping as in the file, a validated
            :class:`MultiPointSpec`) or :class:`MultiPointSettings`; None: defaults.
        base_dir: directory the block's ``profile`` file is relative to.
        profile: a speed profile to follow (instead of the block's ``profile`` file).
    """
    strategy = "fastest"
    profile_file = None
    if settings is None or isinstance(settings, dict):
        settings = multipoint_settings_from_dict(settings or {})
    if isinstance(settings, MultiPointSpec):
        strategy, profile_file = settings.strategy, settings.profile
        mp_settings = settings.build()
    else:
        mp_settings = settings
    if profile is not None:
        strategy = "follow"
    elif profile_file:
        path = Path(profile_file)
        if not path.is_absolute():
            path = Path(base_dir or ".") / path
        profile = read_profile(path, str(path))
    if strategy == "follow":
        assert profile is not None
        return follow_profile(scenario.train, scenario.route, profile, mp_settings, scenario.settings)
    return run_multipoint_fastest(scenario.train, scenario.route, mp_settings, scenario.settings)


def multipoint_scenario_from_dict(
    data: dict[str, Any],
    source: str = "<scenario>",
    base_dir: str | Path | None = None,
    *,
    path: str | Path | None = None,
) -> tuple[Scenario, MultiPointSpec | None]:
    """The scenario of a scenario mapping that may choose ``model: multi_point``, and its validated
    ``multi_point`` block (None for ``model: single_point`` or no ``model`` key). File names in the
    mapping (route, train, the block's ``profile``) are relative to ``base_dir``; the profile's is
    made absolute here, so the scenario runs the same from any working directory. ``path``: the file
    the mapping was read from, for line numbers in errors."""
    from trainsim.io.trainsim_yaml import scenario_from_dict

    data = dict(data)
    model = data.pop("model", "single_point")
    block = data.pop("multi_point", None)
    if model not in ("single_point", "multi_point"):
        raise InputError(
            "unknown model", file=source, field="model", value=model, allowed="single_point, multi_point"
        )
    if model == "single_point" and block is not None:
        raise InputError("a 'multi_point' block needs 'model: multi_point'", file=source, field="multi_point")
    scenario = scenario_from_dict(data, source, base_dir=base_dir)
    if model != "multi_point":
        return scenario, None
    spec = multipoint_settings_from_dict(block, source, path=path)
    if spec.profile and base_dir is not None and not Path(spec.profile).is_absolute():
        spec = spec.model_copy(update={"profile": str(Path(base_dir) / spec.profile)})
    return scenario, spec


def load_multipoint_scenario(path: str | Path) -> tuple[Scenario, MultiPointSpec | None]:
    """Read a scenario file that may choose ``model: multi_point``: the scenario and its validated
    ``multi_point`` block (None for ``model: single_point`` or no ``model`` key)."""
    from trainsim.io.trainsim_yaml import read_yaml

    path = Path(path)
    data = read_yaml(path)
    if not isinstance(data, dict):
        raise InputError("expected a mapping of fields at the top level", file=str(path))
    return multipoint_scenario_from_dict(data, str(path), base_dir=path.parent, path=path)
