"""trainsim: train performance calculator and energy-efficient driving optimizer.

The public API::

    import trainsim
    scenario = trainsim.load_scenario("examples/metro_b/scenario.yaml")
    result = trainsim.run(scenario)                 # fastest run
    result.summary()                                # JSON-ready summary
    result.to_dataframe()                           # the trace as a pandas DataFrame

    session = trainsim.DrivingSession(scenario)     # driving by command, step by step
    state = session.step(command=1.0, dt_s=0.5)
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from trainsim.errors import InfeasibleError, InputError, TrainsimError

if TYPE_CHECKING:
    from trainsim.model import *  # noqa: F403  (the domain objects, re-exported)
    from trainsim.model.scenario import RunSettings, Scenario
    from trainsim.multipoint.result import MultiPointResult
    from trainsim.sim.fastest import run_fastest, run_scenario
    from trainsim.sim.result import EnergyFigures, RunResult, SectionSummary, Trace

# Everything but the errors is imported on first use: `import trainsim` (and `trainsim --help`) must
# not pay for scipy, pandas, pydantic or the compiled kernels (issue 14's start-up budget).
_LAZY: dict[str, str] = {
    "RunSettings": "trainsim.model.scenario",
    "Scenario": "trainsim.model.scenario",
    "run_fastest": "trainsim.sim.fastest",
    "run_scenario": "trainsim.sim.fastest",
    "EnergyFigures": "trainsim.sim.result",
    "RunResult": "trainsim.sim.result",
    "SectionSummary": "trainsim.sim.result",
    "Trace": "trainsim.sim.result",
    **dict.fromkeys(
        ("load_train", "load_route", "load_scenario", "scenario_from_files", "check_file"),
        "trainsim.io.loader",
    ),
    "DrivingSession": "trainsim.sim.driving",
    "DrivingState": "trainsim.sim.driving",
}

__version__ = "0.1.0"


def run(scenario: Scenario) -> RunResult | MultiPointResult:
    """The fastest run of a scenario (its train over its route, with its stops and settings).

    A ``RunResult``; for a scenario with ``model: multi_point`` a ``MultiPointResult`` (per-vehicle
    speeds and coupler forces), whose ``.run`` is the same kind of ``RunResult``. A scenario with a
    ``driving`` block (strategy and supplement or timetable) is driven by that strategy.
    """
    if scenario.model == "multi_point":
        from trainsim.io.multipoint_spec import run_multipoint_scenario

        return run_multipoint_scenario(scenario, scenario.multi_point)
    if scenario.strategy != "fastest":
        from trainsim.optimize.api import optimize

        return optimize(
            scenario.train, scenario.route, scenario.timetable, scenario.strategy, scenario.settings
        ).run
    from trainsim.sim.fastest import run_scenario

    return run_scenario(scenario)


def __getattr__(name: str):
    import importlib

    module = _LAZY.get(name)
    if module is None:
        model = importlib.import_module("trainsim.model")  # the domain objects: Train, Route ...
        if name not in model.__all__:
            raise AttributeError(f"module 'trainsim' has no attribute {name!r}")
        module = "trainsim.model"
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})


__all__ = [
    "Braking",
    "Curve",
    "DrivingSession",
    "DrivingState",
    "EffortCurve",
    "Electrical",
    "ElectrificationSection",
    "EnergyFigures",
    "GradientSection",
    "InfeasibleError",
    "InputError",
    "LineResistanceSettings",
    "Quadratic",
    "ResistanceTerm",
    "Route",
    "RunResult",
    "RunSettings",
    "Scenario",
    "SectionSummary",
    "SpeedLimit",
    "Station",
    "Trace",
    "Train",
    "TrainsimError",
    "Tunnel",
    "Vehicle",
    "check_file",
    "load_route",
    "load_scenario",
    "load_train",
    "run",
    "run_fastest",
    "run_scenario",
    "scenario_from_files",
]
