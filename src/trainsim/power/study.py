"""Trains of a timetable on a power network, with voltage-limited traction fed back into their runs.

A :class:`TrainService` is one train (a :class:`~trainsim.model.scenario.Scenario`: train, route,
settings, driving strategy) placed on a network track with its departure times. :func:`run_study`
runs each scenario once (fastest, or the scenario's energy-efficient strategy), places every
departure on the network and solves it over time (:func:`trainsim.power.simulation.simulate`).

Feedback: where the line voltage limits traction (EN 50388 reduction below ``traction_full_v``),
a train gets less power than its run assumed, and would run slower. trainsim's single-train core
cannot (yet) take a time-varying power cap, so each affected departure is re-simulated with one
constant cap on its traction power at the wheel (``EffortCurve.capped``): the least electrical
power the line delivered to it at a limited step, times its traction efficiency (lowered again
at each iteration where it is still limited). The network is solved again, until every departure
gets at least ``1 - tolerance`` of the traction energy it asks (or ``max_iterations`` is reached).
The time lost is the running time of the capped run minus the nominal one. One cap for the whole
run is conservative: the train is also held back where the voltage would have allowed more.

Status (:func:`with_status`, :data:`STATUSES`): a study that ran, but whose trains, substations or
solution are not what was asked, says so in ``summary()["status"]`` (the most severe condition) and
``summary()["statuses"]`` (every one), so that ``trainsim power`` exits with 3 (docs/POWER.md,
"Status"). Regenerated energy burnt on board because the line could not take it is reported
(``regen_kwh``, a warning) but is no status: the train still brakes as asked.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from itertools import pairwise
from typing import Any

import numpy as np

from trainsim.constants import KWH
from trainsim.errors import InputError
from trainsim.model.route import ElectrificationSection, Route
from trainsim.model.scenario import Scenario
from trainsim.model.spans import electrification_cover, split_spans
from trainsim.model.train import Train
from trainsim.power.network import Network
from trainsim.power.onboard import OnboardStorage
from trainsim.power.simulation import (
    CompactPowerResult,
    PowerResult,
    TrainLoad,
    simulate,
    train_load_from_run,
)
from trainsim.power.stretches import JoinedRun, joined_run, stop_positions
from trainsim.power.traction_share import SHARE_FLOOR, ShareProfile, route_with_share, step_spans
from trainsim.sim.result import RunResult

__all__ = [
    "STATUSES",
    "TIME_LOST_TOLERANCE_S",
    "FeedbackSettings",
    "TrainService",
    "route_with_neutral_sections",
    "run_study",
    "with_neutral_sections",
    "with_status",
]

#: What a power study's ``status`` can say, the most severe first: anything but ``ok`` means "ran,
#: but not as asked" (exit code 3). Every condition found is listed in ``statuses``; ``status`` is
#: the first of them in this order (a solution that did not converge makes every other figure
#: doubtful, so it leads).
STATUSES: dict[str, str] = {
    "not_converged": "the network solution did not converge at some time steps",
    "voltage_out_of_limits": "a pantograph voltage left Umin2 .. Umax2 (EN 50163)",
    "feedback_not_converged": "the runs fed back with voltage-limited traction did not become consistent "
    "with the network within max_iterations",
    "substation_overloaded": "a substation delivered more than its admissible overload power",
    "traction_limited": "the line voltage limited traction and the limitation was not fed back into the runs "
    "(feedback disabled, or operated trains): their running times do not show it",
    "time_lost": "a train lost running time to voltage-limited traction (more than TIME_LOST_TOLERANCE_S)",
    "ok": "every train got the traction it asked or ran its timetable, within every limit",
}

#: A departure whose running time grows by more than this under voltage-limited traction has lost
#: time [s]. Half a second: timetables are kept to the second, so a smaller loss does not move any
#: timetabled time when rounded.
TIME_LOST_TOLERANCE_S = 0.5

#: A route's own section without traction and a network's neutral section agree when their ends differ
#: by at most this [m]: the network's node resolution (trainsim.power.solver.POSITION_RESOLUTION_M).
NEUTRAL_SECTION_TOLERANCE_M = 0.1

#: Relative tolerance of the energy sums below which a shortfall or a curtailment is rounding [-]
#: (the same as the energy balance's, docs/POWER.md).
_ENERGY_RTOL = 1e-6


@dataclass(frozen=True)
class TrainService:
    """One train of the timetable: what runs, where on the network and when.

    Attributes:
        id: name (departures are named ``id``, or ``id#k`` when there are several).
        scenario: the train, its route, settings and driving strategy.
        track: network track it runs on.
        origin_m: chainage of the route's start on the network [m].
        direction: 1 if the route's positions increase with the chainage, -1 otherwise.
        departures_s: departure times from the route's first stop [s].
        onboard_storage: the train's on-board storage (each departure starts at its initial
            state of charge), or None.
    """

    id: str
    scenario: Scenario
    track: str
    origin_m: float
    direction: int
    departures_s: tuple[float, ...]
    onboard_storage: OnboardStorage | None = None


@dataclass(frozen=True)
class FeedbackSettings:
    """Voltage-limited traction fed back into the runs.

    Attributes:
        enabled: re-simulate trains whose traction the line limits.
        max_iterations: network solutions at most (the first one included).
        tolerance: a departure is consistent when it gets at least 1 - tolerance of the traction
            energy it asks [-].
        method: ``per_step`` (the share of traction the line gave at each limited time step,
            laid over the positions the train covered in that step, see
            :mod:`trainsim.power.traction_share`; any strategy), ``per_stretch`` (a cap per
            stretch between two stops, where the line limited that stretch; fastest runs only,
            others fall back to ``constant``) or ``constant`` (one cap for the whole run).
        knock_on: the timetable says a train may not depart before the previous departure of the
            same train (service) has made up its delay: each later departure of a service is
            shifted by the previous one's shift plus its time lost, less ``buffer_s``. False (the
            default): departures keep their times and the time lost is only reported.
        buffer_s: recovery time the timetable holds between two departures of a service [s].
    """

    enabled: bool = True
    max_iterations: int = 10
    tolerance: float = 1e-3
    method: str = "per_stretch"
    knock_on: bool = False
    buffer_s: float = 0.0

    def __post_init__(self) -> None:
        if not 1 <= self.max_iterations <= 50:
            raise InputError(
                "invalid number of iterations",
                field="simulation.feedback.max_iterations",
                value=self.max_iterations,
                allowed="1 .. 50",
            )
        if self.method not in ("per_step", "per_stretch", "constant"):
            raise InputError("unknown feedback method", field="simulation.feedback.method", value=self.method,
                             allowed="per_step, per_stretch, constant")  # fmt: skip
        if not (np.isfinite(self.buffer_s) and self.buffer_s >= 0):
            raise InputError("invalid buffer time", field="simulation.feedback.buffer_s", value=self.buffer_s,
                             allowed=">= 0 s")  # fmt: skip
        if not 0 < self.tolerance < 0.5:
            raise InputError(
                "invalid tolerance",
                field="simulation.feedback.tolerance",
                value=self.tolerance,
                allowed="0 < x < 0.5",
            )


def _run(scenario: Scenario, power_cap_w: float) -> RunResult:
    """The scenario's run with its traction power at the wheel capped (fastest or its strategy)."""
    train = scenario.train
    if np.isfinite(power_cap_w):
        train = dataclasses.replace(train, traction=train.traction.capped(power_cap_w=power_cap_w))
    if scenario.strategy != "fastest":
        from trainsim.optimize.api import optimize

        return optimize(train, scenario.route, scenario.timetable, scenario.strategy, scenario.settings).run
    from trainsim.sim.fastest import run_fastest

    return run_fastest(train, scenario.route, scenario.settings)


