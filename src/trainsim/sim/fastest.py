"""The fastest run over a route with its stops and dwell times."""

from __future__ import annotations

import math
from itertools import pairwise

import numpy as np

from trainsim.constants import KMH, KN
from trainsim.errors import InputError
from trainsim.model.effort import POWER_CAP_MIN_SPEED_MPS
from trainsim.model.route import Route
from trainsim.model.scenario import RunSettings, Scenario
from trainsim.model.train import Train
from trainsim.sim import _kernel_c
from trainsim.sim.codes import (
    DWELL,
    P_BRAKE_FRACTION,
    P_DECEL,
    P_MASS,
    P_R0,
    P_R1,
    P_R2,
    STATUS_FULL,
    STATUS_OK,
)
from trainsim.sim.parameters import kernel_parameters, kink_speeds, regenerative_arrays
from trainsim.sim.profile import compile_route
from trainsim.sim.result import RunResult, build_result

#: Stretches shorter than this in both distance [m] and time [s] are root-finding residue.
EMPTY_STRETCH = 1e-6


def drop_empty_stretches(s, v, t, regime):
    """Remove points that start a stretch of no length and no duration (a regime switch found twice
    by root finding), so that no point shows the forces of a regime the train is never in."""
    empty = (np.diff(s) < EMPTY_STRETCH) & (np.diff(t) < EMPTY_STRETCH) & (regime[:-1] != DWELL)
    if not empty.any():
        return s, v, t, regime  # the usual case: no copies
    keep = np.concatenate([~empty, [True]])
    return s[keep], v[keep], t[keep], regime[keep]


def _branch_force(v: np.ndarray, coefs_j: np.ndarray, fcap: float, pcap: float) -> np.ndarray:
    """Force [N] of one interval's law of a compiled EffortCurve at speeds v [m/s], with the curve's
    caps and the clip at 0, evaluated as the kernel's ``effort`` (``sim/_forces.pxd``) does (the law
    is inf at standstill when it has a hyperbolic term), but on the given interval whatever the
    speed (so that both sides of a table step are seen)."""
    c0, c1, c2, ch = coefs_j
    with np.errstate(divide="ignore"):
        hyperbolic = np.where(v > 0.0, ch / np.where(v > 0.0, v, 1.0), np.inf) if ch else 0.0
    law = c0 + c1 * v + c2 * v * v + hyperbolic
    f = np.minimum(law, fcap)
    f = np.minimum(f, pcap / np.maximum(v, POWER_CAP_MIN_SPEED_MPS))
    return np.maximum(f, 0.0)


def _real_roots(coefs: list[float], lo: float, hi: float) -> list[float]:
    """Real roots in [lo, hi] of the polynomial with ``coefs`` (highest power first, degree <= 3):
    closed forms up to degree 2 (most braking tables are linear pieces), numpy's roots beyond."""
    c = [float(x) for x in coefs]
    if not all(math.isfinite(x) for x in c):
        return []
    while c and c[0] == 0.0:
        c.pop(0)
    roots: list[float] = []
    while len(c) > 1 and c[-1] == 0.0:  # a factor v
        c.pop()
        roots.append(0.0)
    if len(c) == 2:
        roots.append(-c[1] / c[0])
    elif len(c) == 3:
        a, b, q = c
        disc = b * b - 4.0 * a * q
        if disc >= 0.0:
            # the stable pair of formulas (no cancellation between b and the root)
            t = -0.5 * (b + math.copysign(math.sqrt(disc), b))
            roots += [t / a] + ([q / t] if t != 0.0 else [])
    elif len(c) == 4:
        r = np.roots(c)
        roots += [float(x) for x in r.real[np.abs(r.imag) <= 1e-9 * (1.0 + np.abs(r.real))]]
    return [x for x in roots if lo <= x <= hi]


