"""The fastest run over a route with its stops and dwell times."""

from __future__ import annotations

from itertools import pairwise

import numpy as np

from trainsim.errors import InputError
from trainsim.model.route import Route
from trainsim.model.scenario import RunSettings, Scenario
from trainsim.model.train import Train
from trainsim.sim import kernel
from trainsim.sim.profile import compile_track
from trainsim.sim.result import RunResult, build_result

_NO_CURVE = (np.zeros(1), np.zeros((1, 4)), 0.0, 0.0)


def kernel_parameters(train: Train, settings: RunSettings) -> tuple:
    """Scalar parameter vector and compiled effort curves of a train for the kernel."""
    law = train.resistance_law
    P = np.zeros(kernel.N_PARAMS)
    P[kernel.P_INERTIAL_MASS] = train.inertial_mass_kg
    # the compiled track's line resistance is per unit mass (ratio x the route's g) [N/kg]
    P[kernel.P_MASS] = train.mass_kg
    P[kernel.P_R0], P[kernel.P_R1], P[kernel.P_R2] = law.c0, law.c1, law.c2
    braking = train.braking
    if braking.deceleration_mps2 is not None:
        P[kernel.P_DECEL] = braking.deceleration_mps2 * settings.braking_fraction
        brake_curve = _NO_CURVE
    else:
        brake_curve = braking.service_force.as_arrays()
    P[kernel.P_BRAKE_FRACTION] = settings.braking_fraction
    P[kernel.P_TRACTION_SCALE] = 1.0
    return P, train.traction.as_arrays(), brake_curve


def regenerative_arrays(train: Train) -> tuple:
    """The compiled regenerative braking curve (zero force when the train has none)."""
    regen = train.braking.regenerative
    return regen.as_arrays() if regen is not None else _NO_CURVE


def kink_speeds(starts: np.ndarray, coefs: np.ndarray, force_cap: float, power_cap: float) -> np.ndarray:
    """Speeds where an effort curve is not smooth: interval starts and where the power cap takes
    over from the force cap [m/s]."""
    kinks = list(starts[1:])
    if np.isfinite(power_cap) and np.isfinite(force_cap) and force_cap > 0:
        kinks.append(power_cap / force_cap)
    return np.array(sorted(k for k in kinks if k > 0), dtype=float)


#: Stretches shorter than this in both distance [m] and time [s] are root-finding residue.
EMPTY_STRETCH = 1e-6


def drop_empty_stretches(s, v, t, regime):
    """Remove points that start a stretch of no length and no duration (a regime switch found twice
    by root finding), so that no point shows the forces of a regime the train is never in."""
    empty = (np.diff(s) < EMPTY_STRETCH) & (np.diff(t) < EMPTY_STRETCH) & (regime[:-1] != kernel.DWELL)
    keep = np.concatenate([~empty, [True]])
    return s[keep], v[keep], t[keep], regime[keep]


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


def run_fastest(train: Train, route: Route, settings: RunSettings | None = None) -> RunResult:
    """Simulate the fastest run of ``train`` over ``route``, stopping at every station with
    ``stop`` set for its dwell time.

    Speed limits hold until the train's rear has cleared them; the train brakes at service
    braking to every lower limit and stop and accelerates with maximum traction otherwise.
    A train that stalls on a grade gives a result with ``status == "stalled"`` that ends where
    it stopped, and a warning saying where and why.
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
    for k in range(len(stops) - 1):
        i0, i1 = int(track.stop_index[k]), int(track.stop_index[k + 1])
        n, status, stall_at = kernel.fastest_segment(
            track.x, track.a0, track.a1, track.b0, track.b1, track.vlim, track.traction_scale,
            i0, i1, t, P, curves, tk, bk, out_s, out_v, out_t, out_m, n,
        )  # fmt: skip
        if status != kernel.STATUS_OK:
            break
        t = out_t[n - 1]
        if k + 1 < len(stops) - 1:
            dwell = stations[k + 1].dwell_s
            t += dwell
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
        status="ok" if status == kernel.STATUS_OK else "stalled",
        stall_position_m=stall_at,
        kind="fastest",
    )


def run_scenario(scenario: Scenario) -> RunResult:
    """The fastest run of a scenario."""
    return run_fastest(scenario.train, scenario.route, scenario.settings)