def _efficiency(service: TrainService) -> float:
    el = service.scenario.train.electrical
    return 1.0 if el is None else el.traction_efficiency


def _load(service: TrainService, run: RunResult, name: str, departure_s: float) -> TrainLoad:
    el = service.scenario.train.electrical
    if el is None:
        raise InputError(
            "the train has no electrical data (electrical: line_voltage_v, efficiencies, auxiliaries)",
            field=f"trains[{service.id}].train",
            value=service.scenario.train.name,
            allowed="a train with an electrical block",
        )
    load = train_load_from_run(
        run,
        id=name,
        track=service.track,
        departure_s=departure_s,
        origin_m=service.origin_m,
        direction=service.direction,
        traction_efficiency=el.traction_efficiency,
        regenerative_efficiency=el.regenerative_efficiency,
        auxiliary_power_w=el.auxiliary_power_w,
        power_factor=el.power_factor,
    )
    return (
        load
        if service.onboard_storage is None
        else dataclasses.replace(load, onboard_storage=service.onboard_storage)
    )


def _uncovered_m(lo_m: float, hi_m: float, spans: list[tuple[float, float]]) -> float:
    """Length of ``[lo_m, hi_m]`` that none of ``spans`` covers [m]."""
    length, pos = 0.0, lo_m
    for a, b in sorted(spans):
        if b <= pos:
            continue
        if a >= hi_m:
            break
        length += max(0.0, a - pos)
        pos = max(pos, b)
    return length + max(0.0, hi_m - pos)


