"""The fastest run over a route with its stops and dwell times."""

from __future__ import annotations

from itertools import pairwise

import numpy as np

from trainsim.constants import KMH, KN
from trainsim.errors import InputError
from trainsim.model.route import Route
from trainsim.model.scenario import RunSettings, Scenario
from trainsim.model.train import Train
from trainsim.sim import kernel
from trainsim.sim.parameters import kernel_parameters, kink_speeds, regenerative_arrays
from trainsim.sim.profile import compile_track
from trainsim.sim.result import RunResult, build_result

#: Stretches shorter than this in both distance [m] and time [s] are root-finding residue.
EMPTY_STRETCH = 1e-6


def drop_empty_stretches(s, v, t, regime):
    """Remove points that start a stretch of no length and no duration (a regime switch found twice
    by root finding), so that no point shows the forces of a regime the train is never in."""
    empty = (np.diff(s) < EMPTY_STRETCH) & (np.diff(t) < EMPTY_STRETCH) & (regime[:-1] != kernel.DWELL)
    keep = np.concatenate([~empty, [True]])
    return s[keep], v[keep], t[keep], regime[keep]


#: Speeds sampled between standstill and the ceiling when checking whether the brakes can slow the
#: train (besides the braking curve's kinks).
BRAKE_CHECK_SPEEDS = 24


def brake_limited_interval(track, P: np.ndarray, curves: tuple, bk: np.ndarray, i0: int, i1: int) -> tuple:
    """The first grid interval in [i0, i1) where full service braking cannot slow the train down at
    some speed between standstill and the interval's ceiling (a descent steeper than the brakes), as
    ``(index, speed [m/s], surplus force [N])`` with the surplus of downhill force over braking force
    plus resistance at its worst; ``(-1, nan, nan)`` when the brakes suffice everywhere. Trains
    braking at a constant deceleration (TrainRuns.jl's convention) always suffice."""
    if P[kernel.P_DECEL] > 0.0 or i1 <= i0:
        return -1, float("nan"), float("nan")
    idx = np.arange(i0, i1)
    w = track.x[idx + 1] - track.x[idx]
    vmax = float(np.max(track.vlim[idx]))
    speeds = np.unique(np.concatenate([np.linspace(0.0, vmax, BRAKE_CHECK_SPEEDS), bk[bk < vmax]]))
    bs, bc, bf, bp = curves[4:8]
    brake = np.array([P[kernel.P_BRAKE_FRACTION] * kernel.effort(v, bs, bc, bf, bp) for v in speeds])
    running = P[kernel.P_R0] + P[kernel.P_R1] * speeds + P[kernel.P_R2] * speeds**2
    m = P[kernel.P_MASS]
    worst = np.full(len(idx), -np.inf)
    worst_v = np.zeros(len(idx))
    for u in (np.zeros(len(idx)), w):  # both ends of each interval (the laws are linear in between)
        line = m * (
            (track.a0[idx] + track.a1[idx] * u)[:, None]
            + (track.b0[idx] + track.b1[idx] * u)[:, None] * speeds**2
        )
        surplus = -(brake + running)[None, :] - line  # > 0: the train accelerates under full braking
        surplus[speeds[None, :] > track.vlim[idx][:, None] + 1e-9] = -np.inf
        j = np.argmax(surplus, axis=1)
        better = surplus[np.arange(len(idx)), j] > worst
        worst = np.where(better, surplus[np.arange(len(idx)), j], worst)
        worst_v = np.where(better, speeds[j], worst_v)
    bad = np.flatnonzero(worst >= 0.0)
    if not len(bad):
        return -1, float("nan"), float("nan")
    k = int(bad[0])
    return int(idx[k]), float(worst_v[k]), float(worst[k])


def stops_of(route: Route) -> list[float]:
    """Positions where the run stops, first and last included."""
    stops = [s.position_m for s in route.stops]
    if len(stops) < 2:
        raise InputError(
            "a run needs at least two stops (origin and destination)",
            field="stations",
            value=[s.name for s in route.stops],
            allowed="two or more stations with stop: true",
        )
    if any(b - a < 1.0 for a, b in pairwise(stops)):
        raise InputError(
            "two consecutive stops are less than 1 m apart", field="stations.position", value=stops
        )
    return stops


