"""Energy-efficient runs to a timetable: one entry point for every strategy.

Strategies (by name, in ``STRATEGIES``):

* ``fastest``: the fastest run (for comparison);
* ``optimal``: the optimal strategy of optimal train control (``optimal.py``);
* ``lesov``: source 004's algorithm (``lesov.py``);
* ``reference``: the direct-transcription optimum with CasADi/IPOPT (``reference.py``).

A line supplement is split between sections with one common price of time mu (equal marginal
energy per second in every section); per-section schedules are met section by section. When a
section's schedule is shorter than its fastest run, that section runs fastest and a warning says
by how much the schedule cannot be met.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from itertools import pairwise
from typing import Any

import numpy as np
from scipy.optimize import brentq

from trainsim.constants import KMH
from trainsim.errors import InputError
from trainsim.model.route import Route, Station
from trainsim.model.scenario import RunSettings
from trainsim.model.timetable import TimingPoint
from trainsim.model.train import Train
from trainsim.optimize.constraints import DrivingConstraints, constrained_route, constrained_train
from trainsim.optimize.optimal import TIME_TOLERANCE_S, SectionPlan, SectionSolver
from trainsim.optimize.timetable import Timetable
from trainsim.optimize.windows import enforce_windows
from trainsim.sim import codes
from trainsim.sim.fastest import run_fastest, stops_of
from trainsim.sim.profile import line_resistance_profile, speed_ceiling
from trainsim.sim.result import RunResult, build_result

#: Starts the warning that some stretches are labelled with a regime they do not drive (issue 13).
OFF_REGIME_NOTE = "regime labels"
#: A section's schedule counts as met within max(0.5 s, 0.05 %) (issue 3).
SCHEDULE_TOLERANCE_S = 0.5
SCHEDULE_TOLERANCE_FRACTION = 5e-4


@dataclass(frozen=True)
class SwitchingPoint:
    """Where the driving regime changes: position [m], speed [km/h], time [s], new regime."""

    position_m: float
    speed_kmh: float
    time_s: float
    regime: str


@dataclass(frozen=True)
class OptimizationResult:
    """An energy-efficient run with its schedule, switching points and savings."""

    strategy: str
    run: RunResult
    fastest: RunResult
    scheduled_running_time_s: tuple[float, ...]
    schedule_deviation_s: tuple[float, ...]
    switching_points: tuple[SwitchingPoint, ...]
    price_of_time_w: tuple[float, ...]
    warnings: tuple[str, ...] = field(default=())
    #: how the run passes every timing point of the timetable: position_m, time_s (from its
    #: section's departure), speed_mps, the window, met (bool)
    timing_points: tuple[dict[str, Any], ...] = field(default=())
    #: what the driving constraints did that does not change the status: arcs a speed limit or the
    #: stop keeps shorter than the minimum regime time, the energy the regime rules cost
    notes: tuple[str, ...] = field(default=())

    @property
    def energy_saved_kwh(self) -> float:
        """Net electrical energy saved against the fastest run [kWh]."""
        return self.fastest.energy_kwh.net - self.run.energy_kwh.net

    def summary(self) -> dict[str, Any]:
        """The run summary (as ``trainsim run --json``) plus the optimisation's own figures."""
        out = self.run.summary()
        out["warnings"] = list(self.warnings) + out["warnings"]
        # a note on regime labels says how the figures were integrated; they are still the run's
        binding = [w for w in self.warnings if not w.startswith(OFF_REGIME_NOTE)]
        if binding and out["status"] == "ok":
            missed = any(not p["met"] for p in self.timing_points)
            late = any("cannot be met" in w or "shorter than the fastest" in w for w in self.warnings)
            out["status"] = "timing window missed" if missed and not late else "infeasible schedule"
        out["strategy"] = self.strategy
        out["scheduled_running_time_s"] = list(self.scheduled_running_time_s)
        out["schedule_deviation_s"] = list(self.schedule_deviation_s)
        out["switching_points"] = [dataclasses.asdict(p) for p in self.switching_points]
        out["price_of_time_w"] = [float(x) if np.isfinite(x) else None for x in self.price_of_time_w]
        if self.timing_points:
            out["timing_points"] = [dict(p) for p in self.timing_points]
        if self.notes:
            out["notes"] = list(self.notes)
        fastest_net = self.fastest.energy_kwh.net
        out["fastest"] = {
            "running_time_s": self.fastest.running_time_s,
            "energy_kwh": dataclasses.asdict(self.fastest.energy_kwh),
        }
        out["energy_saved_kwh"] = self.energy_saved_kwh
        out["energy_saved_percent"] = 100.0 * self.energy_saved_kwh / fastest_net if fastest_net > 0 else None
        return out