def route_with_neutral_sections(
    route: Route, train: Train, network: Network, track: str, origin_m: float, direction: int
) -> tuple[Route, list[dict[str, Any]]]:
    """``route`` with the network's neutral sections on ``track`` as sections without traction.

    The network cuts the contact line at a gap of some length (a neutral or dead section): a train
    there gets no supply, so its run must coast through it, as it does through a section of its
    route with ``voltage_v`` 0. The route is placed on the network with its start at chainage
    ``origin_m`` [m], running towards increasing (``direction`` 1) or decreasing (-1) chainage.
    Each neutral section that overlaps the route is laid over it as an
    :class:`~trainsim.model.route.ElectrificationSection` of voltage 0 (the rest of the route's
    electrification kept, parts it leaves uncovered at the train's nominal line voltage, as the core
    assumes); the route's own sections without traction stay: the train coasts through the union.
    Section insulators (gaps of length 0) cut the line but no train's supply: they change nothing.

    Returns the route (``route`` itself when every neutral section is already in it) and one record
    per section without traction for the study's ``neutral_sections`` block: ``gap`` (the network
    gap's id, None for a section of the route alone), ``track``, ``start_km`` and ``end_km``
    (chainage), ``in_network``, ``in_route`` (the route's own sections cover it, within
    :data:`NEUTRAL_SECTION_TOLERANCE_M`) and ``route_has_own`` (the route has sections without
    traction of its own). Where the route has some, a record with ``in_network`` and ``in_route`` not
    both true is a disagreement between the route and the network (:func:`with_status` warns of it);
    a route electrified throughout simply takes the network's.
    """
    tol = NEUTRAL_SECTION_TOLERANCE_M

    def to_route(x0: float, x1: float) -> tuple[float, float]:
        s0, s1 = (route.start_m + direction * (x - origin_m) for x in (x0, x1))
        return max(min(s0, s1), route.start_m), min(max(s0, s1), route.end_m)

    def to_chainage(s: float) -> float:
        return origin_m + direction * (s - route.start_m)

    gaps = []
    for g in network.gaps:
        if g.track != track or g.end_m <= g.start_m:
            continue
        lo, hi = to_route(g.start_m, g.end_m)
        if hi > lo:
            gaps.append((g, lo, hi))
    dead = [(e.start_m, e.end_m) for e in route.electrification if e.voltage_v == 0]
    records: list[dict[str, Any]] = []
    for g, lo, hi in gaps:
        a, b = sorted((to_chainage(lo), to_chainage(hi)))
        in_route = _uncovered_m(lo, hi, dead) <= tol
        records.append({"gap": g.id, "track": track, "start_km": a / 1000, "end_km": b / 1000,
                        "in_network": True, "in_route": in_route})  # fmt: skip
    spans = [(lo, hi) for _, lo, hi in gaps]
    for lo, hi in dead:
        lo, hi = max(lo, route.start_m), min(hi, route.end_m)
        if hi > lo and _uncovered_m(lo, hi, spans) > tol:
            a, b = sorted((to_chainage(lo), to_chainage(hi)))
            records.append({"gap": None, "track": track, "start_km": a / 1000, "end_km": b / 1000,
                            "in_network": False, "in_route": True})  # fmt: skip
    for r in records:
        r["route_has_own"] = bool(dead)
    if all(r["in_route"] for r in records):
        return route, records
    nominal = train.electrical.line_voltage_v if train.electrical else 0.0
    pieces = split_spans(electrification_cover(route, nominal), np.array([x for sp in spans for x in sp]))
    sections: list[ElectrificationSection] = []
    for e in pieces:
        mid = 0.5 * (e.start_m + e.end_m)
        inside = any(lo <= mid < hi for lo, hi in spans)
        sections.append(dataclasses.replace(e, voltage_v=0.0, traction_share=1.0) if inside else e)
    return dataclasses.replace(route, electrification=tuple(sections)), records


