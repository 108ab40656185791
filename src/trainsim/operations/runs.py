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
from trainsim.model import Route, SpeedLimit, Station, Train
from trainsim.model.scenario import RunSettings
from trainsim.model.spans import route_between
from trainsim.operations.blocking import Trajectory
from trainsim.operations.ceiling import with_limits
from trainsim.sim.fastest import run_fastest
from trainsim.sim.result import RunResult

#: Two stops of one run closer than this are merged (the core needs them >= 1 m apart) [m].
MIN_STOP_SPACING_M = 2.0
#: Speed caps of the slowed runs of a stretch (running-time disturbances), as fractions of the top
#: speed of its undisturbed run [-]; 1 is the undisturbed run. Steps of 5 % keep linear
#: interpolation of the energy in running time within a few 0.1 % (tests/operations/test_slowed_energy.py).
SLOWED_CAP_FRACTIONS = tuple(round(1.0 - 0.05 * k, 2) for k in range(17))  # 1.0 .. 0.2


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
    ) -> Trajectory:
        """The trajectory when the train leaves stop ``k`` at ``departures_s[k]`` (one per stop but the
        last) [s]; the last stop is held for ``final_dwell_s`` [s]. ``time_factors[k]`` (>= 1) stretches
        the run from stop ``k`` in time (a running-time disturbance: the same path driven slower, speed
        divided by the factor, so that the train is late at every point by the share of the running
        time it has run)."""
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
        self._keep.extend((train, directed))  # ids stay valid while the cache lives
        result = run_fastest(train, service_route(directed, [a, b], limits), self.settings)
        tr = result.trace
        s, v, t = tr.position_m, tr.speed_mps, tr.time_s
        if result.status == "ok" and abs(s[-1] - b[1]) > 1e-6:
            s, v, t = np.append(s, b[1]), np.append(v, 0.0), np.append(t, t[-1])
        found = (s, v, t, result)
        self._runs[key] = found
        self.computed += 1
        return found

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

    def slowed_energy_kwh(
        self,
        train: Train,
        directed: Route,
        a: tuple[str, float],
        b: tuple[str, float],
        limits: Sequence[SpeedLimit],
        running_time_s: float,
    ) -> tuple[float, float]:
        """Net energy from the line [kWh] of the stretch from ``a`` to ``b`` run slower so that it takes
        ``running_time_s`` [s]: linear in running time between two of the capped runs of ``slowed``
        (each one the core's run, auxiliaries included). Returns it with the time beyond the slowest
        capped run [s] (0 inside the table), counted as standing at auxiliary power: a longer running
        time than a run at a fifth of the top speed is a stand somewhere on the stretch."""
        _caps, times, energies = self.slowed(train, directed, a, b, limits, running_time_s)
        if running_time_s <= times[-1]:
            return float(np.interp(running_time_s, times, energies)), 0.0
        beyond = float(running_time_s - times[-1])
        return float(energies[-1] + auxiliary_power_w(train) * beyond / KWH), beyond

    def movement(
        self,
        train: Train,
        directed: Route,
        stops: list[tuple[str, float]],
        limits: Sequence[SpeedLimit] = (),
    ) -> Movement:
        """The fastest run of ``train`` on ``directed`` through ``stops`` (names and running positions)
        under the extra ceilings ``limits`` (running positions); one object per train, route, stop
        positions and limits (identical trains, or a train trying the same stops again, share it)."""
        key = (
            id(train), id(directed), tuple(round(p, 6) for _n, p in stops),
            self._limits_key(limits),
        )  # fmt: skip
        found = self._movements.get(key)
        if found is not None:
            self.hits += len(stops) - 1
            return found
        found = self._movements[key] = self._movement(train, directed, stops, limits)
        return found

    def _movement(
        self, train: Train, directed: Route, stops: list[tuple[str, float]], limits: Sequence[SpeedLimit]
    ) -> Movement:
        ss, vs, ts, results = [], [], [], []
        arr, dep = [0], [0]
        n = 0
        t0 = 0.0
        for a, b in pairwise(stops):
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


def auxiliary_power_w(train: Train) -> float:
    """The train's auxiliary power, 0 without electrical data [W]."""
    return float(train.electrical.auxiliary_power_w) if train.electrical is not None else 0.0


__all__ = [
    "Movement",
    "RunCache",
    "auxiliary_power_w",
    "direction_route",
    "service_route",
]
