"""Source 004's algorithm (Lesov, Adilov, Miryakubov, Usmonov): switching points of traction,
steady running, recuperative and mechanical braking from the scheduled time.

The method works in Russian traction-calculation units (PTR): speeds in km/h, time in minutes,
distances in metres, specific forces in N/kN of train weight. Our reading of the paper, where it
is ambiguous (documented in docs/OPTIMIZATION.md):

* specific forces: f_u(V) = 1000 F_u(V) / ((P+Q) g), w_m(V) = 1000 R(V) / ((P+Q) g), w_a(S) the
  line resistance in per mille; the accelerating force f_t = f_u - w_m - w_a;
* speed steps dV = 10 km/h up to V_l = 50 km/h, 5 km/h above, 1 km/h within 5 km/h of the target;
* time of a step dt = dV / (zeta f_t) [min], where the paper's "2" is zeta = 3.6 * 60 g / (1000 rho)
  km/h per minute per N/kN, i.e. 2.0 for rho = 1.06; we use the train's rho;
* path of a step dS = 16.7 (V_c + dV/2) dt [m] (16.7 = 1000/60);
* the "coasting" mode of the paper runs at the constant speed V_ss (its time formula
  dt = dS / (16.7 V_ss) says so): steady running;
* recuperative braking with f_ru = 0.8 f_u(V) from V_ss down to V_mech = 10 km/h ("when the speed
  reaches a certain limit, mechanical braking is applied"), then mechanical (service) braking;
* the schedule check t_i = t_tr +- epsilon with epsilon = 0.5 s, and the correction of the speed
  increment dV = (dS - 16.7 V_c dt_tr) / (8.35 dt_tr) applied to the steady speed: V_ss <- V_ss +
  dV / 2 (the mean speed that covers the steady-running distance in the time left for it);
* the slope correction t_b = k_cor (S_i / S) t_norm: each gradient sub-section gets the time budget
  of its length share, corrected by k_cor = its share of the fastest run's time over its length
  share (``slope_budgets``, in ``LesovSwitching.slope_budgets``); the paper does not say how the
  budgets move the switching points, so they are computed and returned, not used for driving.

The switching points found this way are then driven by trainsim's simulator (same physics as every
other strategy), with the regenerative brake at 0.8 x the traction curve as the paper says.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from trainsim.constants import KMH
from trainsim.model.route import Route, Station
from trainsim.model.scenario import RunSettings
from trainsim.model.train import Braking, Train
from trainsim.optimize import pmp_kernel as pk
from trainsim.optimize.optimal import SectionPlan, SectionSolver
from trainsim.sim import kernel
from trainsim.sim.profile import line_resistance_profile

RECUPERATION_SHARE = 0.8  #: f_ru = 0.8 f_u(V) (source 004)
SPEED_STEP_LOW_KMH = 10.0
SPEED_STEP_HIGH_KMH = 5.0
SPEED_STEP_FINE_KMH = 1.0
SPEED_STEP_LIMIT_KMH = 50.0  #: V_l: above it the step is 5 km/h
MECHANICAL_BRAKING_SPEED_KMH = 10.0
EPSILON_MIN = 0.5 / 60.0  #: schedule tolerance [min]
PATH_PER_KMH_MIN = 16.7  #: m per (km/h x min)


def zeta_kmh_per_min(train: Train, g_mps2: float) -> float:
    """Acceleration [km/h per min] of 1 N/kN of net specific force: 3.6 x 60 g / (1000 rho), with g
    [m/s^2] the route's gravity (``Route.gravity_mps2``)."""
    return 3.6 * 60.0 * g_mps2 / (1000.0 * train.rotating_mass_factor)


def specific_force_n_per_kn(force_n: float, train: Train, g_mps2: float) -> float:
    """A force [N] as specific force [N/kN] of the train's weight m g (source 004 eq. for f_t max)."""
    return 1000.0 * force_n / (train.mass_kg * g_mps2)


def net_specific_force_n_per_kn(deceleration_mps2: float, train: Train, g_mps2: float) -> float:
    """The net specific force [N/kN] that gives a deceleration [m/s^2]: a x 1000 rho / g, the
    inverse of zeta (source 004's dt = dV / (zeta f_t))."""
    return deceleration_mps2 * 1000.0 * train.rotating_mass_factor / g_mps2


def speed_step_kmh(v_kmh: float, target_kmh: float) -> float:
    """dV: 10 km/h up to V_l, 5 km/h above, 1 km/h within 5 km/h of the target (source 004)."""
    if target_kmh - v_kmh <= 5.0:
        return SPEED_STEP_FINE_KMH
    return SPEED_STEP_LOW_KMH if v_kmh <= SPEED_STEP_LIMIT_KMH else SPEED_STEP_HIGH_KMH


