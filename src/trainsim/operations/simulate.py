"""Many trains on a signalled line, simulated together in time.

Each train runs its own fastest run (``trainsim.run_fastest``) through its stops. Trains claim routes
from a dispatcher; a discrete-event simulation processes route requests and releases in time order:

* A train **requests** a route when it must see a proceed aspect for it: when its head passes the
  route's approach start, minus the sight/reaction and setup times (``blocking.approach_start_m``), or,
  if it stands at a stop inside the approach, that long before its departure.
* The route is **given** when every resource of one of its alternatives (platform tracks) is free; on
  single track a section is only given together with a platform track at the next station.
* A train whose route is not given stays at the stop it stands at, or, running, **brakes to a stand**
  ``standing_distance_m`` before the signal (its fastest run with one more stop) and waits. When the
  route is given it leaves ``setup_s + reaction_s`` later (route set, signal clears, driver reacts).
  Driver model: a train that has seen a restrictive aspect comes to a stand (it does not pick up speed
  again if the signal clears while it brakes); see docs/OPERATIONS.md.
* A resource is **released** ``release_s`` after the train's rear has passed its release point
  (sectional or whole-route release). A train leaves the line at its destination: what it still holds
  is released ``release_s`` after its dwell there.
* **Dispatching rules** when a resource is freed and several trains wait for it: ``fcfs`` gives it to
  the train that asked first, ``priority`` to the train of highest priority (then the one that asked
  first). A request made while its resources are free is always given.
* A **deadlock** (trains waiting for each other's resources; no event left) is detected and reported
  with the trains and resources involved: the simulation never hangs. Every train's number of events
  is bounded (one request per route, at most one stop per signal, one release per resource).

Runs are cached by train, direction and stops: identical unhindered trains are simulated once, and only
a hindered train (one more stop) needs a new run.
"""

from __future__ import annotations

import heapq
import math
from bisect import bisect_left, bisect_right
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from itertools import pairwise
from typing import Literal

import numpy as np

from trainsim.errors import InputError
from trainsim.model import Route as GeometryRoute
from trainsim.model import SpeedLimit, Train
from trainsim.model.scenario import RunSettings
from trainsim.model.timetable import TimingPoint
from trainsim.operations.blocking import (
    BlockingTime,
    Headway,
    Trajectory,
    approach_start_m,
    blocking_times,
    braking_distance_table,
    minimum_headway,
    route_release_points,
)
from trainsim.operations.ceiling import MIN_CEILING_MPS, driver_braking_steps, release_steps
from trainsim.operations.line import Direction, Line, Route, RouteStep
from trainsim.operations.runs import (
    AWARE_RESERVE,
    ECO_MIN_SUPPLEMENT_S,
    EcoPlan,
    Movement,
    RunCache,
    Splice,
    auxiliary_power_w,
    min_running_time_s,
)
from trainsim.operations.separation import EtcsBraking, etcs_approach_distance, ma_indication_steps
from trainsim.optimize.api import SCHEDULE_TOLERANCE_S

Rule = Literal["fcfs", "priority"]
#: How a train drives between its stops (``TrainService.strategy``).
STRATEGIES = ("fastest", "optimal", "signal_aware")
#: A train leaving a stop later than scheduled by more than this drives the next stretch fastest [s].
LATE_TOLERANCE_S = 1.0
#: A signal-aware train passes an approach start this long after its route can be set at the earliest
#: (the optimisation meets a timing window within 0.5 s) [s].
AWARE_MARGIN_S = 1.0
#: The most simulations of a timetable with signal-aware trains (each takes its timing points from
#: the blocking times of the one before).
MAX_AWARE_ITERATIONS = 6
#: Timing points of two simulations this close are the same (the iteration has converged) [s, m].
#: Under moving block a train's approach start follows its own speed (its braking distance) and moves
#: by some 0.1 m from one simulation to the next; half a metre is passed well within ``AWARE_MARGIN_S``.
AWARE_CONVERGED_S = 1e-3
AWARE_CONVERGED_M = 0.5
#: Running times and timing points asked of the optimisation are rounded to these decimals of a
#: second (1 ms: far below the schedule tolerance of 0.5 s).
ASKED_DIGITS = 3
#: Times closer than this are the same instant (a follower at exactly the minimum headway) [s].
TIME_TOLERANCE_S = 1e-6
#: Grid of the release points of trains that pick up speed again [m].
RELEASE_GRID_M = 10.0
#: Operated blocking times may touch within this much (trace interpolation between run points) [s].
INVARIANT_TOLERANCE_S = 1e-3


@dataclass(frozen=True)
class ScheduledStop:
    """A stop of a train at a station.

    Attributes:
        station: station name.
        dwell_s: minimum dwell [s].
        arrival_s: scheduled arrival [s], or None (the planned run's arrival).
        departure_s: scheduled departure [s], or None (arrival + dwell).
        track: platform track to use, or None (the dispatcher's choice).
        extra_dwell_s: a sampled disturbance [s]: time lost at the stop that the operated run takes
            and the planned one does not.
    """

    station: str
    dwell_s: float = 0.0
    arrival_s: float | None = None
    departure_s: float | None = None
    track: int | None = None
    extra_dwell_s: float = 0.0


@dataclass(frozen=True)
class TrainService:
    """One train of the timetable.

    Attributes:
        id: unique id.
        train: the train.
        direction: ``up`` (increasing line position) or ``down``.
        origin, destination: station names.
        departure_s: scheduled departure from the origin [s].
        stops: intermediate stops in running order; a stop at the destination gives its scheduled
            arrival and dwell (the time before the train leaves the line).
        priority: higher runs first under the ``priority`` rule.
        entry_delay_s: delay at the origin [s] (given or sampled).
        origin_track: platform track at the origin, or None.
        running_extra_s: running-time disturbances [s], one per stretch between two scheduled stops
            (origin, stops, destination), or empty: the operated train drives the stretch as the
            fastest run under a speed cap whose running time is this much longer
            (``RunCache.capped``); its trajectory, blocking times and energy are that run's
            (``TrainOutcome.disturbed``). The planned run does not have it.
        traction_power_cap_w: cap on the traction power at the wheel of the operated runs [W]
            (``EffortCurve.capped``; infinite: none). The planned run does not have it, so that a
            train slowed by it (a weak supply, fed back by the power study) shows as late.
        strategy: ``fastest``; ``optimal`` (each stretch between scheduled stops driven by
            ``trainsim.optimize``'s optimal strategy in its scheduled running time, fastest when the
            train leaves late or a signal stops it); ``signal_aware`` (``optimal`` with timing points
            from the blocking times of the trains ahead: it passes each approach start only when its
            route is set). The last two need a scheduled arrival at every stop and the destination.
    """

    id: str
    train: Train
    direction: Direction
    origin: str
    destination: str
    departure_s: float
    stops: tuple[ScheduledStop, ...] = ()
    priority: int = 0
    entry_delay_s: float = 0.0
    origin_track: int | None = None
    running_extra_s: tuple[float, ...] = ()
    traction_power_cap_w: float = math.inf
    strategy: str = "fastest"


@dataclass(frozen=True)
class StopTimes:
    """Scheduled (or planned) and simulated times at one station of a train [s]."""

    station: str
    kind: str  # origin, stop, pass, destination
    scheduled_arrival_s: float | None
    scheduled_departure_s: float | None
    arrival_s: float | None
    departure_s: float | None
    delay_s: float | None
    track: int | None

    def to_dict(self) -> dict[str, object]:
        def r(x: float | None) -> float | None:
            return None if x is None or not np.isfinite(x) else round(float(x), 3)

        return {
            "station": self.station,
            "kind": self.kind,
            "scheduled_arrival_s": r(self.scheduled_arrival_s),
            "scheduled_departure_s": r(self.scheduled_departure_s),
            "arrival_s": r(self.arrival_s),
            "departure_s": r(self.departure_s),
            "delay_s": r(self.delay_s),
            "track": self.track,
        }


@dataclass(frozen=True)
class Hindrance:
    """A wait: at a signal (``signal``) or held at a stop (``stop``), ``wait_s`` long from ``time_s``."""

    kind: str
    where: str
    position_m: float
    time_s: float
    wait_s: float
    route: str


@dataclass(frozen=True)
class DisturbedStretch:
    """How a stretch with a running-time disturbance was driven.

    Attributes:
        start, end: its scheduled stops.
        extra_s: the disturbance [s].
        running_time_s: the disturbed running time, the undisturbed run's plus ``extra_s`` [s].
        driven_s: running time of the trajectory's run of the stretch (unhindered) [s].
        cap_mps: the speed cap of that run [m/s], or None (time-scaled, or no capped run).
        hold_s: the part of ``running_time_s`` no capped run takes, stood before leaving ``start`` [s].
        status: ``ok`` (a capped run of the disturbed time), ``undisturbed`` (an extension within
            ``CAP_TIME_TOLERANCE_S``: the fastest run), ``time_scaled`` (the fastest run's path with
            time stretched: ``simulate(disturbed_energy=False)``), or the fallback of
            ``CappedRun.status`` (a warning says so).
    """

    start: str
    end: str
    extra_s: float
    running_time_s: float
    driven_s: float
    cap_mps: float | None
    hold_s: float
    status: str

    def to_dict(self) -> dict[str, object]:
        return {
            "from": self.start,
            "to": self.end,
            "extra_s": round(self.extra_s, 3),
            "running_time_s": round(self.running_time_s, 6),
            "driven_s": round(self.driven_s, 6),
            "cap_kmh": None if self.cap_mps is None else round(self.cap_mps * 3.6, 3),
            "hold_s": round(self.hold_s, 3),
            "status": self.status,
        }


