"""Reference optimum by direct transcription (CasADi + IPOPT), and a lower bound that certifies it.

**The transcription** (``solve_reference``). Distance-domain collocation of one section between two
stops (Kouzoupis, Pendharkar, Corman 2023, TTOBench; Wang, De Schutter, van den Boom, Ning 2013):
speeds v_k at the nodes of a grid that contains every breakpoint of the line and every timing point
and is graded geometrically towards both stops (the time spent in the last metres before a stop
depends on the braking law at walking speed, so a uniform grid is badly wrong there);
piecewise-constant traction, regenerative and friction forces on each interval; the trapezoidal
rule for kinetic energy,
    M (v_{k+1}^2 - v_k^2) / 2 = h (u_t - u_r - u_f - c0 - c1 v_m - (c2 + m g b) v2_m - m g a),
with v_m = (v_k + v_{k+1}) / 2 and v2_m = (v_k^2 + v_{k+1}^2) / 2 (the trapezoidal rule on v^2),
the time of an interval 2 h / (v_k + v_{k+1}) (exact at constant acceleration), the running time
as a constraint, and the electrical energy sum h (u_t / eta_t - eta_r u_r) as the objective.
Force limits: ``u <= F`` and ``u v_m <= P`` for effort curves made of a force and a power cap (the
TTOBench trains); otherwise ``u <= F(v_m)`` with F interpolated linearly from the curve. Speeds are
bounded below by 0 (IPOPT may return -1e-26 at a bound; it is clipped there).

**Mesh refinement** (``certified_reference``): the number of intervals is doubled, each solve warm
started from the last, until the optimum moves by less than ``REFINEMENT_TOLERANCE``.

**Time limits are CPU time** (IPOPT's ``max_cpu_time``, and the refinement loop's budget measured
with ``time.process_time``): on a loaded machine a wall-clock limit stopped the same solve at a
different iterate, so the reference's result depended on the load (issue 16). The wall time is
still reported beside it.

**The lower bound** (``lower_bound``): a convex relaxation of the same transcription in the kinetic
energy per unit mass E = v^2 / 2, the interval time dt and the mean speed h / dt:
    M (E_{k+1} - E_k) = h (u_t - u_r - u_f - c0 - m g a - (c2 + m g b) (E_k + E_{k+1})) - q_k,
    h c1 h/dt_k <= q_k <= h c1 (sqrt(2 E_k) + sqrt(2 E_{k+1})) / 2   (convex, concave),
    dt_k >= 2 h / (sqrt(2 E_k) + sqrt(2 E_{k+1}))              (convex: 1 / a concave function),
    u <= a_i + b_i dt_k / h                                     (the concave hull of F(1/w) in w = 1/v),
    sum dt_k <= T,   0 <= E_k <= v_lim^2 / 2.
The v^2 terms of the transcription, v2_m = E_k + E_{k+1}, are linear in E. Every point of the transcription is a point of the relaxation (with
dt = 2h / (v_k + v_{k+1}) and q = h c1 v_m; a force curve lies below its concave hull in 1/v), so
the minimum of the relaxation is at most the minimum of the transcription on the same grid. The
only freedom the relaxation adds is to take longer over an interval than its speeds say (which
saves some of the c1 v resistance, but less than the time it costs is worth) and the hulls of
force curves that are not concave in 1/v. The relaxation is convex
(linear objective and equalities, convex functions bounded above), so IPOPT's optimum is its global
optimum: a bound that holds even where IPOPT stops the transcription in a local optimum.

**Regime rules** (``DrivingConstraints``, issue 16). Coasting only above v_c is the floor
v_k >= min(v_c, v_fastest(s_k)) at every inner node: an approximation of "below v_c the train
holds or powers" that lets it fall below v_c only on the fastest run's braking curves (into the stop
and lower limits) and, at departure, only while it accelerates at full effort (where the optimum
powers anyway). The minimum regime time is combinatorial (the sign pattern of the forces) and is
not imposed on the transcription.
"""

from __future__ import annotations

import time as _time
from collections.abc import Sequence
from dataclasses import dataclass, field
from itertools import pairwise

import numpy as np