def time_step_min(dv_kmh: float, f_t: float, zeta: float) -> float:
    """dt = dV / (zeta f_t) [min] (source 004, with the paper's 2 = zeta)."""
    return dv_kmh / (zeta * f_t)


def path_step_m(v_kmh: float, dv_kmh: float, dt_min: float) -> float:
    """dS = 16.7 (V_c + dV/2) dt [m] (source 004)."""
    return PATH_PER_KMH_MIN * (v_kmh + 0.5 * dv_kmh) * dt_min


def corrected_speed_increment_kmh(ds_m: float, v_kmh: float, dt_tr_min: float) -> float:
    """dV = (dS - 16.7 V_c dt_tr) / (8.35 dt_tr) (source 004): the increment that covers dS in dt_tr."""
    return (ds_m - PATH_PER_KMH_MIN * v_kmh * dt_tr_min) / (8.35 * dt_tr_min)


@dataclass(frozen=True)
class LesovSwitching:
    """Switching points of source 004's method for one section."""

    steady_speed_kmh: float
    traction_end_m: float
    recuperation_start_m: float
    mechanical_start_m: float
    predicted_time_min: float
    iterations: int
    slope_budgets: tuple[tuple[float, float, float], ...]  # (start m, end m, budget s)


def _phases(train: Train, route: Route, s0: float, s1: float, v_ss: float, zeta: float):
    """Traction from 0 to v_ss, and braking (recuperative, then mechanical) from v_ss to 0, by the
    paper's speed steps; returns (traction distance, time, braking distance, time, mech distance)."""
    prof = line_resistance_profile(route, train)
    g = route.gravity_mps2

    def w_a(s: float) -> float:
        return 1000.0 * float(prof.gradient(s) + prof.curve(s) + prof.tunnel(s))

    def f_u(v_kmh: float) -> float:
        return specific_force_n_per_kn(float(train.traction(v_kmh * KMH)), train, g)

    def w_m(v_kmh: float) -> float:
        return specific_force_n_per_kn(float(train.running_resistance_n(v_kmh * KMH)), train, g)

    s, t, v = s0, 0.0, 0.0
    while v < v_ss - 1e-9 and s < s1:
        dv = min(speed_step_kmh(v, v_ss), v_ss - v)
        vm = v + 0.5 * dv
        f_t = f_u(vm) - w_m(vm) - w_a(s)
        if f_t <= 1e-3:
            break  # the accelerating force vanishes: steady running from here (source 004)
        dt = time_step_min(dv, f_t, zeta)
        s += path_step_m(v, dv, dt)
        t += dt
        v += dv
    trac_s, trac_t, v_top = s - s0, t, v
    # braking backwards from the stop: mechanical to V_mech, recuperative above
    s, t, v = s1, 0.0, 0.0
    mech = None
    while v < v_top - 1e-9 and s > s0:
        dv = min(speed_step_kmh(v, v_top), v_top - v)
        vm = v + 0.5 * dv
        if vm <= MECHANICAL_BRAKING_SPEED_KMH:
            if train.braking.service_force is not None:
                b = specific_force_n_per_kn(float(train.braking.service_force(vm * KMH)), train, g)
            else:
                # a train that brakes at a constant net deceleration (resistance and grade
                # included): the specific force that gives it, less what resistance and grade add
                b = net_specific_force_n_per_kn(train.braking.deceleration_mps2, train, g) - w_m(vm) - w_a(s)
        else:
            if mech is None:
                mech = s
            b = RECUPERATION_SHARE * f_u(vm)
        f_t = b + w_m(vm) + w_a(s)
        dt = time_step_min(dv, max(f_t, 1e-3), zeta)
        s -= path_step_m(v, dv, dt)
        t += dt
        v += dv
    return trac_s, trac_t, s1 - s, t, (mech if mech is not None else s1), v_top


def slope_budgets(
    train: Train, route: Route, s0: float, s1: float, scheduled_s: float
) -> list[tuple[float, float, float]]:
    """Source 004's boundary times t_b = k_cor (S_i / S) t_norm of the gradient sub-sections, as
    (start m, end m, t_b s). Our reading of k_cor: the sub-section's share of the fastest run's time
    over its share of the length, so that slopes that cost time get more of the schedule."""
    from trainsim.sim.fastest import run_fastest

    if not route.gradients:
        return []
    section = dataclasses.replace(route, stations=(Station("a", s0), Station("b", s1)))
    tr = run_fastest(train, section).trace
    t_fast = float(tr.time_s[-1] - tr.time_s[0])
    budgets = []
    for g in route.gradients:
        a, b = max(g.start_m, s0), min(g.end_m, s1)
        if b > a and t_fast > 0:
            share = (b - a) / (s1 - s0)
            dt_fast = float(np.interp(b, tr.position_m, tr.time_s) - np.interp(a, tr.position_m, tr.time_s))
            k_cor = (dt_fast / t_fast) / share
            budgets.append((a, b, k_cor * share * scheduled_s))
    return budgets