@dataclass(frozen=True)
class DrivenStretch:
    """How an ``optimal`` or ``signal_aware`` train drove a stretch between two scheduled stops.

    Attributes:
        start, end: its scheduled stops.
        driven: ``optimal``, ``signal_aware`` (optimal with timing points) or ``fastest``.
        reason: why ``fastest`` (``late`` by ``late_s``, ``signal`` stop or slowdown, ``no_supplement``:
            the schedule leaves no time over the fastest run), else empty.
        scheduled_s: scheduled running time (arrival minus departure) [s].
        running_time_s: the running time of the run driven, stands at signals excluded [s].
        timing_points: the timing points of a signal-aware stretch (running position, earliest time
            from the stretch's departure) [m, s].
        late_s: how late the train left ``start`` [s].
        asked_s: the running time the optimisation was asked for: the scheduled one, or for a
            signal-aware stretch whose timing points the schedule cannot meet the shortest running
            time that meets them plus ``AWARE_RESERVE`` (the train arrives later); None when driven
            fastest [s].
    """

    start: str
    end: str
    driven: str
    reason: str
    scheduled_s: float
    running_time_s: float
    timing_points: tuple[TimingPoint, ...] = ()
    late_s: float = 0.0
    asked_s: float | None = None

    def to_dict(self) -> dict[str, object]:
        return {
            "from": self.start,
            "to": self.end,
            "driven": self.driven,
            "reason": self.reason or None,
            "scheduled_s": round(self.scheduled_s, 3),
            "running_time_s": round(self.running_time_s, 3),
            "late_s": round(self.late_s, 3),
            "asked_s": None if self.asked_s is None else round(self.asked_s, 6),
            "timing_points": [
                {
                    "position_m": round(p.position_m, 3),
                    "earliest_s": round(float(p.earliest_s), 3),
                    "name": p.name,
                }
                for p in self.timing_points
            ],
        }


@dataclass
class TrainOutcome:
    """What happened to one train."""

    id: str
    direction: Direction
    status: str  # ok, stalled, deadlocked
    stops: list[StopTimes]
    delay_s: float
    energy_kwh: float
    planned_energy_kwh: float
    hindrances: list[Hindrance]
    trajectory: Trajectory | None
    planned_trajectory: Trajectory
    routes: list[tuple[int, Route]]
    warnings: list[str] = field(default_factory=list)
    #: the core's runs of the operated movement, one per stretch between two stops (signal stops too)
    runs: tuple = ()
    #: how running-time disturbances were driven and their energy found, else empty
    energy_note: str = ""
    #: how the operated trajectory was made when it is not ``runs`` joined (time-scaled), else empty
    trajectory_note: str = ""
    #: the stretches with running-time disturbances and how each was driven
    disturbed: tuple[DisturbedStretch, ...] = ()
    #: the driving strategy (``TrainService.strategy``)
    strategy: str = "fastest"
    #: how each stretch between scheduled stops was driven (``optimal``, ``signal_aware``), else empty
    stretches: tuple[DrivenStretch, ...] = ()

    def to_dict(self) -> dict[str, object]:
        return {
            "id": self.id,
            "direction": self.direction,
            "strategy": self.strategy,
            "status": self.status,
            "delay_s": round(self.delay_s, 3) if np.isfinite(self.delay_s) else None,
            "energy_kwh": round(self.energy_kwh, 4) if np.isfinite(self.energy_kwh) else None,
            "planned_energy_kwh": round(self.planned_energy_kwh, 4),
            "stops": [s.to_dict() for s in self.stops],
            "hindrances": [
                {"kind": h.kind, "where": h.where, "time_s": round(h.time_s, 3), "wait_s": round(h.wait_s, 3)}
                for h in self.hindrances
            ],
            "warnings": self.warnings,
            **({"energy_note": self.energy_note} if self.energy_note else {}),
            **({"trajectory_note": self.trajectory_note} if self.trajectory_note else {}),
            **({"disturbed": [d.to_dict() for d in self.disturbed]} if self.disturbed else {}),
            **({"stretches": [d.to_dict() for d in self.stretches]} if self.stretches else {}),
        }


@dataclass(frozen=True)
class Conflict:
    """Two trains' planned blocking times overlapping on one resource."""

    first: str
    second: str
    route: str
    resource: str
    time_s: float
    overlap_s: float

    def to_dict(self) -> dict[str, object]:
        return {
            "trains": [self.first, self.second],
            "block": self.route,
            "resource": self.resource,
            "time_s": round(self.time_s, 3),
            "overlap_s": round(self.overlap_s, 3),
        }


@dataclass
class OperationResult:
    """The result of simulating a timetable on a line.

    ``status``: ``ok``; ``conflicts`` (the planned timetable has conflicting blocking times: trains ran
    later than planned); ``deadlock`` (some trains could not finish); ``stalled`` (a train's run
    stalled).
    """

    status: str
    warnings: list[str]
    trains: list[TrainOutcome]
    conflicts: list[Conflict]
    headways: list[Headway]
    blocking: list[BlockingTime]
    planned_blocking: list[BlockingTime]
    runs_computed: int
    runs_reused: int
    deadlock: list[str] = field(default_factory=list)
    #: simulations made (> 1: signal-aware trains took their timing points from the one before)
    iterations: int = 1

    def summary(self) -> dict[str, object]:
        """JSON-ready summary."""
        return {
            "status": self.status,
            "warnings": self.warnings,
            "deadlock": self.deadlock,
            "trains": [t.to_dict() for t in self.trains],
            "conflicts": [c.to_dict() for c in self.conflicts],
            "headways": [h.to_dict() for h in self.headways],
            "runs": {"computed": self.runs_computed, "reused": self.runs_reused},
            "iterations": self.iterations,
            "total_delay_s": round(sum(t.delay_s for t in self.trains if np.isfinite(t.delay_s)), 3),
            "energy_kwh": {
                "operated": round(sum(t.energy_kwh for t in self.trains if np.isfinite(t.energy_kwh)), 4),
                "planned": round(sum(t.planned_energy_kwh for t in self.trains), 4),
            },
        }


# --------------------------------------------------------------------------- per-train state


@dataclass
class _Stop:
    name: str
    position_m: float
    kind: str  # origin, stop, signal, destination
    dwell_s: float
    scheduled_departure_s: float | None
    track: int | None = None
    extra_s: float = 0.0  # a sampled disturbance the planned run does not have [s]


def _stretch_schedule(svc: TrainService, stops: list[_Stop]) -> dict[float, tuple[float, float, float]]:
    """Each stretch between two scheduled stops by the position of its first: (position of its last,
    scheduled departure, scheduled arrival) [m, s]. A stop's scheduled departure is the given one, else
    its scheduled arrival plus its dwell (``_check_services`` makes sure the arrivals are given)."""
    sched = {s.station: s for s in svc.stops}
    out = {}
    dep = svc.departure_s
    for a, b in pairwise(stops):
        arr = sched[b.name].arrival_s
        out[a.position_m] = (b.position_m, float(dep), float(arr))
        s = sched[b.name]
        dep = s.departure_s if s.departure_s is not None else arr + s.dwell_s
    return out