def worst_braking_surplus(
    P: np.ndarray, brake_curve: tuple, q2_extra: float, v_max: float
) -> tuple[float, float]:
    """Largest value over speeds v in [0, v_max] [m/s] of ``-(f B(v) + R(v)) - q2_extra v^2`` [N],
    with B the service braking curve, f the braking fraction, R the running resistance and
    ``q2_extra`` the line's v^2 coefficient times the mass [N s^2/m^2], as ``(speed, value)`` (the
    lowest such speed when several tie).

    Exact: on each interval of the braking curve the function is the smallest of a few smooth
    branches (the interval's law, the force cap, the power cap, zero), so its maximum lies at an
    interval end (both sides of a table step), where two branches cross (the roots of cubics), or
    where a branch is stationary (the roots of cubics again), and every such speed is evaluated.
    A sampled check could miss a narrow dip of the braking force between its samples."""
    starts, coefs, fcap, pcap = brake_curve
    frac = float(P[P_BRAKE_FRACTION])
    r0, q1, q2 = float(P[P_R0]), float(P[P_R1]), float(P[P_R2]) + q2_extra
    vmin = POWER_CAP_MIN_SPEED_MPS
    best_v, best = 0.0, -np.inf
    for j in range(len(starts)):
        lo = 0.0 if j == 0 else float(starts[j])
        hi = float(starts[j + 1]) if j + 1 < len(starts) else v_max
        hi = min(hi, v_max)
        if lo > v_max or hi < lo:
            continue
        c0, c1, c2, ch = (float(c) for c in coefs[j])
        cand = [lo, hi, vmin, pcap / fcap if fcap > 0 else 0.0]
        if q2 != 0.0:
            cand.append(-q1 / (2.0 * q2))  # stationary with a constant (or zero) braking force
        cand += _real_roots([2.0 * (frac * c2 + q2), frac * c1 + q1, 0.0, -frac * ch], lo, hi)
        cand += _real_roots([c2, c1, c0, ch], lo, hi)  # the law crosses zero
        if np.isfinite(fcap):
            cand += _real_roots([c2, c1, c0 - fcap, ch], lo, hi)
        if np.isfinite(pcap):
            cand += _real_roots([2.0 * q2, q1, 0.0, -frac * pcap], lo, hi)  # stationary on the power cap
            cand += _real_roots([c2, c1, c0, ch - pcap], lo, hi)
            cand += _real_roots([c2, c1, c0 - pcap / vmin, ch], lo, hi)
        v = np.array(sorted(x for x in cand if lo <= x <= hi))
        value = -(frac * _branch_force(v, coefs[j], fcap, pcap) + r0 + q1 * v + q2 * v * v)
        k = int(np.argmax(value))
        if value[k] > best or (value[k] == best and v[k] < best_v):
            best_v, best = float(v[k]), float(value[k])
    return best_v, best