def switching_for_speed(
    train: Train,
    route: Route,
    s0: float,
    s1: float,
    steady_kmh: float,
    scheduled_s: float = 0.0,
    iterations: int = 0,
) -> LesovSwitching:
    """The switching points of source 004's mode sequence for a steady speed [km/h]."""
    zeta = zeta_kmh_per_min(train, route.gravity_mps2)
    trac_s, trac_t, brk_s, brk_t, mech_s, v_top = _phases(train, route, s0, s1, steady_kmh, zeta)
    cruise_s = max((s1 - s0) - trac_s - brk_s, 0.0)
    budgets = slope_budgets(train, route, s0, s1, scheduled_s)
    return LesovSwitching(
        steady_speed_kmh=v_top,
        traction_end_m=s0 + trac_s,
        recuperation_start_m=s1 - brk_s,
        mechanical_start_m=mech_s,
        predicted_time_min=trac_t + brk_t + cruise_s / (PATH_PER_KMH_MIN * max(v_top, 1e-9)),
        iterations=iterations,
        slope_budgets=tuple(budgets),
    )


def lesov_switching(train: Train, route: Route, s0: float, s1: float, scheduled_s: float) -> LesovSwitching:
    """Source 004's iteration for the steady speed V_ss and the switching points of a section."""
    zeta = zeta_kmh_per_min(train, route.gravity_mps2)
    vmax_kmh = train.max_speed_mps / KMH
    t_sched = scheduled_s / 60.0
    v_ss = vmax_kmh
    iterations = 0
    for iterations in range(1, 100):  # noqa: B007 - the count is reported
        trac_s, trac_t, brk_s, brk_t, mech_s, v_top = _phases(train, route, s0, s1, v_ss, zeta)
        cruise_s = (s1 - s0) - trac_s - brk_s
        if cruise_s < 0.0:
            v_ss *= 0.9  # phases overlap: lower the steady speed
            continue
        t_total = trac_t + brk_t + cruise_s / (PATH_PER_KMH_MIN * v_top)
        if abs(t_total - t_sched) < EPSILON_MIN:
            break
        dt_tr = t_sched - trac_t - brk_t
        if dt_tr <= 0.0:
            v_ss = min(vmax_kmh, v_ss * 1.05)
            if v_ss >= vmax_kmh:
                break
            continue
        dv = corrected_speed_increment_kmh(cruise_s, v_top, dt_tr)
        v_new = min(vmax_kmh, max(5.0, v_top + 0.5 * dv))
        if abs(v_new - v_ss) < 1e-6:
            break
        v_ss = v_new
    budgets = slope_budgets(train, route, s0, s1, scheduled_s)
    return LesovSwitching(
        steady_speed_kmh=v_top,
        traction_end_m=s0 + trac_s,
        recuperation_start_m=s1 - brk_s,
        mechanical_start_m=mech_s,
        predicted_time_min=t_total,
        iterations=iterations,
        slope_budgets=tuple(budgets),
    )


def lesov_train(train: Train) -> Train:
    """The train with source 004's recuperative brake: 0.8 x its traction curve. A train without
    a regenerative brake of its own brakes electrically this way without returning energy (a
    rheostatic brake): the line accepts nothing from it."""
    electrical = train.electrical
    if electrical is not None and train.braking.regenerative is None:
        electrical = dataclasses.replace(electrical, receptivity=0.0)
    return dataclasses.replace(
        train,
        electrical=electrical,
        braking=Braking(
            service_force=train.braking.service_force,
            deceleration_mps2=train.braking.deceleration_mps2,
            regenerative=train.traction.scaled(RECUPERATION_SHARE, label="0.8 x traction (source 004)"),
            full_force=train.braking.full_force,
        ),
    )


#: Where the recuperation point is searched, it is located to this [m]: far below what moves energy
#: or time by 1e-9 (a metro at 20 m/s covers it in 5e-11 s).
RECUPERATION_POINT_TOLERANCE_M = 1e-9


