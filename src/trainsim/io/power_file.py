"""The power-supply file (``schema: trainsim/power``, version 1) and running it.

This is the file layer of the power package (it reads YAML and other trainsim files); the power
core (limits, network, solver, simulation, study) never imports it. Every problem is an
:class:`~trainsim.errors.InputError` naming the file, the field, the value and what is allowed.
The format is described field by field in docs/POWER.md.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    ValidationError,
    ValidationInfo,
    field_validator,
    model_validator,
)
from pydantic_core import PydanticCustomError

from trainsim.errors import InputError, Problem
from trainsim.power.limits import EN50163, standard_limits
from trainsim.power.network import Connection, Gap, Network, Storage, Substation, Track, regulation_points
from trainsim.power.onboard import OnboardStorage
from trainsim.power.simulation import CompactPowerResult, PowerResult, TrainLoad
from trainsim.power.study import FeedbackSettings, TrainService, run_study

__all__ = ["PowerFile", "StudyReader", "StudyTrains", "load_power_file", "run_power_file"]

SCHEMA = "trainsim/power"
VERSIONS = (1,)
Positive = Annotated[float, Field(gt=0)]
NonNegative = Annotated[float, Field(ge=0)]


def _not_bool(allowed: str) -> BeforeValidator:
    """Refuse true/false where a Literal of numbers is wanted: YAML's true is a Python bool, and
    bool is an int, so even a strict Literal[1, -1] would take it for 1."""

    def check(value: Any) -> Any:
        if isinstance(value, bool):
            raise PydanticCustomError("bool_not_number", "true/false is not a number", {"allowed": allowed})
        return value

    return BeforeValidator(check)


#: a direction along the track: +1 (increasing km) or -1
Direction = Annotated[Literal[1, -1], _not_bool("1 or -1")]


class _Spec(BaseModel):
    # strict: a bool or a string never becomes a number (true -> 1 pass, "3" -> 3) and a string
    # never becomes a bool ('yes' -> True); ints are still taken for floats
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, strict=True)


class LimitsSpec(_Spec):
    """Overrides of the EN 50163 limits and the trains' limitation thresholds [V]."""

    min2_v: Positive | None = None
    min1_v: Positive | None = None
    max1_v: Positive | None = None
    max2_v: Positive | None = None
    traction_full_v: Positive | None = None
    regen_full_v: Positive | None = None
    regen_zero_v: Positive | None = None
    max3_v: Positive | None = None


class TrackSpec(_Spec):
    id: str
    start_km: float
    end_km: float
    #: > 0 for DC, >= 0 for AC (with a reactance): the network states the range of its system
    contact_resistance_ohm_per_km: float
    #: >= 0, and 0 on every track or none (an ideal return): the network states it
    rail_resistance_ohm_per_km: float = 0.0
    rail_to_earth_conductance_s_per_km: NonNegative = 0.0
    contact_reactance_ohm_per_km: NonNegative = 0.0


class SubstationSpec(_Spec):
    id: str
    position_km: float
    tracks: list[str] = Field(min_length=1)
    no_load_voltage_v: Positive | None = None
    #: > 0 for DC, >= 0 for AC (with a reactance): the network states the range of its system
    internal_resistance_ohm: float | None = None
    internal_reactance_ohm: NonNegative = 0.0
    rated_power_kw: Positive | None = None
    overload_power_kw: Positive | None = None
    reversible: bool
    #: DC regulation curve [[current_a, voltage_v], ...] instead of no_load_voltage_v and
    #: internal_resistance_ohm (which it sets: the voltage at 0 A and the first segment's slope)
    regulation: list[tuple[float, Positive]] | None = Field(default=None, min_length=2, max_length=100)

    @field_validator("regulation", mode="before")
    @classmethod
    def _pairs_as_tuples(cls, value: Any) -> Any:
        # YAML gives lists; strict mode takes only tuples for a tuple, the numbers in them stay strict
        if isinstance(value, list):
            return [tuple(v) if isinstance(v, list) else v for v in value]
        return value

    @model_validator(mode="after")
    def _source(self) -> SubstationSpec:
        given = (self.no_load_voltage_v is not None, self.internal_resistance_ohm is not None)
        if self.regulation is None and not all(given):
            raise ValueError("give no_load_voltage_v and internal_resistance_ohm, or a regulation curve")
        if self.regulation is not None and any(given):
            raise ValueError(
                "give either a regulation curve or no_load_voltage_v and internal_resistance_ohm, not both"
            )
        return self


class ConnectionSpec(_Spec):
    id: str
    position_km: float
    tracks: list[str] = Field(min_length=2)
    kind: Literal["paralleling_post", "cross_bond"]


class GapSpec(_Spec):
    id: str
    track: str
    start_km: float
    end_km: float


class StorageSpec(_Spec):
    id: str
    position_km: float
    tracks: list[str] = Field(min_length=1)
    capacity_kwh: Positive
    max_power_kw: Positive
    efficiency: Annotated[float, Field(gt=0, le=1)]
    charge_above_v: Positive
    discharge_below_v: Positive
    ramp_v: Positive = 20.0
    initial_soc: Annotated[float, Field(ge=0, le=1)] = 0.5


class NetworkSpec(_Spec):
    name: str = "network"
    system: Literal[tuple(EN50163)]  # type: ignore[valid-type]
    limits: LimitsSpec = Field(default_factory=LimitsSpec)
    negative_earthed: bool = False
    tracks: list[TrackSpec] = Field(min_length=1)
    substations: list[SubstationSpec] = Field(min_length=1)
    connections: list[ConnectionSpec] = Field(default_factory=list)
    gaps: list[GapSpec] = Field(default_factory=list)
    storages: list[StorageSpec] = Field(default_factory=list)


class HeadwaySpec(_Spec):
    first_s: float = 0.0
    every_s: Positive
    count: Annotated[int, Field(ge=1, le=10_000)]