def with_neutral_sections(
    network: Network, services: list[TrainService]
) -> tuple[list[TrainService], list[dict[str, Any]]]:
    """Every service with the network's neutral sections laid over its route
    (:func:`route_with_neutral_sections`), and the records of the sections, each with its ``train``
    (the study's ``neutral_sections`` block). Any path that makes the services' runs itself (not
    through :func:`run_study`) calls it first, so that its trains coast through the sections too."""
    out, records = [], []
    for s in services:
        sc = s.scenario
        route, found = route_with_neutral_sections(
            sc.route, sc.train, network, s.track, s.origin_m, s.direction
        )
        records.extend({"train": s.id, **r} for r in found)
        out.append(
            s if route is sc.route else dataclasses.replace(s, scenario=dataclasses.replace(sc, route=route))
        )
    return out, records


def run_study(
    network: Network,
    services: list[TrainService],
    *,
    dt_s: float = 1.0,
    start_s: float | None = None,
    end_s: float | None = None,
    feedback: FeedbackSettings | None = None,
    traces: str = "full",
) -> PowerResult:
    """Run every service, solve the network over time, feed limited traction back (see module doc).

    The result's summary has per train ``running_time_s``, ``traction_power_cap_kw`` (null when not
    capped), ``time_lost_s`` and a ``feedback`` block (iterations, consistent).
    ``traces``: how each network solution keeps the trains' series
    (:func:`~trainsim.power.simulation.simulate`): ``full`` (time x train arrays) or ``on_network``
    (a :class:`CompactPowerResult`, for a whole day, :mod:`trainsim.power.day`). The feedback reads
    every train's series through ``result.train_series``, so both give the same caps, iterations and
    time lost (the sums over a train's steps to rounding: NaN padding and summation order differ).
    """
    feedback = feedback or FeedbackSettings()
    if not services:
        raise InputError("no trains", field="trains", allowed="one or more trains")
    # before any run: a train must coast through the network's neutral sections, where it gets no supply
    services, neutral = with_neutral_sections(network, services)
    runs: dict[tuple, RunResult | JoinedRun] = {}
    per_stretch = [feedback.method == "per_stretch" and s.scenario.strategy == "fastest" for s in services]
    stops = [stop_positions(s.scenario.route) for s in services]

    def run_of(k: int, cap: np.ndarray | float | ShareProfile) -> RunResult | JoinedRun:
        if isinstance(cap, ShareProfile):
            return shared_run(k, cap)
        caps_k = np.atleast_1d(np.asarray(cap, dtype=float))
        key = (k, tuple(round(c, 3) if np.isfinite(c) else np.inf for c in caps_k))
        if key not in runs:
            if per_stretch[k] and len(caps_k) > 1 and np.isfinite(caps_k).any():
                sc = services[k].scenario
                run = joined_run(sc.train, sc.route, sc.settings, np.array(key[1]))
            else:
                run = _run(services[k].scenario, float(np.min(caps_k)))
            if run.status != "ok":
                raise InputError(
                    f"the run of train {services[k].id} is not possible: " + "; ".join(run.warnings),
                    field=f"trains[{k}]",
                    value=services[k].id,
                )
            runs[key] = run
        return runs[key]

    def shared_run(k: int, profile: ShareProfile) -> RunResult:
        key = (k, "share", profile.key())
        if key not in runs:
            sc = services[k].scenario
            shared = dataclasses.replace(sc, route=route_with_share(sc.route, sc.train, profile))
            run = _run(shared, np.inf)
            if run.status != "ok":
                raise InputError(
                    f"the run of train {services[k].id} under the line's traction limitation is not possible: "
                    + "; ".join(run.warnings),
                    field=f"trains[{k}]",
                    value=services[k].id,
                )
            runs[key] = run
        return runs[key]  # type: ignore[return-value]

    departures = [
        (k, f"{s.id}#{j}" if len(s.departures_s) > 1 else s.id, dep)
        for k, s in enumerate(services)
        for j, dep in enumerate(s.departures_s)
    ]
    per_step = feedback.method == "per_step"
    caps: list = [
        ShareProfile.full(services[k].scenario.route.start_m, services[k].scenario.route.end_m)
        if per_step
        else np.full(len(stops[k]) - 1 if per_stretch[k] else 1, np.inf)
        for k, _, _ in departures
    ]
    shift = np.zeros(len(departures))

    def time_lost(i: int) -> tuple[float, float]:
        """(running time, nominal running time) of departure i with its caps [s]: the nominal the
        same way (joined stretches or the whole run), so that no cap means no loss."""
        k = departures[i][0]
        actual = run_of(k, caps[i])
        if isinstance(caps[i], ShareProfile):
            nominal = run_of(k, ShareProfile.full(caps[i].x_m[0], caps[i].x_m[-1]))
        elif isinstance(actual, JoinedRun):
            sc = services[k].scenario
            nominal = joined_run(sc.train, sc.route, sc.settings, np.full(len(caps[i]), np.inf))
        else:
            nominal = run_of(k, np.inf)
        return actual.running_time_s, nominal.running_time_s

    def knock_on() -> np.ndarray:
        out = np.zeros(len(departures))
        for k in range(len(services)):
            mine = sorted((dep, i) for i, (kk, _, dep) in enumerate(departures) if kk == k)
            for (_, prev), (_, nxt) in pairwise(mine):
                actual, nominal = time_lost(prev)
                out[nxt] = max(0.0, out[prev] + actual - nominal - feedback.buffer_s)
        return out

    efficiency = np.array([_efficiency(services[k]) for k, _, _ in departures])
    iterations = 0
    result: PowerResult | None = None
    consistent = False
    while True:
        iterations += 1
        loads = [
            _load(services[k], run_of(k, caps[i]), name, dep + shift[i])
            for i, (k, name, dep) in enumerate(departures)
        ]
        if per_step:
            # the network is asked what each train would draw at full supply, and applies the limitation
            loads = [_full_demand(load, run_of(k, caps[i]), caps[i]) for load, (i, (k, _, _)) in
                     zip(loads, enumerate(departures), strict=True)]  # fmt: skip
        result = simulate(network, loads, dt_s=dt_s, start_s=start_s, end_s=end_s, traces=traces)
        if isinstance(result, CompactPowerResult):
            asked = np.array(
                [np.nansum(result.train_series(result.traction_demand_w, i)) for i in range(len(loads))]
            )
            got = np.array(
                [np.nansum(result.train_series(result.traction_delivered_w, i)) for i in range(len(loads))]
            )
        else:
            # kept as it was (one reduction over the time axis): full-trace figures stay bit for bit
            asked = np.nansum(result.traction_demand_w, axis=0)
            got = np.nansum(result.traction_delivered_w, axis=0)
        if per_step:
            # consistent: the network gives each train the traction its run used (the run's share of the
            # full demand), step by step summed over the run
            used = np.array([np.nansum(_run_share(result, i, services[k], caps[i])
                                       * result.train_series(result.traction_demand_w, i))
                             for i, (k, _, _) in enumerate(departures)])  # fmt: skip
            mismatch = np.abs(got - used) / np.maximum(used, 1e-30)
            limited = mismatch > feedback.tolerance
        else:
            ratio = np.where(asked > 0, got / np.where(asked > 0, asked, 1.0), 1.0)
            mismatch = 1.0 - ratio
            limited = ratio < 1.0 - feedback.tolerance
        settled = not feedback.knock_on or bool(np.allclose(knock_on(), shift, rtol=0.0, atol=1e-6))
        consistent = not limited.any() and settled
        if consistent or not feedback.enabled or iterations >= feedback.max_iterations:
            break
        for i in np.flatnonzero(limited):
            if per_step:
                caps[i] = _measured_share(result, i, services[departures[i][0]], caps[i])
                continue
            k = departures[i][0]
            svc = services[k]
            delivered_i = result.train_series(result.traction_delivered_w, i)
            short = delivered_i < result.train_series(result.traction_demand_w, i) * (
                1.0 - feedback.tolerance
            )
            # the stretch of each limited step: back from chainage to the route's own position
            s_route = svc.scenario.route.start_m + svc.direction * (
                result.train_series(result.train_position_m, i)[short] - svc.origin_m
            )
            stretch = np.clip(np.searchsorted(stops[k], s_route, side="right") - 1, 0, len(caps[i]) - 1)
            delivered = delivered_i[short]
            for j in np.unique(stretch) if len(caps[i]) > 1 else [0]:
                mine = delivered[stretch == j] if len(caps[i]) > 1 else delivered
                caps[i][j] = min(caps[i][j], float(np.min(mine)) * efficiency[i])
        if feedback.knock_on:
            shift = knock_on()
    trains: list[dict[str, Any]] = []
    for i, (_, name, _) in enumerate(departures):
        actual, nominal = time_lost(i)
        if isinstance(caps[i], ShareProfile):
            trains.append(_share_summary(name, actual, nominal, caps[i], float(shift[i])))
            trains[-1]["traction_used_kwh"] = float(used[i]) * result.dt_s / KWH
            continue
        finite = np.isfinite(caps[i])
        trains.append(
            {
                "id": name,
                "running_time_s": actual,
                "nominal_running_time_s": nominal,
                "time_lost_s": actual - nominal,
                "traction_power_cap_kw": float(np.min(caps[i])) / 1e3 if finite.any() else None,
                "departure_delay_s": float(shift[i]),
                "traction_power_caps_kw": [float(c) / 1e3 if np.isfinite(c) else None for c in caps[i]]
                if len(caps[i]) > 1
                else None,
            }
        )
    extra = {
        "trains": trains,
        "neutral_sections": neutral,
        "feedback": {
            "enabled": feedback.enabled,
            "iterations": iterations,
            "consistent": bool(consistent),
            "mismatch": float(np.max(mismatch, initial=0.0)),
            "knock_on": feedback.knock_on,
            "buffer_s": feedback.buffer_s,
            "method": (
                "the share of traction the line gave at each limited step, over the positions the train "
                "covered in that step (a share of tractive effort along the route)"
                if per_step
                else "a cap on the traction power at the wheel per stretch between two stops: the least power "
                "delivered at a limited step of that stretch"
                if feedback.method == "per_stretch"
                else "constant cap on the traction power at the wheel: least power delivered at a limited step"
            ),
        },
    }
    return with_status(dataclasses.replace(result, extra=extra))


