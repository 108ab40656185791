"""Reader of the operation file (``schema: trainsim/operation``, version 1): a line, its signalling and
a timetable of trains. Trains and the line's geometry are read with trainsim's own loaders
(``trainsim.load_train``, ``trainsim.load_route``); see docs/OPERATIONS.md for the fields.

Strict: unknown fields, wrong types and values out of range are ``InputError`` naming the file, the
field, the value and what is allowed, all problems of a file at once.
"""

from __future__ import annotations

import copy
import re
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, ValidationError, field_validator

from trainsim.constants import KMH
from trainsim.errors import InputError, Problem
from trainsim.model import Route as GeometryRoute
from trainsim.model import Train
from trainsim.model.scenario import RunSettings
from trainsim.operations.disturbances import Disturbances, disturbances_from_dict
from trainsim.operations.etcs import EtcsNationalValues, StepFunction
from trainsim.operations.line import (
    Line,
    Signalling,
    StationLayout,
    SwitchLayout,
    TrackLayout,
    build_line,
)
from trainsim.operations.separation import EtcsBraking
from trainsim.operations.simulate import ScheduledStop, TrainService

SCHEMA = "trainsim/operation"
VERSIONS = (1,)
#: Highest release speed an operation file may give [m/s] (the core's bound for V_NVREL).
ETCS_MAX_RELEASE_SPEED_MPS = 100.0
#: Most trains one file may expand to (repeat included): bounds memory and run time.
MAX_TRAINS = 20_000
_CLOCK = re.compile(r"^(\d{1,2}):([0-5]\d)(?::([0-5]\d(?:\.\d+)?))?$")