class _TrainState:
    def __init__(
        self,
        index: int,
        svc: TrainService,
        line: Line,
        directed: GeometryRoute,
        cache: RunCache,
        ma_steps: Callable[[float, float, float], tuple[SpeedLimit, ...]] | None = None,
        disturbed_energy: bool = True,
        aware_points: tuple[tuple[float, float, str], ...] = (),
    ) -> None:
        self.index = index
        self.ma_steps = ma_steps
        self.svc = svc
        self.line = line
        self.directed = directed
        self.cache = cache
        self.path = line.paths[svc.direction]
        self.length_m = svc.train.length_m
        # the train the operated runs are made with (svc.train itself without a traction power cap)
        self.train = cache.power_capped(svc.train, svc.traction_power_cap_w)
        path = self.path
        p0 = path.stop_m[svc.origin]
        p1 = path.stop_m[svc.destination]
        first = next(j for j, st in enumerate(path.steps) if st.kind == "entry" and st.station == svc.origin)
        last = next(
            j for j, st in enumerate(path.steps) if st.kind == "entry" and st.station == svc.destination
        )
        self.steps = list(range(first, last + 1))
        self.stops: list[_Stop] = [
            _Stop(svc.origin, p0, "origin", 0.0, svc.departure_s + svc.entry_delay_s, svc.origin_track)
        ]
        dest_dwell = 0.0
        for s in svc.stops:
            if s.station == svc.destination:
                dest_dwell = s.dwell_s
                continue
            self.stops.append(
                _Stop(
                    s.station,
                    path.stop_m[s.station],
                    "stop",
                    s.dwell_s,
                    s.departure_s,
                    s.track,
                    s.extra_dwell_s,
                )
            )
        self.stops.append(_Stop(svc.destination, p1, "destination", dest_dwell, None))
        self.strategy = svc.strategy
        # energy-efficient driving: station stop position -> (next station stop position, scheduled
        # departure, scheduled arrival there) [m, s]
        self.schedule: dict[float, tuple[float, float, float]] = {}
        if self.strategy != "fastest":
            self.schedule = _stretch_schedule(svc, self.stops)
        # signal-aware timing points: (running position, earliest passing time, name) [m, s]
        self.aware_points = aware_points
        # station stop positions whose stretch a signal stopped or slowed the train on (driven fastest)
        # -> the energy-efficient run it was on up to the braking (None: it was driving fastest)
        self.signal_affected: dict[float, Splice | None] = {}
        # station stop position -> (driven, reason, scheduled running time, timing points, late, running
        # time asked of the optimisation) of the stretch from it, as last decided for the operated run
        self.driven: dict[float, tuple] = {}
        # running-time disturbances as time factors per scheduled stretch (None: none, or driven as
        # capped runs), from its unhindered run
        self.stretch_m = np.array([s.position_m for s in self.stops])
        self.factors: np.ndarray | None = None
        self.holds: dict[float, float] = {}  # stop position -> stand of a disturbance [s]
        self.disturbed: list[DisturbedStretch] = []
        self.dest_dwell_s = dest_dwell
        self.tracks = {s.name: s.track for s in self.stops if s.track is not None}
        self.override: dict[float, float] = {}  # stop position -> decided departure
        self.next = 0  # index into self.steps of the next route to request
        self.granted: list[tuple[int, Route]] = []
        self.held: list[list] = []  # [resource, release point, route name, release time or None]
        self.waiting_since: float | None = None
        self.waiting_stop: float | None = None
        self.hindrances: list[Hindrance] = []
        self.warnings: list[str] = []
        self.version = 0
        self.done = False
        self.movement: Movement | None = None
        self.trajectory: Trajectory | None = None
        self._request_key: tuple | None = None
        self.stalled_m: float | None = None
        self.given_at: dict[str, float] = {}  # route name -> when the dispatcher gave it
        self.released: dict[tuple[str, str], float] = {}  # (route, resource) -> when it was released
        self._request_value: tuple[float, float | None, float] = (0.0, None, 0.0)
        self.trajectory_version = 0
        self.limits: list[SpeedLimit] = []  # driver's braking curves to signals (running positions)
        # signal stop position -> (its braking curve's steps, trajectory before, signal position)
        self.approaches: dict[float, tuple[tuple[SpeedLimit, ...], Trajectory, float]] = {}
        if ma_steps is not None:
            self.limits.extend(self._stop_ceilings())
        # the diverging switches of the platform tracks asked for (the others when given, ``grant``)
        for s in self.stops:
            if s.track is not None:
                self.limits.extend(path.track_speed_limits(s.name, s.track))
        self.refresh_movement()
        # the plan is the uncapped train's: a traction power cap is a disturbance of the operation
        if self.strategy != "fastest":
            # on time, without the timing points of the trains it meets in operation
            self.plan_movement = self.candidate(self.stops, self.limits, svc.train, planned=True)
        elif self.train is svc.train:
            self.plan_movement = self.movement
        else:
            self.plan_movement = cache.movement(
                svc.train, directed, [(s.name, s.position_m) for s in self.stops], tuple(self.limits)
            )
        if any(svc.running_extra_s) and self.movement.status == "ok":
            if disturbed_energy:
                self._cap_disturbed()
            else:
                self._scale_disturbed()

    def _scale_disturbed(self) -> None:
        """Running-time disturbances as time factors: the fastest run's path driven with time
        stretched (``Movement.trajectory``), cheap but not a run of the train (no energy)."""
        rt = self.movement.running_times_s()
        extra = np.asarray(self.svc.running_extra_s, dtype=float)
        self.factors = 1.0 + np.divide(extra, rt, out=np.zeros_like(extra), where=rt > 0)
        for k, (a, b) in enumerate(pairwise(self.stops)):
            if extra[k] > 0:
                t = float(rt[k] * self.factors[k])
                self.disturbed.append(
                    DisturbedStretch(a.name, b.name, float(extra[k]), t, t, None, 0.0, "time_scaled")
                )
        self.refresh_trajectory()

    def _cap_disturbed(self) -> None:
        """Each disturbed stretch driven as the fastest run under the speed cap that takes its
        disturbed running time (``RunCache.capped``): the caps join the train's ceilings, so every
        later run of the stretch (split at a signal, released) keeps them."""
        rt = self.movement.running_times_s()
        caps = []
        for k, (a, b) in enumerate(pairwise(self.stops)):
            extra = float(self.svc.running_extra_s[k])
            if extra <= 0 or rt[k] <= 0 or self.movement.results[k].status != "ok":
                continue
            target = float(rt[k] + extra)
            c = self.cache.capped(
                self.train,
                self.directed,
                (a.name, a.position_m),
                (b.name, b.position_m),
                self.limits,
                target,
            )
            if c.limit is not None:
                caps.append(c.limit)
            if c.hold_s > 0:
                self.holds[a.position_m] = self.holds.get(a.position_m, 0.0) + c.hold_s
            cap = None if c.limit is None else c.limit.limit_mps
            self.disturbed.append(
                DisturbedStretch(a.name, b.name, extra, target, c.running_time_s, cap, c.hold_s, c.status)
            )
            if c.status not in ("ok", "undisturbed"):
                self.warnings.append(
                    f"running-time disturbance {a.name} - {b.name}: no capped run takes {target:.1f} s "
                    f"({c.status}); driven in {c.running_time_s:.1f} s"
                    + ("" if cap is None else f" at {cap * 3.6:.1f} km/h")
                    + f", standing {c.hold_s:.1f} s at {a.name} before leaving (auxiliaries only)"
                )
        if caps:
            self.limits.extend(caps)
            self.refresh_movement()

    def factor_at(self, x_m: float) -> float:
        """The time factor of the scheduled stretch at running position ``x_m``."""
        if self.factors is None:
            return 1.0
        k = int(np.searchsorted(self.stretch_m, x_m, side="right")) - 1
        return float(self.factors[min(max(k, 0), len(self.factors) - 1)])

    def time_factors(self) -> list[float] | None:
        """The time factor of each stretch between two of the current stops (signal stops included),
        or None when the train has no running-time disturbance."""
        if self.factors is None:
            return None
        return [self.factor_at(0.5 * (a.position_m + b.position_m)) for a, b in pairwise(self.stops)]

    def _stop_ceilings(self) -> list[SpeedLimit]:
        """ETCS: a train asks for the route beyond a stop only while it stands there, so it runs into
        every stop under an MA ending at the end of the stop's entry route; the indication limit of
        that MA is part of its run (planned and operated alike)."""
        out: list[SpeedLimit] = []
        for prev, stop in pairwise(self.stops):
            entry = [
                st for j, st in enumerate(self.path.steps)
                if j in self.steps and st.kind == "entry" and st.station == stop.name
            ]  # fmt: skip
            if not entry:
                continue
            eoa = min(r.end_m for r in entry[0].alternatives)
            if eoa >= stop.position_m:
                out.extend(self.ma_steps(eoa, prev.position_m, stop.position_m))
        return out

    # -- runs and trajectories
    def candidate(
        self,
        stops: list[_Stop],
        limits: Sequence[SpeedLimit],
        train: Train | None = None,
        planned: bool = False,
    ) -> Movement:
        """The train's run through ``stops`` under ``limits``: fastest, or with the stretches between
        scheduled stops driven energy-efficiently (``_eco_plan``). A stretch's plan depends on when
        the train leaves its first stop, which depends on the stretches before it only: the plans are
        decided stretch by stretch in running order, each from the run with the plans before it."""
        train = train or self.train
        named = [(s.name, s.position_m) for s in stops]
        if self.strategy == "fastest":
            return self.cache.movement(train, self.directed, named, tuple(limits))
        plans: dict[int, EcoPlan | Splice] = {}
        driven: dict[float, tuple] = {}
        m = None
        for k in range(len(stops) - 1):
            if stops[k].position_m not in self.schedule:
                continue
            if m is None:
                m = self.cache.movement(train, self.directed, named, tuple(limits), plans)
                if m.status != "ok":
                    return m
            deps = self._departures(stops, m, planned)
            plan, how = self._eco_plan(stops, limits, deps, train, planned, k)
            if how is not None:
                driven[stops[k].position_m] = how
            if not planned and self.signal_affected.get(stops[k].position_m) is not None:
                plan = self.signal_affected[stops[k].position_m]
            if plan is not None:
                plans[k] = plan
                m = None  # the departures after it change
        if m is None:
            m = self.cache.movement(train, self.directed, named, tuple(limits), plans)
        if not planned and stops is self.stops:
            self.driven = driven
        return m

    def mark_signal(self, k: int, start_m: float) -> None:
        """A signal stop was put in at ``stops[k]``, the driver braking from ``start_m`` [m]: the
        scheduled stretch it lies on is driven as the fastest strategy drives it (braking curve to the
        signal, a stand or a release, fastest runs on); an energy-efficient run up to the braking
        stays what it was (``Splice``), the first signal on a stretch decides."""
        a_m = max(s.position_m for s in self.stops[:k] if s.kind != "signal")
        if a_m in self.signal_affected or a_m not in self.schedule:
            return
        how = self.driven.get(a_m)
        old = [s.position_m for s in self.stops if s is not self.stops[k]]
        splice = None
        if how is not None and how[0] != "fastest" and self.movement.status == "ok":
            tr = self.movement.results[old.index(a_m)].trace
            if tr is not None:
                splice = Splice(tr.position_m, tr.speed_mps, tr.time_s, tr.regime, float(start_m), how[0])
        self.signal_affected[a_m] = splice

    def _eco_plan(
        self,
        stops: list[_Stop],
        limits: Sequence[SpeedLimit],
        deps: list[float],
        train: Train,
        planned: bool,
        k: int,
    ) -> tuple[EcoPlan | None, tuple | None]:
        """How stretch ``k`` (from ``stops[k]``, a scheduled stop) is driven when the train leaves it
        at ``deps[k]``: energy-efficiently from its departure to the scheduled arrival at the next
        scheduled stop (with the timing points that fall on it, from its departure), unless the train
        leaves late, a signal stopped or slowed it there (the braking curve is a fastest run's), or
        the schedule leaves no time over the fastest run. Returns the plan (None: fastest) and
        (driven, reason, scheduled running time, timing points, late, time asked), None for the
        part of a stretch split at a signal."""
        a, b = stops[k], stops[k + 1]
        sched = self.schedule[a.position_m]
        target = sched[2] - sched[1]
        if a.position_m in self.signal_affected and not planned:
            splice = self.signal_affected[a.position_m]
            kind = "fastest" if splice is None else f"{splice.driven}, fastest from the braking"
            return None, (kind, "signal", target, (), 0.0, None)
        if b.kind == "signal" or abs(sched[0] - b.position_m) > 1e-6:
            return None, None
        late = 0.0 if planned else float(deps[k] - sched[1])
        if late > LATE_TOLERANCE_S:
            return None, ("fastest", "late", target, (), late, None)
        fs, _fv, ft, fr = self.cache.stretch(
            train, self.directed, (a.name, a.position_m), (b.name, b.position_m), limits
        )
        points: tuple[TimingPoint, ...] = ()
        if not planned and self.aware_points:
            points = tuple(
                TimingPoint(x, earliest_s=float(round(e - deps[k], ASKED_DIGITS)), name=n)
                for x, e, n in self.aware_points
                if a.position_m + 1.0 < x < b.position_m - 1.0 and e - deps[k] > 0
            )
        # a train that left early (no scheduled departure given) uses the time it gained; times to
        # the millisecond, so that a train on time (its arrival within the optimisation's tolerance)
        # shares the planned run
        run_s = target if planned else round(sched[2] - deps[k], ASKED_DIGITS)
        if points:
            run_s = max(run_s, min_running_time_s(fs, ft, points) * (1 + AWARE_RESERVE))
        if fr.status != "ok" or run_s <= float(ft[-1] - ft[0]) + ECO_MIN_SUPPLEMENT_S:
            return None, ("fastest", "no_supplement", target, (), late, None)
        kind = "signal_aware" if points else "optimal"
        return EcoPlan(float(run_s), points), (kind, "", target, points, late, float(run_s))

    def refresh_movement(self) -> None:
        self.movement = self.candidate(self.stops, self.limits)
        if self.movement.status != "ok" and self.stalled_m is None:
            # the run stalls: the train stands where it stalled for good, keeping what it holds there;
            # it asks for no route whose signal lies beyond
            self.stalled_m = float(self.movement.position_m[-1])
            self.steps = [j for j in self.steps if self.path.steps[j].start_m < self.stalled_m]
            self.next = min(self.next, len(self.steps))
        self.refresh_trajectory()

    def departures(self, planned: bool = False) -> list[float]:
        return self._departures(self.stops, self.plan_movement if planned else self.movement, planned)

    def _departures(self, stops: list[_Stop], m: Movement, planned: bool) -> list[float]:
        rt = m.running_times_s()
        if not planned and self.factors is not None and stops is self.stops:
            rt = rt * self.time_factors()
        holds = self.holds if not planned else {}
        deps: list[float] = []
        for k, s in enumerate(stops[:-1]):
            arrival = s.scheduled_departure_s if k == 0 else deps[-1] + rt[k - 1]
            dep = arrival + s.dwell_s + (0.0 if planned else s.extra_s)
            if s.scheduled_departure_s is not None:
                dep = max(dep, s.scheduled_departure_s)
            if holds:
                # a disturbance no capped run takes: stood before leaving, a wait for the route
                # (override) may cover it
                dep += holds.get(s.position_m, 0.0)
            dep = max(dep, self.override.get(s.position_m, -np.inf))
            deps.append(dep)
        return deps

    def origin_hold_s(self) -> float:
        """The stand at the origin of a disturbance no capped run takes [s]: in the trajectory and
        its energy, before the departure (the stands at later stops lie between arrival and
        departure)."""
        return self.holds.get(self.stops[0].position_m, 0.0) if self.holds else 0.0

    def refresh_trajectory(self) -> None:
        if self.strategy != "fastest" and self.movement is not None and self.movement.status == "ok":
            # a stand that moves a departure (a wait for a route) may make the train late there: the
            # stretches after it are decided again (the same runs, from the cache, when nothing changed)
            self.movement = self.candidate(self.stops, self.limits)
        self.trajectory = self.movement.trajectory(
            self.departures(), self.length_m, self.dest_dwell_s, self.time_factors(), self.origin_hold_s()
        )
        # a counter, not id(): a discarded trajectory's id can be reused by the next one
        self.trajectory_version += 1

    def stop_positions(self) -> np.ndarray:
        return np.array([s.position_m for s in self.stops])

    # -- requests
    def pending_step(self) -> tuple[int, RouteStep] | None:
        if self.next >= len(self.steps):
            return None
        j = self.steps[self.next]
        return j, self.path.steps[j]

    def request_point(self, approach_fn) -> tuple[float, float | None, float]:
        """(request time, stop standing inside the approach or None, approach start)."""
        key = (self.next, self.trajectory_version, len(self.stops))
        if self._request_key == key:
            return self._request_value
        value = self._request_point(approach_fn)
        self._request_key, self._request_value = key, value
        return value

    def _request_point(self, approach_fn) -> tuple[float, float | None, float]:
        value = self._own_request_point(self.steps[self.next], approach_fn)
        if self.line.signalling.system == "fixed_block":
            return value
        # ETCS and moving block: the approach distance falls with the speed, so a later route's approach
        # can start before this one's (at a stop, the exit route's approach is a few metres, the next
        # block's the indication distance at line speed). Routes are given in order, so this route is
        # needed when the earliest of them is: a train standing at a stop inside a later route's
        # approach has its MA extended over both before its departure (issue 17)
        margin = self.line.signalling.safety_margin_m
        for k in range(self.next + 1, len(self.steps)):
            x = self.path.steps[self.steps[k]].start_m
            if x - margin - _longest_approach_m(approach_fn, x, self.svc.train.max_speed_mps) >= value[2]:
                break  # its approach cannot start before this one's (nor can the next ones')
            later = self._own_request_point(self.steps[k], approach_fn)
            if later[0] < value[0]:
                value = later
        return value

    def _own_request_point(self, j: int, approach_fn) -> tuple[float, float | None, float]:
        """(request time, stop standing inside the approach or None, approach start) of route step
        ``j`` on its own."""
        step = self.path.steps[j]
        sig = self.line.signalling
        a = approach_start_m(self.path, j, sig, self.trajectory, approach_fn)
        # a few stops, asked some 50 times per train: plain floats beat numpy's per-call cost
        pos = [s.position_m for s in self.stops]
        lo, hi = a - 1e-9, step.start_m
        inside = [p for p in pos if lo <= p < hi]
        if hi <= pos[0] + 1e-9:
            # the route into the origin's platform: the train stands in it until it leaves
            inside = pos[:1]
        if inside:
            q = float(max(inside))
            t_see = self.trajectory.last_time_at(q)
            return t_see - sig.reaction_s - sig.setup_s, q, a
        t_see = self.trajectory.first_time_s(a)
        return t_see - sig.reaction_s - sig.setup_s, None, a

    def horizon_m(self, approach_fn) -> float:
        if self.pending_step() is None or self.waiting_since is not None:
            if self.waiting_since is not None:
                return self.waiting_stop
            return np.inf
        _t, q, a = self.request_point(approach_fn)
        return q if q is not None else a

    def release_time(self, point_m: float) -> float:
        sig = self.line.signalling
        head = point_m + self.length_m
        if self.stalled_m is not None and head > self.stalled_m - 1e-9:
            return np.inf  # never: the train stands there
        if head > self.stops[-1].position_m + 1e-9:
            # the train leaves the line at its destination after its dwell there
            return float(self.trajectory.time_s[-1]) + sig.release_s
        return self.trajectory.first_time_s(head) + sig.release_s