def with_status(result: PowerResult) -> PowerResult:
    """The result with the study's status (see :data:`STATUSES`) in its summary.

    ``status``, ``statuses`` (every condition found, most severe first, empty when ok) and
    ``warnings`` (the simulation's, then the study's: time lost, traction not fed back, regenerated
    energy curtailed) go into ``result.extra``, which :meth:`PowerResult.summary` lays over its own
    figures; each train of ``extra["trains"]`` gets ``status`` (``ok`` or ``time_lost``). The
    conditions are recomputed from the result, not read from ``PowerResult.problems()``, which
    names only one, so none is hidden behind a more severe one. Calling it twice gives the same.
    """
    lim = result.network.limits
    _, warnings = result.problems()
    found: set[str] = set()
    if not np.all(result.converged):
        found.add("not_converged")
    v = result.train_voltage_v
    # the same bounds as PowerResult.problems()
    if np.any(np.isfinite(v)) and (np.nanmin(v) < lim.min2_v - 1e-6 or np.nanmax(v) > lim.max2_v + 1e-6):
        found.add("voltage_out_of_limits")
    fb = result.extra.get("feedback") or {}
    if fb.get("enabled") and not fb.get("consistent"):
        found.add("feedback_not_converged")
    events = [e for si in range(len(result.network.substations)) for e in result.overload_events(si)]
    if any(e["beyond_overload"] for e in events):
        found.add("substation_overloaded")
    dt = result.dt_s
    asked = float(np.nansum(result.traction_demand_w)) * dt
    shortfall = asked - float(np.nansum(result.traction_delivered_w)) * dt
    if not fb.get("enabled") and shortfall > _ENERGY_RTOL * max(asked, 1.0):
        found.add("traction_limited")
        warnings.append(
            "the limited traction was not fed back into the runs (feedback disabled or operated trains): "
            "their running times assume full traction"
        )
    trains = [dict(t) for t in result.extra.get("trains", [])]
    for t in trains:
        lost = t.get("time_lost_s", 0.0)
        # None: an operated train that no longer reached its destination under its traction cap
        t["status"] = "time_lost" if lost is None or lost > TIME_LOST_TOLERANCE_S else "ok"
    late = [t for t in trains if t["status"] == "time_lost"]
    if late:
        found.add("time_lost")
        known = [t for t in late if t["time_lost_s"] is not None]
        if known:
            worst = max(known, key=lambda t: t["time_lost_s"])
            total = sum(t["time_lost_s"] for t in known)
            warnings.append(
                f"{len(known)} of {len(trains)} departures lost time to voltage-limited traction: {total:.1f} s "
                f"in all, {worst['time_lost_s']:.1f} s at most ({worst['id']})"
            )
        unfinished = [t["id"] for t in late if t["time_lost_s"] is None]
        if unfinished:
            warnings.append(
                f"{len(unfinished)} operated train(s) did not reach their destination with the traction the "
                "line allowed (their own cap, or held behind a train that stalled; feedback.unfinished says "
                "which): " + ", ".join(unfinished)
            )
    offered = float(np.nansum(result.regen_offered_w)) * dt
    curtailed = offered - float(np.nansum(result.regen_accepted_w)) * dt
    if curtailed > _ENERGY_RTOL * max(offered, 1.0):
        # informational: the train brakes as asked, the resistors or the friction brakes take the rest
        warnings.append(
            f"regenerative braking curtailed by the line voltage: {curtailed / KWH:.2f} of "
            f"{offered / KWH:.2f} kWh offered not taken by the line (stored on board or dissipated)"
        )
    for r in result.extra.get("neutral_sections", []):
        if not r["route_has_own"]:
            continue  # a route electrified throughout takes the network's neutral sections as they are
        where = f"{r['start_km']:g} .. {r['end_km']:g} km of track {r['track']}"
        if not r["in_route"]:
            warnings.append(
                f"train {r['train']}: the network's neutral section {r['gap']} ({where}) is not a section without "
                "traction of its route: applied to its run, which coasts through it"
            )
        elif not r["in_network"]:
            warnings.append(
                f"train {r['train']}: its route has no traction at {where}, where the network's contact line is "
                "live: the run coasts there as its route says"
            )
    statuses = [s for s in STATUSES if s in found]
    extra = {**result.extra, "status": statuses[0] if statuses else "ok", "statuses": statuses}
    extra["warnings"] = warnings
    if trains:
        extra["trains"] = trains
    return dataclasses.replace(result, extra=extra)