class _Spec(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class _Station(_Spec):
    name: str
    position_m: float | None = None
    tracks: int = 1
    entry_signal_distance_m: float = 400.0
    exit_signal_offset_m: float = 20.0
    switch_zone_m: float = 100.0


class _EtcsStep(_Spec):
    """A step function of speed (SUBSET-026-3 3.13.2.2.3.1.3): ``values[0]`` up to the first limit,
    the last value open ended; limits in km/h (as data sheets give them) or m/s, or in m for Kr_int."""

    values: list[float]
    upper_limits_kmh: list[float] | None = None
    upper_limits_mps: list[float] | None = None
    upper_limits_m: list[float] | None = None


_EtcsValue = float | _EtcsStep


class _EtcsTrain(_Spec):
    """ETCS braking data of one train type (SUBSET-026-3 3.13.2.2); see docs/ETCS.md for each field."""

    a_brake_emergency_mps2: _EtcsValue | None = None
    a_brake_service_mps2: _EtcsValue | None = None
    a_brake_normal_service_mps2: _EtcsValue | None = None
    a_brake_normal_service_sets_mps2: list[_EtcsValue] | None = None
    a_sb01_mps2: float | None = None
    a_sb12_mps2: float | None = None
    t_brake_emergency_s: float | None = None
    t_brake_service_s: float | None = None
    t_brake_emergency_cmt_s: float | None = None
    t_brake_service_cmt_s: float | None = None
    t_traction_cut_off_s: float | None = None
    brake_percentage: float | None = None
    brake_position: Literal["passenger_p", "freight_p", "freight_g"] | None = None
    kdry_rst: _EtcsValue | None = None
    kdry_rst_by_ebcl: dict[int, _EtcsValue] | None = None
    kwet_rst: _EtcsValue | None = None
    kn_plus_mps2: _EtcsValue | None = None
    kn_minus_mps2: _EtcsValue | None = None
    m_rotating_nom_percent: float | None = None
    traction_cut_off_implemented: bool | None = None
    service_brake_command: bool | None = None
    service_brake_feedback: bool | None = None
    speed_under_reading_mps: float | None = None
    speed_under_reading_ratio: float | None = None
    adhesion_independent_brake: bool | None = None


class _EtcsNational(_Spec):
    """National values (SUBSET-026-3 3.18, A.3.2 defaults when not given)."""

    m_nvebcl: int | None = None
    m_nvavadh: float | None = None
    q_nvinhsmicperm: bool | None = None
    q_nvguiperm: bool | None = None
    q_nvsbtsmperm: bool | None = None
    q_nvsbfbperm: bool | None = None
    v_nvrel_mps: float | None = None
    kv_int_freight: _EtcsValue | None = None
    kv_int_passenger_a: _EtcsValue | None = None
    kv_int_passenger_b: _EtcsValue | None = None
    a_nvp12_mps2: float | None = None
    a_nvp23_mps2: float | None = None
    kr_int: _EtcsValue | None = None
    kt_int: float | None = None
    #: null: the national value asks for driver information instead of a limit (3.13.2.3.7.7)
    a_nvmaxredadh1_mps2: float | None = None
    a_nvmaxredadh2_mps2: float | None = None
    a_nvmaxredadh3_mps2: float | None = None


class _EtcsFixed(_Spec):
    """Fixed values (SUBSET-026-3 A.3.1 defaults when not given)."""

    dv_ebi_min_mps: float | None = None
    dv_ebi_max_mps: float | None = None
    v_ebi_min_mps: float | None = None
    v_ebi_max_mps: float | None = None
    dv_sbi_min_mps: float | None = None
    dv_sbi_max_mps: float | None = None
    v_sbi_min_mps: float | None = None
    v_sbi_max_mps: float | None = None
    dv_warning_min_mps: float | None = None
    dv_warning_max_mps: float | None = None
    v_warning_min_mps: float | None = None
    v_warning_max_mps: float | None = None
    t_warning_s: float | None = None
    t_driver_s: float | None = None
    m_rotating_max_percent: float | None = None
    m_rotating_min_percent: float | None = None
    gravity_mps2: float | None = None
    a_est2_max_mps2: float | None = None
    t_indication_min_s: float | None = None
    t_indication_bs_factor: float | None = None


class _Etcs(_EtcsTrain):
    """``line.signalling.etcs``: the line's train data (for every train without its own entry), the
    national and fixed values, the release speed and other trains' braking data."""

    national: _EtcsNational = _EtcsNational()
    fixed: _EtcsFixed = _EtcsFixed()
    release_speed: Literal["calculated", "national"] | None = None
    release_speed_mps: float | None = None
    #: braking data by train id (``trains[i].id``) or train file (``trains[i].train``, as written)
    trains: dict[str, _EtcsTrain] = {}


class _Signalling(_Spec):
    system: Literal["fixed_block", "etcs_l2", "moving_block"]
    aspects: Literal[2, 3, 4] = 3
    distant_distance_m: float = 1000.0
    sighting_distance_m: float = 200.0
    overlap_m: float = 50.0
    setup_s: float = 6.0
    reaction_s: float = 6.0
    release_s: float = 3.0
    release: Literal["sectional", "whole_route"] = "sectional"
    safety_margin_m: float = 50.0
    moving_block_step_m: float = 50.0
    standing_distance_m: float = 10.0
    etcs: _Etcs | None = None


class _LineResistance(_Spec):
    curve_formula: str
    tunnel_formula: str


class _Railml(_Spec):
    """The line read from a railML 2 or 3 file: its route and its signalling (issue 17)."""

    file: str
    train_id: str | None = None
    ocps: list[str] | None = None
    line_resistance: _LineResistance | None = None
    #: read the down track too (the route's stations in reverse order through the other track)
    double_track: bool = False
    #: use the file's switches and train detection points (and, with double_track, the down track's own
    #: station signals) in the line model
    tracks: bool = False
    #: with tracks: from a switch's blade tip to its clearance point, towards its station [m], for the
    #: switches with no detection point between them and the station's stopping point (railML gives
    #: no clearance points)
    clearance_distance_m: float | None = None


class _Spreadsheet(_Spec):
    """The line read from a workbook or CSV folder: its track tables and its signalling tables."""

    file: str
    #: use the tables' switches and detection points (and the down signals as the down track's own
    #: station signals on a double track) in the line model
    tracks: bool = False
    clearance_distance_m: float | None = None


class _Switch(_Spec):
    name: str
    position_m: float
    clearance_m: float | None = None
    #: highest speed over the diverging branch [km/h]; none: line speed
    diverging_speed_kmh: float | None = None
    #: the platform tracks reached over the diverging branch; none: all but track 1
    diverging_tracks: list[int] | None = None

    @field_validator("diverging_speed_kmh")
    @classmethod
    def _diverging_speed(cls, v: float | None) -> float | None:
        if v is not None and not (np.isfinite(v) and 0 < v <= 540):
            raise ValueError("the diverging speed must be 0 < v <= 540 km/h, or none for line speed")
        return v


class _Track(_Spec):
    """What is given of one track (``up``/``down`` on double track, ``both`` on single track)."""

    detection_points_m: list[float] = []
    switches: list[_Switch] = []
    station_signals_m: dict[str, tuple[float, float]] = {}
    block_signals_m: list[float] | None = None


class _Line(_Spec):
    route: str | None = None
    railml: _Railml | None = None
    spreadsheet: _Spreadsheet | None = None
    layout: Literal["double_track", "single_track"]
    stations: list[_Station] = []
    signalling: _Signalling
    block_length_m: float = 2000.0
    block_signals_m: dict[Literal["up", "down"], list[float]] | None = None
    tracks: dict[Literal["up", "down", "both"], _Track] | None = None


class _Stop(_Spec):
    station: str
    dwell_s: float = 0.0
    arrival: str | None = None
    arrival_s: float | None = None
    departure: str | None = None
    departure_s: float | None = None
    track: int | None = None


class _Repeat(_Spec):
    count: int
    every_s: float

    @field_validator("count")
    @classmethod
    def _count(cls, v: int) -> int:
        if not 1 <= v <= MAX_TRAINS:
            raise ValueError(f"count must be 1 .. {MAX_TRAINS}")
        return v

    @field_validator("every_s")
    @classmethod
    def _every(cls, v: float) -> float:
        if not (np.isfinite(v) and v > 0):
            raise ValueError("every_s must be > 0")
        return v


class _Train(_Spec):
    id: str
    train: str
    direction: Literal["up", "down"]
    origin: str
    destination: str
    departure: str | None = None
    departure_s: float | None = None
    stops: list[_Stop] = []
    priority: int = 0
    entry_delay_s: float = 0.0
    origin_track: int | None = None
    strategy: Literal["fastest", "optimal", "signal_aware"] = "fastest"
    repeat: _Repeat | None = None


class _Delays(_Spec):
    seed: int
    probability: float
    mean_s: float


class _Dispatching(_Spec):
    rule: Literal["fcfs", "priority"] = "fcfs"
    lookahead_s: float = 0.0


class _Settings(_Spec):
    max_step_m: float = 20.0
    braking_fraction: float = 1.0


class _Connection(_Spec):
    train: str
    line: str
    feeder: str
    station: str | None = None
    min_s: float = 0.0


class _Operation(_Spec):
    schema_: str
    version: int
    name: str
    description: str | None = None
    line: _Line
    trains: list[_Train]
    dispatching: _Dispatching = _Dispatching()
    settings: _Settings = _Settings()
    delays: _Delays | None = None
    disturbances: dict[str, Any] | None = None
    compare_systems: list[Literal["fixed_block", "etcs_l2", "moving_block"]] = []
    pattern_period_s: float | None = None
    connections: list[_Connection] = []


@dataclass(frozen=True)
class DelayModel:
    """Sampled entry delays: each train is late at its origin with ``probability`` [-], by an
    exponentially distributed time of mean ``mean_s`` [s], from a generator seeded with ``seed``."""

    probability: float
    mean_s: float
    seed: int

    def sample(self, services: list[TrainService], rng: np.random.Generator) -> list[TrainService]:
        """The services with a sampled delay added to their given entry delay (two draws per train,
        in order, so a seed gives the same delays whatever the outcome)."""
        out = []
        for svc in services:
            late, size = rng.random(), rng.exponential(self.mean_s)
            extra = float(size) if late < self.probability else 0.0
            out.append(replace(svc, entry_delay_s=svc.entry_delay_s + extra))
        return out


@dataclass(frozen=True)
class Connection:
    """A train of this line that leaves its origin only when a train of another line (an operation
    file of the same network-day, by its ``name``) has arrived somewhere, plus a least time: a
    passenger connection or a turnaround of the same unit (``trainsim.batch.network_day``).

    Attributes:
        train: the id of the waiting train (this file's).
        line: the name of the other file's line.
        feeder: the id of the train there it waits for.
        station: where the feeder arrives (None: its destination).
        min_s: the least time from the feeder's arrival to the waiting train's departure [s].
    """

    train: str
    line: str
    feeder: str
    station: str | None
    min_s: float


#: The longest least time of a connection [s] (a day).
MAX_CONNECTION_S = 86_400.0


@dataclass
class Operation:
    """An operation file, read: the line, its geometry, the trains and the run options."""

    name: str
    file: str
    line: Line
    geometry: GeometryRoute
    services: list[TrainService]
    settings: RunSettings
    rule: str
    etcs: EtcsBraking | None
    compare_systems: list[str] = field(default_factory=list)
    pattern_period_s: float | None = None
    lookahead_s: float = 0.0
    line_args: dict[str, Any] = field(default_factory=dict)
    delays: DelayModel | None = None
    #: the services before delays were sampled (for Monte Carlo samples)
    given_services: list[TrainService] = field(default_factory=list)
    #: sampled entry, dwell and running-time disturbances (instead of ``delays``)
    disturbances: Disturbances | None = None
    #: trains that wait for trains of other lines (used by a network-day)
    connections: tuple[Connection, ...] = ()

    def with_system(self, system: str) -> Line:
        """The same line with another train separation."""
        sig = replace(self.line.signalling, system=system)
        if system == "moving_block":
            sig = replace(sig, overlap_m=0.0)
        return build_line(**{**self.line_args, "signalling": sig})


def parse_clock(text: str, field_name: str, file: str) -> float:
    """``"HH:MM"`` or ``"HH:MM:SS"`` -> seconds after midnight [s]."""
    m = _CLOCK.match(text.strip())
    if not m or int(m.group(1)) > 47:
        raise InputError(
            "invalid time of day",
            file=file,
            field=field_name,
            value=text,
            allowed="HH:MM or HH:MM:SS (00:00 .. 47:59)",
        )
    return int(m.group(1)) * 3600 + int(m.group(2)) * 60 + float(m.group(3) or 0)


def _time(
    clock: str | None,
    seconds: float | None,
    field_name: str,
    file: str,
    required: bool,
    problems: list[Problem],
) -> float | None:
    if clock is not None and seconds is not None:
        problems.append(Problem("give the time once", file=file, field=field_name, value=(clock, seconds)))
        return None
    if clock is not None:
        try:
            return parse_clock(clock, field_name, file)
        except InputError as e:
            problems.extend(e.problems)
            return None
    if seconds is not None:
        if not np.isfinite(seconds):
            problems.append(Problem("must be finite", file=file, field=f"{field_name}_s", value=seconds))
            return None
        return float(seconds)
    if required:
        problems.append(
            Problem(
                "a departure time is required",
                file=file,
                field=field_name,
                allowed="departure: HH:MM:SS or departure_s",
            )
        )
    return None


def _line_of(text: str, loc: list) -> int | None:
    """The YAML line (1-based) of the node at ``loc`` (keys and indices), or of its nearest parent."""
    try:
        node = yaml.compose(text)
    except yaml.YAMLError:
        return None
    line = None
    for key in loc:
        if node is None:
            break
        line = node.start_mark.line + 1
        if isinstance(node, yaml.MappingNode):
            node = next((v for k, v in node.value if getattr(k, "value", None) == key), None)
        elif isinstance(node, yaml.SequenceNode) and isinstance(key, int) and key < len(node.value):
            node = node.value[key]
        else:
            node = None
    return node.start_mark.line + 1 if node is not None else line


def _validation_problems(err: ValidationError, file: str, text: str = "") -> list[Problem]:
    out = []
    for e in err.errors():
        loc = [("schema" if x == "schema_" else x) for x in e["loc"]]
        path = ""
        for x in loc:
            path += f"[{x}]" if isinstance(x, int) else (f".{x}" if path else str(x))
        allowed = None
        ctx = e.get("ctx") or {}
        if "expected" in ctx:
            allowed = str(ctx["expected"])
        reason = "unknown field" if e["type"] == "extra_forbidden" else e["msg"]
        if e["type"] in ("dict_type", "model_type"):
            reason = "a mapping is expected here"
        value = e.get("input") if e["type"] != "missing" else None
        line = _line_of(text, ["schema" if x == "schema_" else x for x in e["loc"]]) if text else None
        out.append(Problem(reason, file=file, line=line, field=path, value=value, allowed=allowed))
    return out


def read_operation(path: str | Path) -> Operation:
    """Read and check an operation file; trains and the line's route are loaded relative to it."""
    from trainsim.io.loader import load_route, load_train
    from trainsim.io.trainsim_yaml import read_yaml

    path = Path(path)
    file = str(path)
    data = read_yaml(path)
    if not isinstance(data, dict):
        raise InputError("an operation file is a mapping", file=file, value=type(data).__name__)
    if data.get("schema") != SCHEMA:
        raise InputError(
            "not an operation file", file=file, field="schema", value=data.get("schema"), allowed=SCHEMA
        )
    if data.get("version") not in VERSIONS:
        raise InputError(
            "unsupported version", file=file, field="version", value=data.get("version"), allowed="1"
        )
    data = {("schema_" if k == "schema" else k): v for k, v in data.items()}
    try:
        spec = _Operation.model_validate(data)
    except ValidationError as err:
        raise InputError.from_problems(_validation_problems(err, file, path.read_text())) from None
    base = path.parent
    problems: list[Problem] = []

    def load(kind: str, name: str, where: str):
        target = (base / name).resolve()
        if not target.is_file():
            problems.append(
                Problem(
                    "file not found",
                    file=file,
                    field=where,
                    value=name,
                    allowed="a path relative to the operation file",
                )
            )
            return None
        try:
            return load_train(target) if kind == "train" else load_route(target)
        except InputError as e:
            problems.extend(p if p.file else replace(p, file=str(target)) for p in e.problems)
            return None

    signalling_read = None
    given = [k for k in ("route", "railml", "spreadsheet") if getattr(spec.line, k) is not None]
    if len(given) != 1:
        raise InputError(
            "the line needs its route: give one of 'route' (a route file), 'railml' (a railML file "
            "with signals) or 'spreadsheet' (a workbook or CSV folder with signal tables)",
            file=file,
            field="line",
            value=given,
            allowed="line.route, line.railml or line.spreadsheet",
        )
    if spec.line.railml is not None:
        geometry, signalling_read = _railml_line(spec.line.railml, base, file, problems)
    elif spec.line.spreadsheet is not None:
        geometry, signalling_read = _spreadsheet_line(spec.line.spreadsheet, base, file, problems)
    else:
        assert spec.line.route is not None
        geometry = load("route", spec.line.route, "line.route")
    trains: dict[str, Train] = {}
    for i, t in enumerate(spec.trains):
        if t.train not in trains:
            loaded = load("train", t.train, f"trains[{i}].train")
            if loaded is not None:
                trains[t.train] = loaded
    if problems:
        raise InputError.from_problems(problems)
    assert geometry is not None
    if abs(geometry.start_m) > 1e-6:
        raise InputError(
            "the line's route must start at 0 (line positions run from 0 to its length)",
            file=file,
            field="line.route",
            value=geometry.start_m,
        )
    route_stations = {s.name: s.position_m for s in geometry.stations}
    line_stations = spec.line.stations
    block_signals_m = spec.line.block_signals_m
    if signalling_read is not None:
        line_stations = _stations_with_signals(signalling_read, line_stations)
        read_blocks = signalling_read.block_signals_m()
        if block_signals_m is None and spec.line.layout == "double_track" and any(read_blocks.values()):
            block_signals_m = {d: v for d, v in read_blocks.items() if v}
    tracks, track_blocks = _tracks(spec, signalling_read, file, problems)
    if track_blocks:
        if block_signals_m is not None and spec.line.block_signals_m is not None:
            problems.append(
                Problem(
                    "block signals given twice: in line.block_signals_m and in line.tracks",
                    file=file,
                    field="line.tracks",
                    allowed="one of them",
                )
            )
        block_signals_m = {**(block_signals_m or {}), **track_blocks}
    if not line_stations:
        problems.append(
            Problem(
                "a line needs its stations", file=file, field="line.stations", allowed="a list of stations"
            )
        )
    stations = []
    for i, s in enumerate(line_stations):
        pos = s.position_m if s.position_m is not None else route_stations.get(s.name)
        if pos is None:
            problems.append(
                Problem(
                    "station position unknown: give position_m or a station of that name in the line's route",
                    file=file,
                    field=f"line.stations[{i}].position_m",
                    value=s.name,
                )
            )
            continue
        stations.append(
            StationLayout(
                s.name,
                float(pos),
                s.tracks,
                s.entry_signal_distance_m,
                s.exit_signal_offset_m,
                s.switch_zone_m,
            )
        )
    sg = spec.line.signalling
    etcs, etcs_trains = _etcs_braking(spec, trains, file, problems)
    wants_etcs = sg.system == "etcs_l2" or "etcs_l2" in spec.compare_systems
    if wants_etcs and sg.etcs is None:
        problems.append(
            Problem(
                "ETCS Level 2 needs the trains' ETCS braking data",
                file=file,
                field="line.signalling.etcs",
                allowed="a mapping with a_brake_emergency_mps2, a_brake_service_mps2, t_brake_emergency_s, "
                "t_brake_service_s, t_traction_cut_off_s",
            )
        )
    if problems:
        raise InputError.from_problems(problems)
    fields = sg.model_dump(exclude={"etcs"})
    if sg.system == "moving_block" and "overlap_m" not in sg.model_fields_set:
        fields["overlap_m"] = 0.0
    try:
        signalling = Signalling(**fields)
        line_args = {
            "name": spec.name,
            "length_m": geometry.end_m,
            "layout": spec.line.layout,
            "stations": tuple(stations),
            "signalling": signalling,
            "block_length_m": spec.line.block_length_m,
            "block_signals_m": block_signals_m,
            "tracks": tracks,
        }
        line = build_line(**line_args)
        settings = RunSettings(
            max_step_m=spec.settings.max_step_m, braking_fraction=spec.settings.braking_fraction
        )
    except InputError as e:
        raise e.located(file) from None
    services = _etcs_services(spec, _services(spec, trains, file, problems), etcs_trains)
    for i, t in enumerate(spec.trains):
        # a train must fit on the platform tracks / passing loops it may stand on
        if t.train in trains:
            problems += [
                replace(p, file=file)
                for p in line.loop_problems(
                    t.direction, t.origin, t.destination, trains[t.train].length_m, f"trains[{i}]"
                )
            ]
    if problems:
        raise InputError.from_problems(problems)
    delays = (
        None
        if spec.delays is None
        else DelayModel(spec.delays.probability, spec.delays.mean_s, spec.delays.seed)
    )
    disturbances = None
    if spec.disturbances is not None:
        if delays is not None:
            raise InputError(
                "give either 'delays' or 'disturbances' (its 'entry' distribution replaces 'delays')",
                file=file,
                field="disturbances",
            )
        disturbances = disturbances_from_dict(spec.disturbances, file)
    connections = _connections(spec, services, file)
    given = list(services)
    sampler = disturbances if disturbances is not None else delays
    if sampler is not None:
        services = sampler.sample(services, np.random.default_rng(sampler.seed))
    return Operation(
        spec.name, file, line, geometry, services, settings, spec.dispatching.rule, etcs,
        list(spec.compare_systems), spec.pattern_period_s, spec.dispatching.lookahead_s, line_args, delays,
        given, disturbances, connections,
    )  # fmt: skip


#: Fields of an ``etcs`` train block and the ``EtcsTrainData`` field each fills (those not named here
#: are EtcsBraking's own: the decelerations, the build-up times, T_traction_cut_off, brake_percentage).
_ETCS_TRAIN_DATA = {
    "a_brake_normal_service_mps2": "a_brake_normal_service",
    "a_brake_normal_service_sets_mps2": "a_brake_normal_service_sets",
    "a_sb01_mps2": "a_sb01_mps2",
    "a_sb12_mps2": "a_sb12_mps2",
    "t_brake_emergency_cmt_s": "t_brake_emergency_cmt_s",
    "t_brake_service_cmt_s": "t_brake_service_cmt_s",
    "brake_position": "brake_position",
    "kdry_rst": "kdry_rst",
    "kdry_rst_by_ebcl": "kdry_rst",
    "kwet_rst": "kwet_rst",
    "kn_plus_mps2": "kn_plus",
    "kn_minus_mps2": "kn_minus",
    "m_rotating_nom_percent": "m_rotating_nom_percent",
    "traction_cut_off_implemented": "traction_cut_off_implemented",
    "service_brake_command": "service_brake_command",
    "service_brake_feedback": "service_brake_feedback",
    "speed_under_reading_mps": "speed_under_reading_mps",
    "speed_under_reading_ratio": "speed_under_reading_ratio",
    "adhesion_independent_brake": "adhesion_independent_brake",
}
#: The core's field names back to the file's (for the messages).
_ETCS_FILE_FIELD = {
    "a_brake_emergency": "a_brake_emergency_mps2",
    "a_brake_service": "a_brake_service_mps2",
    **{v: k for k, v in _ETCS_TRAIN_DATA.items() if k != "kdry_rst_by_ebcl"},
}


def _etcs_step(
    value: float | _EtcsStep, where: str, file: str, problems: list[Problem], length: bool = False
) -> float | StepFunction | None:
    """A number, or a step function of speed (limits in km/h or m/s) or, ``length``, of the train
    length (limits in m); None after adding the problem."""
    if not isinstance(value, _EtcsStep):
        return float(value)
    given = {k: getattr(value, k) for k in ("upper_limits_kmh", "upper_limits_mps", "upper_limits_m")}
    given = {k: v for k, v in given.items() if v is not None}
    allowed_key = ("upper_limits_m",) if length else ("upper_limits_kmh", "upper_limits_mps")
    wrong = [k for k in given if k not in allowed_key]
    if wrong or len(given) > 1 or (not given and len(value.values) != 1):
        problems.append(
            Problem(
                "a step function needs its step limits once, in one unit",
                file=file,
                field=f"{where}.{wrong[0] if wrong else next(iter(given), allowed_key[0])}",
                value=sorted(given),
                allowed=f"{' or '.join(allowed_key)} ({len(value.values) - 1} limits for "
                f"{len(value.values)} values; none for one value)",
            )
        )
        return None
    key, limits = next(iter(given.items()), (allowed_key[0], []))
    scale = KMH if key == "upper_limits_kmh" else 1.0
    try:
        return StepFunction(tuple(value.values), tuple(x * scale for x in limits))
    except InputError as e:
        for pr in e.problems:
            name = key if pr.field == "upper_limits" else (pr.field or "values")
            problems.append(replace(pr, file=file, field=f"{where}.{name}"))
        return None


def _etcs_block(t: _EtcsTrain, where: str, file: str, problems: list[Problem]) -> EtcsBraking | None:
    """The braking data of one ``etcs`` block (without national values and release speed)."""
    before = len(problems)
    own: dict[str, Any] = {}
    for name in ("a_brake_emergency_mps2", "a_brake_service_mps2"):
        v = getattr(t, name)
        own[name] = None if v is None else _etcs_step(v, f"{where}.{name}", file, problems)
    extra: list[tuple[str, Any]] = []
    if t.kdry_rst is not None and t.kdry_rst_by_ebcl is not None:
        problems.append(
            Problem("give Kdry_rst once", file=file, field=f"{where}.kdry_rst_by_ebcl",
                    allowed="kdry_rst (any confidence level) or kdry_rst_by_ebcl (by M_NVEBCL index)")
        )  # fmt: skip
    for name, target in _ETCS_TRAIN_DATA.items():
        v = getattr(t, name)
        if v is None:
            continue
        if isinstance(v, _EtcsStep):
            v = _etcs_step(v, f"{where}.{name}", file, problems)
        elif name == "a_brake_normal_service_sets_mps2":
            v = tuple(_etcs_step(x, f"{where}.{name}[{k}]", file, problems) for k, x in enumerate(v))
        elif name == "kdry_rst_by_ebcl":
            v = {k: _etcs_step(x, f"{where}.{name}.{k}", file, problems) for k, x in v.items()}
        extra.append((target, v))
    if len(problems) > before:
        return None
    return EtcsBraking(
        own["a_brake_emergency_mps2"], own["a_brake_service_mps2"], t.t_brake_emergency_s, t.t_brake_service_s,
        t.t_traction_cut_off_s, train_fields=tuple(extra), brake_percentage=t.brake_percentage,
    )  # fmt: skip


def _etcs_national(e: _Etcs, file: str, problems: list[Problem]) -> EtcsNationalValues | None:
    """The national and fixed values given (the others at their SUBSET-026 defaults)."""
    before = len(problems)
    given: dict[str, Any] = {}
    where: dict[str, str] = {}
    for part, spec in (("national", e.national), ("fixed", e.fixed)):
        for name in spec.model_fields_set:
            v = getattr(spec, name)
            path = f"line.signalling.etcs.{part}.{name}"
            where[name] = path
            if v is None and not name.startswith("a_nvmaxredadh"):
                problems.append(Problem("a value is needed", file=file, field=path, value=None))
                continue
            if isinstance(v, _EtcsStep):
                v = _etcs_step(v, path, file, problems, length=name == "kr_int")
            given[name] = v
    if len(problems) > before:
        return None
    try:
        return EtcsNationalValues(**given)
    except InputError as err:
        problems += [
            replace(pr, file=file, field=where.get(pr.field or "", f"line.signalling.etcs.{pr.field}"))
            for pr in err.problems
        ]
        return None


def _etcs_release(e: _Etcs, file: str, problems: list[Problem]) -> float | str:
    if e.release_speed is not None and e.release_speed_mps is not None:
        problems.append(
            Problem("give the release speed once", file=file, field="line.signalling.etcs.release_speed_mps",
                    value=(e.release_speed, e.release_speed_mps),
                    allowed="release_speed (calculated, national) or release_speed_mps")
        )  # fmt: skip
    if e.release_speed_mps is not None:
        v = e.release_speed_mps
        if not (np.isfinite(v) and 0.0 <= v <= ETCS_MAX_RELEASE_SPEED_MPS):
            problems.append(
                Problem("release speed out of range", file=file, field="line.signalling.etcs.release_speed_mps",
                        value=v, allowed=f"0 to {ETCS_MAX_RELEASE_SPEED_MPS:g} m/s")
            )  # fmt: skip
        return float(v)
    return e.release_speed or "calculated"


def _etcs_braking(
    spec: _Operation, trains: dict[str, Train], file: str, problems: list[Problem]
) -> tuple[EtcsBraking | None, dict[str, Train]]:
    """``line.signalling.etcs`` read and checked for every train that uses it, and the trains of the
    train ids that have their own braking data (a copy of their train each, so that the braking data
    can be found by the train: ``EtcsBraking.per_train``)."""
    e = spec.line.signalling.etcs
    if e is None:
        return None, {}
    before = len(problems)
    national = _etcs_national(e, file, problems)
    release = _etcs_release(e, file, problems)
    base = "line.signalling.etcs"
    line_block = _etcs_block(e, base, file, problems)
    ids = {t.id: t.train for t in spec.trains}
    files = {t.train for t in spec.trains}
    blocks: dict[str, tuple[str, EtcsBraking | None, _EtcsTrain]] = {}
    for key, t in e.trains.items():
        where = f"{base}.trains.{key}"
        if key not in ids and key not in files:
            problems.append(
                Problem("no train of this id or train file", file=file, field=where, value=key,
                        allowed="a trains[i].id or a trains[i].train of this file")
            )  # fmt: skip
            continue
        blocks[key] = (where, _etcs_block(t, where, file, problems), t)
    if len(problems) > before or national is None or line_block is None:
        return None, {}
    copies = {key: copy.copy(trains[ids[key]]) for key in blocks if key in ids and ids[key] in trains}
    per_train = [(copies[k], b) for k, (_w, b, _t) in blocks.items() if k in copies]
    per_train += [(trains[k], b) for k, (_w, b, _t) in blocks.items() if k not in ids and k in trains]
    etcs = EtcsBraking(
        line_block.a_brake_emergency_mps2, line_block.a_brake_service_mps2, line_block.t_brake_emergency_s,
        line_block.t_brake_service_s, line_block.t_traction_cut_off_s, national, line_block.train_fields,
        line_block.brake_percentage, release, tuple(per_train),
    )  # fmt: skip
    # every train's ETCS data, built once here so that a bad value is named before any run
    users = [(f"trains[{i}]", t.id, t.train) for i, t in enumerate(spec.trains)]
    for where_train, tid, tfile in users:
        train = copies.get(tid) or trains.get(tfile)
        if train is None:
            continue
        where, _b, given = blocks.get(tid, blocks.get(tfile, (base, None, e)))
        try:
            etcs.train_data(train).kdry_for(etcs.national.m_nvebcl)
        except InputError as err:
            for pr in err.problems:
                name = _ETCS_FILE_FIELD.get(pr.field or "", pr.field)
                if name == "kdry_rst" and given.kdry_rst_by_ebcl is not None:
                    name = "kdry_rst_by_ebcl"
                field_path = where if name in (None, base) else f"{where}.{name}"
                problems.append(
                    replace(pr, file=file, field=field_path,
                            reason=f"{pr.reason} (ETCS data of {where_train}, train {tfile})")
                )  # fmt: skip
    if len(problems) > before:
        return None, {}
    return etcs, copies


def _etcs_services(
    spec: _Operation, services: list[TrainService], copies: dict[str, Train]
) -> list[TrainService]:
    """The services of the train ids with their own ETCS braking data run with that id's train copy."""
    if not copies:
        return services
    out, k = list(services), 0
    for t in spec.trains:
        count = t.repeat.count if t.repeat else 1
        if t.id in copies:
            for j in range(k, min(k + count, len(out))):
                if out[j].id in (t.id, f"{t.id}.{j - k + 1}"):
                    out[j] = replace(out[j], train=copies[t.id])
        k += count
    return out


def _connections(spec: _Operation, services: list[TrainService], file: str) -> tuple[Connection, ...]:
    """The file's connections, each checked on its own (the other line is checked by the
    network-day that has it)."""
    ids = [s.id for s in services]
    problems: list[Problem] = []
    out = []
    for i, c in enumerate(spec.connections):
        where = f"connections[{i}]"
        if c.train not in ids:
            problems.append(
                Problem("unknown train", file=file, field=f"{where}.train", value=c.train,
                        allowed=", ".join(ids[:20]) + (" ..." if len(ids) > 20 else ""))
            )  # fmt: skip
        if c.line == spec.name:
            problems.append(
                Problem("a train waits for a train of another line", file=file, field=f"{where}.line",
                        value=c.line, allowed="the name of another operation file's line")
            )  # fmt: skip
        if not (np.isfinite(c.min_s) and 0.0 <= c.min_s <= MAX_CONNECTION_S):
            problems.append(
                Problem("invalid connection time", file=file, field=f"{where}.min_s", value=c.min_s,
                        allowed=f"0 .. {MAX_CONNECTION_S:g} s")
            )  # fmt: skip
        out.append(Connection(c.train, c.line, c.feeder, c.station, float(c.min_s)))
    if problems:
        raise InputError.from_problems(problems)
    return tuple(out)


def _railml_line(railml: _Railml, base: Path, file: str, problems: list[Problem]):
    """The route and the signalling of ``line.railml`` (None, None with problems when unreadable)."""
    from trainsim.io.interchange import detect_and_load
    from trainsim.io.railml_signalling import read_signalling

    target = (base / railml.file).resolve()
    if not target.is_file():
        problems.append(
            Problem(
                "file not found",
                file=file,
                field="line.railml.file",
                value=railml.file,
                allowed="a path relative to the operation file",
            )
        )
        return None, None
    options: dict = {"train_id": railml.train_id, "ocps": railml.ocps}
    if railml.line_resistance is not None:
        options["line_resistance"] = railml.line_resistance.model_dump()
    try:
        route = detect_and_load(target, "route", **options)
        if route is None:
            raise InputError("not a railML file", file=str(target), field="line.railml.file")
        read = read_signalling(
            target, train_id=railml.train_id, ocps=railml.ocps, double_track=railml.double_track
        )
        return route, read
    except InputError as e:
        problems.extend(p if p.file else replace(p, file=str(target)) for p in e.problems)
        return None, None


def _spreadsheet_line(sheet: _Spreadsheet, base: Path, file: str, problems: list[Problem]):
    """The route and the signalling of ``line.spreadsheet`` (None, None with problems when unreadable)."""
    from trainsim.io.interchange import detect_and_load
    from trainsim.io.spreadsheet import is_spreadsheet, read_spreadsheet_signalling

    target = (base / sheet.file).resolve()
    if not (target.exists() and is_spreadsheet(target)):
        problems.append(
            Problem(
                "spreadsheet not found" if not target.exists() else "not a spreadsheet",
                file=file,
                field="line.spreadsheet.file",
                value=sheet.file,
                allowed="an Excel workbook (.xlsx) or a folder of CSV tables, relative to the operation file",
            )
        )
        return None, None
    try:
        route = detect_and_load(target, "route")
        return route, read_spreadsheet_signalling(target, route)
    except InputError as e:
        problems.extend(p if p.file else replace(p, file=str(target)) for p in e.problems)
        return None, None


def _tracks(
    spec: _Operation, read, file: str, problems: list[Problem]
) -> tuple[dict[str, TrackLayout] | None, dict[str, list[float]]]:
    """The line's tracks from ``line.tracks``, or from a railML file's switches, detection points and
    down-track station signals with ``line.railml.tracks``; and the block signals given per track."""
    given = spec.line.tracks
    railml = spec.line.railml if spec.line.railml is not None else spec.line.spreadsheet
    if railml is not None and railml.tracks:
        if given is not None:
            problems.append(
                Problem(
                    "tracks given twice: in line.tracks and read from the railML file or spreadsheet "
                    "(its tracks: true)",
                    file=file,
                    field="line.tracks",
                    allowed="one of them",
                )
            )
            return None, {}
        d = railml.clearance_distance_m
        if d is not None and not (np.isfinite(d) and 0 < d < 1000):
            problems.append(
                Problem(
                    "invalid clearance distance",
                    file=file,
                    field=f"line.{'railml' if spec.line.railml is not None else 'spreadsheet'}.clearance_distance_m",
                    value=d,
                    allowed="0 < x < 1000 m",
                )
            )
            return None, {}
        return _railml_tracks(spec, read), {}
    if given is None:
        return None, {}
    tracks = {
        key: TrackLayout(
            tuple(t.detection_points_m),
            tuple(
                SwitchLayout(
                    w.name,
                    w.position_m,
                    w.clearance_m,
                    None if w.diverging_speed_kmh is None else w.diverging_speed_kmh * KMH,
                    None if w.diverging_tracks is None else tuple(w.diverging_tracks),
                )
                for w in t.switches
            ),
            dict(t.station_signals_m),
        )
        for key, t in given.items()
    }
    blocks = {key: list(t.block_signals_m) for key, t in given.items() if t.block_signals_m is not None}
    if "both" in blocks:
        problems.append(
            Problem(
                "single track has one block between stations; block signals are for double track",
                file=file,
                field="line.tracks.both.block_signals_m",
                value=blocks["both"],
            )
        )
    return tracks, {k: v for k, v in blocks.items() if k != "both"}


def _railml_tracks(spec: _Operation, read) -> dict[str, TrackLayout] | None:
    """Tracks from what the railML or spreadsheet reader found: the switches (their clearance points are the nearest
    detection points towards the station) and detection points of each path; on a double track read
    with its down path, the down track's own station signals."""
    if read is None:
        return None
    single = spec.line.layout == "single_track"
    source = spec.line.railml if spec.line.railml is not None else spec.line.spreadsheet
    assert source is not None
    # the down signals are the down track's own where that track was read as such: a railML double
    # track read with its down path, or a spreadsheet's signals table (directions given)
    own_down = spec.line.spreadsheet is not None or getattr(source, "double_track", False)
    out: dict[str, TrackLayout] = {}
    for path in ("up", "down"):
        if single and path == "down":
            break
        signals: dict[str, tuple[float, float]] = {}
        if path == "down" and own_down:
            for entry in read.station_signals("down"):
                if "entry_signal_distance_m" in entry and "exit_signal_offset_m" in entry:
                    p = float(entry["position_m"])
                    signals[str(entry["name"])] = (
                        p + float(entry["entry_signal_distance_m"]),
                        p - float(entry["exit_signal_offset_m"]),
                    )
        dets = [d.position_m for d in read.detection_points if d.path == path]
        switches = []
        for w in read.switches:
            if w.path != path:
                continue
            clearance = w.clearance_m
            stop = min(
                (st.position_m for st in read.stations), key=lambda x: abs(x - w.position_m), default=None
            )
            distance = source.clearance_distance_m
            if clearance is None and stop is not None and distance is not None:
                lo, hi = sorted((w.position_m, stop))
                if not any(lo < d < hi for d in dets):
                    clearance = w.position_m + (distance if stop > w.position_m else -distance)
            switches.append(SwitchLayout(w.name, w.position_m, clearance, w.diverging_speed_mps))
        out["both" if single else path] = TrackLayout(tuple(dets), tuple(switches), signals)
    return out


def _stations_with_signals(read, given: list[_Station]) -> list[_Station]:
    """The stations of a railML or spreadsheet line with the signal distances read for the up direction
    (the line model holds one value for both directions); a station given in the operation file
    overrides, field by field, what was read."""
    by_name = {s.name: s for s in given}
    out = []
    for entry in read.station_signals("up"):
        mine = by_name.pop(str(entry["name"]), None)
        fields = dict(entry)
        if mine is not None:
            fields.update({k: getattr(mine, k) for k in mine.model_fields_set})
        out.append(_Station(**fields))
    return out + list(by_name.values())


def _services(
    spec: _Operation, trains: dict[str, Train], file: str, problems: list[Problem]
) -> list[TrainService]:
    total = sum(t.repeat.count if t.repeat else 1 for t in spec.trains)
    if total > MAX_TRAINS:
        problems.append(
            Problem("too many trains", file=file, field="trains", value=total, allowed=f"<= {MAX_TRAINS}")
        )
        return []
    if spec.delays and not (0 <= spec.delays.probability <= 1 and 0 <= spec.delays.mean_s <= 86400):
        problems.append(
            Problem(
                "invalid delay distribution",
                file=file,
                field="delays",
                value=spec.delays.model_dump(),
                allowed="0 <= probability <= 1, 0 <= mean_s <= 86400",
            )
        )
    out = []
    for i, t in enumerate(spec.trains):
        where = f"trains[{i}]"
        dep = _time(t.departure, t.departure_s, f"{where}.departure", file, True, problems)
        stops = []
        for k, s in enumerate(t.stops):
            arr = _time(s.arrival, s.arrival_s, f"{where}.stops[{k}].arrival", file, False, problems)
            sdep = _time(s.departure, s.departure_s, f"{where}.stops[{k}].departure", file, False, problems)
            if arr is not None and sdep is not None and sdep < arr:
                problems.append(
                    Problem(
                        "departure before arrival",
                        file=file,
                        field=f"{where}.stops[{k}].departure",
                        value=(arr, sdep),
                    )
                )
            if not (np.isfinite(s.dwell_s) and 0 <= s.dwell_s <= 86400):
                problems.append(
                    Problem(
                        "invalid dwell",
                        file=file,
                        field=f"{where}.stops[{k}].dwell_s",
                        value=s.dwell_s,
                        allowed="0 .. 86400 s",
                    )
                )
            stops.append(ScheduledStop(s.station, s.dwell_s, arr, sdep, s.track))
        if not (np.isfinite(t.entry_delay_s) and t.entry_delay_s >= 0):
            problems.append(
                Problem(
                    "invalid entry delay",
                    file=file,
                    field=f"{where}.entry_delay_s",
                    value=t.entry_delay_s,
                    allowed=">= 0 s",
                )
            )
        if dep is None or t.train not in trains:
            continue
        count, every = (t.repeat.count, t.repeat.every_s) if t.repeat else (1, 0.0)
        for r in range(count):
            shift = r * every
            delay = t.entry_delay_s
            out.append(
                TrainService(
                    t.id if count == 1 else f"{t.id}.{r + 1}",
                    trains[t.train],
                    t.direction,
                    t.origin,
                    t.destination,
                    dep + shift,
                    tuple(
                        replace(
                            s,
                            arrival_s=None if s.arrival_s is None else s.arrival_s + shift,
                            departure_s=None if s.departure_s is None else s.departure_s + shift,
                        )
                        for s in stops
                    ),
                    t.priority,
                    delay,
                    t.origin_track,
                    strategy=t.strategy,
                )
            )
    return out


def check_operation(path: str | Path):  # -> trainsim.io.report.CheckReport
    """What ``trainsim check`` shows for an operation file (register with
    ``trainsim.io.loader.register_checker(SCHEMA, check_operation)``); InputError if it is not valid."""
    from trainsim.io.report import CheckReport

    op = read_operation(path)
    sig = op.line.signalling
    deps = [s.departure_s for s in op.services]
    figures = {
        "line": f"{op.line.length_m / 1000:.3f} km, {op.line.layout.replace('_', ' ')}",
        "stations": ", ".join(f"{s.name} ({s.tracks})" for s in op.line.stations),
        "signalling": sig.system + (f", {sig.aspects} aspects" if sig.system == "fixed_block" else ""),
        "routes per direction": str(len(op.line.paths["up"].steps)),
        "trains": str(len(op.services)),
        "departures": f"{min(deps):.0f} .. {max(deps):.0f} s" if deps else "-",
        "dispatching": op.rule + (f", look-ahead {op.lookahead_s:g} s" if op.lookahead_s else ""),
    }
    if op.line.tracks:
        figures["tracks"] = "; ".join(
            f"{key}: {len(t.switches)} switches, {len(t.detection_points_m)} detection points"
            + (f", own signals at {len(t.station_signals_m)} stations" if t.station_signals_m else "")
            for key, t in op.line.tracks.items()
        )
        loops = [f"{name} {hi - lo:g} m" for name, (lo, hi) in op.line.paths["up"].platform_m.items()]
        if loops:
            figures["loops (up, clearance to clearance)"] = ", ".join(loops)
    notes = []
    if op.delays is not None:
        notes.append(
            f"entry delays sampled: probability {op.delays.probability:g}, mean {op.delays.mean_s:g} s, "
            f"seed {op.delays.seed}"
        )
    return CheckReport(str(path), "operation", f"{SCHEMA} v1", op.name, figures, notes)
