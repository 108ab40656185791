"""Driving strategies the web application can run, by name.

A strategy turns a train, a route, run settings and its own parameters into a :class:`RunResult`.
The run endpoint (``POST /api/runs``) takes ``{"strategy": NAME, "params": {...}}``; the page
lists the registered strategies (``GET /api/strategies``) and builds a form for each one's
parameters from their JSON schema. Only ``fastest`` exists today; the energy-efficient optimizer
plugs in by registering itself, e.g.::

    from pydantic import BaseModel, Field
    from trainsim.web.strategies import Strategy, register

    class EcoParams(BaseModel):
        supplement_percent: float = Field(7.0, ge=0, le=50, description="running time supplement [%]")

    register(Strategy(
        name="energy_efficient",
        label="Energy-efficient",
        description="least energy within the fastest time plus a supplement",
        params=EcoParams,
        run=lambda train, route, settings, params: optimize(train, route, settings, params),
    ))

Parameters are validated by the strategy's pydantic model before the run; its messages come back
to the page next to the field (``params.supplement_percent``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import Annotated, Any

from pydantic import BaseModel, ConfigDict, Field

from trainsim.model.route import Route
from trainsim.model.scenario import RunSettings
from trainsim.model.train import Train
from trainsim.sim.fastest import run_fastest
from trainsim.sim.result import RunResult

__all__ = [
    "EnergyParams",
    "NoParams",
    "Strategy",
    "TimingPointParams",
    "available",
    "get",
    "register",
    "unregister",
]


class NoParams(BaseModel):
    """A strategy without parameters."""

    model_config = ConfigDict(extra="forbid")


@dataclass(frozen=True)
class Strategy:
    """A registered strategy.

    Attributes:
        name: identifier used by the API (``fastest``).
        label: name shown in the page.
        description: one sentence for the page and the API docs.
        params: pydantic model of its parameters (``extra="forbid"`` recommended).
        run: ``run(train, route, settings, params) -> RunResult``; may raise the core's errors.
    """

    name: str
    label: str
    description: str
    params: type[BaseModel]
    run: Callable[[Train, Route, RunSettings, Any], RunResult]

    def describe(self) -> dict[str, Any]:
        """What ``GET /api/strategies`` says about it."""
        return {
            "name": self.name,
            "label": self.label,
            "description": self.description,
            "params_schema": self.params.model_json_schema(),
        }


_REGISTRY: dict[str, Strategy] = {}
#: strategies registered when this module is imported: the worker processes know them
BUILT_IN: set[str] = set()


def register(strategy: Strategy) -> None:
    """Add (or replace) a strategy."""
    _REGISTRY[strategy.name] = strategy


def unregister(name: str) -> None:
    """Remove a strategy (tests)."""
    _REGISTRY.pop(name, None)


def get(name: str) -> Strategy | None:
    """The strategy of that name, or None."""
    return _REGISTRY.get(name)


def available() -> list[Strategy]:
    """The registered strategies, in registration order."""
    return list(_REGISTRY.values())


register(
    Strategy(
        name="fastest",
        label="Fastest",
        description="maximum traction, cruising at the limits, service braking to every lower limit and stop",
        params=NoParams,
        run=lambda train, route, settings, params: run_fastest(train, route, settings),
    )
)


# ====================================================================== energy-efficient runs
_Finite = Annotated[float, Field(ge=0, le=1e7, allow_inf_nan=False)]


class TimingPointParams(BaseModel):
    """A timing point: a position with a time window (from the departure of its section) and a
    speed window; None where unconstrained."""

    model_config = ConfigDict(extra="forbid")

    position_m: _Finite = Field(description="position on the line [m]")
    earliest_s: _Finite | None = Field(
        None, description="earliest passing time from the section's departure [s]"
    )
    latest_s: _Finite | None = Field(None, description="latest passing time from the section's departure [s]")
    min_speed_kmh: Annotated[float, Field(ge=0, le=1000, allow_inf_nan=False)] | None = Field(
        None, description="lowest speed at the point [km/h]"
    )
    max_speed_kmh: Annotated[float, Field(ge=0, le=1000, allow_inf_nan=False)] | None = Field(
        None, description="highest speed at the point [km/h]"
    )
    name: str = Field("", max_length=80)


class EnergyParams(BaseModel):
    """Schedule of an energy-efficient run: a line supplement, or a running time per section."""

    model_config = ConfigDict(extra="forbid")

    supplement_percent: float = Field(
        10.0,
        ge=0,
        le=300,
        allow_inf_nan=False,
        description="running-time supplement over the fastest run for the whole line [%], split between "
        "the sections by the optimizer",
    )
    section_running_times_s: list[Annotated[float, Field(gt=0, le=1e6, allow_inf_nan=False)]] | None = Field(
        None,
        max_length=1000,
        description="a timetable instead: the scheduled running time of each section between stops [s]",
    )
    timing_points: list[TimingPointParams] | None = Field(
        None,
        max_length=200,
        description="passing points with time and speed windows; the run reports each window met or missed",
    )


def _optimizer_run(name: str) -> Callable[[Train, Route, RunSettings, EnergyParams], RunResult]:
    from trainsim.optimize.api import optimize
    from trainsim.optimize.timetable import SectionSchedule, Timetable

    def run(train: Train, route: Route, settings: RunSettings, params: EnergyParams) -> RunResult:
        from trainsim.constants import KMH
        from trainsim.model.timetable import TimingPoint

        points = tuple(
            TimingPoint(
                position_m=p.position_m,
                earliest_s=p.earliest_s,
                latest_s=p.latest_s,
                min_speed_mps=None if p.min_speed_kmh is None else p.min_speed_kmh * KMH,
                max_speed_mps=None if p.max_speed_kmh is None else p.max_speed_kmh * KMH,
                name=p.name,
            )
            for p in params.timing_points or ()
        )
        if params.section_running_times_s:
            timetable = Timetable(
                sections=tuple(SectionSchedule(running_time_s=t) for t in params.section_running_times_s),
                timing_points=points,
            )
        else:
            timetable = Timetable(
                line=SectionSchedule(supplement_fraction=params.supplement_percent / 100.0),
                timing_points=points,
            )
        result = optimize(train, route, timetable, name, settings)
        # the optimizer's own warnings (a schedule that cannot be met) go with the run
        return dataclasses.replace(result.run, warnings=(*result.warnings, *result.run.warnings))

    return run


def _register_optimizer() -> None:
    try:
        optimal, lesov = _optimizer_run("optimal"), _optimizer_run("lesov")
    except ImportError:  # the web application works without the optimizer: fastest only
        return
    register(
        Strategy(
            name="energy_efficient",
            label="Energy-efficient",
            description="least energy for the schedule (optimal train control: traction, holding, coasting, "
            "braking)",
            params=EnergyParams,
            run=optimal,
        )
    )
    register(
        Strategy(
            name="lesov",
            label="Energy-efficient (source 004)",
            description="source 004's algorithm for the same schedule",
            params=EnergyParams,
            run=lesov,
        )
    )


_register_optimizer()
BUILT_IN.update(_REGISTRY)
