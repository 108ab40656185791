"""Runs under ETCS supervision: the movement authority's supervision limit as a speed ceiling.

The single-train core knows line speed limits only. The permitted (or indication) supervision limit
of ``trainsim.operations.etcs`` toward the end of authority is handed to it as a staircase of extra
limits that never exceeds the curve (``ceiling.staircase``), refined (steps halved) until the running
time changes by less than ``tolerance_s``; the fastest run, or an energy-efficient run of
``trainsim.optimize.api``, is then the core's run under those limits. The run therefore never exceeds
the curve anywhere, and with an authority far away it is the plain run.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from trainsim.errors import InputError
from trainsim.model import Route, SpeedLimit, Train
from trainsim.model.scenario import RunSettings
from trainsim.model.timetable import Timetable
from trainsim.operations.ceiling import staircase, with_limits
from trainsim.operations.etcs import SupervisionCurves
from trainsim.optimize.api import OptimizationResult, optimize
from trainsim.sim.fastest import run_fastest
from trainsim.sim.result import RunResult

#: First staircase step length [m] and speed step [m/s] (both halved at each refinement), and the
#: largest number of steps tried.
FIRST_STEP_M = 200.0
FIRST_DV_MPS = 2.0
MAX_STEPS = 20_000
#: The staircase samples the ceiling up to this distance before the end of authority [m].
EOA_OPEN_M = 1e-6
SUPERVISED_KINDS = ("permitted", "indication", "sbi", "warning", "ebi", "guidance", "sbd", "ebd")


@dataclass(frozen=True)
class SupervisedRun:
    """A run under an ETCS speed ceiling.

    Attributes:
        run: the core's run under the ceiling (fastest), or the energy-efficient run's ``run``.
        optimization: the energy-efficient result, or None for the fastest run.
        limits: the ceiling's steps handed to the core (positions on the route) [m, m/s].
        steps: number of steps of the final staircase.
        refinements: running time [s] after each refinement (steps doubled each time).
        warnings: e.g. the refinement did not converge within ``MAX_STEPS``.
    """

    run: RunResult
    optimization: OptimizationResult | None
    limits: tuple[SpeedLimit, ...]
    steps: int
    refinements: tuple[float, ...]
    warnings: tuple[str, ...] = ()


def _ceiling(curves: SupervisionCurves, kind: str):
    if kind not in SUPERVISED_KINDS:
        raise InputError(
            "unknown supervision curve", field="ceiling", value=kind, allowed=", ".join(SUPERVISED_KINDS)
        )
    fn = getattr(curves, kind)
    return lambda x: np.asarray(fn(np.asarray(x, dtype=float)), dtype=float)


def _stop_short(route: Route, limits: tuple[SpeedLimit, ...], end_m: float) -> Route:
    """Where the ceiling falls below the lowest limit the core takes (``MIN_CEILING_MPS``) before the
    last stop (an EoA without release speed), the train stops where the staircase ends instead, a
    few centimetres to decimetres short: the core cannot follow a ceiling down to 0."""
    stops = [s for s in route.stations if s.stop]
    if not limits or not stops or limits[-1].end_m >= end_m - 1e-6:
        return route
    short = limits[-1].end_m
    last = stops[-1]
    if any(s.position_m > short + 1e-9 for s in stops[:-1]) or last.position_m < short:
        return route
    stations = tuple(replace(s, position_m=short) if s is last else s for s in route.stations)
    return replace(route, stations=stations)


def supervised_run(
    train: Train,
    route: Route,
    curves: SupervisionCurves,
    settings: RunSettings | None = None,
    *,
    ceiling: str = "permitted",
    strategy: str = "fastest",
    timetable: Timetable | None = None,
    tolerance_s: float = 0.1,
) -> SupervisedRun:
    """The fastest (``strategy="fastest"``) or energy-efficient (``optimal``, ``lesov``,
    ``reference``, with ``timetable``) run of ``train`` over ``route`` that never exceeds the
    supervision limit ``ceiling`` of ``curves`` (positions on the route's axis) [m/s].

    The train must stop at or before the end of authority: the route's last stop may not lie beyond
    it (an ``InputError`` otherwise)."""
    settings = settings or RunSettings()
    if not (np.isfinite(tolerance_s) and tolerance_s > 0):
        raise InputError("invalid tolerance", field="tolerance_s", value=tolerance_s, allowed="> 0 s")
    fn = _ceiling(curves, ceiling)
    last_stop = max(s.position_m for s in route.stops) if route.stops else route.end_m
    eoa = curves.eoa_position_m
    if last_stop > eoa + 1e-6:
        raise InputError(
            "the run ends beyond the end of authority: the train must stop at or before it",
            field="route.stations",
            value=last_stop,
            allowed=f"<= {eoa:g} m (the EoA)",
        )
    if strategy != "fastest" and timetable is None:
        raise InputError("an energy-efficient run needs a timetable", field="timetable", value=strategy)
    start, end = route.start_m, min(route.end_m, eoa)
    if end >= eoa - EOA_OPEN_M:
        # every limit is 0 from the EoA on: the staircase's last step ends there but must not take that
        # value, or a train with a release speed stops short by up to a step (and each refinement,
        # halving that step, moves its stop, so the running time converges only geometrically)
        inside = fn
        fn = lambda x: inside(np.minimum(x, eoa - EOA_OPEN_M))  # noqa: E731

    def run_with(limits: tuple[SpeedLimit, ...]) -> tuple[RunResult, OptimizationResult | None]:
        r = with_limits(_stop_short(route, limits, end), limits)
        if strategy == "fastest":
            return run_fastest(train, r, settings), None
        opt = optimize(train, r, timetable, strategy, settings)
        return opt.run, opt

    steps = first = max(1, int(np.ceil((end - start) / FIRST_STEP_M)))
    times: list[float] = []
    warnings: list[str] = []
    while True:
        limits = staircase(fn, start, end, steps, dv_mps=FIRST_DV_MPS * first / steps)
        run, opt = run_with(limits)
        times.append(float(run.running_time_s))
        if len(times) >= 2 and abs(times[-1] - times[-2]) < tolerance_s:
            break
        if 2 * steps > MAX_STEPS:
            warnings.append(
                f"the ceiling's staircase did not converge to {tolerance_s:g} s within {steps} steps: the "
                f"last refinement changed the running time by {abs(times[-1] - times[-2]):.3f} s"
            )
            break
        steps *= 2
    if warnings:
        run = replace(run, warnings=[*run.warnings, *warnings]) if hasattr(run, "warnings") else run
    return SupervisedRun(run, opt, limits, steps, tuple(times), tuple(warnings))


__all__ = ["SupervisedRun", "supervised_run"]
