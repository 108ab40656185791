"""Reference optimum by direct transcription (CasADi + IPOPT), to check the optimal strategy.

Distance-domain collocation of one section between two stops (Kouzoupis, Pendharkar, Corman 2023,
TTOBench; Wang, De Schutter, van den Boom, Ning 2013): speeds v_k at the nodes of a grid that
contains every breakpoint of the line and is graded geometrically towards both stops (the time
spent in the last metres before a stop depends on the braking law at walking speed, so a uniform
grid is badly wrong there); piecewise-constant traction, regenerative and friction forces on each
interval; the trapezoidal rule for kinetic energy,
    M (v_{k+1}^2 - v_k^2) / 2 = h (u_t - u_r - u_f - R(v_m) - m g (a(s_m) + b(s_m) v_m^2)),
the time of an interval 2 h / (v_k + v_{k+1}) (exact at constant acceleration), the running time
as an equality, and the electrical energy sum h (u_t / eta_t - eta_r u_r) as the objective.
Force limits: ``u <= F`` and ``u v_m <= P`` for effort curves made of a force and a power cap (the
TTOBench trains); otherwise ``u <= F(v_m)`` with F interpolated linearly from the curve.

CasADi is an optional dependency: ``pip install trainsim[reference]``.
"""

from __future__ import annotations

import time as _time
from dataclasses import dataclass

import numpy as np

from trainsim.constants import KWH, G
from trainsim.errors import InputError, TrainsimError
from trainsim.model.effort import EffortCurve
from trainsim.model.route import Route
from trainsim.model.train import Train
from trainsim.sim.profile import line_resistance_profile, speed_ceiling


@dataclass(frozen=True)
class ReferenceSolution:
    """Result of the direct transcription."""

    s: np.ndarray  # node positions [m]
    v: np.ndarray  # node speeds [m/s]
    traction_n: np.ndarray  # per interval [N]
    regenerative_n: np.ndarray
    friction_n: np.ndarray
    energy_j: float  # electrical energy drawn from the line (without auxiliaries) [J]
    running_time_s: float
    intervals: int
    solve_time_s: float
    status: str


#: Unit of the force variables in the NLP [N].
FORCE_SCALE = 1.0e5


def _grid(breaks: np.ndarray, s0: float, s1: float, intervals: int, smallest: float = 0.01) -> np.ndarray:
    """About ``intervals`` intervals between s0 and s1, with every breakpoint, geometrically finer
    towards both stops."""
    length = s1 - s0
    h = length / intervals
    grade = []
    d = smallest
    while d < 0.5 * min(length, 40.0 * h):
        grade += [s0 + d, s1 - d]
        d *= 1.35
    uniform = np.linspace(s0, s1, intervals + 1)
    pts = np.unique(np.concatenate([uniform, breaks[(breaks > s0) & (breaks < s1)], np.array(grade)]))
    return pts[np.concatenate([[True], np.diff(pts) > 1e-6])]


def _initial_speeds(
    train: Train, route: Route, s0: float, s1: float, s: np.ndarray, running_time_s: float
) -> np.ndarray:
    """The fastest run's speeds at the grid nodes, scaled down to the scheduled time."""
    import dataclasses

    from trainsim.model.route import Station
    from trainsim.sim.fastest import run_fastest

    section = dataclasses.replace(route, stations=(Station("from", s0), Station("to", s1)))
    fastest = run_fastest(train, section)
    tr = fastest.trace
    v = np.interp(s, tr.position_m, tr.speed_mps)
    return v * min(1.0, fastest.running_time_s / running_time_s)


def _caps(curve: EffortCurve) -> tuple[float, float] | None:
    """(force cap, power cap) when the curve is only a force cap and a power cap, else None."""
    c = curve.coefficients
    if len(c) == 1 and c[0, 1] == c[0, 2] == c[0, 3] == 0.0:
        return min(float(c[0, 0]), curve.force_cap_n), curve.power_cap_w
    return None