def braking_surplus(track, P: np.ndarray, curves: tuple, i0: int, i1: int) -> tuple[np.ndarray, np.ndarray]:
    """For each grid interval in [i0, i1): the worst surplus of downhill force over full service
    braking plus resistance at any speed between standstill and the interval's ceiling [N] (>= 0:
    the brakes cannot hold the train there), and the speed where it is worst [m/s].

    The line's laws are linear over an interval, so the worst is at one of its ends; the line's
    constant part only shifts the surplus, so the exact worst over the speeds
    (``worst_braking_surplus``) is computed once per distinct v^2 coefficient and ceiling."""
    idx = np.arange(i0, i1)
    w = track.x[idx + 1] - track.x[idx]
    m = P[P_MASS]
    brake_curve = curves[4:8]
    ends = np.concatenate([np.zeros(len(idx)), w])  # both ends (the laws are linear in between)
    ii = np.concatenate([idx, idx])
    a = track.a0[ii] + track.a1[ii] * ends
    b = track.b0[ii] + track.b1[ii] * ends
    # distinct (v^2 coefficient, ceiling) pairs, through integer codes (unique rows of floats is slow)
    ub, ib = np.unique(b, return_inverse=True)
    uv, iv = np.unique(track.vlim[ii], return_inverse=True)
    codes, inverse = np.unique(ib * len(uv) + iv, return_inverse=True)
    per_key = np.array(
        [worst_braking_surplus(P, brake_curve, m * ub[c // len(uv)], uv[c % len(uv)]) for c in codes.tolist()]
    ).reshape(-1, 2)
    surplus = (per_key[inverse, 1] - m * a).reshape(2, len(idx))
    speed = per_key[inverse, 0].reshape(2, len(idx))
    end = np.argmax(surplus, axis=0)  # the start when both ends are as bad
    cols = np.arange(len(idx))
    return surplus[end, cols], speed[end, cols]


def brake_limited_interval(track, P: np.ndarray, curves: tuple, bk: np.ndarray, i0: int, i1: int) -> tuple:
    """The first grid interval in [i0, i1) where full service braking cannot slow the train down at
    some speed between standstill and the interval's ceiling (a descent steeper than the brakes), as
    ``(index, speed [m/s], surplus force [N])`` with the surplus of downhill force over braking force
    plus resistance at its worst (``braking_surplus``); ``(-1, nan, nan)`` when the brakes suffice
    everywhere. Trains braking at a constant deceleration (TrainRuns.jl's convention) always
    suffice. ``bk`` (the braking curve's kinks) is kept for the callers; the exact check needs no
    sampled speeds."""
    if P[P_DECEL] > 0.0 or i1 <= i0:
        return -1, float("nan"), float("nan")
    return _first_bad(*braking_surplus(track, P, curves, i0, i1), i0)


def _first_bad(worst: np.ndarray, worst_v: np.ndarray, i0: int) -> tuple:
    bad = np.flatnonzero(worst >= 0.0)
    if not len(bad):
        return -1, float("nan"), float("nan")
    k = int(bad[0])
    return i0 + k, float(worst_v[k]), float(worst[k])


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
    compiled = compile_route(route, train, stops, settings.max_step_m)
    track, profile, ceiling = compiled.track, compiled.profile, compiled.ceiling
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
    status = STATUS_OK
    stall_at = float("nan")
    stations = route.stops
    warnings: list[str] = []
    brake_limited = False
    # the brake check of every interval at once (one set of distinct laws for the whole line)
    first, last = int(track.stop_index[0]), int(track.stop_index[-1])
    checked = P[P_DECEL] == 0.0 and last > first
    worst, worst_v = braking_surplus(track, P, curves, first, last) if checked else (None, None)
    for k in range(len(stops) - 1):
        i0, i1 = int(track.stop_index[k]), int(track.stop_index[k + 1])
        j, v_bad, surplus = (
            _first_bad(worst[i0 - first : i1 - first], worst_v[i0 - first : i1 - first], i0)
            if checked and i1 > i0
            else (-1, float("nan"), float("nan"))
        )
        if j >= 0:
            # the brakes cannot slow the train from x[j] on: run to a standstill before it, and say so
            brake_limited = True
            stall_at = float(track.x[j])
            warnings.append(_brake_limited_message(train, route, settings, track, j, v_bad, surplus))
            i1 = j
            if i1 == i0:
                break
        while True:
            # the kernel places a point at every effort-curve kink it steps across (one pass)
            n_next, status, stall_at_k = _kernel_c.fastest_segment(
                track.x, track.a0, track.a1, track.b0, track.b1, track.vlim, track.traction_scale,
                i0, i1, t, P, curves, tk, bk, out_s, out_v, out_t, out_m, n, kink_points=True, grow=True,
                slow_steps=True,
            )  # fmt: skip
            if status != STATUS_FULL:
                break
            out_s, out_v, out_t, out_m = (
                np.concatenate([a, np.empty_like(a)]) for a in (out_s, out_v, out_t, out_m)
            )
        n = n_next
        if status != STATUS_OK:
            stall_at = stall_at_k
            break
        if brake_limited:
            break
        t = out_t[n - 1]
        if k + 1 < len(stops) - 1:
            dwell = stations[k + 1].dwell_s
            t += dwell
    if n == 0:  # brake-limited where it starts: it stays at standstill there
        out_s[0], out_v[0], out_t[0], out_m[0] = stops[0], 0.0, 0.0, DWELL
        n = 1
    s, v, t, regime = drop_empty_stretches(out_s[:n], out_v[:n], out_t[:n], out_m[:n])
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
        status="stalled" if status != STATUS_OK else "brake_limited" if brake_limited else "ok",
        stall_position_m=stall_at,
        kind="fastest",
        warnings=warnings,
        with_trace=trace,
        availability=compiled.available,
        voltage=compiled.voltage,
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