class _Dispatcher:
    def __init__(
        self, line: Line, states: list[_TrainState], rule: Rule, approach_fns: dict[int, Callable]
    ) -> None:
        self.line = line
        self.states = states
        self.rule = rule
        self.approach = approach_fns
        self.holder: dict[str, int] = {}
        self.heap: list[tuple[float, int, int, int, int]] = []
        self.seq = 0
        self.now = -np.inf
        self.waiting: list[int] = []
        self.lookahead_s = 0.0

    # -- events
    def schedule(self, st: _TrainState) -> None:
        st.version += 1
        if st.done:
            return
        fn = self.approach[st.index]
        best: tuple[float, int] | None = None
        if st.waiting_since is None and st.pending_step() is not None:
            t_req, _q, _a = st.request_point(fn)
            best = (max(t_req, self.now), 1)
        horizon = st.horizon_m(fn)
        for h in st.held:
            if h[3] is None and h[1] + st.length_m <= horizon + 1e-9:
                h[3] = st.release_time(h[1])
            if h[3] is not None and math.isfinite(h[3]) and (best is None or (h[3], 0) < best):
                best = (max(h[3], self.now), 0)
        if best is None:
            if st.pending_step() is None and (not st.held or st.stalled_m is not None):
                st.done = True
            return
        self.seq += 1
        heapq.heappush(self.heap, (best[0], best[1], self.seq, st.index, st.version))

    def run(self) -> None:
        for st in self.states:
            self.schedule(st)
        while self.heap:
            t, kind, _seq, i, version = heapq.heappop(self.heap)
            st = self.states[i]
            if version != st.version:
                continue
            self.now = t
            if kind == 0:
                self.release_due(st, t)
                self.schedule(st)
                self.wake(t)
            else:
                self.request(st, t)

    def release_due(self, st: _TrainState, t: float) -> None:
        keep = []
        for h in st.held:
            if h[3] is not None and h[3] <= t + TIME_TOLERANCE_S:
                if self.holder.get(h[0]) == st.index:
                    del self.holder[h[0]]
                st.released[(h[2], h[0])] = h[3]
            else:
                keep.append(h)
        st.held = keep
        if not st.held and st.pending_step() is None:
            st.done = True

    def _free(self, st: _TrainState, routes: Sequence[Route], t: float) -> bool:
        for r in routes:
            for res in r.resources:
                k = self.holder.get(res.name)
                if k is None or k == st.index:
                    continue
                other = self.states[k]
                due = [h for h in other.held if h[0] == res.name]
                if due and due[0][3] is not None and due[0][3] <= t + TIME_TOLERANCE_S:
                    # released at this very instant (a follower at exactly the minimum headway)
                    self.release_due(other, t)
                    self.schedule(other)
                    # let the trains waiting for what it freed try again at this instant
                    self.seq += 1
                    heapq.heappush(self.heap, (t, 0, self.seq, other.index, other.version))
                    continue
                return False
        return True

    def _choices(self, st: _TrainState) -> list[list[tuple[int, Route]]]:
        j, step = st.pending_step()
        first = self._alternatives(st, j, step)
        if any(r.reserve_next for r in step.alternatives) and st.next + 1 < len(st.steps):
            j2 = st.steps[st.next + 1]
            second = self._alternatives(st, j2, st.path.steps[j2])
            return [[(j, a), (j2, b)] for a in first for b in second]
        return [[(j, a)] for a in first]

    def _alternatives(self, st: _TrainState, j: int, step: RouteStep) -> list[Route]:
        if step.kind != "entry" or len(step.alternatives) == 1:
            return list(step.alternatives)
        wanted = st.tracks.get(step.station)
        if wanted is not None:
            return [r for r in step.alternatives if r.track == wanted]
        return list(step.alternatives)

    def try_grant(self, st: _TrainState, t: float, standing: bool = False) -> bool:
        for choice in self._choices(st):
            routes = [r for _j, r in choice]
            if self._free(st, routes, t):
                if standing and self._yields(st, choice, t):
                    return False
                self.grant(st, choice, t)
                return True
        return False

    def _yields(self, st: _TrainState, choice: list[tuple[int, Route]], t: float) -> bool:
        """Priority rule with look-ahead: a train standing at a stop is held when, leaving now and
        running to its next stop, it would still hold a resource when a running train of higher
        priority needs it within ``lookahead_s`` (both judged from their present trajectories)."""
        if self.rule != "priority" or self.lookahead_s <= 0:
            return False
        sig = self.line.signalling
        here = (
            st.waiting_stop if st.waiting_stop is not None else st.request_point(self.approach[st.index])[1]
        )
        later = [
            s.position_m for s in st.stops if s.position_m > (here if here is not None else -np.inf) + 1e-9
        ]
        next_stop = min(later) if later else np.inf
        steps = list(choice)
        k = st.next + len(choice)
        while k < len(st.steps) and st.path.steps[st.steps[k]].start_m < next_stop:
            j = st.steps[k]
            steps.append((j, self._alternatives(st, j, st.path.steps[j])[0]))
            k += 1
        mine = {res.name for _j, r in steps for res in r.resources}
        low: dict[str, tuple[float, float]] | None = None
        for other in self.states:
            if other.done or other.svc.priority <= st.svc.priority or other.waiting_since is not None:
                continue
            ahead = [
                (j, self._alternatives(other, j, other.path.steps[j])[0]) for j in other.steps[other.next :]
            ]
            if not any(res.name in mine for _j, r in ahead for res in r.resources):
                continue
            if low is None:
                mine_bt = blocking_times(
                    st.svc.id, st.trajectory, st.path, steps, list(st.stop_positions()), sig,
                    None, self.approach[st.index],
                )  # fmt: skip
                low = {b.resource: (b.start_s, b.end_s) for b in mine_bt}
            high = blocking_times(
                other.svc.id, other.trajectory, other.path, ahead, list(other.stop_positions()), sig,
                None, self.approach[other.index],
            )  # fmt: skip
            for b in high:
                if b.resource in low and t - 1e-9 <= b.start_s <= t + self.lookahead_s:
                    start, end = low[b.resource]
                    if start <= b.start_s and end > b.start_s + TIME_TOLERANCE_S:
                        return True
        return False

    def grant(self, st: _TrainState, choice: list[tuple[int, Route]], t: float) -> None:
        sig = self.line.signalling
        # a route over a diverging switch: the train keeps to its speed (line.Route.speed_limits)
        extra = [x for _j, r in choice for x in r.speed_limits if x not in st.limits]
        if extra:
            st.limits.extend(extra)
            st.refresh_movement()
        for j, r in choice:
            for res in r.resources:
                self.holder[res.name] = st.index
            for res, point in zip(r.resources, route_release_points(r, sig.release), strict=True):
                st.held.append([res.name, point, r.name, None])
            st.granted.append((j, r))
            st.given_at[r.name] = t
        st.next += len(choice)
        if st.waiting_since is not None and self._release(st, t, choice):
            self.schedule(st)
            return
        if st.waiting_since is not None:
            depart = t + sig.setup_s + sig.reaction_s
            q = st.waiting_stop
            before = st.trajectory.last_time_at(q)
            st.override[q] = max(st.override.get(q, -np.inf), depart)
            st.refresh_trajectory()
            after = st.trajectory.last_time_at(q)
            kind = "signal" if any(s.kind == "signal" and s.position_m == q for s in st.stops) else "stop"
            where = next(s.name for s in st.stops if s.position_m == q)
            if after > before + TIME_TOLERANCE_S or kind == "signal":
                st.hindrances.append(
                    Hindrance(kind, where, q, st.waiting_since, after - before, choice[0][1].name)
                )
            st.waiting_since = None
            st.waiting_stop = None
            if st.index in self.waiting:
                self.waiting.remove(st.index)
        self.schedule(st)

    def _release(self, st: _TrainState, t: float, choice: list[tuple[int, Route]]) -> bool:
        """The signal a running train brakes for clears (route given at ``t``): the driver sees it
        ``setup_s + reaction_s`` later and, if the train has not come to a stand by then, picks up speed
        again from where it is (``release_steps``) instead of stopping. Kept when it reaches the next
        stop earlier than stopping and starting again would (a train almost at a stand, held at a
        crawl for a train length, would not). Returns whether the train was released."""
        q = st.waiting_stop
        if q not in st.approaches:
            return False
        sig = self.line.signalling
        t_clear = t + sig.setup_s
        t_seen = t_clear + sig.reaction_s
        steps, before, signal_m = st.approaches[q]
        traj = st.trajectory
        if traj.first_time_s(q) <= t_seen + TIME_TOLERANCE_S:
            return False  # it stands at the signal by then
        later = [s.position_m for s in st.stops if s.position_m > q + 1e-9]
        if not later:
            return False
        nxt = min(later)
        # released at the next point of a fixed grid (a little later: on the safe side), so that
        # identical trains released near the same place share their run
        p_c = min(float(np.ceil(position_at_time(traj, t_seen, q) / RELEASE_GRID_M) * RELEASE_GRID_M), q)
        v_c = traj.speed_at(p_c) * st.factor_at(p_c)  # the run's speed, not the disturbed one
        if v_c < MIN_CEILING_MPS:
            return False
        stops = [s for s in st.stops if not (s.kind == "signal" and s.position_m == q)]
        mine = {id(y) for y in steps}
        limits = [x for x in st.limits if id(x) not in mine]
        kept = release_steps(steps, p_c, v_c, slowed=v_c < before.speed_at(p_c) * st.factor_at(p_c) - 1e-6)
        # kept is None: cleared before the train had to slow down, it runs as if it had seen proceed
        limits_new = limits if kept is None else limits + list(kept)
        movement = st.candidate(stops, limits_new)
        if movement.status != "ok":
            return False
        old = (st.stops, st.limits, st.movement, st.trajectory)
        st.stops, st.limits, st.movement = stops, limits_new, movement
        st.refresh_trajectory()
        t_release = st.trajectory.first_time_s(nxt)
        passes = st.trajectory.first_time_s(signal_m)
        # stopping and starting again: the stand ends when the driver has seen the signal clear
        st.stops, st.limits, st.movement, st.trajectory = old
        prev = st.override.get(q)
        st.override[q] = max(st.override.get(q, -np.inf), t_seen)
        st.refresh_trajectory()
        t_stop = st.trajectory.first_time_s(nxt)
        if prev is None:
            del st.override[q]
        else:
            st.override[q] = prev
        if not (t_release < t_stop - TIME_TOLERANCE_S and passes >= t_clear - TIME_TOLERANCE_S):
            st.refresh_trajectory()
            return False
        del st.approaches[q]
        st.stops, st.limits, st.movement = stops, limits_new, movement
        st.refresh_trajectory()
        if kept is not None:
            lost = st.trajectory.first_time_s(signal_m) - before.first_time_s(signal_m)
            where = f"signal {choice[0][1].signal}"
            st.hindrances.append(
                Hindrance("slowed", where, p_c, st.waiting_since, float(lost), choice[0][1].name)
            )
        st.waiting_since = None
        st.waiting_stop = None
        if st.index in self.waiting:
            self.waiting.remove(st.index)
        return True

    def request(self, st: _TrainState, t: float) -> None:
        t_req, q, _a = st.request_point(self.approach[st.index])
        if self.try_grant(st, t, standing=q is not None):
            if q is not None and t > t_req + TIME_TOLERANCE_S:
                # asked late (after standing elsewhere): it leaves the stop once the route is set
                st.override[q] = max(
                    st.override.get(q, -np.inf),
                    t + self.line.signalling.setup_s + self.line.signalling.reaction_s,
                )
                st.refresh_trajectory()
                self.schedule(st)
            return
        # not given: wait at the stop inside the approach, or brake to a stand before the signal
        _t, q, a = st.request_point(self.approach[st.index])
        _j, step = st.pending_step()
        sig = self.line.signalling
        if q is not None:
            ahead = [x.start_m for x in st.path.steps if x.start_m > q + 1e-9]
            if ahead and step.start_m > min(ahead) + 1e-9:
                # another signal lies between the stop and this one: the train leaves and brakes later
                q = None
        if q is None:
            q = step.start_m - sig.standing_distance_m
            pos = st.stop_positions()
            near = pos[np.abs(pos - q) < 2.0]
            if near.size:
                q = float(near[0])
            else:
                name = f"signal {step.alternatives[0].signal}"
                k = int(np.searchsorted(pos, q))
                st.stops.insert(k, _Stop(name, q, "signal", 0.0, None))
                v = st.trajectory.speed_at(a)
                brake = self.approach_brake(st)
                if brake is not None and brake(v) > q - a + 1e-6:
                    st.warnings.append(
                        f"{name}: the train needs {brake(v):.0f} m to stop from {v * 3.6:.0f} km/h but sees the "
                        f"aspect only {q - a:.0f} m before (warning too late for its braking distance)"
                    )
                start = max(a, float(pos[pos < q - 1e-9].max(initial=a)))
                st.mark_signal(k, start)
                if st.ma_steps is not None:
                    # ETCS: the MA ends at this route's start; the driver brakes to its indication limit
                    steps = st.ma_steps(step.start_m, start, q)
                else:
                    v_start = st.trajectory.speed_at(start) * st.factor_at(start)  # the run's speed
                    steps = driver_braking_steps(v_start, start, q)
                st.approaches[q] = (steps, st.trajectory, step.start_m)
                st.limits.extend(steps)
                st.refresh_movement()
        st.waiting_since = t
        st.waiting_stop = q
        st.version += 1
        self.waiting.append(st.index)
        self.schedule(st)

    def approach_brake(self, st: _TrainState):
        return getattr(st, "_brake", None)

    def wake(self, t: float) -> None:
        if not self.waiting:
            return
        if self.rule == "priority":
            order = sorted(
                self.waiting, key=lambda i: (-self.states[i].svc.priority, self.states[i].waiting_since, i)
            )
        else:
            order = sorted(self.waiting, key=lambda i: (self.states[i].waiting_since, i))
        for i in order:
            st = self.states[i]
            if i in self.waiting and st.waiting_since is not None:
                # a stand at a signal cannot end before the train has arrived there: it simply
                # leaves once both are done (override keeps the later of the two)
                self.try_grant(st, t, standing=True)


