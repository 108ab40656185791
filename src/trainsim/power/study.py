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
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np

from trainsim.errors import InputError
from trainsim.model.scenario import Scenario
from trainsim.power.network import Network
from trainsim.power.onboard import OnboardStorage
from trainsim.power.simulation import PowerResult, TrainLoad, simulate, train_load_from_run
from trainsim.sim.result import RunResult

__all__ = ["FeedbackSettings", "TrainService", "run_study"]


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
    """

    enabled: bool = True
    max_iterations: int = 10
    tolerance: float = 1e-3

    def __post_init__(self) -> None:
        if not 1 <= self.max_iterations <= 50:
            raise InputError(
                "invalid number of iterations",
                field="simulation.feedback.max_iterations",
                value=self.max_iterations,
                allowed="1 .. 50",
            )
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
    return load if service.onboard_storage is None else dataclasses.replace(
        load, onboard_storage=service.onboard_storage
    )


def run_study(
    network: Network,
    services: list[TrainService],
    *,
    dt_s: float = 1.0,
    start_s: float | None = None,
    end_s: float | None = None,
    feedback: FeedbackSettings | None = None,
) -> PowerResult:
    """Run every service, solve the network over time, feed limited traction back (see module doc).

    The result's summary has per train ``running_time_s``, ``traction_power_cap_kw`` (null when not
    capped), ``time_lost_s`` and a ``feedback`` block (iterations, consistent).
    """
    feedback = feedback or FeedbackSettings()
    if not services:
        raise InputError("no trains", field="trains", allowed="one or more trains")
    runs: dict[tuple[int, float], RunResult] = {}

    def run_of(k: int, cap: float) -> RunResult:
        key = (k, round(cap, 3) if np.isfinite(cap) else np.inf)
        if key not in runs:
            run = _run(services[k].scenario, key[1])
            if run.status != "ok":
                raise InputError(
                    f"the run of train {services[k].id} is not possible: " + "; ".join(run.warnings),
                    field=f"trains[{k}]",
                    value=services[k].id,
                )
            runs[key] = run
        return runs[key]

    departures = [
        (k, f"{s.id}#{j}" if len(s.departures_s) > 1 else s.id, dep)
        for k, s in enumerate(services)
        for j, dep in enumerate(s.departures_s)
    ]
    caps = np.full(len(departures), np.inf)
    efficiency = np.array([_efficiency(services[k]) for k, _, _ in departures])
    iterations = 0
    result: PowerResult | None = None
    consistent = False
    while True:
        iterations += 1
        loads = [
            _load(services[k], run_of(k, caps[i]), name, dep) for i, (k, name, dep) in enumerate(departures)
        ]
        result = simulate(network, loads, dt_s=dt_s, start_s=start_s, end_s=end_s)
        asked = np.nansum(result.traction_demand_w, axis=0)
        got = np.nansum(result.traction_delivered_w, axis=0)
        ratio = np.where(asked > 0, got / np.where(asked > 0, asked, 1.0), 1.0)
        limited = ratio < 1.0 - feedback.tolerance
        consistent = not limited.any()
        if consistent or not feedback.enabled or iterations >= feedback.max_iterations:
            break
        short = result.traction_delivered_w < result.traction_demand_w * (1.0 - feedback.tolerance)
        for i in np.flatnonzero(limited):
            delivered = result.traction_delivered_w[short[:, i], i]
            caps[i] = min(caps[i], float(np.min(delivered)) * efficiency[i])
    trains: list[dict[str, Any]] = []
    for i, (k, name, _) in enumerate(departures):
        nominal = run_of(k, np.inf).running_time_s
        actual = run_of(k, caps[i]).running_time_s
        trains.append(
            {
                "id": name,
                "running_time_s": actual,
                "nominal_running_time_s": nominal,
                "time_lost_s": actual - nominal,
                "traction_power_cap_kw": float(caps[i]) / 1e3 if np.isfinite(caps[i]) else None,
            }
        )
    extra = {
        "trains": trains,
        "feedback": {
            "enabled": feedback.enabled,
            "iterations": iterations,
            "consistent": bool(consistent),
            "method": "constant cap on the traction power at the wheel: least power delivered at a limited step",
        },
    }
    return dataclasses.replace(result, extra=extra)