def _execute(solver: SectionSolver, sw: LesovSwitching) -> SectionPlan:
    """Drive the switching points: hold V_ss, recuperative braking from the recuperation point
    until the service braking curve to the stop, then service braking.

    If the paper's point (computed with its coarse speed steps) would stop the train short, it is
    moved to the first point from which the recuperative brake meets the service braking curve, located
    to :data:`RECUPERATION_POINT_TOLERANCE_M` (a fixed point of the line, whatever the step). Where no
    such point exists (a recuperative brake stronger than the service braking curve, as 0.8 x the
    traction of a freight locomotive can be: from anywhere it stops short), the train brakes along the
    service braking curve itself, which is blended: the recuperative brake supplies what it can."""
    v_ss = sw.steady_speed_kmh * KMH
    tr = solver.track
    vhold = np.minimum(tr.vlim, v_ss)
    out = [np.empty(solver.n_max) for _ in range(3)] + [np.empty(solver.n_max, dtype=np.int8)]
    modes = np.full(len(tr.a0), kernel.BRAKE, dtype=np.int64)
    n, _ = pk.holding_segment(
        tr.x, tr.a0, tr.a1, tr.b0, tr.b1, vhold, vhold, tr.traction_scale, solver.i0, solver.i1,
        solver.P, solver.curves, solver.tk, solver.bk, solver.rk, solver.Cr, solver.US, modes, *out,
    )  # fmt: skip
    phase_a = tuple(a[:n] for a in out)

    def run_from(s_r: float):
        # phi just below eta_r, mu = 0: regenerative braking until the braking curve (phi stays > 0)
        return solver._phase_b_forced(phase_a, s_r)

    s_r = min(max(sw.recuperation_start_m, solver.s0), solver.s1)
    points, status = run_from(s_r)
    if status != pk.HIT_CEILING:
        lo, hi = s_r, solver.s1
        found = None
        for _ in range(200):
            if hi - lo <= RECUPERATION_POINT_TOLERANCE_M * max(1.0, abs(hi)):
                break
            mid = 0.5 * (lo + hi)
            p, st = run_from(mid)
            if st == pk.HIT_CEILING and mid < solver.s1:
                hi, found = mid, p
            else:
                lo = mid
        if found is not None and hi < solver.s1:
            points, s_r = found, hi
        else:
            points, s_r = phase_a, solver.s1  # phase A brakes along the service curve to the stop
    s, v, t, m = points
    m = m.copy()
    m[-1] = kernel.DWELL
    return SectionPlan(s, v, t, m, float(t[-1]), v_ss, s_r, np.nan, solver.fastest_time_s, True)


def lesov_plans(
    train: Train, route: Route, solvers: list[SectionSolver], targets: list[float], settings: RunSettings
) -> tuple[list[SectionPlan], list[str]]:
    """Source 004's runs of every section for its scheduled time."""
    warnings: list[str] = []
    plans = []
    lt = lesov_train(train)
    for sv, T in zip(solvers, targets, strict=True):
        solver = SectionSolver(lt, route, sv.s0, sv.s1, settings)
        if solver.fastest_time_s >= T:
            plans.append(solver.solve(T))
            continue
        sw = lesov_switching(lt, route, sv.s0, sv.s1, T)
        plan = _execute(solver, sw)
        # the paper's schedule check and correction, applied to the run as driven: the time left
        # for steady running sets a new speed increment (source 004, dV formula), until within epsilon
        for _ in range(20):
            error_min = (plan.running_time_s - T) / 60.0
            if abs(error_min) < EPSILON_MIN:
                break
            steady_m = max(sw.recuperation_start_m - sw.traction_end_m, 1.0)
            steady_min = steady_m / (PATH_PER_KMH_MIN * sw.steady_speed_kmh)
            dt_tr = max(steady_min - error_min, 1e-3)
            dv = corrected_speed_increment_kmh(steady_m, sw.steady_speed_kmh, dt_tr)
            v_new = min(train.max_speed_mps / KMH, max(5.0, sw.steady_speed_kmh + 0.5 * dv))
            sw = switching_for_speed(lt, route, sv.s0, sv.s1, v_new, T, sw.iterations + 1)
            plan = _execute(solver, sw)
        if abs(plan.running_time_s - T) > max(0.5, 5e-4 * T):
            # the increment correction can stall where the steady speed is not reached before the
            # braking point (short sections, small supplements): bisect the steady speed instead
            lo, hi = 5.0, train.max_speed_mps / KMH
            for _ in range(40):
                mid = 0.5 * (lo + hi)
                sw_mid = switching_for_speed(lt, route, sv.s0, sv.s1, mid, T, sw.iterations + 1)
                p_mid = _execute(solver, sw_mid)
                if p_mid.running_time_s > T:
                    lo = mid
                else:
                    hi = mid
                if abs(p_mid.running_time_s - T) < abs(plan.running_time_s - T):
                    plan, sw = p_mid, sw_mid
                if abs(plan.running_time_s - T) <= 0.1:
                    break
        if abs(plan.running_time_s - T) > max(0.5, 5e-4 * T):
            warnings.append(
                f"source 004's method: section {sv.s0:.0f}-{sv.s1:.0f} m runs {plan.running_time_s - T:+.1f} s "
                "off its schedule after its corrections"
            )
        plans.append(plan)
    return plans, warnings