def position_at_time(traj: Trajectory, t_s: float, upto_m: float) -> float:
    """Where the head is at ``t_s`` [m] (bisection on ``first_time_at``; at most ``upto_m``)."""
    lo, hi = float(traj.position_m[0]), float(upto_m)
    if traj.first_time_s(hi) <= t_s:
        return hi
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if traj.first_time_s(mid) <= t_s:
            lo = mid
        else:
            hi = mid
        if hi - lo < 1e-6:
            break
    return lo


# --------------------------------------------------------------------------- public entry


def service_braking_deceleration(
    train: Train, braking_fraction: float = 1.0
) -> Callable[[np.ndarray], np.ndarray]:
    """The train's service braking deceleration over speed, ``F_b(v) / (rho m)`` or its constant
    deceleration [m/s^2] (running resistance and gradient left out: a braking distance on the safe
    side on level track)."""
    b = train.braking
    if b.deceleration_mps2 is not None:
        d = float(b.deceleration_mps2) * braking_fraction
        return lambda v: np.full_like(np.asarray(v, dtype=float), d)
    curve = b.service_force
    m = train.inertial_mass_kg
    return lambda v: np.asarray(curve(np.asarray(v, dtype=float)), dtype=float) * braking_fraction / m


def _longest_approach_m(approach_fn, x_m: float, v_max_mps: float) -> float:
    """The longest approach distance to a signal at ``x_m`` [m], at any speed of the train."""
    longest = getattr(approach_fn, "max_m", None)
    return float(longest(x_m)) if longest is not None else float(approach_fn(v_max_mps))