def _route_positions(result: PowerResult, i: int, service: TrainService) -> tuple[np.ndarray, np.ndarray]:
    """(indices of departure ``i``'s series where it is on the network, its route positions there [m]):
    chainage back to the route's own position. The indices are into ``result.train_series(.., i)``:
    time steps of a full result, the train's own steps of a compact one."""
    position = result.train_series(result.train_position_m, i)
    on = np.flatnonzero(np.isfinite(position))
    route = service.scenario.route
    return on, route.start_m + service.direction * (position[on] - service.origin_m)


def _run_share(result: PowerResult, i: int, service: TrainService, profile: ShareProfile) -> np.ndarray:
    """The share of tractive effort departure ``i``'s run had at each step of its series (NaN off the
    network)."""
    out = np.full(len(result.train_series(result.train_position_m, i)), np.nan)
    on, s_route = _route_positions(result, i, service)
    out[on] = profile.at(s_route)
    return out


def _full_demand(load: TrainLoad, run: RunResult, profile: ShareProfile) -> TrainLoad:
    """The load of a run made under ``profile`` with the traction power it would ask at full supply:
    the run's traction power over its share at each point (a share below SHARE_FLOOR counts as that,
    so that a train held at nothing still shows what it asks)."""
    if not profile.limited:
        return load
    share = np.maximum(profile.at(run.trace.position_m), SHARE_FLOOR)
    return dataclasses.replace(load, traction_power_w=load.traction_power_w / share)


