"""The power-supply file (``schema: trainsim/power``, version 1) and running it.

This is the file layer of the power package (it reads YAML and other trainsim files); the power
core (limits, network, solver, simulation, study) never imports it. Every problem is an
:class:`~trainsim.errors.InputError` naming the file, the field, the value and what is allowed.
The format is described field by field in docs/POWER.md.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from trainsim.errors import InputError, Problem
from trainsim.power.limits import EN50163, standard_limits
from trainsim.power.network import Connection, Gap, Network, Storage, Substation, Track, regulation_points
from trainsim.power.onboard import OnboardStorage
from trainsim.power.simulation import TrainLoad, simulate
from trainsim.power.study import FeedbackSettings, TrainService, run_study, with_status

__all__ = ["PowerFile", "load_power_file", "run_power_file"]

SCHEMA = "trainsim/power"
VERSIONS = (1,)
Positive = Annotated[float, Field(gt=0)]
NonNegative = Annotated[float, Field(ge=0)]


class _Spec(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


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
    contact_resistance_ohm_per_km: NonNegative
    rail_resistance_ohm_per_km: NonNegative = 0.0
    rail_to_earth_conductance_s_per_km: NonNegative = 0.0
    contact_reactance_ohm_per_km: NonNegative = 0.0


class SubstationSpec(_Spec):
    id: str
    position_km: float
    tracks: list[str] = Field(min_length=1)
    no_load_voltage_v: Positive | None = None
    internal_resistance_ohm: NonNegative | None = None
    internal_reactance_ohm: NonNegative = 0.0
    rated_power_kw: Positive | None = None
    overload_power_kw: Positive | None = None
    reversible: bool
    #: DC regulation curve [[current_a, voltage_v], ...] instead of no_load_voltage_v and
    #: internal_resistance_ohm (which it sets: the voltage at 0 A and the first segment's slope)
    regulation: list[tuple[float, Positive]] | None = Field(default=None, min_length=2, max_length=100)

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
    direction: Literal[1, -1] = 1
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


class SimulationSpec(_Spec):
    step_s: Annotated[float, Field(gt=0, le=60)] = 1.0
    start_s: float | None = None
    end_s: float | None = None
    feedback: FeedbackSpec = Field(default_factory=FeedbackSpec)


class OperationLinkSpec(_Spec):
    """The trains of an operation file (``trainsim operate``), as operated, on this network."""

    file: str
    tracks: dict[Literal["up", "down"], str] = Field(min_length=1)
    origin_km: float = 0.0


class PowerFile(_Spec):
    """The whole file."""

    schema_: Literal["trainsim/power"] = Field(alias="schema")
    version: Literal[1]
    name: str = "power supply"
    description: str | None = None
    network: NetworkSpec
    trains: list[TrainSpec] = Field(default_factory=list)
    operation: OperationLinkSpec | None = None
    simulation: SimulationSpec = Field(default_factory=SimulationSpec)

    @model_validator(mode="after")
    def _trains_or_operation(self) -> PowerFile:
        if bool(self.trains) == (self.operation is not None):
            raise ValueError("give either trains (a timetable of scenarios) or operation (an operation file)")
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


def load_power_file(path: str | Path) -> tuple[PowerFile, Network, list[TrainService]]:
    """Read and check a power-supply file: its spec, the network and the train services (each
    scenario file read relative to the power file)."""
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
        if t.track not in {tr.id for tr in network.tracks}:
            raise InputError(
                "unknown track",
                file=file,
                field=f"trains[{k}].track",
                value=t.track,
                allowed=", ".join(tr.id for tr in network.tracks),
            )
        track = network.tracks[network.track_index(t.track)]
        origin = t.origin_km * 1000
        end = origin + t.direction * (scenario.route.end_m - scenario.route.start_m)
        lo, hi = min(origin, end), max(origin, end)
        if lo < track.start_m - 1e-6 or hi > track.end_m + 1e-6:
            raise InputError(
                f"train {t.id} runs off the wire: its route covers {lo / 1000:g} .. {hi / 1000:g} km",
                file=file,
                field=f"trains[{k}].origin_km",
                value=t.origin_km,
                allowed=f"a route within track {track.id}'s {track.start_m / 1000:g} .. {track.end_m / 1000:g} km",
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
    op: Any, services: list, result: Any, file: str, tracks: dict[str, str], origin_m: float
) -> tuple[list[TrainLoad], dict[str, Any]]:
    """The loads and ``operation`` block of an operation's ``result`` (see
    :func:`operated_train_loads`); ``services`` are the ones it ran (a fastest rerun is made with
    the same traction power cap as the operation's runs)."""
    from trainsim.operations.runs import direction_route, service_route
    from trainsim.sim.fastest import run_fastest

    by_id = {svc.id: svc for svc in services}
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
        directed = direction_route(op.geometry, op.line.length_m, outcome.direction)
        train = svc.train
        if np.isfinite(svc.traction_power_cap_w):
            train = dataclasses.replace(
                train, traction=train.traction.capped(power_cap_w=svc.traction_power_cap_w)
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


def _arrival_s(outcome: Any) -> float:
    """When an operated train arrived at its destination [s] (NaN: it did not)."""
    last = outcome.stops[-1] if outcome.stops else None
    if last is None or last.arrival_s is None or not np.isfinite(last.arrival_s):
        return float("nan")
    return float(last.arrival_s)


def _run_operated(path: Path, spec: PowerFile, network: Network) -> Any:
    """The power study of the operation file's trains, with voltage-limited traction fed back into
    the operation when ``simulation.feedback.enabled``.

    Feedback: each operated train whose traction the line limits (it gets less than 1 - tolerance of
    the traction energy it asks) gets one cap on its traction power at the wheel for its whole run:
    the least electrical power the line delivered to it at a limited step, times its traction
    efficiency, lowered again at each iteration where it is still limited (the timetable study's
    ``constant`` method). The operation is simulated again with those caps (only its operated runs:
    the plan stays the uncapped one, so the slowed train shows as late), so that a slower train
    holds the trains behind it through the signalling (knock-on between services), and the network
    is solved again, until no train is limited or ``max_iterations`` is reached. A train's
    ``time_lost_s`` is its arrival at its destination minus its arrival in the operation without
    feedback: its own slower running and the waits behind slowed trains.
    """
    from trainsim.io.operation_file import read_operation
    from trainsim.io.operation_run import run_operation
    from trainsim.operations.runs import RunCache

    sim = spec.simulation
    link = spec.operation
    where = path.parent / link.file
    tracks = dict(link.tracks)
    origin_m = link.origin_km * 1000
    op = read_operation(where)
    fb = sim.feedback
    caps = {svc.id: np.inf for svc in op.services}
    cache: RunCache | None = None
    iterations = 0
    nominal: dict[str, float] = {}
    while True:
        iterations += 1
        if iterations == 1:
            # without caps exactly as without feedback (no shared cache), so that disabling it changes nothing
            services = list(op.services)
            operated = run_operation(op)
            nominal = {o.id: _arrival_s(o) for o in operated.trains}
        else:
            cache = cache or RunCache(op.settings)
            services = [
                dataclasses.replace(svc, traction_power_cap_w=caps[svc.id])
                if np.isfinite(caps[svc.id])
                else svc
                for svc in op.services
            ]
            operated = run_operation(op, services, cache)
        loads, info = _operated_loads(op, services, operated, str(where), tracks, origin_m)
        if not loads:
            raise InputError("no operated train reached the network", file=str(path), field="operation.file",
                             value=link.file)  # fmt: skip
        try:
            result = simulate(network, loads, dt_s=sim.step_s, start_s=sim.start_s, end_s=sim.end_s)
        except InputError as exc:
            raise exc.located(str(path)) from None
        if not fb.enabled:
            break
        asked = np.nansum(result.traction_demand_w, axis=0)
        got = np.nansum(result.traction_delivered_w, axis=0)
        ratio = np.where(asked > 0, got / np.where(asked > 0, asked, 1.0), 1.0)
        mismatch = 1.0 - ratio
        limited = ratio < 1.0 - fb.tolerance
        consistent = not limited.any()
        if consistent or iterations >= fb.max_iterations:
            break
        short = result.traction_delivered_w < result.traction_demand_w * (1.0 - fb.tolerance)
        efficiency = {svc.id: svc.train.electrical.traction_efficiency for svc in op.services}
        for i in np.flatnonzero(limited):
            tid = result.train_ids[i]
            delivered = result.traction_delivered_w[short[:, i], i]
            if delivered.size:
                # lowered only: a cap raised again could make the iteration cycle
                caps[tid] = min(caps[tid], float(np.min(delivered)) * efficiency[tid])
    if not fb.enabled:
        feedback = {"enabled": False, "iterations": 1, "consistent": True,
                    "method": "none",
                    "note": "operated trains are solved once: their delays come from the operation"}  # fmt: skip
        return with_status(dataclasses.replace(result, extra={"operation": info, "feedback": feedback}))
    arrivals = {o.id: _arrival_s(o) for o in operated.trains}
    trains = []
    for tid in result.train_ids:
        lost = arrivals.get(tid, np.nan) - nominal.get(tid, np.nan)
        trains.append({
            "id": tid,
            "arrival_s": _finite(arrivals.get(tid, np.nan)),
            "nominal_arrival_s": _finite(nominal.get(tid, np.nan)),
            # a train that no longer arrives under its cap lost all: no finite figure, said by its status
            "time_lost_s": float(lost) if np.isfinite(lost) else None,
            "traction_power_cap_kw": float(caps[tid]) / 1e3 if np.isfinite(caps[tid]) else None,
            "traction_power_caps_kw": None,
        })  # fmt: skip
    feedback = {
        "enabled": True,
        "iterations": iterations,
        "consistent": bool(consistent),
        "mismatch": float(np.max(mismatch, initial=0.0)),
        # between services the operation's signalling and dispatching pass the delays on (not the
        # timetable study's knock_on between departures of one service, which does not apply)
        "knock_on": True,
        "buffer_s": None,
        # a method name like the timetable study's (constant, per_stretch, per_step); what it means in note
        "method": "per_train",
        "note": "constant cap on the traction power at the wheel per operated train for its whole run: least "
        "power delivered at a limited step; the operation re-simulated with the caps (per-stretch and "
        "per-step feedback are not done for operated trains)",
    }
    return with_status(
        dataclasses.replace(result, extra={"operation": info, "feedback": feedback, "trains": trains})
    )


def _finite(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


def run_power_file(
    path: str | Path, out_dir: str | Path | None = None, *, plots: bool = True
) -> tuple[dict[str, Any], str]:
    """Run a power-supply file: (summary, status). With ``out_dir``: ``summary.json``, the time
    series as CSV (``trains.csv``, ``substations.csv``, ``network.csv``) and, with ``plots``, PNG
    plots (see :mod:`trainsim.power.plots`). With ``operation:`` the operated trains, with
    voltage-limited traction fed back into the operation unless ``simulation.feedback.enabled`` is
    false (then solved once, as before: their delays come from the operation alone)."""
    spec, network, services = load_power_file(path)
    sim = spec.simulation
    if spec.operation is not None:
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
        fb = FeedbackSettings(
        sim.feedback.enabled, sim.feedback.max_iterations, sim.feedback.tolerance, sim.feedback.method,
        sim.feedback.knock_on, sim.feedback.buffer_s,
    )  # fmt: skip
        result = run_study(
            network, services, dt_s=sim.step_s, start_s=sim.start_s, end_s=sim.end_s, feedback=fb
        )
    summary = result.summary()
    summary["name"] = spec.name
    if out_dir is not None:
        from trainsim.power.output import write_outputs

        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        (out / "summary.json").write_text(json.dumps(summary, indent=2, allow_nan=False))
        write_outputs(result, out, plots=plots)
    return summary, summary["status"]