def approach_function(
    line: Line,
    train: Train,
    settings: RunSettings,
    etcs: EtcsBraking | None = None,
    directed: GeometryRoute | None = None,
) -> Callable[[float], float] | None:
    """The approach distance over speed [m] of ``train`` under the line's separation: None for fixed
    block (the signals fix it), the service braking distance for moving block, the indication distance
    for ETCS Level 2 (on the gradients of ``directed``, the line as the train runs it, per EoA; level
    track without it)."""
    sig = line.signalling
    brake = braking_distance_table(
        service_braking_deceleration(train, settings.braking_fraction), train.max_speed_mps
    )
    if sig.system == "fixed_block":
        return None
    if sig.system == "moving_block":
        return brake
    return etcs_approach_distance(train, etcs, sig.overlap_m, directed)


def _check_services(line: Line, services: Sequence[TrainService]) -> None:
    from trainsim.errors import Problem

    problems = []
    ids = [s.id for s in services]
    names = {s.name for s in line.stations}
    for k, svc in enumerate(services):
        where = f"trains[{k}]"
        if ids.count(svc.id) > 1:
            problems.append(Problem("train ids must be unique", field=f"{where}.id", value=svc.id))
        for f in ("origin", "destination"):
            if getattr(svc, f) not in names:
                problems.append(
                    Problem(
                        "unknown station",
                        field=f"{where}.{f}",
                        value=getattr(svc, f),
                        allowed=", ".join(sorted(names)),
                    )
                )
        if svc.direction not in ("up", "down"):
            problems.append(
                Problem(
                    "unknown direction", field=f"{where}.direction", value=svc.direction, allowed="up, down"
                )
            )
            continue
        if svc.origin not in names or svc.destination not in names:
            continue
        path = line.paths[svc.direction]
        p0, p1 = path.stop_m[svc.origin], path.stop_m[svc.destination]
        if not p1 > p0:
            problems.append(
                Problem(
                    f"the destination does not lie ahead of the origin in the {svc.direction} direction (the route is not connected)",
                    field=f"{where}.destination",
                    value=svc.destination,
                )
            )
            continue
        last = p0
        for i, s in enumerate(svc.stops):
            if s.station not in names:
                problems.append(
                    Problem(
                        "unknown station",
                        field=f"{where}.stops[{i}].station",
                        value=s.station,
                        allowed=", ".join(sorted(names)),
                    )
                )
                continue
            p = path.stop_m[s.station]
            if not (last < p <= p1):
                problems.append(
                    Problem(
                        "stops must lie between origin and destination, in running order",
                        field=f"{where}.stops[{i}].station",
                        value=s.station,
                    )
                )
            last = p
            n = line.station(s.station).tracks
            if s.track is not None and not 1 <= s.track <= n:
                problems.append(
                    Problem(
                        "no such platform track",
                        field=f"{where}.stops[{i}].track",
                        value=s.track,
                        allowed=f"1 .. {n}",
                    )
                )
            if not (np.isfinite(s.dwell_s) and s.dwell_s >= 0):
                problems.append(
                    Problem(
                        "invalid dwell",
                        field=f"{where}.stops[{i}].dwell_s",
                        value=s.dwell_s,
                        allowed=">= 0 s",
                    )
                )
        if svc.strategy not in STRATEGIES:
            problems.append(
                Problem(
                    "unknown driving strategy",
                    field=f"{where}.strategy",
                    value=svc.strategy,
                    allowed=", ".join(STRATEGIES),
                )
            )
        elif svc.strategy != "fastest":
            at = {s.station: i for i, s in enumerate(svc.stops)}
            for name in [s.station for s in svc.stops if s.station != svc.destination] + [svc.destination]:
                i = at.get(name)
                if i is None or svc.stops[i].arrival_s is None:
                    problems.append(
                        Problem(
                            f"strategy {svc.strategy} drives each stretch in its scheduled running time: "
                            f"give the scheduled arrival at {name}"
                            + (
                                " (a stop entry for the destination: {station: ..., arrival: ...})"
                                if i is None
                                else ""
                            ),
                            field=f"{where}.stops" if i is None else f"{where}.stops[{i}].arrival",
                            value=None,
                            allowed="a time",
                        )
                    )
        n_stretches = 1 + sum(1 for s in svc.stops if s.station != svc.destination)
        extra = svc.running_extra_s
        if extra and not (len(extra) == n_stretches and all(np.isfinite(x) and x >= 0 for x in extra)):
            problems.append(
                Problem(
                    "one finite running-time disturbance >= 0 s per stretch between scheduled stops",
                    field=f"{where}.running_extra_s",
                    value=extra,
                    allowed=f"{n_stretches} values >= 0 s",
                )
            )
        if not (np.isfinite(svc.departure_s) and np.isfinite(svc.entry_delay_s) and svc.entry_delay_s >= 0):
            problems.append(
                Problem(
                    "departure and entry delay must be finite (delay >= 0)",
                    field=f"{where}.departure",
                    value=(svc.departure_s, svc.entry_delay_s),
                )
            )
        if svc.train.length_m > 0.9 * min(
            st.switch_zone_m + st.entry_signal_distance_m for st in line.stations
        ):
            problems.append(
                Problem(
                    "the train is longer than the station platforms (entry signal to stopping point plus switch zone)",
                    field=f"{where}.train",
                    value=svc.train.length_m,
                )
            )
    if problems:
        raise InputError.from_problems(problems)


def simulate(
    line: Line,
    geometry: GeometryRoute,
    services: Sequence[TrainService],
    settings: RunSettings | None = None,
    rule: Rule = "fcfs",
    conflicts: bool = True,
    headways: bool = True,
    etcs: EtcsBraking | None = None,
    lookahead_s: float = 0.0,
    cache: RunCache | None = None,
    disturbed_energy: bool = True,
) -> OperationResult:
    """Simulate ``services`` on ``line`` together in time, and compare with their planned runs.

    Args:
        line: the signalled line (``build_line``).
        geometry: the line's speed limits, gradients, curves, tunnels and electrification as a
            ``Route`` in up-direction positions covering ``0 .. line.length_m``.
        services: the trains.
        settings: run settings of every train's fastest run.
        rule: dispatching rule, ``fcfs`` or ``priority``.
        conflicts: list the conflicts of the planned timetable.
        headways: compute the minimum headway of consecutive trains of each direction.
        etcs: the trains' ETCS braking data (needed for ``etcs_l2``).
        cache: single-train runs to share with other simulations of the same line and settings.
        disturbed_energy: drive every stretch with a running-time disturbance as the capped run of
            its disturbed running time (some ten more runs per disturbed stretch): trajectory,
            blocking times and energy are that run's. False (studies of delays only): the fastest
            run's path time-scaled, said in ``trajectory_note``, with energy NaN (``energy_note``).
        lookahead_s: ``priority`` rule: a train standing at a stop is held while a train of higher
            priority will ask for the same resources within this time [s]; 0: no look-ahead.

    Signal-aware trains (``TrainService.strategy``) take their timing points from the operated
    blocking times of the trains ahead: the timetable is simulated with them driving ``optimal``, then
    again with the timing points from the simulation before, until the points settle (at most
    ``MAX_AWARE_ITERATIONS`` simulations; ``OperationResult.iterations`` says how many, a warning if
    they did not settle). Trains ahead whose own run changes (signal-aware themselves) are simulated
    again each time, so a chain of followers settles one train per simulation.
    """
    settings = settings or RunSettings()
    if cache is None or cache.settings != settings:
        cache = RunCache(settings)
    _check_inputs(line, geometry, services, rule, lookahead_s)
    fns = _approach_functions(line, geometry, services, settings, etcs, cache)
    args = (line, geometry, services, settings, rule, conflicts, headways, etcs, lookahead_s, cache, fns)
    result = _simulate_once(*args, disturbed_energy, {})
    aware = [i for i, svc in enumerate(services) if svc.strategy == "signal_aware"]
    if not aware:
        return result
    points = _aware_points(line, services, result, aware, fns)
    for n in range(2, MAX_AWARE_ITERATIONS + 1):
        result = _simulate_once(*args, disturbed_energy, points)
        result.iterations = n
        new = _aware_points(line, services, result, aware, fns)
        if _same_points(new, points):
            return result
        points = new
    result.warnings.append(
        f"the timing points of the signal-aware trains did not settle in {MAX_AWARE_ITERATIONS} simulations "
        "(each from the blocking times of the one before): the last simulation is shown"
    )
    return result