def _section_route(route: Route, s0: float, s1: float) -> Route:
    return dataclasses.replace(route, stations=(Station("from", s0), Station("to", s1)))


def switching_points(s: np.ndarray, v: np.ndarray, t: np.ndarray, regime: np.ndarray) -> list[SwitchingPoint]:
    """Every point where the regime changes (dwell excluded)."""
    points = []
    for k in range(len(s)):
        if regime[k] == codes.DWELL:
            continue
        if k + 1 < len(s) and s[k + 1] - s[k] < 1e-6 and t[k + 1] - t[k] < 1e-6:
            continue  # a regime held for no distance and no time
        if k == 0 or regime[k] != regime[k - 1]:
            points.append(
                SwitchingPoint(
                    float(s[k]), float(v[k] / KMH), float(t[k]), codes.REGIME_NAMES[int(regime[k])]
                )
            )
    return points


def _assemble(
    train: Train,
    route: Route,
    settings: RunSettings,
    plans: list[SectionPlan],
    kind: str,
) -> RunResult:
    stops = route.stops
    s_all, v_all, t_all, m_all = [], [], [], []
    t0 = 0.0
    for k, plan in enumerate(plans):
        s_all.append(plan.s)
        v_all.append(plan.v)
        t_all.append(plan.t + t0)
        m_all.append(plan.regime)
        t0 += plan.t[-1] + (stops[k + 1].dwell_s if k + 1 < len(plans) else 0.0)
    return build_result(
        train=train,
        route=route,
        settings=settings,
        profile=line_resistance_profile(route, train),
        ceiling=speed_ceiling(route, train),
        s=np.concatenate(s_all),
        v=np.concatenate(v_all),
        t=np.concatenate(t_all),
        regime=np.concatenate(m_all).astype(np.int8),
        status="ok",
        kind=kind,
    )


def _targets(timetable: Timetable, fastest: list[float]) -> list[float] | None:
    if timetable.sections:
        if len(timetable.sections) != len(fastest):
            raise InputError(
                "the timetable must give one schedule per section",
                file=timetable.source or None,
                field="sections",
                value=len(timetable.sections),
                allowed=f"{len(fastest)} (the route's sections between stops)",
            )
        return [sched.target_s(f) for sched, f in zip(timetable.sections, fastest, strict=True)]
    return None


def proportional_targets(timetable: Timetable, fastest: list[float]) -> list[float]:
    """The scheduled running time of every section [s]: the timetable's per-section schedules, or its
    line supplement shared in proportion to the sections' fastest running times (the rule of the
    strategies that do not split it by the price of time, ``fastest`` among them).

    Args:
        timetable: the timetable (per-section schedules or one line supplement).
        fastest: the fastest running time of every section between stops [s].

    Returns:
        One target running time per section [s], in the order of ``fastest``.

    Raises:
        InputError: the timetable's per-section schedules are not one per section.
    """
    targets = _targets(timetable, fastest)
    if targets is not None:
        return targets
    total = timetable.line.target_s(sum(fastest))
    return [total * f / sum(fastest) for f in fastest]


