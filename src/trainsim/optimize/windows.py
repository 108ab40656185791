"""Timing windows (earliest / latest passing times inside a section) enforced by the optimal strategy.

With a passing-time constraint at a point p inside a section, the price of time is piecewise
constant: it jumps at p where the constraint binds, while the speed (and its adjoint) stay continuous
(Albrecht, Howlett, Pudney, Vu, Zhou 2016, "The key principles of optimal train control", Part 1,
Section 6: intermediate time constraints split the journey into stages with their own holding
speeds). The run therefore holds V1 up to p and V2 after it; at p the holding arc of V1 is left by
coasting (V1 > V2, the train was late) or by full traction (V1 < V2, early), which is what the
adjoint does from phi = 1 at p with the price of time of V2. The train does not stop at p.

Only windows the unconstrained optimum misses are enforced (an active set built in order of
position): V1 is solved so that the run passes p at the bound it missed (the window's latest or
earliest time), V2 so that the section keeps its scheduled time. Where no run can meet a window, the
run keeps the section's schedule and comes as close to the window as it allows, and a note says
which window and by how much.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from trainsim.model.scenario import RunSettings
from trainsim.model.timetable import TimingPoint
from trainsim.optimize.optimal import SectionPlan, SectionSolver
from trainsim.sim import codes

#: A binding window is met to this [s] (far inside the 0.5 s a window is checked with).
WINDOW_TIME_TOLERANCE_S = 1e-3
#: A window counts as missed by the unconstrained run (and is enforced) beyond this [s].
WINDOW_ENFORCE_TOLERANCE_S = 1e-3
#: Holding speeds above this many times the highest limit give the fastest run [-].
FAST_FACTOR = 1000.0
#: Holding speed of the slowest run after the last binding point [m/s] (a walk: the section's solver
#: refuses schedules that need less).
WALKING_SPEED_MPS = 0.5
#: A run after a binding point may fall short of the section's time by this much [s] before the
#: stretch speeds are lowered (the section's time is then met to the solver's own tolerance).
TIME_SLACK_S = 1e-6
#: Rounds of correction where the final coast or a departure choice looks across a binding point.
CORRECTION_ROUNDS = 10


@dataclass(frozen=True)
class WindowOutcome:
    """The run of a section with its timing windows enforced.

    Attributes:
        plan: the run.
        binding: (position [m], passing time [s]) of the windows it was driven to.
        holding_speeds_mps: the holding speed of each stretch (before each binding point, then after
            the last one).
        notes: one message per window that no run can meet with the section's schedule.
    """

    plan: SectionPlan
    binding: tuple[tuple[float, float], ...]
    holding_speeds_mps: tuple[float, ...]
    notes: tuple[str, ...]


def passing_time_s(plan: SectionPlan, position_m: float) -> float:
    """When a plan passes ``position_m`` [s from the section's departure]."""
    return float(np.interp(position_m, plan.s, plan.t))


def window_miss_s(t: float, point: TimingPoint) -> float:
    """How far a passing time ``t`` [s] is outside the point's time window [s]: > 0 late, < 0 early,
    0 inside."""
    if point.latest_s is not None and t > point.latest_s:
        return t - point.latest_s
    if point.earliest_s is not None and t < point.earliest_s:
        return t - point.earliest_s
    return 0.0


def enforce_windows(
    solver: SectionSolver,
    running_time_s: float,
    windows: Sequence[TimingPoint],
    plan: SectionPlan,
    settings: RunSettings | None = None,
) -> WindowOutcome:
    """The optimal run of ``solver``'s section in ``running_time_s`` that passes every timing point of
    ``windows`` (times from the section's departure) inside its time window where a run can.

    ``plan`` is the run without windows: returned unchanged when it meets them all. Windows outside
    the section and windows without a time bound are ignored (speed windows are only checked, by the
    caller)."""
    inside = sorted(
        (
            w
            for w in windows
            if solver.s0 < w.position_m < solver.s1 and (w.earliest_s, w.latest_s) != (None, None)
        ),
        key=lambda w: w.position_m,
    )
    first_miss = _first_missed(plan, inside, ())
    if first_miss is None or not plan.feasible:
        # an infeasible schedule is driven fastest: no time is left to move between stretches
        return WindowOutcome(plan, (), (plan.holding_speed_mps,), ())
    ws = SectionSolver(
        solver.train,
        solver.route,
        solver.s0,
        solver.s1,
        settings,
        breaks_m=tuple(w.position_m for w in inside),
    )
    binding: list[tuple[TimingPoint, float]] = []
    outcome = WindowOutcome(plan, (), (plan.holding_speed_mps,), ())
    while first_miss is not None:
        w = first_miss
        target = (
            w.latest_s if window_miss_s(passing_time_s(outcome.plan, w.position_m), w) > 0.0 else w.earliest_s
        )
        binding.append((w, float(target)))
        binding.sort(key=lambda wt: wt[0].position_m)
        outcome = _solve_binding(ws, running_time_s, binding)
        first_miss = _first_missed(outcome.plan, inside, tuple(b[0] for b in binding))
    ws.stretches = ()
    if outcome.notes and _total_miss_s(outcome.plan, inside) > _total_miss_s(plan, inside) + 1e-9:
        # the stretches could not meet a window, and the run without them comes closer to every
        # window: that one is kept, with a note per window it misses
        missed = [w for w in inside if window_miss_s(passing_time_s(plan, w.position_m), w) != 0.0]
        notes = tuple(
            f"{w.name or f'timing point at {w.position_m:.0f} m'}: no run of the optimal strategy that keeps "
            "the section's schedule passes it closer to its window than the optimum without it"
            for w in missed
        )
        return WindowOutcome(plan, (), (plan.holding_speed_mps,), notes)
    return outcome


def _total_miss_s(plan: SectionPlan, windows: Sequence[TimingPoint]) -> float:
    """How far a plan passes outside all the windows, summed [s]."""
    return sum(abs(window_miss_s(passing_time_s(plan, w.position_m), w)) for w in windows)


def _first_missed(plan: SectionPlan, inside, bound) -> TimingPoint | None:
    for w in inside:
        if w in bound:
            continue
        if abs(window_miss_s(passing_time_s(plan, w.position_m), w)) > WINDOW_ENFORCE_TOLERANCE_S:
            return w
    return None


def _solve_binding(ws: SectionSolver, running_time_s: float, binding) -> WindowOutcome:
    """The run that passes each binding point at its target time and keeps the section's time.

    Each stretch's holding speed is first solved so that phase A (the holding phases, driven
    forward) passes its point on time. Where the final coast starts before a binding point, or a
    departure ahead of a descent or a lower limit looks across it, the whole run passes it at
    another time: the time phase A aims at is then corrected by regula falsi on the run's passing
    time, per point."""
    big = FAST_FACTOR * float(ws.track.vlim.max())
    targets = [t for _, t in binding]
    aims = list(targets)
    history: list[list[tuple[float, float]]] = [[] for _ in binding]
    notes: dict[int, str] = {}
    plan = None
    speeds: list[float] = []
    for _ in range(CORRECTION_ROUNDS):
        speeds, notes = _stretch_speeds(ws, binding, aims, big)
        ws.stretches = tuple((w.position_m, v) for (w, _), v in zip(binding, speeds, strict=True))
        if _longest_s(ws) < running_time_s - TIME_SLACK_S:
            plan, speeds, note = _lose_time_after(ws, running_time_s, binding, speeds)
            k = len(binding) - 1
            if note:
                notes[k] = f"{notes[k]}; {note}" if k in notes else note
            break
        plan = ws.solve(running_time_s)
        if plan.running_time_s > running_time_s + max(0.5, 5e-4 * running_time_s):
            plan, speeds, note = _keep_schedule(ws, running_time_s, binding, speeds, big)
            if note:
                notes[len(binding) - 1] = note
            break
        errors = [passing_time_s(plan, w.position_m) - t for (w, _), t in zip(binding, targets, strict=True)]
        moved = [k for k, e in enumerate(errors) if abs(e) > WINDOW_TIME_TOLERANCE_S and k not in notes]
        if not moved:
            break
        for k in moved:
            history[k].append((aims[k], errors[k]))
            aims[k] = _next_aim(history[k])
    assert plan is not None
    return WindowOutcome(
        plan,
        tuple((w.position_m, passing_time_s(plan, w.position_m)) for w, _ in binding),
        (*speeds, plan.holding_speed_mps),
        tuple(notes[k] for k in sorted(notes)),
    )


def _next_aim(history: list[tuple[float, float]]) -> float:
    """The next time phase A aims at, from the (aim, passing time error) pairs tried: regula falsi
    between the closest pair on either side of the target, else a secant on the last two, else a
    shift by the error."""
    aim, error = history[-1]
    late = [h for h in history if h[1] > 0.0]
    early = [h for h in history if h[1] < 0.0]
    if late and early:
        (a0, e0), (a1, e1) = min(late, key=lambda h: h[1]), max(early, key=lambda h: h[1])
        return a0 - e0 * (a1 - a0) / (e1 - e0)
    if len(history) >= 2:
        a0, e0 = history[-2]
        slope = (error - e0) / (aim - a0) if aim != a0 else 0.0
        if slope > 0.0:
            # (a step of at most 4x the error: far from linear it is only a direction)
            return aim - float(np.clip(error / slope, -4.0 * abs(error), 4.0 * abs(error)))
    return aim - error


def _passing_time_with(ws: SectionSolver, fixed, position_m: float, speed: float) -> float:
    """When phase A passes ``position_m`` with the stretches ``fixed`` and ``speed`` after them."""
    ws.stretches = tuple(fixed)
    s, _, t, _ = ws._phase_a(speed)
    return float(np.interp(position_m, s, t))


def _stretch_speeds(ws: SectionSolver, binding, aims, big: float) -> tuple[list[float], dict[int, str]]:
    """The holding speed of each stretch that makes the run pass its binding point at its aim, in
    order of position (phase A is driven forward, so a stretch's passing time does not depend on
    the holding speeds after it)."""
    fixed: list[tuple[float, float]] = []
    speeds: list[float] = []
    notes: dict[int, str] = {}
    for k, ((w, _), aim) in enumerate(zip(binding, aims, strict=True)):
        p = w.position_m

        def late(log_v: float, p=p, aim=aim) -> float:
            return _passing_time_with(ws, fixed, p, float(np.exp(log_v))) - aim

        e_fast = late(np.log(big))
        late_target = e_fast + aim - binding[k][1]
        if e_fast > 0.0 and late_target > 0.0:
            # even the fastest run to p passes late: drive fastest up to p
            notes[k] = (
                f"{w.name or f'timing point at {p:.0f} m'}: no run can meet its latest time: the fastest "
                f"passes {late_target:.1f} s late"
            )
            v = big
        elif e_fast > 0.0:
            v = big  # a corrected aim below what phase A can reach: as fast as it goes
        else:
            start = fixed[-1][0] if fixed else ws.s0
            t_start = _passing_time_with(ws, fixed, start, big) if fixed else 0.0
            # the average speed the stretch needs, a little higher (it accelerates and brakes too)
            guess = 1.1 * (p - start) / max(aim - t_start, 1e-3)
            lo = hi = float(np.log(min(max(guess, 0.6), big)))
            e_lo = e_hi = late(lo)
            while e_hi > 0.0 and hi < np.log(big):
                lo, e_lo, hi = hi, e_hi, min(hi + np.log(1.3), np.log(big))
                e_hi = late(hi) if hi < np.log(big) else e_fast
            while e_lo < 0.0 and lo > np.log(0.5):
                hi, e_hi, lo = lo, e_lo, lo - np.log(1.3)
                e_lo = late(lo)
            if e_lo >= 0.0 >= e_hi:
                v = float(np.exp(brentq(late, lo, hi, xtol=1e-12, rtol=1e-12, maxiter=100)))
            else:
                v = float(np.exp(lo if abs(e_lo) < abs(e_hi) else hi))
        fixed.append((p, v))
        speeds.append(v)
    return speeds, notes


def _keep_schedule(ws: SectionSolver, running_time_s: float, binding, speeds: list[float], big: float):
    """Where passing the last binding point at its earliest time leaves too little time to reach the
    stop: the run that keeps the section's schedule and passes that point as late as it can (the
    fastest run after it); (plan, stretch speeds, note)."""
    w, target = binding[-1]
    fixed = [(b.position_m, v) for (b, _), v in zip(binding[:-1], speeds[:-1], strict=True)]

    def total(V: float) -> float:
        ws.stretches = (*fixed, (w.position_m, V))
        return float(ws._phase_a(big)[2][-1])

    rest = total(speeds[-1]) - target
    slack = running_time_s - target
    lo, hi = np.log(0.5), np.log(big)
    if total(float(np.exp(hi))) > running_time_s:
        return (
            ws.solve(running_time_s),
            speeds,
            "",
        )  # the schedule itself cannot be met: reported by the caller
    if total(float(np.exp(lo))) > running_time_s:
        V = float(
            np.exp(brentq(lambda x: total(float(np.exp(x))) - running_time_s, lo, hi, xtol=1e-12, rtol=1e-12))
        )
    else:
        V = float(np.exp(lo))
    ws.stretches = (*fixed, (w.position_m, V))
    s, v, t, m = ws._phase_a(big)
    m = m.copy()
    m[-1] = codes.DWELL
    plan = SectionPlan(s, v, t, m, float(t[-1]), big, ws.s1, np.inf, ws.fastest_time_s, True)
    passed = passing_time_s(plan, w.position_m)
    note = (
        f"{w.name or f'timing point at {w.position_m:.0f} m'}: no run can meet its earliest time and the "
        f"section's schedule: passing at {target:.1f} s leaves {slack:.1f} s to the stop, the fastest run "
        f"from there takes {rest:.1f} s; it passes at {passed:.1f} s, {target - passed:.1f} s early"
    )
    return plan, [*speeds[:-1], V], note


def _longest_s(ws: SectionSolver) -> float:
    """The longest running time of the section with its stretch speeds as set [s]: the slowest holding
    speed after the last binding point (coasting from there when the train is faster)."""
    return ws.plan(WALKING_SPEED_MPS).running_time_s


def _lose_time_after(ws: SectionSolver, running_time_s: float, binding, speeds: list[float]):
    """Where passing the last binding point by its latest time leaves more time to the stop than the
    run can take after it (coasting from there it still arrives early: braking down to a lower
    holding speed is not among the strategy's arcs): the run that keeps the section's schedule and
    passes that point as early as it then can, the last stretch's holding speed lowered until the
    longest run after it takes the section's time; (plan, stretch speeds, note)."""
    w, target = binding[-1]
    fixed = [(b.position_m, v) for (b, _), v in zip(binding[:-1], speeds[:-1], strict=True)]

    def spare(log_v: float) -> float:
        ws.stretches = (*fixed, (w.position_m, float(np.exp(log_v))))
        return _longest_s(ws) - running_time_s

    hi = float(np.log(speeds[-1]))
    lo = hi
    while spare(lo) < 0.0:
        hi, lo = lo, lo - np.log(1.3)
        if lo < np.log(WALKING_SPEED_MPS):
            ws.stretches = tuple(fixed)
            return ws.solve(running_time_s), speeds, ""  # not a window's doing: the caller reports
    if hi > lo:
        lo = brentq(spare, lo, hi, xtol=1e-10, rtol=1e-12, maxiter=100)
    # a little below the root, on the side where the schedule can be kept
    for _ in range(20):
        if spare(lo) >= 0.0:
            break
        lo -= 1e-9
    V = float(np.exp(lo))
    ws.stretches = (*fixed, (w.position_m, V))
    plan = ws.solve(running_time_s)
    passed = passing_time_s(plan, w.position_m)
    note = (
        f"{w.name or f'timing point at {w.position_m:.0f} m'}: passes at {passed:.1f} s, "
        f"{passed - target:.1f} s after its latest time, keeping the section's schedule: passing earlier "
        "would leave more time to the stop than the slowest run from there (coasting) takes (braking "
        "down to a lower holding speed is not among the optimal strategy's arcs)"
    )
    return plan, [*speeds[:-1], V], note