def _aware_points(
    line: Line,
    services: Sequence[TrainService],
    result: OperationResult,
    aware: list[int],
    approach_fns: list[Callable[[float], float] | None],
) -> dict[int, tuple[tuple[float, float, str], ...]]:
    """Timing points of each signal-aware train from the operated blocking times of ``result``: at
    the approach start of each of its routes, no earlier than the latest release of the route's
    resources by the trains that used them before it, plus the setup and sighting/reaction times and
    ``AWARE_MARGIN_S`` (the route is then set when the train asks for it: it sees no restrictive
    aspect). A route the train asks for while standing at a stop inside its approach gets none: the
    train waits at the stop. (running position, earliest time, name) [m, s]."""
    sig = line.signalling
    out: dict[int, tuple[tuple[float, float, str], ...]] = {}
    by_resource: dict[str, list[BlockingTime]] = {}
    for b in result.blocking:
        by_resource.setdefault(b.resource, []).append(b)
    for i in aware:
        svc, o = services[i], result.trains[i]
        if o.status != "ok" or o.trajectory is None:
            continue
        path = line.paths[svc.direction]
        fn = approach_fns[i]
        stops_m = [path.stop_m[s.station] for s in o.stops]
        points = []
        for j, route in o.routes:
            x = path.steps[j].start_m
            a = approach_start_m(path, j, sig, o.trajectory, fn)
            if a <= stops_m[0] + 1.0 or any(a - 1e-6 <= p < x for p in stops_m):
                continue
            ends = []
            for res in route.resources:
                items = by_resource.get(res.name, [])
                mine = [b.end_s for b in items if b.train == svc.id]
                if mine:
                    ends += [b.end_s for b in items if b.train != svc.id and b.end_s <= max(mine)]
            if ends:
                earliest = max(ends) + sig.setup_s + sig.reaction_s + AWARE_MARGIN_S
                points.append((float(a), float(earliest), f"approach to {route.name}"))
        out[i] = tuple(points)
    return out


def _check_inputs(
    line: Line, geometry: GeometryRoute, services: Sequence[TrainService], rule: Rule, lookahead_s: float
) -> None:
    if not (np.isfinite(lookahead_s) and 0 <= lookahead_s <= 7200):
        raise InputError(
            "invalid look-ahead", field="dispatching.lookahead_s", value=lookahead_s, allowed="0 .. 7200 s"
        )
    if rule not in ("fcfs", "priority"):
        raise InputError(
            "unknown dispatching rule", field="dispatching.rule", value=rule, allowed="fcfs, priority"
        )
    if not (abs(geometry.start_m) < 1e-6 and abs(geometry.end_m - line.length_m) < 1e-6):
        raise InputError(
            "the line's geometry must cover the whole line",
            field="line.route",
            value=(geometry.start_m, geometry.end_m),
            allowed=f"0 .. {line.length_m:g} m",
        )
    _check_services(line, services)


def _approach_functions(
    line: Line,
    geometry: GeometryRoute,
    services: Sequence[TrainService],
    settings: RunSettings,
    etcs: EtcsBraking | None,
    cache: RunCache,
) -> list[Callable[[float], float] | None]:
    """Each train's approach function (``approach_function``) on the line as it runs it, one per train
    and direction (an ETCS one tabulates each EoA once for all the trains sharing it)."""
    shared: dict[tuple[int, str], Callable[[float], float] | None] = {}
    out = []
    for svc in services:
        key = (id(svc.train), svc.direction)
        if key not in shared:
            directed = cache.directed(geometry, line.length_m, svc.direction)
            shared[key] = approach_function(line, svc.train, settings, etcs, directed)
        out.append(shared[key])
    return out


def _same_points(a: dict, b: dict) -> bool:
    if a.keys() != b.keys():
        return False
    for k in a:
        if len(a[k]) != len(b[k]):
            return False
        for p, q in zip(a[k], b[k], strict=True):
            if abs(p[0] - q[0]) > AWARE_CONVERGED_M or abs(p[1] - q[1]) > AWARE_CONVERGED_S:
                return False
    return True


def _simulate_once(
    line: Line,
    geometry: GeometryRoute,
    services: Sequence[TrainService],
    settings: RunSettings,
    rule: Rule,
    conflicts: bool,
    headways: bool,
    etcs: EtcsBraking | None,
    lookahead_s: float,
    cache: RunCache,
    approach_fns: list[Callable[[float], float] | None],
    disturbed_energy: bool,
    aware_points: dict[int, tuple[tuple[float, float, str], ...]],
) -> OperationResult:
    """One simulation of ``services`` (``simulate``), signal-aware trains with ``aware_points``."""
    directed = {d: cache.directed(geometry, line.length_m, d) for d in ("up", "down")}
    approach: dict[int, Callable | None] = {}
    states = []
    # ETCS: the supervision curves of each train type and direction on the line's gradients and speed
    # limits as that train runs them
    ma_steps: dict[tuple[int, str], Callable] = {}
    for i, svc in enumerate(services):
        ma = None
        if line.signalling.system == "etcs_l2":
            key = (id(svc.train), svc.direction)
            ma = ma_steps.get(key)
            if ma is None:
                ma = ma_steps[key] = ma_indication_steps(
                    svc.train, etcs, line.signalling.overlap_m, directed[svc.direction]
                )
        st = _TrainState(
            i, svc, line, directed[svc.direction], cache, ma, disturbed_energy, aware_points.get(i, ())
        )
        approach[i] = approach_fns[i]
        st._brake = braking_distance_table(
            service_braking_deceleration(svc.train, settings.braking_fraction), svc.train.max_speed_mps
        )
        states.append(st)
    # planned runs: each train alone, on time
    planned = [_planned(st) for st in states]
    dispatcher = _Dispatcher(line, states, rule, approach)
    dispatcher.lookahead_s = lookahead_s
    dispatcher.run()
    stuck = [st for st in states if not st.done]
    deadlock = []
    if stuck:
        for st in stuck:
            waits = ""
            if st.pending_step() is not None:
                _j, step = st.pending_step()
                # every route the train asks for together (a single-track section is requested with
                # the loop track behind it): the holder may be on the second one
                blockers = sorted(
                    {
                        f"{res.name} (held by {states[dispatcher.holder[res.name]].svc.id})"
                        for choice in dispatcher._choices(st)
                        for _k, r in choice
                        for res in r.resources
                        if res.name in dispatcher.holder and dispatcher.holder[res.name] != st.index
                    }
                )
                if not blockers:
                    blockers = ["no resource held by another train"]
                waits = f" waits for route '{step.alternatives[0].name}': " + ", ".join(blockers)
            deadlock.append(f"train {st.svc.id}{waits}")
    outcomes = []
    blocking: list[BlockingTime] = []
    warnings: list[str] = []
    sig = line.signalling
    for st, plan in zip(states, planned, strict=True):
        fn = approach[st.index]
        outcome = _outcome(st, plan, line, st in stuck)
        outcomes.append(outcome)
        if st not in stuck and st.stalled_m is None and [j for j, _r in st.granted] != st.steps:
            raise RuntimeError(f"train {st.svc.id}: ran without holding every route of its path")
        if st not in stuck:
            # the dispatcher's own times: when each route was given and each resource released (a
            # train held at its origin got its platform, and left the switches behind it, before it
            # knew when it would leave)
            blocking.extend(
                blocking_times(
                    st.svc.id, st.trajectory, st.path, st.granted, list(st.stop_positions()), sig,
                    _line_pos(line, st.svc.direction), fn, st.given_at, st.released,
                )
            )  # fmt: skip
        warnings.extend(f"train {st.svc.id}: {w}" for w in outcome.warnings)
    _check_invariants(outcomes, blocking)
    planned_blocking, conflict_list = _planned_blocking(line, states, planned, approach, conflicts)
    headway_list = _headways(states, planned_blocking) if headways else []
    status = "ok"
    if conflict_list:
        status = "conflicts"
    if stuck:
        status = "deadlock"
    if any(o.status == "stalled" for o in outcomes):
        status = "stalled"  # the trains behind it wait for good: listed under deadlock
    return OperationResult(
        status, warnings, outcomes, conflict_list, headway_list, blocking, planned_blocking,
        cache.computed, cache.hits, deadlock,
    )  # fmt: skip


def _line_pos(line: Line, direction: Direction) -> Callable[[np.ndarray], np.ndarray]:
    return lambda x: line.line_position(direction, x)


@dataclass
class _Plan:
    trajectory: Trajectory
    movement: Movement
    departures: list[float]
    energy_kwh: float


def _planned(st: _TrainState) -> _Plan:
    delay = st.svc.entry_delay_s
    st.stops[0].scheduled_departure_s -= delay
    deps = st.departures(planned=True)
    st.stops[0].scheduled_departure_s += delay
    m = st.plan_movement
    traj = m.trajectory(deps, st.length_m, st.dest_dwell_s)
    standing = _standing_s(m, deps, st.dest_dwell_s)
    energy = m.energy_kwh(standing, auxiliary_power_w(st.svc.train))
    return _Plan(traj, m, deps, energy)


def _standing_s(
    movement: Movement, deps: list[float], final_dwell_s: float, factors: Sequence[float] | None = None
) -> float:
    rt = movement.running_times_s()
    if factors is not None:
        rt = rt * np.asarray(factors)
    standing = final_dwell_s
    for k in range(1, len(deps)):
        standing += deps[k] - (deps[k - 1] + rt[k - 1])
    return standing