def solve_reference(
    train: Train,
    route: Route,
    s0: float,
    s1: float,
    running_time_s: float,
    intervals: int = 1000,
    *,
    max_iter: int = 3000,
) -> ReferenceSolution:
    """The minimum-energy run from standstill at s0 to standstill at s1 in ``running_time_s``."""
    try:
        import casadi as ca
    except ImportError as exc:  # optional dependency
        raise TrainsimError("the reference optimum needs CasADi: pip install 'trainsim[reference]'") from exc
    if intervals < 10:
        raise InputError("too few intervals", field="intervals", value=intervals, allowed=">= 10")
    profile = line_resistance_profile(route, train)
    ceiling = speed_ceiling(route, train)
    breaks = np.unique(np.concatenate([profile.gradient.x, profile.curve.x, profile.tunnel.x, ceiling.x]))
    s = _grid(breaks, s0, s1, intervals)
    n = len(s) - 1
    h = np.diff(s)
    mid = 0.5 * (s[:-1] + s[1:])
    a_mid = profile.gradient(mid) + profile.curve(mid) + profile.tunnel(mid)
    b_mid = profile.tunnel_v2(mid)
    vlim = ceiling(mid)
    node_lim = np.minimum(np.concatenate([vlim, [vlim[-1]]]), np.concatenate([[vlim[0]], vlim]))
    M, m = train.inertial_mass_kg, train.mass_kg
    law = train.resistance_law
    elec = train.electrical
    eta_t = elec.traction_efficiency if elec else 1.0
    regen = train.braking.regenerative
    eta_r = elec.regenerative_efficiency * elec.receptivity if (elec and regen is not None) else 0.0
    if train.braking.service_force is None:
        raise InputError(
            "the reference needs a braking force law, not a constant deceleration", field="braking"
        )

    opti = ca.Opti()
    v = opti.variable(n + 1)
    # forces in units of FORCE_SCALE keep IPOPT's problem well scaled
    ut_s = opti.variable(n)
    ur_s = opti.variable(n)
    uf_s = opti.variable(n)
    ut, ur, uf = FORCE_SCALE * ut_s, FORCE_SCALE * ur_s, FORCE_SCALE * uf_s
    vm = 0.5 * (v[:-1] + v[1:])
    resist = law.c0 + law.c1 * vm + law.c2 * vm**2 + m * G * (a_mid + b_mid * vm**2)
    opti.subject_to(
        M * (v[1:] ** 2 - v[:-1] ** 2) / (2 * FORCE_SCALE) == h * (ut - ur - uf - resist) / FORCE_SCALE
    )
    opti.subject_to(v[0] == 0)
    opti.subject_to(v[n] == 0)
    opti.subject_to(opti.bounded(0, v[1:n], node_lim[1:n]))
    # at least as fast as scheduled: saving energy makes it exactly the scheduled time
    opti.subject_to(ca.sum1(2 * h / (v[:-1] + v[1:])) <= running_time_s)
    for u, curve in ((ut, train.traction), (ur, regen)):
        if curve is None:
            opti.subject_to(u == 0)
            continue
        caps = _caps(curve)
        if caps is not None:
            force, power = caps
            opti.subject_to(opti.bounded(0, u, force))
            if np.isfinite(power):
                opti.subject_to(u * vm <= power)
        else:
            grid_v = np.linspace(0.0, float(vlim.max()) * 1.05, 400)
            table = ca.interpolant("effort", "linear", [grid_v], np.asarray(curve(grid_v), dtype=float))
            opti.subject_to(u >= 0)
            opti.subject_to(u <= table(vm))
    service = train.braking.service_force
    grid_v = np.linspace(0.0, float(vlim.max()) * 1.05, 400)
    total = ca.interpolant("service", "linear", [grid_v], np.asarray(service(grid_v), dtype=float))
    opti.subject_to(uf >= 0)
    opti.subject_to(ur + uf <= total(vm))
    opti.minimize(ca.sum1(h * (ut / eta_t - eta_r * ur)) / KWH)
    # initial guess, independent of the optimal strategy: the fastest run slowed down uniformly to
    # the scheduled time, with the forces that this speed profile needs
    guess = _initial_speeds(train, route, s0, s1, s, running_time_s)
    gm = 0.5 * (guess[:-1] + guess[1:])
    need = M * (guess[1:] ** 2 - guess[:-1] ** 2) / (2 * h) + law(gm) + m * G * (a_mid + b_mid * gm**2)
    opti.set_initial(v, guess)
    opti.set_initial(ut_s, np.maximum(need, 0.0) / FORCE_SCALE)
    opti.set_initial(ur_s, 0.0)
    opti.set_initial(uf_s, np.maximum(-need, 0.0) / FORCE_SCALE)
    opti.solver(
        "ipopt",
        {"print_time": False},
        {"print_level": 0, "max_iter": max_iter, "tol": 1e-9, "acceptable_tol": 1e-7, "sb": "yes"},
    )
    t0 = _time.perf_counter()
    try:
        sol = opti.solve()
        status = "ok"
        get = sol.value
    except RuntimeError:
        status = "not converged: " + str(opti.stats().get("return_status"))
        get = opti.debug.value
    elapsed = _time.perf_counter() - t0
    vv = np.asarray(get(v)).ravel()
    ut_v, ur_v, uf_v = (FORCE_SCALE * np.asarray(get(x)).ravel() for x in (ut_s, ur_s, uf_s))
    energy = float(np.sum(h * (ut_v / eta_t - eta_r * ur_v)))
    run_time = float(np.sum(2 * h / np.maximum(vv[:-1] + vv[1:], 1e-12)))
    return ReferenceSolution(s, vv, ut_v, ur_v, uf_v, energy, run_time, n, elapsed, status)
