"""Timetable synchronisation: shift departures within windows to minimise substation energy.

Braking trains regenerate; on a line with diode rectifiers their energy is only worth something
when another train accelerates nearby at the same time. Every candidate timetable is solved on the
network with the trains' real runs (one run per service: shifting a departure does not change its
run, only its times), and the search keeps the offsets with the least energy delivered by the
substations over one fixed span (every candidate judged over the same time).

:func:`synchronise_departures` (the power file's ``synchronisation:`` block): each departure (or
each service, all its departures together) gets its own offset within +-``window_s``, keeping the
trains' order and ``min_headway_s`` between consecutive departures on the same track in the same
direction. Method: coordinate search. ``rounds`` passes over the departures in time order, each
trying every offset of the grid -window_s, -window_s + step_s, .. window_s allowed by the headways
to its neighbours (and, with ``avoid_overload``, not putting the substations further beyond their
overload power) and keeping the best; then ``refinements`` passes with the step halved each time,
trying the current offset +- the step. A coordinate search finds an optimum of one offset at a
time, not necessarily the joint optimum; the saving is exact for the offsets it reports (two full
solutions, :attr:`SyncOutcome.baseline_kwh` and :attr:`SyncOutcome.synchronised_kwh`).

Speed: without storage, a step's solution depends only on the trains on the network at that step
(the previous step is only a warm start), so a candidate offset of one departure is judged over the
steps where that departure runs under any of its candidates, with the trains there ("local"
evaluation). With wayside or on-board storage the state of charge carries a shift's effect beyond the
train's run, and every candidate is solved over the whole span ("full").

:func:`synchronise` (older, from a script): one offset per named service over a grid.
Feedback of voltage-limited traction is left out of both searches and applied to the best timetable.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from itertools import pairwise

import numpy as np

from trainsim.constants import KWH
from trainsim.errors import InputError
from trainsim.power.network import Network
from trainsim.power.simulation import PowerResult, TrainLoad, simulate
from trainsim.power.study import FeedbackSettings, TrainService, run_study

__all__ = ["SyncOutcome", "SyncResult", "SyncSettings", "synchronise", "synchronise_departures"]

#: An offset is kept only if it lowers the substation energy by more than this [kWh] (the local
#: evaluations differ from a full pass by the solver tolerance, far below it).
IMPROVEMENT_KWH = 1e-6


@dataclass(frozen=True)
class SyncResult:
    """Outcome of a synchronisation.

    Attributes:
        offsets_s: the chosen shift of each service's departures [s] (by service id).
        baseline_kwh: substation energy of the timetable as given [kWh].
        best_kwh: substation energy of the synchronised timetable [kWh].
        evaluations: network solutions computed.
        result: the synchronised timetable's power result (with feedback).
    """

    offsets_s: dict[str, float]
    baseline_kwh: float
    best_kwh: float
    evaluations: int
    result: PowerResult

    @property
    def saving(self) -> float:
        """Relative saving against the timetable as given [-]."""
        return 1.0 - self.best_kwh / self.baseline_kwh if self.baseline_kwh else 0.0


def _shifted(services: list[TrainService], offsets: dict[str, float]) -> list[TrainService]:
    return [
        dataclasses.replace(s, departures_s=tuple(d + offsets.get(s.id, 0.0) for d in s.departures_s))
        for s in services
    ]


def synchronise(
    network: Network,
    services: list[TrainService],
    windows_s: dict[str, tuple[float, float]],
    *,
    grid_s: float = 10.0,
    rounds: int = 2,
    dt_s: float = 1.0,
    start_s: float | None = None,
    end_s: float | None = None,
) -> SyncResult:
    """Shift the departures of the services named in ``windows_s`` by an offset within
    [lo, hi] [s] (grid ``grid_s``) to minimise the substations' energy over [start_s, end_s] (give
    the window explicitly so that every candidate is judged over the same time)."""
    ids = {s.id for s in services}
    for name, (lo, hi) in windows_s.items():
        if name not in ids:
            raise InputError(
                "unknown train service", field="windows_s", value=name, allowed=", ".join(sorted(ids))
            )
        if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
            raise InputError(
                "invalid window", field=f"windows_s.{name}", value=(lo, hi), allowed="lo <= hi [s]"
            )
    if not grid_s > 0:
        raise InputError("invalid grid", field="grid_s", value=grid_s, allowed="> 0 s")
    if rounds < 1:
        raise InputError("invalid number of rounds", field="rounds", value=rounds, allowed=">= 1")
    off = FeedbackSettings(enabled=False, max_iterations=1)
    cache: dict[tuple, float] = {}

    def energy(offsets: dict[str, float]) -> float:
        key = tuple(sorted(offsets.items()))
        if key not in cache:
            res = run_study(
                network, _shifted(services, offsets), dt_s=dt_s, start_s=start_s, end_s=end_s, feedback=off
            )
            cache[key] = res.summary()["substations_energy_kwh"]
        return cache[key]

    offsets = {name: 0.0 for name in windows_s}
    baseline = energy(offsets)
    best = baseline
    for _ in range(rounds):
        improved = False
        for name, (lo, hi) in windows_s.items():
            for x in np.arange(lo, hi + 1e-9, grid_s):
                trial = {**offsets, name: float(x)}
                e = energy(trial)
                if e < best - 1e-9:
                    best, offsets, improved = e, trial, True
        if not improved:
            break
    result = run_study(network, _shifted(services, offsets), dt_s=dt_s, start_s=start_s, end_s=end_s)
    return SyncResult(offsets, baseline, best, len(cache), result)


def _whole(x: object) -> bool:
    return isinstance(x, int | np.integer) and not isinstance(x, bool)


@dataclass(frozen=True)
class SyncSettings:
    """The search of :func:`synchronise_departures` (the power file's ``synchronisation:`` block).

    Attributes:
        window_s: each offset lies within -window_s .. +window_s [s].
        step_s: grid of the first passes [s].
        rounds: passes over the grid at most (fewer when one pass changes nothing).
        refinements: passes after the grid, the step halved each time.
        min_headway_s: least time between consecutive departures on the same track in the same
            direction [s] (keeps their order).
        per: ``departure`` (an offset each) or ``service`` (one offset for all of a service's).
        avoid_overload: refuse an offset that puts the substations further beyond their overload
            power (energy above it, :func:`overload_excess_kwh`) than the current offsets do:
            synchronising brings starts together and raises the peaks.
    """

    window_s: float = 20.0
    step_s: float = 5.0
    rounds: int = 3
    refinements: int = 2
    min_headway_s: float = 90.0
    per: str = "departure"
    avoid_overload: bool = True

    def __post_init__(self) -> None:
        checks = (
            ("window_s", self.window_s, np.isfinite(self.window_s) and 0 < self.window_s <= 3600, "0 < x <= 3600 s"),
            ("step_s", self.step_s, np.isfinite(self.step_s) and 0 < self.step_s <= self.window_s,
             f"0 < x <= window_s ({self.window_s:g} s)"),
            ("rounds", self.rounds, _whole(self.rounds) and 1 <= self.rounds <= 20, "1 .. 20"),
            ("refinements", self.refinements, _whole(self.refinements) and 0 <= self.refinements <= 10,
             "0 .. 10"),
            ("min_headway_s", self.min_headway_s, np.isfinite(self.min_headway_s) and self.min_headway_s >= 0,
             ">= 0 s"),
            ("per", self.per, self.per in ("departure", "service"), "departure, service"),
        )  # fmt: skip
        for name, value, ok, allowed in checks:
            if not ok:
                raise InputError("invalid synchronisation setting", field=f"synchronisation.{name}", value=value,
                                 allowed=allowed)  # fmt: skip


@dataclass(frozen=True)
class SyncOutcome:
    """What :func:`synchronise_departures` found.

    Attributes:
        status: ``ok``, or ``headway_not_met`` (no timetable within the windows keeps min_headway_s
            between consecutive departures; nothing is shifted).
        offsets_s: offset of each departure [s] (the loads' order).
        baseline_kwh: substation energy of the timetable as given over the span [kWh].
        synchronised_kwh: the same with the offsets [kWh] (a full solution each).
        evaluations: network solutions of candidates.
        evaluation: ``local`` or ``full`` (module doc).
        span_s: (start, end) of the span every candidate is judged over [s].
        message: why the status is not ok, or how the search started.
    """

    status: str
    offsets_s: tuple[float, ...]
    baseline_kwh: float
    synchronised_kwh: float
    evaluations: int
    evaluation: str
    span_s: tuple[float, float]
    message: str = ""

    @property
    def saving_kwh(self) -> float:
        return self.baseline_kwh - self.synchronised_kwh

    @property
    def saving_percent(self) -> float:
        return 100.0 * self.saving_kwh / self.baseline_kwh if self.baseline_kwh else 0.0


def substation_energy_kwh(result: PowerResult) -> float:
    """Energy the substations delivered less what they took back [kWh] (the summary's
    ``substations_energy_kwh``, the same sum)."""
    return float(np.sum(result._e(result.substation_power_w))) / KWH


def overload_excess_kwh(result: PowerResult) -> float:
    """Energy the substations delivered above their overload power, summed over them [kWh] (0 for
    substations without one)."""
    limit = np.array(
        [np.inf if s.overload_power_w is None else s.overload_power_w for s in result.network.substations]
    )
    return float(np.sum(np.maximum(result.substation_power_w - limit, 0.0)) * result.dt_s) / KWH


def _shift(load: TrainLoad, offset_s: float) -> TrainLoad:
    return load if offset_s == 0.0 else dataclasses.replace(load, time_s=load.time_s + offset_s)


def _pairs(departures_s: np.ndarray, groups: list) -> list[tuple[int, int]]:
    """(earlier, later) consecutive departures of each group, in the timetable's order."""
    out = []
    for g in dict.fromkeys(groups):
        mine = sorted((float(departures_s[i]), i) for i in range(len(groups)) if groups[i] == g)
        out += [(a, b) for (_, a), (_, b) in pairwise(mine)]
    return out


def _feasible_start(
    dep: np.ndarray, pairs: list[tuple[int, int]], var: np.ndarray, n_var: int, s: SyncSettings
) -> np.ndarray | None:
    """Offsets per variable keeping every headway within the windows: zero if the timetable keeps
    them; per departure, else, each departure pushed later just enough (or, failing that, as early
    as the window allows) group by group; None if there is none."""
    x = np.zeros(n_var)

    def ok(x: np.ndarray) -> bool:
        return all(dep[b] + x[var[b]] - dep[a] - x[var[a]] >= s.min_headway_s - 1e-9 for a, b in pairs)

    if ok(x) or s.per == "service":
        return x if ok(x) else None
    for first in (0.0, -s.window_s):
        t = dep + first
        for a, b in pairs:  # pairs run in time order within each group
            t[b] = max(dep[b] + first, t[a] + s.min_headway_s)
        x = t - dep
        if np.all(x <= s.window_s + 1e-9) and ok(x):
            return x
    return None


def synchronise_departures(
    network: Network,
    loads: list[TrainLoad],
    groups: list,
    settings: SyncSettings,
    *,
    services: list[str] | None = None,
    dt_s: float = 1.0,
    start_s: float | None = None,
    end_s: float | None = None,
) -> SyncOutcome:
    """Offsets of the departures (``loads``, each at its timetabled time) that minimise the
    substations' energy (module doc). ``groups``: per load, what consecutive departures keep the
    headway within (e.g. (track, direction)); ``services``: per load, its service (``per:
    service``). The span defaults to the trains' span widened by the window on both sides."""
    n = len(loads)
    if not n or len(groups) != n or (services is not None and len(services) != n):
        raise InputError("one group (and service) per departure", field="synchronisation", value=n)
    if settings.per == "service" and services is None:
        raise InputError("per: service needs each departure's service", field="synchronisation.per",
                         value=settings.per, allowed="departure")  # fmt: skip
    w = settings.window_s
    t0 = min(float(x.time_s[0]) for x in loads) - w if start_s is None else float(start_s)
    t1 = max(float(x.time_s[-1]) for x in loads) + w if end_s is None else float(end_s)
    dep = np.array([float(x.time_s[0]) for x in loads])
    names = list(dict.fromkeys(services)) if settings.per == "service" else None
    var = np.array([names.index(sv) for sv in services]) if names else np.arange(n)
    n_var = len(names) if names else n
    pairs = _pairs(dep, groups)
    storage = bool(network.storages) or any(x.onboard_storage is not None for x in loads)
    evaluation = "full" if storage or settings.per == "service" else "local"
    count = 0

    def solve(x: np.ndarray, a: float, b: float, local: bool = False) -> tuple[float, float]:
        nonlocal count
        count += 1
        shifted = [_shift(loads[i], float(x[var[i]])) for i in range(n)]
        if local:
            shifted = [ld for ld in shifted if ld.time_s[-1] >= a and ld.time_s[0] <= b]
        if not shifted:
            return 0.0, 0.0
        res = simulate(network, shifted, dt_s=dt_s, start_s=a, end_s=b, traces="on_network")
        return substation_energy_kwh(res), overload_excess_kwh(res)

    zero = np.zeros(n_var)
    baseline = solve(zero, t0, t1)[0]
    x = _feasible_start(dep, pairs, var, n_var, settings)
    if x is None:
        return SyncOutcome("headway_not_met", tuple(0.0 for _ in range(n)), baseline, baseline, count,
                           evaluation, (t0, t1),
                           f"no timetable within +-{w:g} s keeps {settings.min_headway_s:g} s between consecutive "
                           "departures on the same track and direction: nothing shifted")  # fmt: skip
    message = (
        "" if not np.any(x) else "the timetable as given breaks min_headway_s: the search started from the "
    )
    message += "" if not np.any(x) else "nearest timetable that keeps it"

    def bounds(v: int, x: np.ndarray) -> tuple[float, float]:
        lo, hi = -w, w
        for a, b in pairs:
            if var[b] == v and var[a] != v:
                lo = max(lo, dep[a] + x[var[a]] + settings.min_headway_s - dep[b])
            elif var[a] == v and var[b] != v:
                hi = min(hi, dep[b] + x[var[b]] - settings.min_headway_s - dep[a])
        return lo, hi

    def best_of(v: int, x: np.ndarray, candidates: np.ndarray) -> float:
        lo, hi = bounds(v, x)
        cands = sorted({float(c) for c in candidates if lo - 1e-9 <= c <= hi + 1e-9} | {float(x[v])})
        if len(cands) == 1:
            return float(x[v])
        if evaluation == "full":
            a, b = t0, t1
        else:
            mine = np.flatnonzero(var == v)
            first = min(float(loads[i].time_s[0]) for i in mine) + min(cands)
            last = max(float(loads[i].time_s[-1]) for i in mine) + max(cands)
            # the local span on the global grid, so that every step is sampled as in a full pass
            a = t0 + dt_s * max(np.floor((first - t0) / dt_s) - 1, 0)
            b = min(t0 + dt_s * (np.ceil((last - t0) / dt_s) + 1), t1)
        energies = {c: solve(np.where(np.arange(n_var) == v, c, x), a, b, evaluation == "local")
                    for c in cands}  # fmt: skip
        now = energies[float(x[v])]
        if settings.avoid_overload:
            # a shift may not put the substations further beyond their overload power than they are
            cands = [c for c in cands if energies[c][1] <= now[1] + IMPROVEMENT_KWH]
        best = min(cands, key=lambda c: (energies[c][0], abs(c)))
        return best if energies[best][0] < now[0] - IMPROVEMENT_KWH else float(x[v])

    order = np.argsort([min(dep[var == v]) for v in range(n_var)], kind="stable")
    grid = np.arange(-w, w + 1e-9, settings.step_s)
    for _ in range(settings.rounds):
        changed = False
        for v in order:
            new = best_of(int(v), x, grid)
            changed |= new != x[v]
            x[v] = new
        if not changed:
            break
    step = settings.step_s
    for _ in range(settings.refinements):
        step /= 2
        for v in order:
            x[v] = best_of(int(v), x, np.array([x[v] - step, x[v] + step]))
    synchronised = solve(x, t0, t1)[0] if np.any(x) else baseline
    return SyncOutcome("ok", tuple(float(x[var[i]]) for i in range(n)), baseline, synchronised, count,
                       evaluation, (t0, t1), message)  # fmt: skip
