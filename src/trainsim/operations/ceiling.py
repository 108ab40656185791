"""Speed ceilings for the single-train core, expressed as extra line speed limits.

The core (``trainsim.run_fastest``, ``trainsim.optimize``) knows line speed limits only: a limit on
``[a, b)`` binds head positions ``[a, b + L)`` (held until the rear has cleared it). A ceiling over head
position (an ETCS supervision limit, a driver's braking curve to a signal) is handed to it as a
staircase of limits whose every step lies at or below the ceiling. For a ceiling that falls towards its
end the train-length hold costs nothing: the region a step holds beyond its end is bound by the lower
step that follows.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np

from trainsim.errors import InputError
from trainsim.model import Route, SpeedLimit

#: Speeds below this are not handed to the core as limits (it requires limits > 0) [m/s].
MIN_CEILING_MPS = 0.5
#: Breakpoints closer than this are one breakpoint [m].
POSITION_TOLERANCE_M = 1e-6
#: Length of a driver's braking steps [m] and their largest number: fine enough that the steps'
#: braking stays within a few km/h of the curve, coarse enough to keep the runs' breakpoints few.
DRIVER_STEP_M = 25.0
MAX_DRIVER_STEPS = 60
#: Length of the step that holds the speed at which a braking train is released [m] (the core needs
#: a limit of positive length; it is held a train length beyond).
RELEASE_HOLD_M = 1.0


def merge_limits(base: Sequence[SpeedLimit], extra: Sequence[SpeedLimit]) -> tuple[SpeedLimit, ...]:
    """The line limits ``base`` (covering without gaps) with the limits ``extra`` laid over them:
    a cover without overlaps whose value on every piece is the lowest of those covering it.

    Splitting a limit into pieces of lower or equal value keeps what it binds: each piece is held
    until the rear has cleared that piece, and the pieces together bind what the limit bound."""
    if not extra:
        return tuple(base)
    lo, hi = base[0].start_m, base[-1].end_m
    cuts = {lo, hi}
    for x in (*base, *extra):
        for p in (x.start_m, x.end_m):
            if lo < p < hi:
                cuts.add(p)
    xs = np.array(sorted(cuts))
    xs = xs[np.concatenate(([True], np.diff(xs) > POSITION_TOLERANCE_M))]
    if xs[-1] < hi:
        xs[-1] = hi
    mid = 0.5 * (xs[:-1] + xs[1:])
    value = np.full(len(mid), np.inf)
    for x in (*base, *extra):
        inside = (mid >= x.start_m) & (mid < x.end_m)
        value[inside] = np.minimum(value[inside], x.limit_mps)
    out: list[SpeedLimit] = []
    for a, b, v in zip(xs[:-1], xs[1:], value, strict=True):
        if out and out[-1].limit_mps == v:
            out[-1] = replace(out[-1], end_m=float(b))
        else:
            out.append(SpeedLimit(float(a), float(b), float(v)))
    return tuple(out)


def staircase(
    ceiling_mps: Callable[[np.ndarray], np.ndarray],
    start_m: float,
    end_m: float,
    steps: int,
    value_at: str = "min",
    samples: int = 8,
    dv_mps: float | None = None,
) -> tuple[SpeedLimit, ...]:
    """``steps`` equal steps over ``[start_m, end_m)`` approximating the ceiling ``ceiling_mps(x)``
    [m/s] over head position ``x`` [m].

    ``value_at="min"``: each step takes the lowest of ``samples`` + 1 evenly spaced values on it, both
    ends included (exact for a monotonic ceiling): the staircase never exceeds the ceiling.
    ``value_at="start"``: each step takes the ceiling's value at its start (a driver's target curve,
    which the train need not stay under between two steps). Steps below ``MIN_CEILING_MPS`` end the
    staircase; infinite values give no step. ``dv_mps``: also a step boundary wherever the ceiling
    crosses a multiple of ``dv_mps`` (found on the sampled values), so that the steep end of a
    braking curve gets short steps.
    """
    if not (np.isfinite(start_m) and np.isfinite(end_m) and end_m > start_m):
        raise InputError("a ceiling must end after it starts", field="ceiling", value=(start_m, end_m))
    if not 1 <= steps <= 1_000_000:
        raise InputError("invalid number of ceiling steps", field="steps", value=steps, allowed="1 .. 1e6")
    xs = np.linspace(start_m, end_m, steps + 1)
    if dv_mps is not None and dv_mps > 0:
        dense = np.linspace(start_m, end_m, steps * samples + 1)
        v = np.asarray(ceiling_mps(dense), dtype=float)
        level = np.floor(np.where(np.isfinite(v), v, 1e9) / dv_mps)
        crossing = np.flatnonzero(np.diff(level) != 0)
        xs = np.unique(np.concatenate([xs, dense[crossing + 1]]))
    if value_at == "min":
        u = np.linspace(0.0, 1.0, samples + 1)
        pts = xs[:-1, None] + (xs[1:] - xs[:-1])[:, None] * u[None, :]
        values = np.min(np.asarray(ceiling_mps(pts.ravel()), dtype=float).reshape(pts.shape), axis=1)
    elif value_at == "start":
        values = np.asarray(ceiling_mps(xs[:-1]), dtype=float)
    else:
        raise InputError("unknown step value", field="value_at", value=value_at, allowed="min, start")
    out: list[SpeedLimit] = []
    for a, b, v in zip(xs[:-1], xs[1:], values, strict=True):
        if not np.isfinite(v) or v >= 200.0:
            continue
        if v < MIN_CEILING_MPS:
            break
        out.append(SpeedLimit(float(a), float(b), float(v)))
    return tuple(out)


def uniform_braking_curve(v0_mps: float, start_m: float, stop_m: float) -> Callable[[np.ndarray], np.ndarray]:
    """The speed over position of a train braking at constant deceleration from ``v0_mps`` at
    ``start_m`` to a stand at ``stop_m``: ``v(x) = v0 sqrt((stop - x) / (stop - start))`` [m/s]
    (from v^2 = v0^2 - 2 a (x - start) with a = v0^2 / (2 (stop - start)))."""
    span = stop_m - start_m
    if not span > 0:
        raise InputError("the stop must lie ahead of the braking start", field="stop_m", value=stop_m)

    def speed(x: np.ndarray) -> np.ndarray:
        frac = np.clip((stop_m - np.asarray(x, dtype=float)) / span, 0.0, None)
        return v0_mps * np.sqrt(frac)

    return speed


def driver_braking_steps(
    v0_mps: float, start_m: float, stop_m: float, step_m: float = DRIVER_STEP_M
) -> tuple[SpeedLimit, ...]:
    """A driver's braking to a signal at danger: from where the restrictive aspect is seen
    (``start_m``, at speed ``v0_mps``) on the constant-deceleration curve that stops the train at
    ``stop_m`` (``uniform_braking_curve``), as steps of about ``step_m`` taking the curve's value at
    their start. Empty when the train is (almost) at a stand there or the stop is too close."""
    if not (v0_mps >= MIN_CEILING_MPS and stop_m - start_m > 1.0):
        return ()
    steps = int(min(max(np.ceil((stop_m - start_m) / step_m), 1), MAX_DRIVER_STEPS))
    return staircase(uniform_braking_curve(v0_mps, start_m, stop_m), start_m, stop_m, steps, "start")


def release_steps(
    steps: Sequence[SpeedLimit], release_m: float, speed_mps: float, slowed: bool
) -> tuple[SpeedLimit, ...] | None:
    """The braking steps ``steps`` of a train released at ``release_m`` at ``speed_mps`` (the signal
    cleared): the steps before that point, cut there, and a short step at the speed the train has
    there, so that the run up to ``release_m`` is the braking run's (the core brakes to a limit as
    it brakes to a stop) and the train accelerates again once its rear has passed that step (the
    core's rule for any limit: a train length of holding the speed). None when the train is
    released before its first step and is not ``slowed`` (below its unhindered speed) there."""
    before = [x for x in steps if x.start_m < release_m - POSITION_TOLERANCE_M]
    if not before and not slowed:
        return None
    out = [replace(x, end_m=min(x.end_m, release_m)) for x in before]
    out.append(SpeedLimit(release_m, release_m + RELEASE_HOLD_M, max(speed_mps, MIN_CEILING_MPS)))
    return tuple(out)


def with_limits(route: Route, extra: Sequence[SpeedLimit]) -> Route:
    """``route`` with ``extra`` limits laid over its own (``merge_limits``); extra limits outside the
    route are cut off."""
    clipped = [
        SpeedLimit(max(x.start_m, route.start_m), min(x.end_m, route.end_m), x.limit_mps)
        for x in extra
        if min(x.end_m, route.end_m) > max(x.start_m, route.start_m) + POSITION_TOLERANCE_M
    ]
    if not clipped:
        return route
    return replace(route, speed_limits=merge_limits(route.speed_limits, clipped))


__all__ = [
    "MIN_CEILING_MPS",
    "driver_braking_steps",
    "merge_limits",
    "release_steps",
    "staircase",
    "uniform_braking_curve",
    "with_limits",
]