def _optimal_plans(solvers: list[SectionSolver], timetable: Timetable) -> tuple[list[SectionPlan], list[str]]:
    fastest = [sv.fastest_time_s for sv in solvers]
    targets = _targets(timetable, fastest)
    warnings: list[str] = []
    if targets is not None:
        return [sv.solve(T) for sv, T in zip(solvers, targets, strict=True)], warnings
    total = timetable.line.target_s(sum(fastest))
    if total <= sum(fastest) + 1e-6:
        return [sv.solve(f) for sv, f in zip(solvers, fastest, strict=True)], warnings

    # one holding speed for every section: equal price of time, equal marginal energy per second
    seen: dict[float, tuple[float, list[SectionPlan]]] = {}

    def excess(log_v: float) -> float:
        if log_v not in seen:
            plans = [sv.plan(float(np.exp(log_v))) for sv in solvers]
            seen[log_v] = (sum(p.running_time_s for p in plans) - total, plans)
        error, plans = seen[log_v]
        if abs(error) <= TIME_TOLERANCE_S:
            raise _SplitFoundError(plans)
        return error

    vmax = max(float(sv.track.vlim.max()) for sv in solvers)
    try:
        # bracket from the speed the schedule needs, a little higher (the train accelerates and brakes)
        log_lo = log_hi = float(np.log(1.1 * sum(sv.s1 - sv.s0 for sv in solvers) / total))
        step = np.log(1.25)
        while excess(log_hi) > 0.0 and log_hi < np.log(vmax * 1000.0):
            log_lo, log_hi, step = log_hi, log_hi + step, 1.5 * step
        while excess(log_lo) < 0.0 and log_lo > np.log(0.5):
            log_hi, log_lo, step = log_lo, log_lo - step, 1.5 * step
        log_v = brentq(excess, log_lo, log_hi, xtol=1e-12, rtol=1e-12, maxiter=200)
        plans = seen[log_v][1] if log_v in seen else [sv.plan(float(np.exp(log_v))) for sv in solvers]
    except _SplitFoundError as found:
        return found.plans, warnings
    except ValueError:  # no sign change: the runs at the extreme holding speeds
        plans = seen[min(seen, key=lambda k: abs(seen[k][0]))][1]
    # the running time jumps with V here: keep the split of that V and meet it section by section
    times = [p.running_time_s for p in plans]
    scale = total / sum(times)
    return [sv.solve(t * scale) for sv, t in zip(solvers, times, strict=True)], warnings


class _SplitFoundError(Exception):
    """Ends the search for the common holding speed of a line's sections (a result, not an error)."""

    def __init__(self, plans: list[SectionPlan]) -> None:
        super().__init__()
        self.plans = plans


def optimize(
    train: Train,
    route: Route,
    timetable: Timetable,
    strategy: str = "optimal",
    settings: RunSettings | None = None,
    constraints: DrivingConstraints | None = None,
) -> OptimizationResult:
    """The run of ``strategy`` that meets ``timetable`` with least energy (see module doc).

    ``constraints`` (comfort acceleration and deceleration, jerk, a margin below the speed limits,
    ``trainsim.optimize.constraints``) apply to every strategy through the train's force caps and
    the route's limits; the reference also bounds the kinematic acceleration and the jerk."""
    settings = settings or RunSettings()
    if constraints is not None:
        train, route = constrained_train(train, constraints), constrained_route(route, constraints)
    if strategy not in STRATEGIES:
        raise InputError("unknown strategy", field="strategy", value=strategy, allowed=", ".join(STRATEGIES))
    if constraints is not None and constraints.regime_rules and strategy not in REGIME_RULE_STRATEGIES:
        # lesov and fastest drive by their own rule: run without the rules, their warning turned the
        # status into "infeasible schedule" for a timetable that can be met (issue 16)
        asked = [
            name
            for name, value in (
                ("min_regime_time_s", constraints.min_regime_time_s),
                ("coast_min_speed_mps", constraints.coast_min_speed_mps),
            )
            if value > 0.0
        ]
        raise InputError(
            f"{' and '.join(asked)} apply to the {' and '.join(REGIME_RULE_STRATEGIES)} strategies; "
            f"strategy {strategy} does not apply them",
            field=f"constraints.{asked[0]}",
            value=strategy,
            allowed=f"strategy {' or '.join(REGIME_RULE_STRATEGIES)}, or no driving rules",
        )
    fastest = run_fastest(train, route, settings)
    if fastest.status != "ok":
        raise InputError(
            "the fastest run is not possible: " + "; ".join(fastest.warnings), field="route", value=route.name
        )
    if strategy == "reference":
        return _run_reference(train, route, timetable, settings, fastest, constraints)
    if strategy == "optimal" and constraints is not None and constraints.regime_rules:
        return _run_optimal(train, route, timetable, settings, fastest, constraints)
    return STRATEGIES[strategy](train, route, timetable, settings, fastest)


