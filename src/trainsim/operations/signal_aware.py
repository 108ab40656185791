"""Energy-efficient driving that uses signal information: a following train that knows when the
routes ahead of it will be free coasts instead of braking to a restrictive aspect.

From the operated blocking times of the trains ahead (``OperationResult.blocking``) each route of the
follower's first stretch gets a **timing point** at its approach start: the follower may pass it no
earlier than ``free + setup_s + reaction_s`` (the route is set and its signal clears by the time the
driver sees it, so the aspect is never restrictive). The energy-efficient ``reference`` strategy of
``trainsim.optimize.api`` then drives the stretch in the signal-blind follower's running time (it
arrives no later) while meeting those timing points. Energy and arrival are compared with the
signal-blind follower of the simulation.

The signal-blind follower may be faster than any run that meets the timing points: it passes an
approach start under a restrictive aspect, brakes, and picks up speed again where the signal clears,
some hundred metres on. Its running time is then not a schedule the aware follower can keep: it gets
the shortest one that meets the timing points (``min_running_time_s``) plus ``AWARE_RESERVE`` and
arrives later; ``delay_change_s`` says by how much.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from trainsim.constants import KWH
from trainsim.errors import InputError
from trainsim.model import Route as GeometryRoute
from trainsim.model.scenario import RunSettings
from trainsim.model.timetable import SectionSchedule, Timetable, TimingPoint
from trainsim.operations.blocking import approach_start_m
from trainsim.operations.line import Line
from trainsim.operations.runs import (
    AWARE_RESERVE,
    RunCache,
    auxiliary_power_w,
    min_running_time_s,
    service_route,
)
from trainsim.operations.simulate import OperationResult, TrainService, approach_function, simulate
from trainsim.optimize.api import OptimizationResult, optimize


@dataclass(frozen=True)
class SignalAwareComparison:
    """A follower's first stretch driven signal-blind (the simulation) and with signal information.

    Attributes:
        timing_points: the timing points from the blocking times (running positions, times from the
            stretch's departure) [m, s].
        blind_energy_kwh / aware_energy_kwh: net energy of the stretch, auxiliaries while standing
            included [kWh].
        blind_arrival_s / aware_arrival_s: arrival at the end of the stretch [s].
        blind_min_speed_mps / aware_min_speed_mps: lowest speed between the two stops [m/s].
        optimization: the energy-efficient run.
        min_running_time_s: the shortest running time of the stretch that meets every timing point
            (``min_running_time_s``) [s].
        warnings: e.g. the signal-blind running time cannot be kept with the timing points.
    """

    timing_points: tuple[TimingPoint, ...]
    blind_energy_kwh: float
    aware_energy_kwh: float
    blind_arrival_s: float
    aware_arrival_s: float
    blind_min_speed_mps: float
    aware_min_speed_mps: float
    optimization: OptimizationResult
    min_running_time_s: float = np.nan
    warnings: tuple[str, ...] = ()

    @property
    def energy_saved_kwh(self) -> float:
        """Energy saved by using signal information [kWh]."""
        return self.blind_energy_kwh - self.aware_energy_kwh

    @property
    def delay_change_s(self) -> float:
        """Arrival of the signal-aware run minus that of the signal-blind one [s] (<= 0: not later)."""
        return self.aware_arrival_s - self.blind_arrival_s


def _interior_min(speed: np.ndarray) -> float:
    return float(np.min(speed[1:-1])) if len(speed) > 2 else 0.0


def signal_aware_follower(
    line: Line,
    geometry: GeometryRoute,
    services: Sequence[TrainService],
    follower: str,
    settings: RunSettings | None = None,
    result: OperationResult | None = None,
) -> SignalAwareComparison:
    """Simulate ``services`` (or take ``result``), then drive ``follower``'s first stretch (origin to its
    first stop) energy-efficiently with timing points from the blocking times of the trains ahead, in
    the running time the signal-blind follower took. Fixed block and moving block; the follower must be
    a train of ``services``."""
    settings = settings or RunSettings()
    ids = [s.id for s in services]
    if follower not in ids:
        raise InputError("unknown train", field="follower", value=follower, allowed=", ".join(ids))
    res = result if result is not None else simulate(line, geometry, services, settings, headways=False)
    svc = services[ids.index(follower)]
    out = next(t for t in res.trains if t.id == follower)
    if out.status != "ok" or out.trajectory is None:
        raise InputError("the follower did not finish its run", field="follower", value=out.status)
    sig = line.signalling
    path = line.paths[svc.direction]
    stops = [s for s in out.stops]
    first, second = stops[0], stops[1]
    p0, p1 = path.stop_m[first.station], path.stop_m[second.station]
    dep, arr = float(first.departure_s), float(second.arrival_s)
    fn = approach_function(line, svc.train, settings)
    points: list[TimingPoint] = []
    for j, route in out.routes:
        x = path.steps[j].start_m
        if not p0 < x <= p1 + 1e-9:
            continue
        names = {r.name for r in route.resources}
        ahead = [
            b.end_s for b in res.blocking if b.train != follower and b.resource in names and b.end_s <= arr
        ]
        if not ahead:
            continue
        a = approach_start_m(path, j, sig, out.trajectory, fn)
        earliest = max(ahead) + sig.setup_s + sig.reaction_s - dep
        if a > p0 + 1.0 and earliest > 0:
            points.append(TimingPoint(float(a), earliest_s=float(earliest), name=f"approach to {route.name}"))
    cache = RunCache(settings)
    directed = cache.directed(geometry, line.length_m, svc.direction)
    route = service_route(directed, [(first.station, p0), (second.station, p1)])
    fs, _fv, ft, _fr = cache.stretch(svc.train, directed, (first.station, p0), (second.station, p1))
    t_min = min_running_time_s(fs, ft, points)
    running_s, warnings = arr - dep, []
    if running_s < t_min:
        warnings.append(
            f"the signal-blind follower ran {first.station}-{second.station} in {running_s:.1f} s, passing an "
            f"approach start under a restrictive aspect; meeting the timing points takes at least "
            f"{t_min:.1f} s, so the aware follower gets {t_min * (1 + AWARE_RESERVE):.1f} s and arrives later"
        )
        running_s = t_min * (1 + AWARE_RESERVE)
    timetable = Timetable(sections=(SectionSchedule(running_time_s=running_s),), timing_points=tuple(points))
    opt = optimize(svc.train, route, timetable, "reference", settings)
    # the signal-blind stretch: its runs up to the first station stop, and any stand at a signal
    blind_runs, reached = [], p0
    for r in out.runs:
        if reached >= p1 - 1e-6:
            break
        blind_runs.append(r)
        reached = float(r.trace.position_m[-1]) if r.trace is not None else p1
    moving_s = sum(r.running_time_s for r in blind_runs)
    standing = max(arr - dep - moving_s, 0.0)
    blind_energy = sum(r.energy_kwh.net for r in blind_runs) + auxiliary_power_w(svc.train) * standing / KWH
    tr = out.trajectory
    inside = (tr.position_m >= p0) & (tr.position_m <= p1)
    return SignalAwareComparison(
        tuple(points),
        float(blind_energy),
        float(opt.run.energy_kwh.net),
        arr,
        dep + float(opt.run.running_time_s),
        _interior_min(tr.speed_mps[inside]),
        _interior_min(opt.run.trace.speed_mps),
        opt,
        t_min,
        tuple(warnings),
    )


__all__ = ["AWARE_RESERVE", "SignalAwareComparison", "min_running_time_s", "signal_aware_follower"]
