"""Single-train runs for the operations layer: the line's geometry per direction, a train's route
through it, and its fastest run with a given set of stops, cached.

Everything here goes through the public single-train API (``trainsim.run_fastest``). A run between
stops does not depend on how long the train stands at them, so a run is computed once with every dwell
set to zero and the standing times are put in afterwards (``Movement.trajectory``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from itertools import pairwise

import numpy as np

from trainsim.constants import KWH
from trainsim.errors import InputError
from trainsim.model import Route, SpeedLimit, Station, Train
from trainsim.model.scenario import RunSettings
from trainsim.model.spans import route_between
from trainsim.model.timetable import SectionSchedule, Timetable, TimingPoint
from trainsim.operations.blocking import Trajectory
from trainsim.operations.ceiling import with_limits
from trainsim.sim.fastest import run_fastest
from trainsim.sim.profile import line_resistance_profile, speed_ceiling
from trainsim.sim.result import RunResult, build_result

#: Two stops of one run closer than this are merged (the core needs them >= 1 m apart) [m].
MIN_STOP_SPACING_M = 2.0
#: Speed caps of the slowed runs of a stretch (running-time disturbances), as fractions of the top
#: speed of its undisturbed run [-]; 1 is the undisturbed run. They bracket the cap that takes a
#: disturbed running time (``RunCache.capped``); a run at the lowest is as slow as a stretch is driven.
SLOWED_CAP_FRACTIONS = tuple(round(1.0 - 0.05 * k, 2) for k in range(17))  # 1.0 .. 0.2
#: A capped run whose running time is this close to the disturbed one takes it [s].
CAP_TIME_TOLERANCE_S = 1e-7
#: Root-find steps on the cap before giving up (Illinois converges in some 5 to 10 on smooth runs).
CAP_MAX_ITERATIONS = 60
#: Running-time reserve of a signal-aware stretch over the shortest running time that meets its timing
#: points, when the schedule is shorter than that: at the shortest time the run would have to stand at
#: its origin, which the optimisation (time as integral of ds / v) cannot do.
AWARE_RESERVE = 0.05
#: An energy-efficient stretch whose scheduled running time is within this of the fastest run's is
#: driven fastest (no time to save energy with) [s].
ECO_MIN_SUPPLEMENT_S = 1e-3


@dataclass(frozen=True)
class EcoPlan:
    """How one stretch between two stops is to be driven energy-efficiently.

    Attributes:
        running_time_s: the running time to take [s].
        timing_points: earliest passing times from the stretch's departure (running positions) [m, s].
    """

    running_time_s: float
    timing_points: tuple[TimingPoint, ...] = ()

    def key(self) -> tuple:
        return (
            round(self.running_time_s, 6),
            tuple((round(p.position_m, 6), round(p.earliest_s or 0.0, 6)) for p in self.timing_points),
        )


@dataclass(frozen=True)
class CappedRun:
    """How a stretch is driven to take a longer running time (``RunCache.capped``).

    Attributes:
        limit: the extra speed cap over the stretch (running positions, [m/s]), or None (the
            undisturbed run, or no capped run is ``ok``).
        running_time_s: running time of the run under it [s].
        hold_s: the time no capped run takes, stood before leaving the stretch's first stop [s].
        status: ``ok`` (within ``CAP_TIME_TOLERANCE_S`` of the target), ``undisturbed`` (no slower run
            needed), ``beyond_lowest_cap`` (longer than the run at the lowest cap of
            ``SLOWED_CAP_FRACTIONS``), ``no_slower_run`` (a lower cap's run is not ``ok`` or not
            slower), ``capped_run_failed`` (a run inside the bracket is not ``ok``) or
            ``not_converged``; in the last four the slowest suitable cap is driven and ``hold_s``
            stood.
    """

    limit: SpeedLimit | None
    running_time_s: float
    hold_s: float
    status: str


def _mirror_spans(items: tuple, length_m: float, **fields) -> tuple:
    out = []
    for x in items:
        values = {k: f(x) for k, f in fields.items()}
        out.append(replace(x, start_m=length_m - x.end_m, end_m=length_m - x.start_m, **values))
    return tuple(sorted(out, key=lambda y: y.start_m))


def direction_route(geometry: Route, length_m: float, direction: str) -> Route:
    """The line's geometry (a ``Route`` in up-direction positions over ``0 .. length_m``) as seen by a
    train in ``direction``: for ``down`` every position ``x`` becomes ``length_m - x`` and gradients
    change sign."""
    if direction == "up":
        return geometry
    return replace(
        geometry,
        name=f"{geometry.name} (down)",
        start_m=length_m - geometry.end_m,
        end_m=length_m - geometry.start_m,
        stations=tuple(
            Station(s.name, length_m - s.position_m, s.dwell_s, s.stop) for s in reversed(geometry.stations)
        ),
        speed_limits=_mirror_spans(geometry.speed_limits, length_m),
        gradients=_mirror_spans(
            geometry.gradients, length_m, gradient_permille=lambda g: -g.gradient_permille
        ),
        curves=_mirror_spans(geometry.curves, length_m),
        tunnels=_mirror_spans(geometry.tunnels, length_m),
        electrification=_mirror_spans(geometry.electrification, length_m),
    )


def service_route(
    directed: Route, stops: list[tuple[str, float]], limits: Sequence[SpeedLimit] = ()
) -> Route:
    """The route of one run: ``directed`` cut from its first to its last stop, stopping (dwell 0) at
    every ``(name, running position)`` of ``stops``, with the extra speed ceilings ``limits`` (running
    positions) laid over the line's limits."""
    a, b = stops[0][1], stops[-1][1]
    route = route_between(directed, a, b, [Station(n, p, 0.0, True) for n, p in stops])
    return with_limits(route, limits)