def _result(
    strategy: str,
    train: Train,
    route: Route,
    settings: RunSettings,
    fastest: RunResult,
    plans: list[SectionPlan],
    targets: list[float],
    extra_warnings: list[str] | None = None,
    timing_points: tuple[TimingPoint, ...] = (),
    solvers: list[SectionSolver] | None = None,
) -> OptimizationResult:
    # the optimal run is integrated with the train its plans were built for: the solver's electric brake is
    # part of the service brake (never above its curve or cap), so a regenerative stretch is the same
    # motion and the same energy on every path (``SectionSolver.energy_j``)
    planned = solvers[0].train if solvers and strategy == "optimal" else train
    run = _assemble(planned, route, settings, plans, kind=strategy)
    deviations = [sec.running_time_s - T for sec, T in zip(run.sections, targets, strict=True)]
    warnings = list(extra_warnings or [])
    for k, (sec, T, dev) in enumerate(zip(run.sections, targets, deviations, strict=True)):
        if dev > max(SCHEDULE_TOLERANCE_S, SCHEDULE_TOLERANCE_FRACTION * T):
            warnings.append(
                f"section {k + 1} ({sec.from_station} - {sec.to_station}): the schedule of {T:.1f} s cannot be "
                f"met; the fastest run takes {sec.running_time_s:.1f} s ({dev:.1f} s late)"
            )
    off = run.energy_balance.get("off_regime_stretches", 0.0)
    if off:
        warnings.append(
            f"{OFF_REGIME_NOTE}: {int(off)} stretch(es) of the run do not follow their regime's effort (up to "
            f"{run.energy_balance['off_regime_max_speed_difference_mps']:.2g} m/s apart); their energy is "
            "that of the recorded motion"
        )
    pts = []
    for plan in plans:
        pts += switching_points(plan.s, plan.v, plan.t, plan.regime)
    checks = []
    for p in timing_points:
        for k, plan in enumerate(plans):
            if plan.s[0] < p.position_m < plan.s[-1]:
                check, message = _window_check(p, plan, solvers[k] if solvers else None)
                checks.append(check)
                if message:
                    warnings.append(message)
    return OptimizationResult(
        strategy=strategy,
        run=run,
        fastest=fastest,
        scheduled_running_time_s=tuple(targets),
        schedule_deviation_s=tuple(deviations),
        switching_points=tuple(pts),
        price_of_time_w=tuple(p.price_of_time_w for p in plans),
        warnings=tuple(warnings),
        timing_points=tuple(checks),
    )


#: A timing window counts as met within this [s] (the schedule tolerance of a section).
WINDOW_TOLERANCE_S = SCHEDULE_TOLERANCE_S