class OnboardStorageSpec(_Spec):
    capacity_kwh: Positive
    max_power_kw: Positive
    charge_efficiency: Annotated[float, Field(gt=0, le=1)]
    discharge_efficiency: Annotated[float, Field(gt=0, le=1)]
    min_soc: Annotated[float, Field(ge=0, lt=1)] = 0.2
    max_soc: Annotated[float, Field(gt=0, le=1)] = 0.9
    initial_soc: Annotated[float, Field(ge=0, le=1)] = 0.5
    assist_above_kw: NonNegative = 0.0

    def storage(self) -> OnboardStorage:
        return OnboardStorage(
            self.capacity_kwh * 3.6e6, self.max_power_kw * 1000, self.charge_efficiency,
            self.discharge_efficiency, self.min_soc, self.max_soc, self.initial_soc, self.assist_above_kw * 1000,
        )  # fmt: skip


class TrainSpec(_Spec):
    id: str
    scenario: str
    track: str
    origin_km: float = 0.0
    direction: Direction = 1
    departures_s: list[float] | None = None
    headway: HeadwaySpec | None = None
    onboard_storage: OnboardStorageSpec | None = None

    @model_validator(mode="after")
    def _one_timetable(self) -> TrainSpec:
        if (self.departures_s is None) == (self.headway is None):
            raise ValueError(
                "give either departures_s (a list of times) or headway (first_s, every_s, count)"
            )
        if self.departures_s is not None and not self.departures_s:
            raise ValueError("departures_s is empty")
        return self


class FeedbackSpec(_Spec):
    enabled: bool = True
    max_iterations: Annotated[int, Field(ge=1, le=50)] = 10
    tolerance: Annotated[float, Field(gt=0, lt=0.5)] = 1e-3
    method: Literal["per_step", "per_stretch", "constant"] = "per_stretch"
    knock_on: bool = False
    buffer_s: NonNegative = 0.0

    def settings(self) -> FeedbackSettings:
        """The power layer's feedback settings of this block."""
        return FeedbackSettings(
            self.enabled, self.max_iterations, self.tolerance, self.method, self.knock_on, self.buffer_s
        )


class SimulationSpec(_Spec):
    step_s: Annotated[float, Field(gt=0, le=60)] = 1.0
    start_s: float | None = None
    end_s: float | None = None
    feedback: FeedbackSpec = Field(default_factory=FeedbackSpec)
    #: each train's series kept over the whole span (``full``), only while it runs (``on_network``,
    #: a whole day: trainsim.power.day), or ``auto``: full when within the cap, else on_network
    traces: Literal["auto", "full", "on_network"] = "auto"


class SynchronisationSpec(_Spec):
    """Shift departures within windows to minimise the substations' energy (trainsim.power.synchronise)."""

    window_s: Annotated[float, Field(gt=0, le=3600)] = 20.0
    step_s: Annotated[float, Field(gt=0, le=3600)] = 5.0
    rounds: Annotated[int, Field(ge=1, le=20)] = 3
    refinements: Annotated[int, Field(ge=0, le=10)] = 2
    min_headway_s: Annotated[float, Field(ge=0)] = 90.0
    per: Literal["departure", "service"] = "departure"
    #: refuse offsets that put the substations further beyond their overload power
    avoid_overload: bool = True

    @field_validator("step_s")
    @classmethod
    def _step_in_window(cls, step_s: float, info: ValidationInfo) -> float:
        # a field validator (window_s comes first) so the error names synchronisation.step_s
        window_s = info.data.get("window_s")
        if window_s is not None and step_s > window_s:
            raise PydanticCustomError(
                "step_beyond_window",
                f"step_s ({step_s:g} s) must not exceed window_s ({window_s:g} s)",
                {"window_s": window_s},
            )
        return step_s


class TimetableStudySpec(_Spec):
    """The trains of a batch study's timetable (``schema: trainsim/study``, its ``departures:``) on one
    track: every distinct scenario of the study a train service, its runs' departures its timetable."""

    study: str
    track: str
    origin_km: float = 0.0
    direction: Direction = 1
    #: prefix of the services' ids (default: the track's id): ``<id>/<study entry's name>``
    id: str | None = None


@dataclasses.dataclass(frozen=True)
class StudyTrains:
    """One distinct scenario of a batch study and the departures of its runs [s since midnight].

    ``entry`` names the study entry (``runs[k] 'name'``) for the messages."""

    name: str
    entry: str
    scenario: Any
    departures_s: tuple[float, ...]


#: Reads a batch study file into its distinct scenarios with their departures. The batch layer
#: (above this one) provides it: trainsim.batch.power_timetable.read_study_trains.
StudyReader = Callable[[Path], list[StudyTrains]]


class OperationLinkSpec(_Spec):
    """The trains of an operation file (``trainsim operate``), as operated, on this network."""

    file: str
    tracks: dict[Literal["up", "down"], str] = Field(min_length=1)
    origin_km: float = 0.0


class PowerFile(_Spec):
    """The whole file."""

    schema_: Literal["trainsim/power"] = Field(alias="schema")
    version: Annotated[Literal[1], _not_bool("1")]
    name: str = "power supply"
    description: str | None = None
    network: NetworkSpec
    trains: list[TrainSpec] = Field(default_factory=list)
    #: trains from batch studies' timetables (with or without trains:)
    timetable: list[TimetableStudySpec] = Field(default_factory=list)
    operation: OperationLinkSpec | None = None
    simulation: SimulationSpec = Field(default_factory=SimulationSpec)
    synchronisation: SynchronisationSpec | None = None

    @model_validator(mode="after")
    def _trains_or_operation(self) -> PowerFile:
        if bool(self.trains or self.timetable) == (self.operation is not None):
            raise ValueError(
                "give either trains and/or timetable (batch studies) or operation (an operation file)"
            )
        if self.synchronisation is not None and self.operation is not None:
            raise ValueError("synchronisation shifts the departures of trains: not of an operation file")
        if self.operation is not None and self.simulation.traces == "on_network":
            raise ValueError("simulation.traces: on_network is for trains: operated trains keep full traces")
        return self