from trainsim.errors import InputError, TrainsimError
from trainsim.model.effort import EffortCurve
from trainsim.model.route import Route
from trainsim.model.timetable import TimingPoint
from trainsim.model.train import Train
from trainsim.optimize.constraints import DrivingConstraints
from trainsim.sim.profile import line_resistance_profile, speed_ceiling

#: Unit of the force variables in the NLP [N].
FORCE_SCALE = 1.0e5
#: Mesh refinement stops when doubling the intervals moves the optimum by less than this [-].
REFINEMENT_TOLERANCE = 1.0e-4
#: Default limit on the CPU time of one call [s] (issue 16: the reference within 30 s); CPU time, not
#: wall time, so that the machine's load does not change the result.
TIME_LIMIT_S = 30.0
#: The lowest coasting speed's floor stays this fraction below the fastest run's speed [-]: the
#: transcription's trapezoidal motion at full effort is not the integrator's (at 1e-3 IPOPT found
#: the metro's floor infeasible near the stops).
COAST_FLOOR_MARGIN = 0.03
#: Speeds below this are taken as 0 when the solution is read back [m/s]: IPOPT stops within its
#: tolerance of a bound, e.g. at -8.8e-27 for v >= 0.
SPEED_BOUND_TOLERANCE_MPS = 1.0e-6


@dataclass(frozen=True)
class ReferenceSolution:
    """Result of the direct transcription on one grid.

    Attributes:
        s: node positions [m].
        v: node speeds [m/s], >= 0.
        traction_n, regenerative_n, friction_n: forces per interval [N].
        energy_j: electrical energy drawn from the line (without auxiliaries) [J].
        running_time_s: running time of the transcription [s].
        intervals: number of intervals.
        solve_time_s: wall time of IPOPT [s] (of the whole refinement and bound for
            ``certified_reference``).
        status: "ok"; "time limit: ..." (CPU time; the last iterate, said so); "infeasible: ...";
            or "not converged: <IPOPT status>".
        lower_bound_j: a lower bound on the optimum [J] (``certified_reference``), else None.
        mesh: (intervals, energy [J], status) of every solve of the mesh refinement.
        bound_status: status of the lower-bound solve ("" when none was computed).
        solve_cpu_s: CPU time of this process over the same span as ``solve_time_s`` [s] (what the
            time limits count).
    """

    s: np.ndarray
    v: np.ndarray
    traction_n: np.ndarray
    regenerative_n: np.ndarray
    friction_n: np.ndarray
    energy_j: float
    running_time_s: float
    intervals: int
    solve_time_s: float
    status: str
    lower_bound_j: float | None = None
    mesh: tuple[tuple[int, float, str], ...] = field(default=())
    bound_status: str = ""
    solve_cpu_s: float = float("nan")

    @property
    def time_s(self) -> np.ndarray:
        """Time at every node from the departure [s]."""
        dt = 2.0 * np.diff(self.s) / np.maximum(self.v[:-1] + self.v[1:], 1e-12)
        return np.concatenate([[0.0], np.cumsum(dt)])

    def certified_gap(self, energy_j: float) -> float | None:
        """How far ``energy_j`` [J] is at most above the optimum, as a fraction of |lower bound|."""
        if self.lower_bound_j is None or not np.isfinite(self.lower_bound_j):
            return None
        return (energy_j - self.lower_bound_j) / max(abs(self.lower_bound_j), 1.0)


@dataclass(frozen=True)
class LowerBound:
    """The optimum of the convex relaxation (module doc): energy [J], status, wall time [s],
    intervals, CPU time [s]."""

    energy_j: float
    status: str
    solve_time_s: float
    intervals: int
    solve_cpu_s: float = float("nan")


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


def _caps(curve: EffortCurve) -> tuple[float, float] | None:
    """(force cap, power cap) when the curve is only a force cap and a power cap, else None."""
    c = curve.coefficients
    if len(c) == 1 and c[0, 1] == c[0, 2] == c[0, 3] == 0.0:
        return min(float(c[0, 0]), curve.force_cap_n), curve.power_cap_w
    return None