def _window_check(
    p: TimingPoint, plan: SectionPlan, solver: SectionSolver | None
) -> tuple[dict[str, Any], str]:
    """How a section's run passes a timing point, and what is wrong (empty when it is met); where
    the window is missed, whether the fastest run could meet its latest time."""
    t = float(np.interp(p.position_m, plan.s, plan.t))
    v = float(np.interp(p.position_m, plan.s, plan.v))
    problems = []
    if p.latest_s is not None and t > p.latest_s + WINDOW_TOLERANCE_S:
        text = f"passes {t - p.latest_s:.1f} s after its latest time ({t:.1f} s > {p.latest_s:.1f} s from the departure)"
        if solver is not None:
            t_fast = float(np.interp(p.position_m, solver.fastest[0], solver.fastest[2]))
            if t_fast > p.latest_s + WINDOW_TOLERANCE_S:
                text += f"; no run can meet it: the fastest passes {t_fast - p.latest_s:.1f} s late"
        problems.append(text)
    if p.earliest_s is not None and t < p.earliest_s - WINDOW_TOLERANCE_S:
        problems.append(
            f"passes {p.earliest_s - t:.1f} s before its earliest time ({t:.1f} s < {p.earliest_s:.1f} s)"
        )
    if p.min_speed_mps is not None and v < p.min_speed_mps - 1e-6:
        problems.append(f"passes at {v / KMH:.1f} km/h, below its minimum {p.min_speed_mps / KMH:.1f} km/h")
    if p.max_speed_mps is not None and v > p.max_speed_mps + 1e-6:
        problems.append(f"passes at {v / KMH:.1f} km/h, above its maximum {p.max_speed_mps / KMH:.1f} km/h")
    check = {
        "name": p.label,
        "position_m": p.position_m,
        "time_s": t,
        "speed_mps": v,
        "earliest_s": p.earliest_s,
        "latest_s": p.latest_s,
        "min_speed_mps": p.min_speed_mps,
        "max_speed_mps": p.max_speed_mps,
        "met": not problems,
    }
    name = p.name or f"timing point at {p.position_m:.0f} m"
    return check, (f"{name}: " + "; ".join(problems)) if problems else ""


def _solvers(train: Train, route: Route, settings: RunSettings) -> list[SectionSolver]:
    stops = stops_of(route)
    return [SectionSolver(train, route, a, b, settings) for a, b in pairwise(stops)]


def _run_optimal(train, route, timetable, settings, fastest, constraints=None) -> OptimizationResult:
    solvers = _solvers(train, route, settings)
    plans, warnings = _optimal_plans(solvers, timetable)
    fastest_s = [sv.fastest_time_s for sv in solvers]
    targets = _targets(timetable, fastest_s)
    if targets is None:
        # a line supplement: each section's target is what the optimal split gave it
        total = timetable.line.target_s(sum(fastest_s))
        targets = [p.running_time_s for p in plans] if total > sum(fastest_s) else fastest_s
        if total < sum(fastest_s) - 1e-6:
            warnings.append(
                f"the line schedule of {total:.1f} s is shorter than the fastest run "
                f"({sum(fastest_s):.1f} s): the fastest run is returned"
            )
    if timetable.timing_points:
        # windows the optimum misses are enforced section by section, each keeping its time
        for k, (sv, T) in enumerate(zip(solvers, targets, strict=True)):
            outcome = enforce_windows(sv, T, timetable.timing_points, plans[k], settings)
            plans[k] = outcome.plan
            warnings += outcome.notes
    notes: list[str] = []
    if constraints is not None and constraints.regime_rules:
        from trainsim.optimize.regime_rules import apply_regime_rules

        for k, (sv, T) in enumerate(zip(solvers, targets, strict=True)):
            ruled = apply_regime_rules(sv, T, plans[k], constraints)
            plans[k] = ruled.plan
            notes += [f"section {k + 1}: {n}" for n in ruled.notes]
            if not ruled.time_met:
                warnings += [f"section {k + 1}: {n}" for n in ruled.notes if "scheduled" in n]
    result = _result(
        "optimal", train, route, settings, fastest, plans, targets, warnings, timetable.timing_points, solvers
    )
    return dataclasses.replace(result, notes=tuple(notes)) if notes else result


def _run_lesov(train, route, timetable, settings, fastest) -> OptimizationResult:
    from trainsim.optimize.lesov import lesov_plans, lesov_train

    solvers = _solvers(train, route, settings)
    fastest_s = [sv.fastest_time_s for sv in solvers]
    targets = proportional_targets(timetable, fastest_s)
    plans, warnings = lesov_plans(train, route, solvers, targets, settings)
    # source 004 brakes recuperatively at 0.8 x the traction curve: account the run with that brake
    return _result(
        "lesov",
        lesov_train(train),
        route,
        settings,
        fastest,
        plans,
        targets,
        warnings,
        timetable.timing_points,
        solvers,
    )