def _field(loc: tuple) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        elif isinstance(part, str) and part.startswith("function-after["):
            continue
        else:
            out += ("." if out else "") + str(part).replace("schema_", "schema")
    return out


#: what a field of each type takes, for the errors of the strict types (which give no ctx)
_STRICT_ALLOWED = {
    "float_type": "a number (not true/false or a quoted string)",
    "int_type": "a whole number (not true/false, a quoted string or a fraction)",
    "bool_type": "true or false (not 'yes', 1 or a quoted string)",
    "string_type": "a string",
}


def _validation_problems(exc: ValidationError, file: str) -> list[Problem]:
    problems = []
    for err in exc.errors(include_url=False):
        loc = tuple(p for p in err["loc"] if not (isinstance(p, str) and p.startswith("function-")))
        value = err.get("input")
        if isinstance(value, dict | list):
            value = None
        reason = err["msg"].removeprefix("Value error, ")
        ctx = err.get("ctx") or {}
        bounds = [
            f"{sym} {ctx[key]}"
            for key, sym in (("gt", ">"), ("ge", ">="), ("lt", "<"), ("le", "<="))
            if key in ctx
        ]
        allowed = " and ".join(bounds) or (str(ctx["expected"]) if "expected" in ctx else None)
        allowed = _STRICT_ALLOWED.get(err["type"], allowed)
        if err["type"] == "bool_not_number":
            allowed = ctx["allowed"]
        if err["type"] == "step_beyond_window":
            allowed = f"<= window_s ({ctx['window_s']:g} s)"
        if err["type"] == "extra_forbidden":
            reason = "unknown field"
            allowed = "the fields of docs/POWER.md"
        elif err["type"] == "missing":
            reason = "required field is missing"
        problems.append(Problem(reason, file=file, field=_field(loc) or None, value=value, allowed=allowed))
    return problems


def _source(s: SubstationSpec, k: int) -> tuple[float, float, tuple[tuple[float, float], ...] | None]:
    """(E, R_i, regulation) of substation k: given, or from its regulation curve."""
    if s.regulation is None:
        return float(s.no_load_voltage_v), float(s.internal_resistance_ohm), None
    curve = tuple((float(i), float(u)) for i, u in s.regulation)
    try:
        e, r = regulation_points(list(curve))
    except InputError as exc:
        problem = exc.problems[0]
        raise InputError(problem.reason, field=f"substations[{k}].regulation", value=problem.value,
                         allowed=problem.allowed) from None  # fmt: skip
    return e, r, curve


def _network(spec: NetworkSpec, file: str) -> Network:
    base = standard_limits(spec.system)
    try:
        limits = base.with_overrides(**spec.limits.model_dump())
        return Network(
            name=spec.name,
            system="ac" if spec.system.startswith("ac") else "dc",
            limits=limits,
            tracks=tuple(
                Track(
                    t.id,
                    t.start_km * 1000,
                    t.end_km * 1000,
                    t.contact_resistance_ohm_per_km / 1000,
                    t.rail_resistance_ohm_per_km / 1000,
                    t.rail_to_earth_conductance_s_per_km / 1000,
                    t.contact_reactance_ohm_per_km / 1000,
                )
                for t in spec.tracks
            ),
            substations=tuple(
                Substation(
                    s.id,
                    s.position_km * 1000,
                    tuple(s.tracks),
                    *_source(s, k)[:2],
                    s.internal_reactance_ohm,
                    None if s.rated_power_kw is None else s.rated_power_kw * 1000,
                    None if s.overload_power_kw is None else s.overload_power_kw * 1000,
                    s.reversible,
                    _source(s, k)[2],
                )
                for k, s in enumerate(spec.substations)
            ),
            connections=tuple(
                Connection(c.id, c.position_km * 1000, tuple(c.tracks), c.kind) for c in spec.connections
            ),
            gaps=tuple(Gap(g.id, g.track, g.start_km * 1000, g.end_km * 1000) for g in spec.gaps),
            storages=tuple(
                Storage(
                    w.id,
                    w.position_km * 1000,
                    tuple(w.tracks),
                    w.capacity_kwh * 3.6e6,
                    w.max_power_kw * 1000,
                    w.efficiency,
                    w.charge_above_v,
                    w.discharge_below_v,
                    w.ramp_v,
                    w.initial_soc,
                )
                for w in spec.storages
            ),
            negative_earthed=spec.negative_earthed,
            frequency_hz=50.0 if spec.system == "ac_25000" else (16.7 if spec.system == "ac_15000" else 0.0),
        )
    except InputError as exc:
        raise InputError.from_problems(
            [
                Problem(
                    p.reason,
                    file=file,
                    line=p.line,
                    field=("network." + p.field) if p.field else "network",
                    value=p.value,
                    allowed=p.allowed,
                )
                for p in exc.problems
            ]
        ) from exc


def _check_on_track(
    network: Network,
    scenario: Any,
    track_id: str,
    origin_km: float,
    direction: int,
    what: str,
    file: str,
    field: str,
) -> float:
    """The origin [m] of a route laid on track ``track_id``; InputError naming ``field`` if the track
    is unknown or the route leaves the track."""
    if track_id not in {tr.id for tr in network.tracks}:
        raise InputError("unknown track", file=file, field=field.rsplit(".", 1)[0] + ".track", value=track_id,
                         allowed=", ".join(tr.id for tr in network.tracks))  # fmt: skip
    track = network.tracks[network.track_index(track_id)]
    origin = origin_km * 1000
    end = origin + direction * (scenario.route.end_m - scenario.route.start_m)
    lo, hi = min(origin, end), max(origin, end)
    if lo < track.start_m - 1e-6 or hi > track.end_m + 1e-6:
        raise InputError(
            f"{what} runs off the wire: its route covers {lo / 1000:g} .. {hi / 1000:g} km",
            file=file,
            field=field,
            value=origin_km,
            allowed=f"a route within track {track.id}'s {track.start_m / 1000:g} .. {track.end_m / 1000:g} km",
        )
    return origin