def _measured_share(
    result: PowerResult, i: int, service: TrainService, profile: ShareProfile
) -> ShareProfile:
    """Departure ``i``'s share of tractive effort as the network gave it: at each step where it asked
    for traction, delivered / asked (the EN 50388 limitation at its pantograph voltage) over the
    stretch of line that step stands for; 1 elsewhere (see :mod:`trainsim.power.traction_share`)."""
    on, s_route = _route_positions(result, i, service)
    lo, hi = step_spans(s_route)
    asked = result.train_series(result.traction_demand_w, i)[on]
    hit = asked > 0.0
    share = result.train_series(result.traction_delivered_w, i)[on[hit]] / asked[hit]
    full = ShareProfile.full(profile.x_m[0], profile.x_m[-1])
    return full.lowered(lo[hit], hi[hit], np.clip(share, SHARE_FLOOR, 1.0))


def _share_summary(
    name: str, actual_s: float, nominal_s: float, profile: ShareProfile, delay_s: float
) -> dict[str, Any]:
    """A departure's summary under per-step feedback: running times, the least share of tractive
    effort the line allowed and the length of line where it was limited."""
    limited = profile.share < 1.0
    return {
        "id": name,
        "running_time_s": actual_s,
        "nominal_running_time_s": nominal_s,
        "time_lost_s": actual_s - nominal_s,
        "traction_power_cap_kw": None,
        "departure_delay_s": delay_s,
        "traction_power_caps_kw": None,
        "traction_share_min": float(np.min(profile.share)),
        "traction_limited_length_m": float(np.sum(np.diff(profile.x_m)[limited])),
    }