def concave_hull_in_slowness(
    curve: EffortCurve, vmax_mps: float, max_lines: int = 16
) -> list[tuple[float, float]]:
    """Lines (a [N], b [N s/m]) with F(v) <= a + b / v for every 0 < v <= vmax: the upper concave hull
    of the curve over the slowness w = 1/v [s/m] (exact for min(F, P/v), which is concave in w).

    Args:
        curve: a force curve F(v) [N] over speed [m/s].
        vmax_mps: highest speed at which the hull must hold [m/s].
        max_lines: at most this many lines (a subset of the hull's segments, still above F).
    """
    c = np.asarray(curve.coefficients, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        knees = [
            curve.power_cap_w / curve.force_cap_n,  # where the power cap takes over from the force cap
            *(c[:, 3] / c[:, 0]),  # where c0 = ch / v
            *(curve.power_cap_w / c[:, 0]),
            *(c[:, 3] / curve.force_cap_n),
        ]
    kinks = np.asarray([*np.asarray(curve.interval_start_mps, dtype=float), *knees], dtype=float)
    kinks = kinks[np.isfinite(kinks) & (kinks > 1e-3) & (kinks < vmax_mps)]
    v = np.unique(np.concatenate([np.geomspace(1e-3, vmax_mps, 3000), kinks, kinks * (1 - 1e-9)]))
    f = np.asarray(curve(v), dtype=float)
    f0 = float(np.max(curve(np.linspace(0.0, 1e-3, 11))))
    w = np.concatenate([1.0 / v[::-1], [1e12]])
    f = np.concatenate([f[::-1], [max(f0, float(f[0]))]])
    # Andrew's monotone chain, upper hull, w increasing
    hull: list[tuple[float, float]] = []
    for p in zip(w, f, strict=True):
        while len(hull) >= 2:
            (x1, y1), (x2, y2) = hull[-2], hull[-1]
            if (x2 - x1) * (p[1] - y1) - (y2 - y1) * (p[0] - x1) >= 0.0:
                hull.pop()
            else:
                break
        hull.append(p)
    lines = []
    for (x1, y1), (x2, y2) in pairwise(hull):
        b = (y2 - y1) / (x2 - x1)
        lines.append((y1 - b * x1, b))
    # every segment's line lies above a concave function: any subset of them is still an upper
    # bound; at most max_lines, spread over the speeds of their segments, keep the NLP small
    if len(lines) > max_lines:
        keep = np.unique(np.round(np.linspace(0, len(lines) - 1, max_lines)).astype(int))
        lines = [lines[k] for k in keep]
    # between the samples a curve may bulge above the hull: lift it by what a 10x finer check finds
    check = np.geomspace(1e-3, vmax_mps, 30000)
    hull_f = np.min([a + b / check for a, b in lines], axis=0)
    lift = max(0.0, float(np.max(np.asarray(curve(check), dtype=float) - hull_f)))
    lift = 2.0 * lift + 1e-9 * float(np.max(f))
    return [(a + lift, b) for a, b in lines]


@dataclass(frozen=True)
class _Problem:
    """The discretised section: grid, line resistance per interval, limits, train constants."""

    s: np.ndarray
    h: np.ndarray
    a_mid: np.ndarray  # specific line resistance (gradient + curve + tunnel constant) [-]
    b_mid: np.ndarray  # tunnel v^2 coefficient [s^2/m^2]
    node_lim: np.ndarray  # speed limit at the nodes [m/s]
    vmax: float
    weight_n: float  # m g [N]
    M: float
    eta_t: float
    eta_r: float
    windows: tuple[tuple[int, TimingPoint], ...]  # (node index, timing point relative to departure)


def _problem(
    train: Train,
    route: Route,
    s0: float,
    s1: float,
    intervals: int,
    timing_points: Sequence[TimingPoint],
    grid: np.ndarray | None = None,
) -> _Problem:
    if not s1 > s0:
        raise InputError("the section must have a positive length", field="s1", value=s1, allowed=f"> {s0}")
    if intervals < 10:
        raise InputError("too few intervals", field="intervals", value=intervals, allowed=">= 10")
    if train.braking.service_force is None:
        raise InputError(
            "the reference needs a braking force law, not a constant deceleration", field="braking"
        )
    profile = line_resistance_profile(route, train)
    ceiling = speed_ceiling(route, train)
    inside = [p for p in timing_points if s0 < p.position_m < s1]
    breaks = np.unique(
        np.concatenate(
            [
                profile.gradient.x,
                profile.curve.x,
                profile.tunnel.x,
                ceiling.x,
                np.array([p.position_m for p in inside], dtype=float),
            ]
        )
    )
    s = _grid(breaks, s0, s1, intervals) if grid is None else grid
    h = np.diff(s)
    mid = 0.5 * (s[:-1] + s[1:])
    vlim = ceiling(mid)
    node_lim = np.minimum(np.concatenate([vlim, [vlim[-1]]]), np.concatenate([[vlim[0]], vlim]))
    windows = []
    for p in inside:
        k = int(np.argmin(np.abs(s - p.position_m)))
        windows.append((k, p))
    elec = train.electrical
    regen = train.braking.regenerative
    return _Problem(
        s=s,
        h=h,
        a_mid=profile.gradient(mid) + profile.curve(mid) + profile.tunnel(mid),
        b_mid=profile.tunnel_v2(mid),
        node_lim=node_lim,
        vmax=float(vlim.max()),
        weight_n=profile.weight_n(train.mass_kg),
        M=train.inertial_mass_kg,
        eta_t=elec.traction_efficiency if elec else 1.0,
        eta_r=elec.regenerative_efficiency * elec.receptivity if (elec and regen is not None) else 0.0,
        windows=tuple(windows),
    )


def _casadi():
    try:
        import casadi as ca
    except ImportError as exc:  # optional dependency
        raise TrainsimError("the reference optimum needs CasADi: pip install 'trainsim[reference]'") from exc
    return ca


def _ipopt_options(max_iter: int, time_limit_s: float) -> dict:
    return {
        "print_level": 0,
        "max_iter": max_iter,
        "tol": 1e-9,
        "acceptable_tol": 1e-7,
        "sb": "yes",
        # CPU, not wall time: under load a wall-clock limit cut the same solve at another iterate
        "max_cpu_time": max(float(time_limit_s), 0.1),
        # the monotone barrier update took 90-190 s (iteration limit) on a 35 per mille descent at
        # +100 %; the adaptive one converges there in about 30 iterations
        "mu_strategy": "adaptive",
    }


def _status(opti, converged: bool) -> str:
    if converged:
        return "ok"
    stats = opti.stats()
    ret = str(stats.get("return_status"))
    if "CpuTime" in ret:
        return "time limit (CPU time): the last iterate is reported, not converged"
    if "WallTime" in ret:
        return "time limit (wall time): the last iterate is reported, not converged"
    if "Infeasible" in ret:
        return f"infeasible: {ret}"
    return f"not converged: {ret}"


def _window_constraints(opti, prob: _Problem, cumulative_time, speed_sq_half) -> None:
    """Time windows as bounds on the cumulative time at a node, speed windows on E = v^2/2."""
    for k, p in prob.windows:
        if p.earliest_s is not None:
            opti.subject_to(cumulative_time(k) >= p.earliest_s)
        if p.latest_s is not None:
            opti.subject_to(cumulative_time(k) <= p.latest_s)
        if p.min_speed_mps is not None and p.min_speed_mps > 0.0:
            opti.subject_to(speed_sq_half(k) >= 0.5 * p.min_speed_mps**2)
        if p.max_speed_mps is not None:
            opti.subject_to(speed_sq_half(k) <= 0.5 * p.max_speed_mps**2)


def _guess_forces(train: Train, prob: _Problem, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Traction, regenerative and friction forces [N] that a speed profile at the nodes needs."""
    h = prob.h
    vm = 0.5 * (v[:-1] + v[1:])
    v2 = 0.5 * (v[:-1] ** 2 + v[1:] ** 2)
    law = train.resistance_law
    need = (
        prob.M * (v[1:] ** 2 - v[:-1] ** 2) / (2 * h)
        + law.c0
        + law.c1 * vm
        + (law.c2 + prob.weight_n * prob.b_mid) * v2
        + prob.weight_n * prob.a_mid
    )
    regen = train.braking.regenerative
    cap = np.asarray(regen(vm), dtype=float) if regen is not None else np.zeros_like(vm)
    brake = np.maximum(-need, 0.0)
    ur = np.minimum(brake, cap)
    return np.maximum(need, 0.0), ur, brake - ur


def _fastest_guess(
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


def _coast_floor(train: Train, route: Route, s0: float, s1: float, s: np.ndarray, v_c: float) -> np.ndarray:
    """min(v_c, the fastest run's speed) at the nodes [m/s] (the lowest coasting speed as a floor)."""
    import dataclasses

    from trainsim.model.route import Station
    from trainsim.sim.fastest import run_fastest

    section = dataclasses.replace(route, stations=(Station("from", s0), Station("to", s1)))
    tr = run_fastest(train, section).trace
    # below the fastest run by a margin: the transcription's trapezoidal motion is not the integrator's
    return np.minimum(v_c, (1.0 - COAST_FLOOR_MARGIN) * np.interp(s, tr.position_m, tr.speed_mps))


def solve_reference(
    train: Train,
    route: Route,
    s0: float,
    s1: float,
    running_time_s: float,
    intervals: int = 1000,
    *,
    max_iter: int = 3000,
    warm_start: tuple[np.ndarray, np.ndarray] | None = None,
    time_limit_s: float = TIME_LIMIT_S,
    timing_points: Sequence[TimingPoint] = (),
    grid: np.ndarray | None = None,
    constraints: DrivingConstraints | None = None,
) -> ReferenceSolution:
    """The minimum-energy run from standstill at s0 to standstill at s1 in ``running_time_s`` on one grid.

    Args:
        train, route: the train and the line.
        s0, s1: the section's stops [m].
        running_time_s: scheduled running time [s] (the run takes at most this).
        intervals: about this many grid intervals (more near the stops and breakpoints).
        max_iter: IPOPT's iteration limit.
        warm_start: (positions [m], speeds [m/s]) of a run to start from (e.g. the optimal
            strategy's); by default the fastest run slowed down uniformly to the scheduled time.
        time_limit_s: IPOPT's CPU-time limit [s] (``max_cpu_time``: the load of the machine does
            not change the result); past it the last iterate is reported and the status says so.
        timing_points: time windows (from the departure at s0) [s] and speed windows [m/s] at
            positions inside the section, enforced at a grid node placed on each.
        grid: node positions to use instead of building one [m].
        constraints: comfort limits on the kinematic acceleration (v_{k+1}^2 - v_k^2) / (2 h) of
            every interval and on the jerk (its change between intervals per second), the lowest
            coasting speed as a speed floor (``_coast_floor``; the minimum regime time is not an NLP
            constraint: ``optimize`` says so in a note); apply
            ``constrained_train``/``constrained_route`` for the force caps and the speed margin.
    """
    ca = _casadi()
    prob = _problem(train, route, s0, s1, intervals, timing_points, grid)
    s, h, n = prob.s, prob.h, len(prob.s) - 1
    law = train.resistance_law
    opti = ca.Opti()
    v = opti.variable(n + 1)
    # forces in units of FORCE_SCALE keep IPOPT's problem well scaled
    ut_s, ur_s, uf_s = opti.variable(n), opti.variable(n), opti.variable(n)
    ut, ur, uf = FORCE_SCALE * ut_s, FORCE_SCALE * ur_s, FORCE_SCALE * uf_s
    vm = 0.5 * (v[:-1] + v[1:])
    # the v^2 terms by the trapezoidal rule on v^2 (= E_k + E_{k+1}), linear in E: see lower_bound
    v2 = 0.5 * (v[:-1] ** 2 + v[1:] ** 2)
    resist = law.c0 + law.c1 * vm + (law.c2 + prob.weight_n * prob.b_mid) * v2 + prob.weight_n * prob.a_mid
    opti.subject_to(
        prob.M * (v[1:] ** 2 - v[:-1] ** 2) / (2 * FORCE_SCALE) == h * (ut - ur - uf - resist) / FORCE_SCALE
    )
    upper = prob.node_lim.copy()
    upper[0] = upper[-1] = 0.0
    opti.subject_to(opti.bounded(0.0, v, upper))
    dt = 2 * h / (v[:-1] + v[1:])
    # at least as fast as scheduled: saving energy makes it exactly the scheduled time
    opti.subject_to(ca.sum1(dt) <= running_time_s)
    _window_constraints(opti, prob, lambda k: ca.sum1(dt[:k]), lambda k: 0.5 * v[k] ** 2)
    if constraints is not None:
        acc = (v[1:] ** 2 - v[:-1] ** 2) / (2 * h)
        if constraints.max_acceleration_mps2 is not None:
            opti.subject_to(acc <= constraints.max_acceleration_mps2)
        if constraints.max_deceleration_mps2 is not None:
            opti.subject_to(acc >= -constraints.max_deceleration_mps2)
        if constraints.coast_min_speed_mps > 0.0:
            # coasting only above v_c as a speed floor (module doc): min(v_c, the fastest run's speed),
            # so the train falls below v_c only on the braking curves into the stop and lower limits
            floor = _coast_floor(train, route, s0, s1, s, constraints.coast_min_speed_mps)
            opti.subject_to(v[1:-1] >= floor[1:-1])
        if constraints.max_jerk_mps3 is not None and n > 1:
            # change of acceleration between neighbouring intervals over the time between their middles
            dt_mid = 0.5 * (dt[:-1] + dt[1:])
            jerk = acc[1:] - acc[:-1]
            opti.subject_to(jerk <= constraints.max_jerk_mps3 * dt_mid)
            opti.subject_to(jerk >= -constraints.max_jerk_mps3 * dt_mid)
    vtop = prob.vmax * 1.05
    for u, curve in ((ut, train.traction), (ur, train.braking.regenerative)):
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
            grid_v = np.linspace(0.0, vtop, 400)
            table = ca.interpolant("effort", "linear", [grid_v], np.asarray(curve(grid_v), dtype=float))
            opti.subject_to(u >= 0)
            opti.subject_to(u <= table(vm))
    grid_v = np.linspace(0.0, vtop, 400)
    service = train.braking.service_force
    total = ca.interpolant("service", "linear", [grid_v], np.asarray(service(grid_v), dtype=float))
    opti.subject_to(uf >= 0)
    opti.subject_to(ur + uf <= total(vm))
    opti.minimize(ca.sum1(h * (ut / prob.eta_t - prob.eta_r * ur)) / 3.6e6)
    if warm_start is not None:
        guess = np.interp(s, np.asarray(warm_start[0], float), np.asarray(warm_start[1], float))
    else:
        guess = _fastest_guess(train, route, s0, s1, s, running_time_s)
    if constraints is not None and constraints.coast_min_speed_mps > 0.0:
        guess = np.maximum(guess, _coast_floor(train, route, s0, s1, s, constraints.coast_min_speed_mps))
    guess = np.clip(guess, 0.0, prob.node_lim)
    guess[0] = guess[-1] = 0.0
    # an interior start: no interval at standstill at both ends
    floor = 0.05 * float(np.max(guess)) if np.max(guess) > 0 else 1.0
    inner = np.maximum(guess[1:-1], np.minimum(floor, 0.5 * prob.node_lim[1:-1]))
    guess[1:-1] = inner
    g_t, g_r, g_f = _guess_forces(train, prob, guess)
    opti.set_initial(v, guess)
    opti.set_initial(ut_s, g_t / FORCE_SCALE)
    opti.set_initial(ur_s, g_r / FORCE_SCALE)
    opti.set_initial(uf_s, g_f / FORCE_SCALE)
    opti.solver("ipopt", {"print_time": False}, _ipopt_options(max_iter, time_limit_s))
    t0, c0 = _time.perf_counter(), _time.process_time()
    try:
        sol = opti.solve()
        get, converged = sol.value, True
    except RuntimeError:
        get, converged = opti.debug.value, False
    elapsed, cpu = _time.perf_counter() - t0, _time.process_time() - c0
    status = _status(opti, converged)
    vv = np.asarray(get(v), dtype=float).ravel()
    if converged and np.min(vv) < -SPEED_BOUND_TOLERANCE_MPS:
        status = f"not converged: speed {np.min(vv):.3g} m/s below 0"
    vv = np.clip(vv, 0.0, None)
    vv[0] = vv[-1] = 0.0  # fixed by their bounds
    ut_v, ur_v, uf_v = (FORCE_SCALE * np.asarray(get(x), dtype=float).ravel() for x in (ut_s, ur_s, uf_s))
    energy = float(np.sum(h * (ut_v / prob.eta_t - prob.eta_r * ur_v)))
    run_time = float(np.sum(2 * h / np.maximum(vv[:-1] + vv[1:], 1e-12)))
    return ReferenceSolution(s, vv, ut_v, ur_v, uf_v, energy, run_time, n, elapsed, status, solve_cpu_s=cpu)


def lower_bound(
    train: Train,
    route: Route,
    s0: float,
    s1: float,
    running_time_s: float,
    intervals: int = 1000,
    *,
    timing_points: Sequence[TimingPoint] = (),
    grid: np.ndarray | None = None,
    time_limit_s: float = TIME_LIMIT_S,
    warm_start: ReferenceSolution | None = None,
) -> LowerBound:
    """The optimum of the convex relaxation of the transcription on the same grid (module doc): a
    lower bound on the least energy [J] of every run the transcription can represent.

    ``time_limit_s`` is IPOPT's CPU-time limit [s]. Returns status "not convex" (energy -inf) where
    the train's resistance has a negative coefficient or a tunnel a negative v^2 term (the
    relaxation is then not convex)."""
    ca = _casadi()
    prob = _problem(train, route, s0, s1, intervals, timing_points, grid)
    s, h, n = prob.s, prob.h, len(prob.s) - 1
    law = train.resistance_law
    if law.c1 < 0.0 or law.c2 < 0.0 or np.any(prob.b_mid < 0.0):
        return LowerBound(-np.inf, "not convex: a negative resistance coefficient", 0.0, n)
    opti = ca.Opti()
    E = opti.variable(n + 1)  # v^2 / 2 [m^2/s^2]
    dt = opti.variable(n)  # [s]
    ut_s, ur_s, uf_s, q_s = opti.variable(n), opti.variable(n), opti.variable(n), opti.variable(n)
    ut, ur, uf, q = (FORCE_SCALE * x for x in (ut_s, ur_s, uf_s, q_s))
    c0 = law.c0 + prob.weight_n * prob.a_mid
    c2 = law.c2 + prob.weight_n * prob.b_mid
    opti.subject_to(
        prob.M * (E[1:] - E[:-1]) / FORCE_SCALE
        == (h * (ut - ur - uf - c0 - c2 * (E[:-1] + E[1:])) - q) / FORCE_SCALE
    )
    w = h / dt  # mean speed of the interval [m/s]
    # the mean speed v_m = (sqrt(2 E_k) + sqrt(2 E_{k+1})) / 2 is concave in E: dt >= h / v_m is
    # convex, and h c1 v_m lies between h c1 (h/dt) and that concave function (a convex constraint);
    # a floor of 1e-12 m^2/s^2 keeps the roots regular at standstill
    root = ca.sqrt(2.0 * E + 1e-12)
    v_mean = 0.5 * (root[:-1] + root[1:])
    opti.subject_to(dt >= h / v_mean)
    opti.subject_to(q_s >= h * law.c1 * w / FORCE_SCALE)
    opti.subject_to(q_s <= h * law.c1 * v_mean / FORCE_SCALE)
    upper = 0.5 * prob.node_lim**2
    upper[0] = upper[-1] = 0.0
    opti.subject_to(opti.bounded(0.0, E, upper))
    opti.subject_to(ca.sum1(dt) <= running_time_s)
    _window_constraints(opti, prob, lambda k: ca.sum1(dt[:k]), lambda k: E[k])
    slowness = dt / h
    vtop = prob.vmax * 1.05
    for u, curve in ((ut, train.traction), (ur, train.braking.regenerative)):
        if curve is None:
            opti.subject_to(u == 0)
            continue
        opti.subject_to(u >= 0)
        for a, b in concave_hull_in_slowness(curve, vtop):
            opti.subject_to(u / FORCE_SCALE <= (a + b * slowness) / FORCE_SCALE)
    opti.subject_to(uf >= 0)
    for a, b in concave_hull_in_slowness(train.braking.service_force, vtop):
        opti.subject_to((ur + uf) / FORCE_SCALE <= (a + b * slowness) / FORCE_SCALE)
    opti.minimize(ca.sum1(h * (ut / prob.eta_t - prob.eta_r * ur)) / 3.6e6)
    if warm_start is not None and len(warm_start.s) == len(s):
        vv = warm_start.v
        vm = np.maximum(0.5 * (vv[:-1] + vv[1:]), 1e-3)
        opti.set_initial(E, 0.5 * vv**2)
        opti.set_initial(dt, h / vm)
        opti.set_initial(ut_s, warm_start.traction_n / FORCE_SCALE)
        opti.set_initial(ur_s, warm_start.regenerative_n / FORCE_SCALE)
        opti.set_initial(uf_s, warm_start.friction_n / FORCE_SCALE)
        opti.set_initial(q_s, h * law.c1 * vm / FORCE_SCALE)
    else:
        vm = np.full(n, max(1.0, (s1 - s0) / running_time_s))
        opti.set_initial(E, np.minimum(0.5 * vm[0] ** 2, upper))
        opti.set_initial(dt, h / vm)
        opti.set_initial(q_s, h * law.c1 * vm / FORCE_SCALE)
    opti.solver("ipopt", {"print_time": False}, _ipopt_options(3000, time_limit_s))
    t0, c0 = _time.perf_counter(), _time.process_time()
    try:
        sol = opti.solve()
        value, converged = float(sol.value(opti.f)) * 3.6e6, True
    except RuntimeError:
        value, converged = -np.inf, False
    status = _status(opti, converged)
    return LowerBound(
        value if converged else -np.inf, status, _time.perf_counter() - t0, n, _time.process_time() - c0
    )


def certified_reference(
    train: Train,
    route: Route,
    s0: float,
    s1: float,
    running_time_s: float,
    intervals: int = 1000,
    *,
    warm_start: tuple[np.ndarray, np.ndarray] | None = None,
    time_limit_s: float = TIME_LIMIT_S,
    timing_points: Sequence[TimingPoint] = (),
    tolerance: float = REFINEMENT_TOLERANCE,
    max_intervals: int = 32000,
    bound: bool = True,
    bound_time_limit_s: float = TIME_LIMIT_S,
) -> ReferenceSolution:
    """The reference with mesh refinement and a lower bound (module doc).

    The intervals are doubled, each solve warm started from the last (the first from
    ``warm_start``), until the energy moves by less than ``tolerance`` (relative) or
    ``max_intervals`` or ``time_limit_s`` [s] of CPU time is reached (``time.process_time``: the
    machine's load does not change the result); the lower bound is computed on the last grid,
    within its own ``bound_time_limit_s`` [s] of CPU time. The status is "ok" only when the last
    solve converged and the mesh did. ``solve_time_s`` is the wall time of the whole call,
    ``solve_cpu_s`` its CPU time.
    """
    t_start, c_start = _time.perf_counter(), _time.process_time()

    def left() -> float:
        return time_limit_s - (_time.process_time() - c_start)

    mesh: list[tuple[int, float, str]] = []
    best: ReferenceSolution | None = None
    previous: ReferenceSolution | None = None
    n = intervals
    mesh_ok = False
    while True:
        ws = warm_start if previous is None else (previous.s, previous.v)
        sol = solve_reference(
            train,
            route,
            s0,
            s1,
            running_time_s,
            n,
            warm_start=ws,
            time_limit_s=max(left(), 0.5),
            timing_points=timing_points,
        )
        mesh.append((sol.intervals, sol.energy_j, sol.status))
        if sol.status == "ok":
            if previous is not None and previous.status == "ok":
                change = abs(sol.energy_j - previous.energy_j) / max(abs(sol.energy_j), 1.0)
                if change < tolerance:
                    mesh_ok = True
            best, previous = sol, sol
        elif best is None:
            best = sol
        # the next solve has twice the intervals: it is not started unless about 4x this one's CPU is left
        if sol.status != "ok" or mesh_ok or 2 * n > max_intervals or left() < 4.0 * sol.solve_cpu_s:
            break
        n *= 2
    status = best.status
    if status == "ok" and not mesh_ok:
        status = (
            f"mesh not converged: the last doubling moved the optimum by more than {tolerance:.0e} "
            f"(limit of {max_intervals} intervals or {time_limit_s:g} s of CPU time reached)"
        )
    lb, bound_status = None, ""
    if bound and best.status == "ok":
        low = lower_bound(
            train,
            route,
            s0,
            s1,
            running_time_s,
            timing_points=timing_points,
            grid=best.s,
            time_limit_s=bound_time_limit_s,
            warm_start=best,
        )
        lb, bound_status = low.energy_j, low.status
    return ReferenceSolution(
        best.s,
        best.v,
        best.traction_n,
        best.regenerative_n,
        best.friction_n,
        best.energy_j,
        best.running_time_s,
        best.intervals,
        _time.perf_counter() - t_start,
        status,
        lb,
        tuple(mesh),
        bound_status,
        _time.process_time() - c_start,
    )