def _study_services(
    path: Path, spec: PowerFile, network: Network, read_study: StudyReader | None
) -> list[TrainService]:
    """The train services of the file's ``timetable:`` studies."""
    file = str(path)
    services = []
    studies: dict[Path, list[StudyTrains]] = {}
    for k, link in enumerate(spec.timetable):
        where = path.parent / link.study
        if not where.is_file():
            raise InputError("study file not found", file=file, field=f"timetable[{k}].study", value=link.study,
                             allowed="a trainsim/study file, relative to this file")  # fmt: skip
        if read_study is None:
            raise InputError(
                "a batch study's timetable is read by the batch layer: run this file with "
                "trainsim.batch.power_timetable.run_power_file (or load_power_file)",
                file=file, field=f"timetable[{k}].study", value=link.study,
            )  # fmt: skip
        # a study laid on both tracks is read (and its scenarios built) once
        if where.resolve() not in studies:
            studies[where.resolve()] = read_study(where)
        for group in studies[where.resolve()]:
            if group.scenario.model != "single_point":
                raise InputError(
                    f"the power simulation takes single-point scenarios: study entry {group.entry} is "
                    f"{group.scenario.model}", file=file, field=f"timetable[{k}].study", value=link.study,
                    allowed="model: single_point",
                )  # fmt: skip
            origin = _check_on_track(
                network, group.scenario, link.track, link.origin_km, link.direction,
                f"study entry {group.entry} of {link.study}", file, f"timetable[{k}].origin_km",
            )  # fmt: skip
            sid = f"{link.id or link.track}/{group.name}"
            services.append(TrainService(sid, group.scenario, link.track, origin, link.direction,
                                         group.departures_s, None))  # fmt: skip
    ids = [s.id for s in services]
    twice = sorted({i for i in ids if ids.count(i) > 1})
    if twice:
        raise InputError("two timetable studies give services of the same id", file=file, field="timetable",
                         value=twice[0], allowed="a distinct id: per study")  # fmt: skip
    return services


def load_power_file(
    path: str | Path, *, read_study: StudyReader | None = None
) -> tuple[PowerFile, Network, list[TrainService]]:
    """Read and check a power-supply file: its spec, the network and the train services (each
    scenario file read relative to the power file). ``read_study`` reads the batch studies of a
    ``timetable:`` block (the batch layer's, trainsim.batch.power_timetable.read_study_trains)."""
    from trainsim.io.loader import load_scenario
    from trainsim.io.trainsim_yaml import read_yaml

    path = Path(path)
    file = str(path)
    data = read_yaml(path)
    if not isinstance(data, dict):
        raise InputError("a power-supply file is a mapping", file=file, value=type(data).__name__)
    if data.get("schema") != SCHEMA:
        raise InputError(
            "not a power-supply file", file=file, field="schema", value=data.get("schema"), allowed=SCHEMA
        )
    try:
        spec = PowerFile.model_validate(data)
    except ValidationError as exc:
        raise InputError.from_problems(_validation_problems(exc, file)) from None
    network = _network(spec.network, file)
    services = []
    scenarios: dict[str, Any] = {}
    for k, t in enumerate(spec.trains):
        where = path.parent / t.scenario
        if not where.is_file():
            raise InputError(
                "scenario file not found",
                file=file,
                field=f"trains[{k}].scenario",
                value=t.scenario,
                allowed="a trainsim scenario file, relative to this file",
            )
        if t.scenario not in scenarios:
            scenarios[t.scenario] = load_scenario(where)
        scenario = scenarios[t.scenario]
        if scenario.model != "single_point":
            raise InputError(
                "the power simulation takes single-point scenarios",
                file=file,
                field=f"trains[{k}].scenario",
                value=t.scenario,
                allowed="model: single_point",
            )
        origin = _check_on_track(
            network,
            scenario,
            t.track,
            t.origin_km,
            t.direction,
            f"train {t.id}",
            file,
            f"trains[{k}].origin_km",
        )
        if t.departures_s is not None:
            deps = tuple(float(x) for x in t.departures_s)
        else:
            h = t.headway
            deps = tuple(h.first_s + h.every_s * j for j in range(h.count))
        storage = None
        if t.onboard_storage is not None:
            storage = t.onboard_storage.storage()
            problems = storage.problems(f"trains[{k}].onboard_storage")
            if problems:
                raise InputError.from_problems([dataclasses.replace(q, file=file) for q in problems])
        services.append(TrainService(t.id, scenario, t.track, origin, t.direction, deps, storage))
    services.extend(_study_services(path, spec, network, read_study))
    return spec, network, services