def _outcome(st: _TrainState, plan: _Plan, line: Line, stuck: bool) -> TrainOutcome:
    svc = st.svc
    status = "deadlocked" if stuck else ("stalled" if st.movement.status != "ok" else "ok")
    warnings = list(st.warnings)
    if st.movement.status != "ok":
        warnings.extend(st.movement.warnings)
    deps = st.departures() if not stuck else None
    traj = st.trajectory if not stuck else None
    rt = st.movement.running_times_s()
    if st.factors is not None:
        rt = rt * st.time_factors()
    sched = {s.station: s for s in svc.stops}
    plan_rt = plan.movement.running_times_s()
    plan_arr = [None] + [plan.departures[k] + plan_rt[k] for k in range(len(plan.departures))]
    stop_times = []
    station_stops = [k for k, s in enumerate(st.stops) if s.kind != "signal"]
    tracks: dict[str | None, int] = {}  # the track of the first route given into each station
    for _j, r in st.granted:
        if r.track is not None:
            tracks.setdefault(r.station, r.track)
    delay = 0.0
    for pk, k in enumerate(station_stops):
        s = st.stops[k]
        arr = None if k == 0 or deps is None else deps[k - 1] + rt[k - 1]
        dep = None if deps is None or k == len(st.stops) - 1 else deps[k]
        if st.stalled_m is not None and s.position_m > st.stalled_m + 1e-6:
            arr = dep = None  # not reached
        p_arr = plan_arr[pk]
        p_dep = plan.departures[pk] if pk < len(plan.departures) else None
        sc = sched.get(s.name)
        s_arr = sc.arrival_s if sc is not None and sc.arrival_s is not None else p_arr
        s_dep = p_dep
        if k == 0:
            s_dep = svc.departure_s
        elif sc is not None and sc.departure_s is not None:
            s_dep = sc.departure_s
        if s.kind == "destination":
            d = None if arr is None else arr - s_arr
        else:
            d = None if dep is None else dep - s_dep
        if d is not None:
            delay = d
        # an energy-efficient plan meets its schedule within the optimisation's tolerance
        tight = 1e-6 if svc.strategy == "fastest" else SCHEDULE_TOLERANCE_S
        if sc is not None and sc.arrival_s is not None and p_arr is not None and sc.arrival_s < p_arr - tight:
            warnings.append(
                f"scheduled arrival at {s.name} ({sc.arrival_s:.0f} s) is earlier than the train can make it "
                f"on time ({p_arr:.0f} s): the timetable is too tight there"
            )
        track = tracks.get(s.name)
        stop_times.append(StopTimes(s.name, s.kind, s_arr, s_dep, arr, dep, d, track))
    if stuck or st.stalled_m is not None:
        delay = np.inf
    standing = 0.0
    if deps is not None:
        standing = _standing_s(st.movement, deps, st.dest_dwell_s, st.time_factors()) + st.origin_hold_s()
    energy = st.movement.energy_kwh(standing, auxiliary_power_w(svc.train)) if deps is not None else np.nan
    note = traj_note = ""
    if deps is not None and st.factors is not None:
        energy = np.nan
        note = "operated energy not computed (running-time disturbances; asked for delays only)"
        traj_note = (
            "time-scaled: on stretches with running-time disturbances the trajectory (and the blocking "
            "times from it) is the fastest run's path with time stretched, not a run of the train"
        )
    elif st.disturbed:
        n_ok = sum(1 for d in st.disturbed if d.status in ("ok", "undisturbed"))
        note = (
            f"{len(st.disturbed)} stretch(es) with running-time disturbances driven as the fastest run "
            "under a speed cap whose running time is the disturbed one; trajectory, blocking times and "
            "energy are those runs'"
        )
        if n_ok < len(st.disturbed):
            note += f"; {len(st.disturbed) - n_ok} take longer than any capped run: see warnings"
    return TrainOutcome(
        svc.id, svc.direction, status, stop_times, float(delay), energy, plan.energy_kwh,
        st.hindrances, traj, plan.trajectory, list(st.granted), warnings, st.movement.results, note,
        traj_note, tuple(st.disturbed), svc.strategy, _driven_stretches(st),
    )  # fmt: skip


def _driven_stretches(st: _TrainState) -> tuple[DrivenStretch, ...]:
    """How each stretch between scheduled stops of an energy-efficient train was driven, with the
    running time of its runs (split at signal stops: their sum)."""
    if st.strategy == "fastest" or st.movement.status != "ok":
        return ()
    rt = st.movement.running_times_s()
    pos = [s.position_m for s in st.stops]
    names = {s.position_m: s.name for s in st.stops}
    out = []
    for a_m, (b_m, _dep, _arr) in st.schedule.items():
        found = st.driven.get(a_m)
        if found is None:
            continue
        driven, reason, target, points, late, asked = found
        k0, k1 = pos.index(a_m), pos.index(b_m)
        run_s = float(sum(rt[k0:k1]))
        out.append(DrivenStretch(names[a_m], names[b_m], driven, reason, target, run_s, points, late, asked))
    return tuple(out)


def _planned_blocking(
    line: Line, states: list[_TrainState], plans: list[_Plan], approach: dict, want_conflicts: bool
) -> tuple[list[BlockingTime], list[Conflict]]:
    """Blocking times of the planned runs (tracks: the given one, else the first one free in the plan,
    trains taken in order of departure) and their conflicts."""
    sig = line.signalling
    order = sorted(range(len(states)), key=lambda i: plans[i].departures[0])
    booked: dict[str, tuple[list[float], list[float], list[float]]] = {}
    per_train: dict[int, list[BlockingTime]] = {}
    for i in order:
        st, plan = states[i], plans[i]
        stations_stops = [s for s in st.stops if s.kind != "signal"]
        stops_m = [s.position_m for s in stations_stops]
        times: list[BlockingTime] = []
        line_pos = _line_pos(line, st.svc.direction)

        def allowed(j: int, st=st, stations_stops=stations_stops) -> list[Route]:
            step = st.path.steps[j]
            alts = list(step.alternatives)
            if step.kind == "entry" and len(alts) > 1:
                wanted = next((s.track for s in stations_stops if s.name == step.station), None)
                if wanted is not None:
                    alts = [r for r in alts if r.track == wanted] or alts
            return alts

        options = {j: allowed(j) for j in st.steps}
        # every step on its first allowed route at once; other tracks are tried where that one clashes
        first = blocking_times(
            st.svc.id, plan.trajectory, st.path, [(j, options[j][0]) for j in st.steps], stops_m, sig,
            line_pos, approach[i],
        )  # fmt: skip
        by_step: dict[int, list[BlockingTime]] = {}
        for b in first:
            by_step.setdefault(b.step, []).append(b)
        for j in st.steps:
            best = by_step.get(j, [])
            if len(options[j]) > 1 and any(
                _overlaps(booked.get(b.resource), b.start_s, b.end_s) for b in best
            ):
                for r in options[j][1:]:
                    bt = blocking_times(
                        st.svc.id, plan.trajectory, st.path, [(j, r)], stops_m, sig, line_pos, approach[i]
                    )
                    if not any(_overlaps(booked.get(b.resource), b.start_s, b.end_s) for b in bt):
                        best = bt
                        break
            for b in best:
                _book(booked, b)
            times.extend(best)
        per_train[i] = times
    planned = [b for i in range(len(states)) for b in per_train[i]]
    conflicts: list[Conflict] = []
    if want_conflicts:
        by_res: dict[str, list[BlockingTime]] = {}
        for b in planned:
            by_res.setdefault(b.resource, []).append(b)
        for res, items in by_res.items():
            items.sort(key=lambda b: b.start_s)
            active: list[BlockingTime] = []
            for b in items:
                active = [a for a in active if a.end_s > b.start_s + TIME_TOLERANCE_S]
                for a in active:
                    if a.train != b.train:
                        overlap = min(a.end_s, b.end_s) - b.start_s
                        conflicts.append(Conflict(a.train, b.train, b.route, res, b.start_s, overlap))
                active.append(b)
        conflicts.sort(key=lambda c: (c.time_s, c.first, c.second))
    return planned, conflicts


def _headways(states: list[_TrainState], planned: list[BlockingTime]) -> list[Headway]:
    by_train: dict[str, list[BlockingTime]] = {}
    for b in planned:
        by_train.setdefault(b.train, []).append(b)
    out = []
    for direction in ("up", "down"):
        trains = sorted(
            (st for st in states if st.svc.direction == direction),
            key=lambda st: (st.svc.departure_s, st.index),
        )
        for a, b in pairwise(trains):
            lead, follow = by_train.get(a.svc.id, []), by_train.get(b.svc.id, [])
            # where the follower overtakes (passing tracks) the order is reversed: the pair's headway
            # is that of the resources on which the leader runs ahead in the plan
            ahead = {x.resource: x.start_s for x in lead}
            follow = [x for x in follow if x.resource in ahead and x.start_s >= ahead[x.resource]]
            h = minimum_headway(a.svc.id, lead, a.svc.departure_s, b.svc.id, follow, b.svc.departure_s)
            if h is not None:
                out.append(h)
    return out


def _check_invariants(outcomes: list[TrainOutcome], blocking: list[BlockingTime]) -> None:
    """Every operated trajectory is finite with v >= 0 and non-decreasing time and position, and no
    resource is claimed by two trains at once (the dispatcher's promise). A failure is a bug."""
    for o in outcomes:
        tr = o.trajectory
        if tr is None:
            continue
        arrays = (tr.time_s, tr.position_m, tr.speed_mps)
        if not all(np.all(np.isfinite(a)) for a in arrays):
            raise RuntimeError(f"train {o.id}: non-finite values in the operated trajectory")
        if (
            np.any(tr.speed_mps < -1e-9)
            or np.any(np.diff(tr.time_s) < -1e-9)
            or np.any(np.diff(tr.position_m) < -1e-9)
        ):
            raise RuntimeError(f"train {o.id}: negative speed or time or position going back")
    by_res: dict[str, list[BlockingTime]] = {}
    for b in blocking:
        by_res.setdefault(b.resource, []).append(b)
    for res, items in by_res.items():
        items.sort(key=lambda b: b.start_s)
        last_end, last_train = -np.inf, None
        for b in items:
            if b.train != last_train and b.start_s < last_end - INVARIANT_TOLERANCE_S:
                raise RuntimeError(
                    f"resource {res}: trains {last_train} and {b.train} overlap by {last_end - b.start_s:.3f} s in operation"
                )
            if b.end_s > last_end:
                last_end, last_train = b.end_s, b.train


def _book(booked: dict, b: BlockingTime) -> None:
    """Keep a resource's planned blocking times sorted by start, with the longest one's duration."""
    starts, ends, longest = booked.setdefault(b.resource, ([], [], [0.0]))
    k = bisect_right(starts, b.start_s)
    starts.insert(k, b.start_s)
    ends.insert(k, b.end_s)
    longest[0] = max(longest[0], b.end_s - b.start_s)


def _overlaps(entry: tuple | None, start: float, end: float) -> bool:
    """Whether ``[start, end]`` overlaps a booked blocking time (only those that can are looked at)."""
    if entry is None:
        return False
    starts, ends, longest = entry
    k = bisect_left(starts, end - TIME_TOLERANCE_S)
    while k > 0 and starts[k - 1] >= start - longest[0] - 1.0:
        k -= 1
        if ends[k] > start + TIME_TOLERANCE_S:
            return True
    return False