@dataclass(frozen=True)
class Movement:
    """A train's fastest run through its stops with zero dwell times, joined from one run per stretch
    between two stops.

    Attributes:
        stops_m: the stop positions (running coordinate, first and last included) [m].
        position_m, speed_mps, time_s: the joined trace [m, m/s, s].
        arrival_index, departure_index: trace index of arriving at / leaving each stop.
        results: the core's run of each stretch.
    """

    stops_m: tuple[float, ...]
    position_m: np.ndarray
    speed_mps: np.ndarray
    time_s: np.ndarray
    arrival_index: np.ndarray
    departure_index: np.ndarray
    results: tuple[RunResult, ...]

    @property
    def status(self) -> str:
        """``ok``, or the status of the first stretch that is not."""
        return next((r.status for r in self.results if r.status != "ok"), "ok")

    @property
    def warnings(self) -> list[str]:
        """The warnings of every stretch."""
        return [w for r in self.results for w in r.warnings]

    def running_times_s(self) -> np.ndarray:
        """Running time from each stop to the next [s]."""
        return self.time_s[self.arrival_index[1:]] - self.time_s[self.departure_index[:-1]]

    def trajectory(
        self,
        departures_s: list[float],
        length_m: float,
        final_dwell_s: float = 0.0,
        time_factors: Sequence[float] | None = None,
        lead_s: float = 0.0,
    ) -> Trajectory:
        """The trajectory when the train leaves stop ``k`` at ``departures_s[k]`` (one per stop but the
        last) [s]; the last stop is held for ``final_dwell_s`` [s]. ``time_factors[k]`` (>= 1) stretches
        the run from stop ``k`` in time (a running-time disturbance: the same path driven slower, speed
        divided by the factor, so that the train is late at every point by the share of the running
        time it has run). ``lead_s`` > 0 puts a stand of that long at the first stop before leaving it
        into the trajectory (a disturbance no run takes, ``RunCache.capped``) [s]."""
        rel, seg, position_m, speed_mps = self._pieces(len(departures_s))
        dep = np.append(np.asarray(departures_s, dtype=float), 0.0)
        if time_factors is None:
            # per sample (t - t[i0]) + dep, in that order: the same floats as slicing stretch by stretch
            time_s = rel + dep[seg]
        else:
            f = np.append(np.asarray(time_factors, dtype=float), 1.0)[seg]
            time_s = rel * f + dep[seg]
            speed_mps = speed_mps / f  # a new array: the shared one stays as it is
        time_s[-1] = time_s[-2] + final_dwell_s
        if lead_s > 0:
            time_s = np.insert(time_s, 0, time_s[0] - lead_s)
            position_m = np.insert(position_m, 0, position_m[0])
            speed_mps = np.insert(speed_mps, 0, 0.0)
        # position and speed do not depend on the departures: every trajectory shares them (read-only)
        return Trajectory(time_s, position_m, speed_mps, length_m)

    def _pieces(self, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The first ``n`` joined stretches (the last sample repeated for the final stand): time from
        each stretch's start, the stretch of each sample, position and speed, computed once per
        movement."""
        cache = self.__dict__.setdefault("_pieces_cache", {})
        found = cache.get(n)
        if found is None:
            idx, seg = [], []
            for k in range(n):
                i0, i1 = int(self.departure_index[k]), int(self.arrival_index[k + 1])
                idx.append(np.arange(i0, i1 + 1))
                seg.append(np.full(i1 + 1 - i0, k))
            idx.append(idx[-1][-1:])
            seg.append(np.array([n]))
            idx_a, seg_a = np.concatenate(idx), np.concatenate(seg)
            starts = self.time_s[self.departure_index[:n].astype(int)]
            t0 = np.append(starts, 0.0)[seg_a]
            position_m, speed_mps = self.position_m[idx_a], self.speed_mps[idx_a]
            position_m.flags.writeable = speed_mps.flags.writeable = False
            found = cache[n] = (self.time_s[idx_a] - t0, seg_a, position_m, speed_mps)
        return found

    def energy_kwh(self, standing_s: float, auxiliary_power_w: float) -> float:
        """Net energy from the line of the runs plus the auxiliaries while standing ``standing_s`` [kWh]."""
        return float(sum(r.energy_kwh.net for r in self.results) + auxiliary_power_w * standing_s / KWH)


@dataclass(frozen=True, eq=False)
class Splice:
    """An energy-efficient stretch a signal stopped or slowed the train on: the energy-efficient run
    it was driving (``position_m``, ``speed_mps``, ``time_s``, ``regime``, from the stretch's first
    stop) up to where the fastest run under the driver's braking curve meets it, at or before
    ``start_m`` where the driver starts braking, and that fastest run from there (``RunCache.movement``).
    Compared by identity (one per signal stop)."""

    position_m: np.ndarray
    speed_mps: np.ndarray
    time_s: np.ndarray
    regime: np.ndarray
    start_m: float
    driven: str = "optimal"

    def key(self) -> tuple:
        return ("splice", id(self))


def splice_point(
    eco_s: np.ndarray, eco_v: np.ndarray, fast_s: np.ndarray, fast_v: np.ndarray, start_m: float
) -> float:
    """Where a run under the braking curve from ``start_m`` takes over from the energy-efficient run
    [m]: the last position at or before ``start_m`` where the fastest run under the curve is not
    slower than the energy-efficient one (the fastest run is faster everywhere before it brakes to
    the curve's first step, which is the energy-efficient speed at ``start_m``)."""
    grid = np.unique(np.concatenate([eco_s[eco_s <= start_m], fast_s[fast_s <= start_m], [start_m]]))
    diff = np.interp(grid, fast_s, fast_v) - np.interp(grid, eco_s, eco_v)
    ok = np.nonzero(diff >= -1e-9)[0]
    return float(grid[ok[-1]]) if ok.size else float(grid[0])


class RunCache:
    """Fastest runs by train, direction and stretch between two stops, so that identical stretches are
    simulated once: a train held at one more signal only needs the two runs of the stretch it splits.

    A run from a stop to the next does not depend on the other stops (the train is at rest at both
    ends); the one approximation is that a speed limit behind a stop, still under the train's rear when
    it starts, is not held.
    """

    def __init__(self, settings: RunSettings) -> None:
        self.settings = settings
        self._runs: dict[tuple, tuple[np.ndarray, np.ndarray, np.ndarray, RunResult]] = {}
        self._keep: list[object] = []
        self._routes: dict[tuple, Route] = {}
        self._movements: dict[tuple, Movement] = {}
        self._limit_keys: dict[int, tuple[SpeedLimit, tuple[float, float, float]]] = {}
        self._capped_trains: dict[tuple[int, float], tuple[Train, Train]] = {}
        self.computed = 0
        self.hits = 0

    def _limits_key(self, limits: Sequence[SpeedLimit]) -> tuple:
        """The limits rounded (1 um, 1 nm/s) for the cache keys, each limit rounded once: a train's
        braking steps are asked for again at every stretch and every new stop."""
        keys = self._limit_keys
        out = []
        for x in limits:
            found = keys.get(id(x))
            if found is None or found[0] is not x:
                found = keys[id(x)] = (x, (round(x.start_m, 6), round(x.end_m, 6), round(x.limit_mps, 9)))
            out.append(found[1])
        return tuple(out)

    def directed(self, geometry: Route, length_m: float, direction: str) -> Route:
        """``direction_route(geometry, length_m, direction)``, one object per geometry and direction (the
        runs are cached by it)."""
        key = ("directed", id(geometry), float(length_m), direction)
        found = self._routes.get(key)
        if found is None:
            self._keep.append(geometry)
            found = self._routes[key] = direction_route(geometry, length_m, direction)
        return found

    def _stretch_key(
        self, train: Train, directed: Route, a: tuple[str, float], b: tuple[str, float], limits
    ) -> tuple[tuple[SpeedLimit, ...], tuple]:
        """The extra limits that reach into the stretch from ``a`` to ``b``, and the cache key of a run
        of ``train`` over it under them."""
        limits = tuple(x for x in limits if x.end_m > a[1] and x.start_m < b[1])
        return limits, (id(train), id(directed), round(a[1], 6), round(b[1], 6), self._limits_key(limits))

    def stretch(
        self,
        train: Train,
        directed: Route,
        a: tuple[str, float],
        b: tuple[str, float],
        limits: Sequence[SpeedLimit] = (),
    ):
        """The fastest run from stop ``a`` to stop ``b`` (names and running positions) under the extra
        ceilings ``limits``: (position, speed, time, result)."""
        limits, key = self._stretch_key(train, directed, a, b, limits)
        found = self._runs.get(key)
        if found is not None:
            self.hits += 1
            return found
        found = self._runs[key] = self._run_stretch(train, directed, a, b, limits)
        return found

    def eco_stretch(
        self,
        train: Train,
        directed: Route,
        a: tuple[str, float],
        b: tuple[str, float],
        limits: Sequence[SpeedLimit],
        plan: EcoPlan,
    ):
        """The energy-efficient run from stop ``a`` to stop ``b`` under the extra ceilings ``limits`` in
        ``plan.running_time_s`` passing ``plan.timing_points`` no earlier than their times
        (``trainsim.optimize.api.optimize``, strategy ``optimal``): (position, speed, time, result,
        optimisation). The caller makes sure the running time is longer than the fastest run's."""
        from trainsim.optimize.api import optimize

        limits, key = self._stretch_key(train, directed, a, b, limits)
        key = ("eco", *key, plan.key())
        found = self._runs.get(key)
        if found is not None:
            self.hits += 1
            return found
        self._keep.extend((train, directed))
        timetable = Timetable(
            sections=(SectionSchedule(running_time_s=plan.running_time_s),), timing_points=plan.timing_points
        )
        opt = optimize(train, service_route(directed, [a, b], limits), timetable, "optimal", self.settings)
        tr = opt.run.trace
        s, v, t = tr.position_m, tr.speed_mps, tr.time_s
        if abs(s[-1] - b[1]) > 1e-6:
            s, v, t = np.append(s, b[1]), np.append(v, 0.0), np.append(t, t[-1])
        self.computed += 1
        found = self._runs[key] = (s, v, t, opt.run, opt)
        return found

    def spliced_stretch(
        self,
        train: Train,
        directed: Route,
        a: tuple[str, float],
        b: tuple[str, float],
        limits: Sequence[SpeedLimit],
        splice: Splice,
    ):
        """The run from stop ``a`` to stop ``b`` of an energy-efficient stretch a signal stopped or
        slowed the train on (``Splice``): (position, speed, time, result); the result's figures are
        evaluated along the joined points (``build_result``)."""
        limits, key = self._stretch_key(train, directed, a, b, limits)
        key = ("spliced", *key, splice.key())
        found = self._runs.get(key)
        if found is not None:
            self.hits += 1
            return found
        fs, fv, ft, fr = self.stretch(train, directed, a, b, limits)
        if fr.status != "ok" or fr.trace is None:
            return fs, fv, ft, fr
        self._keep.append(splice)
        x = splice_point(splice.position_m, splice.speed_mps, fs, fv, splice.start_m)
        e = splice.position_m < x - 1e-9
        f = fs >= x - 1e-9
        t_e = float(np.interp(x, splice.position_m, splice.time_s))
        t_f = float(np.interp(x, fs, ft))
        s = np.concatenate([splice.position_m[e], fs[f]])
        v = np.concatenate([splice.speed_mps[e], fv[f]])
        t = np.concatenate([splice.time_s[e], ft[f] - t_f + t_e])
        fregime = fr.trace.regime
        if len(fregime) < len(fs):
            # ``stretch`` appended the end point: it takes the last regime
            fregime = np.concatenate([fregime, fregime[-1:]])
        fregime = fregime[f]
        regime = np.concatenate([splice.regime[e], fregime]).astype(np.int8)
        route = service_route(directed, [a, b], limits)
        result = build_result(
            train=train,
            route=route,
            settings=self.settings,
            profile=line_resistance_profile(route, train),
            ceiling=speed_ceiling(route, train),
            s=s,
            v=v,
            t=t,
            regime=regime,
            status="ok",
            kind="spliced",
        )
        self.computed += 1
        found = self._runs[key] = (s, v, t, result)
        return found

    def _run_stretch(
        self, train: Train, directed: Route, a: tuple[str, float], b: tuple[str, float], limits: tuple
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, RunResult]:
        """``stretch`` computed, not looked up nor kept."""
        self._keep.extend((train, directed))  # ids stay valid while the cache lives
        result = run_fastest(train, service_route(directed, [a, b], limits), self.settings)
        tr = result.trace
        s, v, t = tr.position_m, tr.speed_mps, tr.time_s
        if result.status == "ok" and abs(s[-1] - b[1]) > 1e-6:
            s, v, t = np.append(s, b[1]), np.append(v, 0.0), np.append(t, t[-1])
        self.computed += 1
        return s, v, t, result

    def slowed(
        self,
        train: Train,
        directed: Route,
        a: tuple[str, float],
        b: tuple[str, float],
        limits: Sequence[SpeedLimit] = (),
        upto_s: float = np.inf,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The stretch from stop ``a`` to stop ``b`` run slower: the fastest run under an extra speed cap
        over the whole stretch at each of :data:`SLOWED_CAP_FRACTIONS` of the undisturbed run's top
        speed (the same driving, at a lower line speed). Returns the caps [m/s], running times [s]
        (strictly increasing) and net energies from the line [kWh, auxiliaries included]; the first
        entry is the undisturbed run. Caps whose run is not ``ok`` or not slower end the table. The
        caps are run in turn only until one takes ``upto_s`` [s] or more (a disturbance of a few
        seconds needs two or three runs), the rest when a longer time is asked for."""
        limits, key = self._stretch_key(train, directed, a, b, limits)
        key = ("slowed", *key)
        table = self._runs.get(key)
        if table is None:
            _s, v, t, result = self.stretch(train, directed, a, b, limits)
            # [caps, times, energies, index of the next cap to run (len: the table is complete)]
            table = [[float(np.max(v))], [float(t[-1] - t[0])], [float(result.energy_kwh.net)], 1]
            if result.status != "ok":
                table[3] = len(SLOWED_CAP_FRACTIONS)
            self._runs[key] = table
        caps, times, energies = table[0], table[1], table[2]
        while table[3] < len(SLOWED_CAP_FRACTIONS) and times[-1] < upto_s:
            cap = SpeedLimit(a[1], b[1], SLOWED_CAP_FRACTIONS[table[3]] * caps[0])
            run = run_fastest(
                train, service_route(directed, [a, b], (*limits, cap)), self.settings, trace=False
            )
            self.computed += 1
            table[3] += 1
            if run.status != "ok" or run.running_time_s <= times[-1]:
                table[3] = len(SLOWED_CAP_FRACTIONS)
                break
            caps.append(cap.limit_mps)
            times.append(float(run.running_time_s))
            energies.append(float(run.energy_kwh.net))
        return np.array(caps), np.array(times), np.array(energies)

    def capped(
        self,
        train: Train,
        directed: Route,
        a: tuple[str, float],
        b: tuple[str, float],
        limits: Sequence[SpeedLimit],
        running_time_s: float,
    ) -> CappedRun:
        """The stretch from stop ``a`` to stop ``b`` driven so that it takes ``running_time_s`` [s]:
        the fastest run under one extra speed cap over the whole stretch, the cap found by a
        root-find on the running time (inverse quadratic interpolation in 1 / cap, safeguarded by
        Illinois regula falsi on a bracket of two capped runs of ``slowed``) to
        :data:`CAP_TIME_TOLERANCE_S`. The run itself is ``stretch`` under ``limits``
        plus ``CappedRun.limit``, so the trajectory, blocking times and energy of a disturbed
        stretch are one run's.

        Where no capped run takes the time (longer than the run at the lowest cap, or a cap whose run
        is not ``ok``, or no convergence), the fallback is explicit: the slowest capped run that is
        not too slow, and the rest of the time as a stand before leaving ``a``
        (``CappedRun.hold_s``, ``status`` says why)."""
        limits, _key = self._stretch_key(train, directed, a, b, limits)
        caps, times, _energies = self.slowed(train, directed, a, b, limits, running_time_s)
        target = float(running_time_s)
        if target - times[0] <= CAP_TIME_TOLERANCE_S:
            # within the tolerance: the undisturbed run takes it
            return CappedRun(None, float(times[0]), 0.0, "undisturbed")
        if target > times[-1]:
            status = "beyond_lowest_cap" if len(times) == len(SLOWED_CAP_FRACTIONS) else "no_slower_run"
            return self._capped_at(train, directed, a, b, limits, float(caps[-1]), target, status)
        k = int(np.searchsorted(times, target))  # times[k - 1] < target <= times[k]
        # bracket: fast side (time below target, higher cap) and slow side (time above)
        c_fast, g_fast = float(caps[k - 1]), float(times[k - 1]) - target
        c_slow, g_slow = float(caps[k]), float(times[k]) - target
        if abs(g_slow) <= CAP_TIME_TOLERANCE_S:
            return self._capped_at(train, directed, a, b, limits, c_slow, target, "ok")
        # known (time error, 1 / cap): the running time is close to linear in 1 / cap (a stretch run at
        # the cap: length / cap plus the time to reach it and brake from it)
        known = [(float(times[j]) - target, 1.0 / float(caps[j])) for j in range(max(k - 2, 0), k + 1)]
        side = 0
        for _ in range(CAP_MAX_ITERATIONS):
            c = _inverse_quadratic(known[-3:])
            if not c_slow < c < c_fast:
                # Illinois regula falsi in 1 / cap on the bracket, else bisection
                u_fast, u_slow = 1.0 / c_fast, 1.0 / c_slow
                c = 1.0 / (u_fast - g_fast * (u_slow - u_fast) / (g_slow - g_fast))
                if not c_slow < c < c_fast:
                    c = 0.5 * (c_slow + c_fast)
            # traced (it costs little more): the run that takes the time is the one kept
            with_cap, key = self._stretch_key(train, directed, a, b, (*limits, SpeedLimit(a[1], b[1], c)))
            found = self._run_stretch(train, directed, a, b, with_cap)
            if found[3].status != "ok":
                return self._capped_at(train, directed, a, b, limits, c_fast, target, "capped_run_failed")
            g = float(found[3].running_time_s) - target
            if abs(g) <= CAP_TIME_TOLERANCE_S:
                self._runs.setdefault(key, found)
                return self._capped_at(train, directed, a, b, limits, c, target, "ok")
            known.append((g, 1.0 / c))
            # Illinois: halve the weight of an end point kept twice in a row (no stagnation)
            if g < 0:
                c_fast, g_fast = c, g
                g_slow = g_slow * 0.5 if side == -1 else g_slow
                side = -1
            else:
                c_slow, g_slow = c, g
                g_fast = g_fast * 0.5 if side == 1 else g_fast
                side = 1
            if c_fast - c_slow <= 1e-12 * c_fast:
                break
        return self._capped_at(train, directed, a, b, limits, c_fast, target, "not_converged")

    def _capped_at(
        self,
        train: Train,
        directed: Route,
        a: tuple[str, float],
        b: tuple[str, float],
        limits: tuple[SpeedLimit, ...],
        cap_mps: float,
        target_s: float,
        status: str,
    ) -> CappedRun:
        """The traced run of the stretch under ``cap_mps`` [m/s] and what is left of ``target_s`` [s]
        as a stand (0 when it is not slower than the target)."""
        limit = SpeedLimit(a[1], b[1], cap_mps)
        _s, _v, t, result = self.stretch(train, directed, a, b, (*limits, limit))
        if result.status != "ok":
            _s, _v, t, result = self.stretch(train, directed, a, b, limits)
            run_s = float(t[-1] - t[0])
            return CappedRun(None, run_s, max(target_s - run_s, 0.0), "capped_run_failed")
        run_s = float(t[-1] - t[0])
        hold = 0.0 if status == "ok" else max(target_s - run_s, 0.0)
        return CappedRun(limit, run_s, hold, status)

    def power_capped(self, train: Train, power_cap_w: float) -> Train:
        """``train`` with its traction power at the wheel capped at ``power_cap_w`` [W]
        (``EffortCurve.capped``); ``train`` itself when the cap is infinite. One object per train and
        cap, kept alive here: the runs are cached by the train's ``id``, which a collected train
        could hand on to another one."""
        if not np.isfinite(power_cap_w):
            return train
        if not power_cap_w > 0:
            raise InputError("invalid traction power cap", field="traction_power_cap_w", value=power_cap_w,
                             allowed="> 0 W, or infinite for none")  # fmt: skip
        key = (id(train), float(power_cap_w))
        found = self._capped_trains.get(key)
        if found is None or found[0] is not train:
            capped = replace(train, traction=train.traction.capped(power_cap_w=float(power_cap_w)))
            found = self._capped_trains[key] = (train, capped)
        return found[1]

    def movement(
        self,
        train: Train,
        directed: Route,
        stops: list[tuple[str, float]],
        limits: Sequence[SpeedLimit] = (),
        eco: dict[int, EcoPlan | Splice] | None = None,
    ) -> Movement:
        """The fastest run of ``train`` on ``directed`` through ``stops`` (names and running positions)
        under the extra ceilings ``limits`` (running positions); one object per train, route, stop
        positions and limits (identical trains, or a train trying the same stops again, share it).
        ``eco[k]``: stretch ``k`` (from ``stops[k]``) driven energy-efficiently (``eco_stretch``)."""
        eco = eco or {}
        key = (
            id(train), id(directed), tuple(round(p, 6) for _n, p in stops),
            self._limits_key(limits), tuple(sorted((k, p.key()) for k, p in eco.items())),
        )  # fmt: skip
        found = self._movements.get(key)
        if found is not None:
            self.hits += len(stops) - 1
            return found
        found = self._movements[key] = self._movement(train, directed, stops, limits, eco)
        return found

    def _movement(
        self,
        train: Train,
        directed: Route,
        stops: list[tuple[str, float]],
        limits: Sequence[SpeedLimit],
        eco: dict[int, EcoPlan | Splice],
    ) -> Movement:
        ss, vs, ts, results = [], [], [], []
        arr, dep = [0], [0]
        n = 0
        t0 = 0.0
        for k, (a, b) in enumerate(pairwise(stops)):
            if isinstance(eco.get(k), Splice):
                s, v, t, result = self.spliced_stretch(train, directed, a, b, limits, eco[k])
            elif k in eco:
                s, v, t, result, _opt = self.eco_stretch(train, directed, a, b, limits, eco[k])
            else:
                s, v, t, result = self.stretch(train, directed, a, b, limits)
            ss.append(s)
            vs.append(v)
            ts.append(t - t[0] + t0)
            results.append(result)
            dep[-1] = n
            n += len(s)
            arr.append(n - 1)
            dep.append(n - 1)
            t0 = ts[-1][-1]
            if result.status != "ok":
                # a stalled run ends where it stalled: the stops it did not reach point at its end
                arr.extend([n - 1] * (len(stops) - len(arr)))
                dep.extend([n - 1] * (len(stops) - len(dep)))
                break
        return Movement(
            tuple(float(p) for _, p in stops),
            np.concatenate(ss),
            np.concatenate(vs),
            np.concatenate(ts),
            np.array(arr),
            np.array(dep),
            tuple(results),
        )


def _inverse_quadratic(points: list[tuple[float, float]]) -> float:
    """The cap [m/s] where the time error is 0 by Lagrange interpolation of 1 / cap over the time error
    through the (error [s], 1 / cap [s/m]) ``points`` (two: the secant); NaN when two errors coincide
    (the caller then steps on its bracket)."""
    g = [p[0] for p in points]
    u = [p[1] for p in points]
    total = 0.0
    for i in range(len(points)):
        w = u[i]
        for j in range(len(points)):
            if j != i:
                if g[i] == g[j]:
                    return float("nan")
                w *= g[j] / (g[j] - g[i])
        total += w
    return 1.0 / total if total > 0 else float("nan")


def min_running_time_s(position_m: np.ndarray, time_s: np.ndarray, points: Sequence[TimingPoint]) -> float:
    """The shortest running time of a stretch that passes every point no earlier than its
    ``earliest_s`` [s], from the stretch's fastest run (``position_m``, ``time_s`` from its start)
    [m, s]: ``T_f + max(0, max_k(e_k - t_f(x_k)))``.

    The fastest run's speed is the highest any run can have at each position, so a run passing
    ``x_k`` no earlier than ``e_k`` needs at least ``e_k + T_f - t_f(x_k)``; the fastest run started
    ``max_k(e_k - t_f(x_k))`` later (standing at the origin meanwhile) meets every point and takes
    exactly the largest of these bounds."""
    total = float(time_s[-1] - time_s[0])
    wait = 0.0
    for p in points:
        if p.earliest_s is not None:
            t_f = float(np.interp(p.position_m, position_m, time_s) - time_s[0])
            wait = max(wait, float(p.earliest_s) - t_f)
    return total + wait


def auxiliary_power_w(train: Train) -> float:
    """The train's auxiliary power, 0 without electrical data [W]."""
    return float(train.electrical.auxiliary_power_w) if train.electrical is not None else 0.0


__all__ = [
    "AWARE_RESERVE",
    "CAP_TIME_TOLERANCE_S",
    "ECO_MIN_SUPPLEMENT_S",
    "CappedRun",
    "EcoPlan",
    "Movement",
    "RunCache",
    "Splice",
    "auxiliary_power_w",
    "direction_route",
    "min_running_time_s",
    "service_route",
    "splice_point",
]