def _moving_pieces(time_s: np.ndarray, position_m: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) trace index of each movement between two standstills of an operated trajectory
    (a standstill: the position does not change while the time does)."""
    standing = (np.diff(position_m) <= 1e-9) & (np.diff(time_s) > 0)
    pieces, start = [], 0
    for k in np.flatnonzero(standing):
        if position_m[k] - position_m[start] >= 1.0:
            pieces.append((start, int(k)))
        start = int(k) + 1
    if position_m[-1] - position_m[start] >= 1.0:
        pieces.append((start, len(position_m) - 1))
    return pieces


#: A run of the operation spans a movement when its ends are within this of the movement's [m].
RUN_SPAN_TOLERANCE_M = 1e-6


def _runs_span(outcome: Any, pieces: list[tuple[int, int]], position_m: np.ndarray) -> bool:
    """Whether the operated trajectory is the outcome's runs joined, one run per movement with the
    same ends (not time-scaled: ``trajectory_note`` empty)."""
    runs = getattr(outcome, "runs", ())
    if getattr(outcome, "trajectory_note", "") or len(runs) != len(pieces):
        return False
    for run, (i0, i1) in zip(runs, pieces, strict=True):
        x = run.trace.position_m
        if (
            abs(x[0] - position_m[i0]) > RUN_SPAN_TOLERANCE_M
            or abs(x[-1] - position_m[i1]) > RUN_SPAN_TOLERANCE_M
        ):
            return False
    return True


def operated_train_loads(
    operation_file: str | Path, tracks: dict[str, str], origin_m: float = 0.0
) -> tuple[list[TrainLoad], dict[str, Any]]:
    """The trains of an operation file as the power network sees them, as operated (with the
    waits at signals and the delays of ``trainsim operate``).

    Each movement of an operated train between two standstills (stops and signal stops) is the
    core's run the operation itself joined for it (``TrainOutcome.runs``: under the operation's
    extra ceilings where it had some, e.g. the approach to a restrictive signal or ETCS
    supervision); where the operated trajectory is not those runs joined (time-scaled, or runs
    that do not span the movements), the core's fastest run between the same standstills
    (``trainsim.operations.runs.service_route``). Its traction power F v / eta_t and regenerated
    power F_r v eta_r are placed at the operated times of the same positions. ``tracks`` maps each
    direction (``up``, ``down``) to a network track; the line's position x is at chainage
    ``origin_m + x``.

    Returns the loads and an ``operation`` block for the summary: file, status, per train its
    delay and the largest difference between an operated movement's duration and its run's [s]
    (round-off where the operation's runs are used; otherwise what the operation changed).
    """
    from trainsim.io.operation_file import read_operation
    from trainsim.io.operation_run import run_operation

    op = read_operation(operation_file)
    result = run_operation(op)
    return _operated_loads(op, op.services, result, str(operation_file), tracks, origin_m)


def _operated_loads(
    op: Any,
    services: list,
    result: Any,
    file: str,
    tracks: dict[str, str],
    origin_m: float,
    stretch_caps: dict[str, tuple[np.ndarray, np.ndarray]] | None = None,
    directed_routes: dict[str, Any] | None = None,
) -> tuple[list[TrainLoad], dict[str, Any]]:
    """The loads and ``operation`` block of an operation's ``result`` (see
    :func:`operated_train_loads`); ``services`` are the ones it ran. A fastest rerun is made with the
    same traction power cap as the operation's runs: the service's, and with ``stretch_caps`` (per
    train id: its scheduled stops' running positions [m] and a cap per stretch between them [W]) the
    cap of the stretch the movement lies on; and on the same route (``directed_routes`` per
    direction, e.g. with the network's neutral sections, else the operation's own)."""
    from trainsim.operations.runs import direction_route, service_route
    from trainsim.sim.fastest import run_fastest

    by_id = {svc.id: svc for svc in services}
    stretch_caps = stretch_caps or {}
    loads, trains = [], []
    for outcome in result.trains:
        svc = by_id[outcome.id]
        el = svc.train.electrical
        if el is None:
            raise InputError("the train has no electrical data", file=file,
                             field=f"trains[{outcome.id}].train", value=svc.train.name,
                             allowed="a train with an electrical block")  # fmt: skip
        if outcome.direction not in tracks:
            raise InputError("no network track for this direction", field="operation.tracks",
                             value=outcome.direction, allowed="up: TRACK, down: TRACK")  # fmt: skip
        traj = outcome.trajectory
        if traj is None:
            trains.append({"id": outcome.id, "status": outcome.status, "on_network": False})
            continue
        directed = (directed_routes or {}).get(outcome.direction) or direction_route(
            op.geometry, op.line.length_m, outcome.direction
        )
        t_parts, x_parts, pt_parts, pr_parts = [], [], [], []
        mismatch = 0.0
        t, s = traj.time_s, traj.position_m
        pieces = _moving_pieces(t, s)
        # the operation's own runs, when they are the movements: a rerun would drop the extra ceilings
        # it ran some of them under (a fastest rerun of a signal approach is seconds shorter)
        own = list(outcome.runs) if _runs_span(outcome, pieces, s) else None
        for k, (i0, i1) in enumerate(pieces):
            if own is not None:
                run = own[k]
            else:
                train = _capped_train(svc, stretch_caps.get(svc.id), 0.5 * (s[i0] + s[i1]))
                run = run_fastest(train, service_route(directed, [("a", s[i0]), ("b", s[i1])]), op.settings)
            tr = run.trace
            mismatch = max(mismatch, abs((t[i1] - t[i0]) - (tr.time_s[-1] - tr.time_s[0])))
            t_parts.append(np.interp(tr.position_m, s[i0 : i1 + 1], t[i0 : i1 + 1]))
            x_parts.append(tr.position_m)
            pt_parts.append(tr.traction_force_n * tr.speed_mps / el.traction_efficiency)
            pr_parts.append(tr.regenerative_braking_force_n * tr.speed_mps * el.regenerative_efficiency)
        # standing before the first and after the last movement (dwell at the destination)
        t_all = np.concatenate([[t[0]], *t_parts, [t[-1]]])
        x_all = np.concatenate([[s[0]], *x_parts, [s[-1]]])
        pt_all = np.concatenate([[0.0], *pt_parts, [0.0]])
        pr_all = np.concatenate([[0.0], *pr_parts, [0.0]])
        line_x = x_all if outcome.direction == "up" else op.line.length_m - x_all
        loads.append(
            TrainLoad(outcome.id, tracks[outcome.direction], t_all, origin_m + line_x, pt_all, pr_all,
                      el.auxiliary_power_w, el.power_factor)
        )  # fmt: skip
        trains.append({"id": outcome.id, "status": outcome.status, "on_network": True,
                       "delay_s": _finite(outcome.delay_s), "movements": len(t_parts),
                       "movement_time_mismatch_s": mismatch})  # fmt: skip
    info = {"file": file, "status": result.status, "trains": trains}
    return loads, info


def _capped_train(svc: Any, caps: tuple[np.ndarray, np.ndarray] | None, running_m: float) -> Any:
    """The service's train with the traction power cap at the wheel its operated runs have at
    running position ``running_m`` [m]: its own cap, and the cap of that stretch of ``caps`` (stops,
    caps [W]; 0: no traction)."""
    from trainsim.power.operated import stretch_index

    cap = svc.traction_power_cap_w
    if caps is not None:
        stops, values = caps
        cap = min(cap, float(values[int(stretch_index(stops, np.array([running_m]), len(values))[0])]))
    if not np.isfinite(cap):
        return svc.train
    return dataclasses.replace(
        svc.train, traction=svc.train.traction.capped(power_cap_w=cap, force_cap_n=None if cap > 0 else 0.0)
    )


def _arrival_s(outcome: Any) -> float:
    """When an operated train arrived at its destination [s] (NaN: it did not)."""
    if outcome.status != "ok":
        # a stalled or deadlocked train has no arrival, whatever its last stop's record holds
        return float("nan")
    last = outcome.stops[-1] if outcome.stops else None
    if last is None or last.arrival_s is None or not np.isfinite(last.arrival_s):
        return float("nan")
    return float(last.arrival_s)


def _stretch_cap_cache(
    settings: Any, geometry: Any = None, directed_routes: dict[str, Any] | None = None
) -> Any:
    """A run cache of the operation (``trainsim.operations.runs.RunCache``) that runs some trains with
    a traction power cap at the wheel per scheduled stretch (``set_caps``), and, with
    ``directed_routes``, the operation's ``geometry`` in each direction on the route given for it
    (the line with the network's neutral sections).

    The operation makes a train's operated runs with the train ``power_capped(svc.train, ...)`` hands
    back, stretch by stretch between two stops (``stretch``, ``eco_stretch``), and its plan with
    ``svc.train`` itself. So for a capped service ``power_capped`` hands back a stand-in (a copy of the
    train), and a run of the stand-in is made with the train capped at the cap of the scheduled stretch
    the run lies on (signal stops split a scheduled stretch, never join two). The plan stays uncapped:
    a train slowed by the line shows as late. (The operation takes one cap per train of its own,
    ``TrainService.traction_power_cap_w``; this adds the cap per stretch without changing it.)"""
    from trainsim.operations.runs import RunCache
    from trainsim.power.operated import stretch_index

    class StretchCapCache(RunCache):
        def __init__(self) -> None:
            super().__init__(settings)
            # id(train) -> (train, stand-in); id(stand-in) -> (stand-in, train, stops [m], caps [W])
            self._stand_in: dict[int, tuple[Any, Any]] = {}
            self._caps: dict[int, tuple[Any, Any, np.ndarray, np.ndarray]] = {}
            self._no_traction: dict[int, tuple[Any, Any]] = {}

        def directed(self, geometry_: Any, length_m: float, direction: str) -> Any:
            found = (directed_routes or {}).get(direction)
            if found is not None and geometry_ is geometry:
                return found
            return super().directed(geometry_, length_m, direction)

        def set_caps(self, train: Any, stops_m: np.ndarray, caps_w: np.ndarray) -> None:
            """Runs of ``train`` (a service's own object) with ``caps_w[k]`` [W] between ``stops_m[k]``
            and ``stops_m[k + 1]`` (running positions [m]); inf: no cap, 0: no traction."""
            stand_in = dataclasses.replace(train)
            self._keep.extend((train, stand_in))  # ids stay valid while the cache lives
            self._stand_in[id(train)] = (train, stand_in)
            self._caps[id(stand_in)] = (stand_in, train, np.asarray(stops_m, float), np.asarray(caps_w, float))  # fmt: skip

        def power_capped(self, train: Any, power_cap_w: float) -> Any:
            found = self._stand_in.get(id(train))
            if found is not None and found[0] is train:
                if np.isfinite(power_cap_w):
                    raise InputError("a train with caps per stretch has no cap of its own",
                                     field="traction_power_cap_w", value=power_cap_w, allowed="inf")  # fmt: skip
                return found[1]
            return super().power_capped(train, power_cap_w)

        def _resolve(self, train: Any, a: tuple[str, float], b: tuple[str, float]) -> Any:
            found = self._caps.get(id(train))
            if found is None or found[0] is not train:
                return train
            _, base, stops, caps = found
            cap = float(caps[int(stretch_index(stops, np.array([0.5 * (a[1] + b[1])]), len(caps))[0])])
            if cap > 0:
                return super().power_capped(base, cap)
            zero = self._no_traction.get(id(base))
            if zero is None or zero[0] is not base:
                zero = self._no_traction[id(base)] = (
                    base, dataclasses.replace(base, traction=base.traction.capped(force_cap_n=0.0, power_cap_w=0.0))
                )  # fmt: skip
            return zero[1]

        def stretch(self, train, directed, a, b, limits=()):  # type: ignore[no-untyped-def]
            return super().stretch(self._resolve(train, a, b), directed, a, b, limits)

        def eco_stretch(self, train, directed, a, b, *rest, **options):  # type: ignore[no-untyped-def]
            return super().eco_stretch(self._resolve(train, a, b), directed, a, b, *rest, **options)

    return StretchCapCache()


def _wait_s(outcome: Any) -> float:
    """The time an operated train waited at signals and was held at stops [s]."""
    return float(sum(h.wait_s for h in outcome.hindrances))


def _run_operated(path: Path, spec: PowerFile, network: Network) -> Any:
    """The power study of the operation file's trains, with voltage-limited traction fed back into
    the operation when ``simulation.feedback.enabled`` (:func:`trainsim.power.operated.feed_back_operated`:
    caps per stretch or per train as ``feedback.method`` says, the operation re-simulated with them so
    that a slowed train holds the trains behind it at signals). A train's ``time_lost_s`` is its
    arrival at its destination minus its arrival in the operation without caps: its own slower
    running and the waits behind slowed trains (``wait_s`` against ``nominal_wait_s``).
    """
    from trainsim.io.operation_file import read_operation
    from trainsim.io.operation_run import run_operation
    from trainsim.power.operated import Operated, OperatedTrain, feed_back_operated, greatest_wheel_power_w

    sim = spec.simulation
    link = spec.operation
    where = path.parent / link.file
    tracks = dict(link.tracks)
    origin_m = link.origin_km * 1000
    op = read_operation(where)
    length = op.line.length_m
    trains, stops = [], {}
    for svc in op.services:
        at = op.line.paths[svc.direction].stop_m
        names = [svc.origin, *(s.station for s in svc.stops if s.station != svc.destination), svc.destination]
        stops[svc.id] = np.array([at[n] for n in names])
        up = svc.direction == "up"
        el = svc.train.electrical
        trains.append(OperatedTrain(svc.id, stops[svc.id], origin_m if up else origin_m + length, 1 if up else -1,
                                    el.traction_efficiency if el is not None else 1.0,
                                    greatest_wheel_power_w(svc.train), tuple(names)))  # fmt: skip
    try:
        routes, neutral = _operated_neutral_sections(op, network, tracks, origin_m)
    except InputError as exc:
        raise exc.located(str(path)) from None
    cache: Any = None
    own: dict[str, Any] = {}  # a train object per capped service: the cache tells them apart by it

    def operate(caps: dict[str, np.ndarray] | None) -> Operated:
        nonlocal cache
        if caps is None and not routes:
            # without caps exactly as without feedback (no shared cache), so that disabling it changes nothing
            services, operated = list(op.services), run_operation(op)
        else:
            cache = cache or _stretch_cap_cache(op.settings, op.geometry, routes)
            caps = caps or {}
            services = []
            for svc in op.services:
                if svc.id in caps:
                    train = own.setdefault(svc.id, dataclasses.replace(svc.train))
                    cache.set_caps(train, stops[svc.id], caps[svc.id])
                    svc = dataclasses.replace(svc, train=train)
                services.append(svc)
            operated = run_operation(op, services, cache)
        capped = {tid: (stops[tid], c) for tid, c in (caps or {}).items()}
        loads, info = _operated_loads(op, services, operated, str(where), tracks, origin_m, capped, routes)
        if not loads:
            raise InputError("no operated train reached the network", file=str(path), field="operation.file",
                             value=link.file)  # fmt: skip
        return Operated(loads, info, {o.id: _arrival_s(o) for o in operated.trains},
                        {o.id: o.status for o in operated.trains}, {o.id: _wait_s(o) for o in operated.trains})  # fmt: skip

    fb = sim.feedback
    settings = fb.settings()
    try:
        return feed_back_operated(network, trains, operate, settings, explicit=set(fb.model_fields_set),
                                  dt_s=sim.step_s, start_s=sim.start_s, end_s=sim.end_s,
                                  blocks={"neutral_sections": neutral} if neutral else None)  # fmt: skip
    except InputError as exc:
        raise exc.located(str(path)) from None


def _operated_neutral_sections(
    op: Any, network: Network, tracks: dict[str, str], origin_m: float
) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """The operation's line in each direction with the network's neutral sections of that
    direction's track as sections without traction (:func:`trainsim.power.study.route_with_neutral_sections`),
    where they change it, and the records of the sections for the ``neutral_sections`` block, one per
    operated train. The line is one route per direction for all its trains: they must share their
    nominal line voltage (the parts the route leaves uncovered get it)."""
    from trainsim.operations.runs import direction_route
    from trainsim.power.study import route_with_neutral_sections

    length = op.line.length_m
    routes: dict[str, Any] = {}
    records: list[dict[str, Any]] = []
    for direction, track in tracks.items():
        mine = [svc for svc in op.services if svc.direction == direction]
        if not mine:
            continue
        voltages = {svc.train.electrical.line_voltage_v for svc in mine if svc.train.electrical is not None}
        route = direction_route(op.geometry, length, direction)
        # chainage of the route's position s: origin + s up, origin + length - s down
        start = origin_m + route.start_m if direction == "up" else origin_m + length - route.start_m
        new, found = route_with_neutral_sections(route, mine[0].train, network, track, start,
                                                 1 if direction == "up" else -1)  # fmt: skip
        if new is not route:
            if len(voltages) > 1:
                raise InputError("the network's neutral sections are laid over the operation's line, one route for "
                                 "all its trains: they must have one nominal line voltage", field="operation.file",
                                 value=", ".join(f"{v:g} V" for v in sorted(voltages)),
                                 allowed="trains of one line voltage per direction")  # fmt: skip
            routes[direction] = new
        records.extend({**r, "train": svc.id} for svc in mine for r in found)
    return routes, records


def _finite(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


def run_power_file(
    path: str | Path,
    out_dir: str | Path | None = None,
    *,
    plots: bool = True,
    synchronise: bool | None = None,
    read_study: StudyReader | None = None,
) -> tuple[dict[str, Any], str]:
    """Run a power-supply file: (summary, status). With ``out_dir``: ``summary.json``, the time
    series as CSV (``trains.csv``, ``substations.csv``, ``network.csv``) and, with ``plots``, PNG
    plots (see :mod:`trainsim.power.plots`). With ``operation:`` the operated trains, with
    voltage-limited traction fed back into the operation unless ``simulation.feedback.enabled`` is
    false (then solved once, as before: their delays come from the operation alone).

    Timetables (``trains:``): ``simulation.traces`` (``auto``: each train's series over the whole span
    when within :data:`~trainsim.power.simulation.MAX_FULL_TRAIN_STEPS`, else only while it runs, a whole
    day: :mod:`trainsim.power.day`); the ``synchronisation:`` block shifts the departures first
    (:func:`~trainsim.power.synchronise.synchronise_departures`; ``synchronise`` True runs it with the
    block's or the default settings, False skips it) and the summary gets a ``synchronisation`` block.
    ``read_study`` reads the ``timetable:`` block's batch studies (see :func:`load_power_file`)."""
    spec, network, services = load_power_file(path, read_study=read_study)
    sim = spec.simulation
    sync_block = None
    if spec.operation is not None:
        if synchronise:
            raise InputError("synchronisation shifts the departures of trains: not of an operation file",
                             file=str(path), field="synchronisation", allowed="a file with trains:")  # fmt: skip
        link = spec.operation
        where = Path(path).parent / link.file
        if not where.is_file():
            raise InputError("operation file not found", file=str(path), field="operation.file", value=link.file,
                             allowed="a trainsim/operation file, relative to this file")  # fmt: skip
        unknown = [tid for tid in link.tracks.values() if tid not in {t.id for t in network.tracks}]
        if unknown:
            raise InputError("unknown track", file=str(path), field="operation.tracks", value=unknown[0],
                             allowed=", ".join(t.id for t in network.tracks))  # fmt: skip
        result = _run_operated(Path(path), spec, network)
    else:
        fb = sim.feedback.settings()
        wanted = spec.synchronisation if synchronise is None else (
            (spec.synchronisation or SynchronisationSpec()) if synchronise else None)  # fmt: skip
        span = (sim.start_s, sim.end_s)
        if wanted is not None:
            try:
                services, sync_block, span = _synchronised(network, services, wanted, sim)
            except InputError as exc:
                raise exc.located(str(path)) from None
        try:
            result = timetable_result(network, services, sim, fb, span)
        except InputError as exc:
            raise exc.located(str(path)) from None
    summary = result.summary()
    summary["name"] = spec.name
    if sync_block is not None:
        summary["synchronisation"] = sync_block
        if sync_block["status"] != "ok":
            summary["statuses"] = [*summary.get("statuses", []), sync_block["status"]]
            summary["warnings"].append(sync_block["message"])
            if summary["status"] == "ok":
                summary["status"] = sync_block["status"]
    if out_dir is not None:
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        result = _dense_for_outputs(result, summary)
        (out / "summary.json").write_text(json.dumps(summary, indent=2, allow_nan=False))
        if isinstance(result, CompactPowerResult):
            from trainsim.power.day import write_compact_outputs

            write_compact_outputs(result, out)
        else:
            from trainsim.power.output import write_outputs

            write_outputs(result, out, plots=plots)
    return summary, summary["status"]


def _dense_for_outputs(result: PowerResult, summary: dict[str, Any]) -> PowerResult:
    """A compact result as time x train arrays when they fit (tables and plots take them); else as it
    is, the summary saying that the plots are left out."""
    if not isinstance(result, CompactPowerResult):
        return result
    if result.fits_full():
        return result.full()
    n = len(result.time_s) * len(result.train_ids)
    summary.setdefault("traces", {})["outputs"] = (
        "trains.csv, substations.csv and network.csv only: the plots take time x train arrays, "
        f"{n:.2e} train-steps here (more than the cap of full traces); plot a part with start_s, end_s"
    )
    return result


def timetable_result(
    network: Network,
    services: list[TrainService],
    sim: SimulationSpec,
    fb: FeedbackSettings,
    span: tuple[float | None, float | None],
) -> PowerResult:
    """The timetable's study: with every train's series over the span (``run_study``, with feedback)
    or, for a whole day, only while each train runs (``run_day_study``, see simulation.traces)."""
    from trainsim.power.day import run_day_study

    start_s, end_s = span
    if sim.traces != "on_network":
        try:
            return run_study(network, services, dt_s=sim.step_s, start_s=start_s, end_s=end_s, feedback=fb)
        except InputError as exc:
            # auto: the full traces' cap is checked before any step is solved (the runs are made again)
            if sim.traces == "full" or not any(p.field == "simulation.traces" for p in exc.problems):
                raise
    return run_day_study(network, services, dt_s=sim.step_s, start_s=start_s, end_s=end_s, feedback=fb)


def _synchronised(
    network: Network, services: list[TrainService], spec: SynchronisationSpec, sim: SimulationSpec
) -> tuple[list[TrainService], dict[str, Any], tuple[float, float]]:
    """The services with the departures the synchronisation chose, its summary block and the span it
    judged every timetable over (the study is solved over the same span)."""
    from trainsim.power.day import departure_loads
    from trainsim.power.study import with_neutral_sections
    from trainsim.power.synchronise import SyncSettings, synchronise_departures

    settings = SyncSettings(**spec.model_dump())
    # the candidates' runs coast through the network's neutral sections like the study's
    loads, _ = departure_loads(with_neutral_sections(network, services)[0])
    owner = [k for k, s in enumerate(services) for _ in s.departures_s]
    groups = [(services[k].track, services[k].direction) for k in owner]
    out = synchronise_departures(network, loads, groups, settings, services=[services[k].id for k in owner],
                                 dt_s=sim.step_s, start_s=sim.start_s, end_s=sim.end_s)  # fmt: skip
    shifted, i = [], 0
    for s in services:
        n = len(s.departures_s)
        offsets = out.offsets_s[i : i + n]
        shifted.append(dataclasses.replace(s, departures_s=tuple(d + x for d, x in zip(s.departures_s, offsets,
                                                                                       strict=True))))  # fmt: skip
        i += n
    block = {
        "status": out.status,
        "message": out.message,
        "per": settings.per,
        "method": f"coordinate search: {settings.rounds} passes over a {settings.step_s:g} s grid within "
        f"+-{settings.window_s:g} s, then {settings.refinements} with the step halved; "
        f"{settings.min_headway_s:g} s at least between consecutive departures on a track and direction"
        + ("; no shift further beyond the substations' overload power" if settings.avoid_overload else ""),
        "evaluation": out.evaluation,
        "evaluations": out.evaluations,
        "span_s": list(out.span_s),
        "baseline_kwh": out.baseline_kwh,
        "synchronised_kwh": out.synchronised_kwh,
        "saving_kwh": out.saving_kwh,
        "saving_percent": out.saving_percent,
        "departures": [
            {
                "id": ld.id,
                "service": services[k].id,
                "departure_s": float(ld.time_s[0]),
                "offset_s": x,
                "synchronised_departure_s": float(ld.time_s[0]) + x,
            }
            for ld, k, x in zip(loads, owner, out.offsets_s, strict=True)
        ],
    }
    return shifted, block, out.span_s