def _run_reference(train, route, timetable, settings, fastest, constraints=None) -> OptimizationResult:
    from trainsim.optimize.reference import solve_reference

    solvers = _solvers(train, route, settings)
    fastest_s = [sv.fastest_time_s for sv in solvers]
    targets = _targets(timetable, fastest_s)
    if targets is None:
        # the reference splits a line supplement with the optimal strategy's common price of time
        opt_plans, _ = _optimal_plans(solvers, timetable)
        targets = [p.running_time_s for p in opt_plans]
    plans, warnings = [], []
    for sv, T in zip(solvers, targets, strict=True):
        if sv.fastest_time_s >= T:
            plans.append(sv.solve(T))
            continue
        windows = [p for p in timetable.timing_points if sv.s0 < p.position_m < sv.s1]
        warm = sv.solve(T)
        ref = solve_reference(
            train,
            route,
            sv.s0,
            sv.s1,
            T,
            warm_start=(warm.s, warm.v),
            timing_points=windows,
            constraints=constraints,
        )
        if ref.status != "ok":
            warnings.append(f"reference optimum {sv.s0:.0f}-{sv.s1:.0f} m: IPOPT {ref.status}")
        t = np.concatenate([[0.0], np.cumsum(2 * np.diff(ref.s) / np.maximum(ref.v[:-1] + ref.v[1:], 1e-12))])
        regime = np.full(len(ref.s), codes.FOLLOW, dtype=np.int8)
        regime[-1] = codes.DWELL
        plans.append(
            SectionPlan(
                ref.s, ref.v, t, regime, float(t[-1]), np.nan, np.nan, np.nan, sv.fastest_time_s, True
            )
        )
    result = _result(
        "reference",
        train,
        route,
        settings,
        fastest,
        plans,
        targets,
        warnings,
        timetable.timing_points,
        solvers,
    )
    if constraints is not None and constraints.min_regime_time_s > 0.0:
        # the reference's forces are free per interval: a minimum regime time is no NLP constraint
        note = "the reference does not impose the minimum regime time (it bounds the lowest coasting speed)"
        result = dataclasses.replace(result, notes=(note,))
    return result


def _fastest_result(train, route, timetable, settings, fastest) -> OptimizationResult:
    solvers = _solvers(train, route, settings)
    fastest_s = [sv.fastest_time_s for sv in solvers]
    targets = proportional_targets(timetable, fastest_s)
    plans = [sv.solve(0.0) for sv in solvers]
    return _result(
        "fastest", train, route, settings, fastest, plans, targets, [], timetable.timing_points, solvers
    )


#: The strategies that keep the driving rules min_regime_time_s and coast_min_speed_mps (the reference
#: bounds the coasting speed and reports arcs shorter than the minimum regime time).
REGIME_RULE_STRATEGIES = ("optimal", "reference")

STRATEGIES: dict[str, Callable[..., OptimizationResult]] = {
    "fastest": _fastest_result,
    "optimal": _run_optimal,
    "lesov": _run_lesov,
    "reference": _run_reference,
}


def energy_time_curve(
    train: Train,
    route: Route,
    supplements: list[float] | None = None,
    settings: RunSettings | None = None,
):
    """Energy against running time of the optimal strategy for line supplements (fractions),
    as a pandas DataFrame: supplement_percent, running_time_s, energy_kwh (net), energy_traction_kwh."""
    import pandas as pd

    from trainsim.optimize.timetable import SectionSchedule

    supplements = (
        supplements if supplements is not None else [0.0, 0.02, 0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.4]
    )
    settings = settings or RunSettings()
    fastest = run_fastest(train, route, settings)
    rows = []
    for x in supplements:
        res = _run_optimal(
            train, route, Timetable(line=SectionSchedule(supplement_fraction=x)), settings, fastest
        )
        rows.append(
            {
                "supplement_percent": 100.0 * x,
                "running_time_s": res.run.running_time_s,
                "energy_kwh": res.run.energy_kwh.net,
                "energy_traction_kwh": res.run.energy_kwh.traction,
            }
        )
    return pd.DataFrame(rows)