def run_fastest(
    train: Train, route: Route, settings: RunSettings | None = None, *, trace: bool = True
) -> RunResult:
    """Simulate the fastest run of ``train`` over ``route``, stopping at every station with
    ``stop`` set for its dwell time.

    Speed limits hold until the train's rear has cleared them; the train brakes at service
    braking to every lower limit and stop and accelerates with maximum traction otherwise.
    A train that stalls on a grade gives a result with ``status == "stalled"`` that ends where
    it stopped, and a warning saying where and why.

    ``trace=False`` (batch runs) leaves out the trace's force, power and current arrays
    (``RunResult.trace`` is None); every summary figure is the same.
    """
    settings = settings or RunSettings()
    train = train.at_gravity(route.gravity_mps2)
    stops = stops_of(route)
    track, profile, ceiling = compile_track(route, train, stops, settings.max_step_m)
    P, (ts, tc, tf, tp), (bs, bc, bf, bp) = kernel_parameters(train, settings)
    tk = kink_speeds(ts, tc, tf, tp)
    bk = kink_speeds(bs, bc, bf, bp)
    curves = (ts, tc, tf, tp, bs, bc, bf, bp, *regenerative_arrays(train))
    n_max = 4 * len(track.x) + 8 * len(stops) + 16
    out_s = np.empty(n_max)
    out_v = np.empty(n_max)
    out_t = np.empty(n_max)
    out_m = np.empty(n_max, dtype=np.int8)
    n = 0
    t = 0.0
    status = kernel.STATUS_OK
    stall_at = float("nan")
    stations = route.stops
    warnings: list[str] = []
    brake_limited = False
    for k in range(len(stops) - 1):
        i0, i1 = int(track.stop_index[k]), int(track.stop_index[k + 1])
        j, v_bad, surplus = brake_limited_interval(track, P, curves, bk, i0, i1)
        if j >= 0:
            # the brakes cannot slow the train from x[j] on: run to a standstill before it, and say so
            brake_limited = True
            stall_at = float(track.x[j])
            warnings.append(_brake_limited_message(train, route, settings, track, j, v_bad, surplus))
            i1 = j
            if i1 == i0:
                break
        n, status, stall_at_k = kernel.fastest_segment(
            track.x, track.a0, track.a1, track.b0, track.b1, track.vlim, track.traction_scale,
            i0, i1, t, P, curves, tk, bk, out_s, out_v, out_t, out_m, n,
        )  # fmt: skip
        if status != kernel.STATUS_OK:
            stall_at = stall_at_k
            break
        if brake_limited:
            break
        t = out_t[n - 1]
        if k + 1 < len(stops) - 1:
            dwell = stations[k + 1].dwell_s
            t += dwell
    if n == 0:  # brake-limited where it starts: it stays at standstill there
        out_s[0], out_v[0], out_t[0], out_m[0] = stops[0], 0.0, 0.0, kernel.DWELL
        n = 1
    s, v, t, regime = drop_empty_stretches(out_s[:n], out_v[:n], out_t[:n], out_m[:n])
    # a point at every effort-curve kink makes the trapezoidal work integrals exact there
    s, v, t, regime = kernel.insert_kink_points(
        track.x, track.a0, track.a1, track.b0, track.b1, track.traction_scale,
        P, curves, tk, bk, s, v, t, regime,
    )  # fmt: skip
    return build_result(
        train=train,
        route=route,
        settings=settings,
        profile=profile,
        ceiling=ceiling,
        s=s,
        v=v,
        t=t,
        regime=regime,
        status="stalled" if status != kernel.STATUS_OK else "brake_limited" if brake_limited else "ok",
        stall_position_m=stall_at,
        kind="fastest",
        warnings=warnings,
        with_trace=trace,
    )


def _brake_limited_message(
    train: Train, route: Route, settings: RunSettings, track, j: int, v: float, surplus: float
) -> str:
    """Where and by how much the brakes cannot hold the train (see ``brake_limited_interval``)."""
    x = float(track.x[j])
    ratio = float(track.a0[j]) / route.gravity_mps2 * 1000.0  # specific line resistance [per mille]
    brake = (
        settings.braking_fraction * float(train.braking.service_force(v))
        if train.braking.service_force
        else 0.0
    )
    return (
        f"the service brakes cannot hold the train "
        f"{'at standstill' if v == 0.0 else f'at {v / KMH:.1f} km/h'} from {x:.1f} m (line resistance "
        f"{ratio:.1f} per mille, i.e. a descent): the downhill force exceeds the braking force of "
        f"{brake / KN:.1f} kN and the running resistance by {surplus / KN:.1f} kN, so the train would "
        f"accelerate at {surplus / train.inertial_mass_kg:.3f} m/s^2 under full braking; the result ends "
        f"at standstill at {x:.1f} m, before that place (the best feasible run); stronger brakes, a lower "
        "speed limit or a gentler descent are needed"
    )


def run_scenario(scenario: Scenario) -> RunResult:
    """The fastest run of a scenario."""
    return run_fastest(scenario.train, scenario.route, scenario.settings)
