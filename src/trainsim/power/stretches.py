"""A run joined from one run per stretch between two stops, each with its own traction power cap.

Voltage feedback that varies along the run: the line may limit a train's traction on one stretch
(far from a substation, several trains accelerating together) and not on the next. trainsim's
single-train core takes one traction curve per run, so the run is split at its stops (the train
is at rest there, so the stretches are independent runs from rest to rest, as in "a line in
operation") and each stretch is run with its own cap (``EffortCurve.capped``); the stretches are
joined in time with the dwell at each intermediate stop. One approximation: a speed limit behind a
stop that the train's rear has not yet cleared when it starts is not held.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np

from trainsim.model.route import Route, Station
from trainsim.model.spans import route_between
from trainsim.sim.fastest import run_fastest

__all__ = ["JoinedRun", "joined_run", "stop_positions"]


def stop_positions(route: Route) -> np.ndarray:
    """Positions where the train is at rest: the route's ends and every stopping station [m]."""
    inner = [s.position_m for s in route.stations if s.stop and route.start_m < s.position_m < route.end_m]
    return np.array([route.start_m, *inner, route.end_m])


def _stretch(route: Route, a: float, b: float) -> Route:
    stations = tuple(s for s in route.stations if a < s.position_m < b and not s.stop)
    return route_between(route, a, b, (Station("from", a, 0.0, True), *stations, Station("to", b, 0.0, True)))


@dataclass(frozen=True)
class _Trace:
    time_s: np.ndarray
    position_m: np.ndarray
    speed_mps: np.ndarray
    traction_force_n: np.ndarray
    regenerative_braking_force_n: np.ndarray


@dataclass(frozen=True)
class JoinedRun:
    """The joined run: ``trace`` (time, position, speed, traction and regenerative forces, the
    fields ``train_load_from_run`` reads; its time includes the dwells at intermediate stops),
    ``running_time_s`` the sum of the stretches' running times, dwells excluded, as
    ``RunResult.running_time_s`` [s], ``status`` (``ok`` or the first stretch's that is not),
    ``warnings``."""

    trace: Any
    running_time_s: float
    status: str
    warnings: list[str]


def joined_run(
    train, route: Route, settings, caps_w: np.ndarray, shares: np.ndarray | None = None
) -> JoinedRun:
    """The fastest run of ``train`` on ``route`` with traction power at the wheel capped at
    ``caps_w[k]`` [W] on stretch k (inf: not capped), one stretch per pair of consecutive
    :func:`stop_positions`; with ``shares``, the tractive effort on stretch k is also scaled by
    ``shares[k]`` [-] (``EffortCurve.scaled``)."""
    stops = stop_positions(route)
    dwell = {s.position_m: s.dwell_s for s in route.stations if s.stop}
    parts: list[list[np.ndarray]] = [[], [], [], [], []]
    t0, status, warnings, running = 0.0, "ok", [], 0.0
    for k in range(len(stops) - 1):
        capped = train
        if np.isfinite(caps_w[k]):
            capped = dataclasses.replace(train, traction=train.traction.capped(power_cap_w=float(caps_w[k])))
        if shares is not None and shares[k] != 1.0:
            capped = dataclasses.replace(capped, traction=capped.traction.scaled(float(shares[k])))
        run = run_fastest(capped, _stretch(route, float(stops[k]), float(stops[k + 1])), settings)
        tr = run.trace
        running += run.running_time_s
        for part, values in zip(parts, (tr.time_s - tr.time_s[0] + t0, tr.position_m, tr.speed_mps,
                                        tr.traction_force_n, tr.regenerative_braking_force_n), strict=True):  # fmt: skip
            part.append(values)
        if run.status != "ok" and status == "ok":
            status = run.status
        warnings.extend(run.warnings)
        t0 = float(parts[0][-1][-1]) + (dwell.get(float(stops[k + 1]), 0.0) if k + 2 < len(stops) else 0.0)
    trace = _Trace(*(np.concatenate(p) for p in parts))
    return JoinedRun(trace, running, status, warnings)
