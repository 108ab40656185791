"""Compiled part of the energy-optimal strategy: the final phase of a section driven by the
adjoint of Pontryagin's principle.

With distance s as the independent variable, speed v as state and the price of time mu [W] (the
multiplier of the running-time constraint, equal to -dE/dT), write phi = -lambda / (M v) for the
scaled adjoint of v. Minimising the Hamiltonian
    H = u_t / eta_t - eta_r u_r + mu / v + lambda (u_t - u_r - u_f - R(v) - G(s)) / (M v)
gives the optimal control from phi alone:
    phi > 1 / eta_t: maximum traction;     phi = 1 / eta_t: hold the speed (partial traction);
    eta_r < phi < 1 / eta_t: coast;        0 < phi <= eta_r: maximum regenerative braking;
    phi <= 0: maximum service braking (regenerative and friction),
and the adjoint equation becomes, whatever the control and the grade,
    dphi/ds = (phi R'(v) - mu / v^2) / (M v).
On a speed-holding arc phi stays 1 / eta_t, hence mu = V^2 R'(V) / eta_t: the holding speed V
fixes mu (Albrecht, Howlett, Pudney, Vu, Zhou 2016, "The key principles of optimal train control",
Transportation Research Part B 94, Part 1 section 3; our eta factors follow from the cost).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from trainsim.sim.kernel import (
    BRAKE,
    COAST,
    CRUISE,
    DWELL,
    P_BRAKE_FRACTION,
    P_DECEL,
    P_INERTIAL_MASS,
    P_R1,
    P_R2,
    P_TRACTION_SCALE,
    P_WEIGHT,
    REGEN,
    TRACTION,
    acceleration,
    distance_to_speed,
    effort,
    resistance_force,
    rk4_energy_time,
    step_energy,
    step_energy_time,
)

HIT_CEILING = 1  # met the braking curve to the stop: coasting started too late
STOPPED_SHORT = 2  # came to rest before the stop: coasting started too early

#: Below this speed [m/s] the adjoint is not integrated further (mu / v^2 is singular at rest and
#: the control is maximum braking there anyway).
PHI_MIN_SPEED = 0.05
#: A final phase that comes to rest no farther than this before the stop arrives there (HIT_CEILING)
#: [m]: the run's outcome jumps where its shortfall crosses this, which the coasting point's search
#: aims at (``optimal.SectionSolver.plan``).
REST_AT_STOP_M = 1e-6


@njit(cache=True)
def mode_of(phi, inv_eta_t, eta_r, has_regen):
    if phi >= inv_eta_t:
        return TRACTION
    if phi > eta_r or (not has_regen and phi > 0.0):
        return COAST
    if phi > 0.0:
        return REGEN
    return BRAKE


@njit(cache=True)
def phi_slope(phi, E, u, b0, b1, P, mu):
    """dphi/ds [1/m] at kinetic energy per mass E and offset u."""
    v = np.sqrt(2.0 * E) if E > 0.0 else 0.0
    if v < PHI_MIN_SPEED:
        v = PHI_MIN_SPEED
    # slope of the running plus tunnel resistance over speed [N s/m]
    dR = P[P_R1] + 2.0 * P[P_R2] * v + 2.0 * P[P_WEIGHT] * (b0 + b1 * u) * v
    return (phi * dR - mu / (v * v)) / (P[P_INERTIAL_MASS] * v)


@njit(cache=True)
def phi_step(phi, E0, E1, u, h, b0, b1, P, mu, Em=-1.0):
    """RK4 for phi over a step h; E at the midpoint ``Em`` (by default (< 0) E varying linearly:
    an O(h^2) error that moved the switching points with the step)."""
    if Em < 0.0:
        Em = 0.5 * (E0 + E1)
    k1 = phi_slope(phi, E0, u, b0, b1, P, mu)
    k2 = phi_slope(phi + 0.5 * h * k1, Em, u + 0.5 * h, b0, b1, P, mu)
    k3 = phi_slope(phi + 0.5 * h * k2, Em, u + 0.5 * h, b0, b1, P, mu)
    k4 = phi_slope(phi + h * k3, E1, u + h, b0, b1, P, mu)
    return phi + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


#: Longest RK4 step of the adjoint as a share of the motion's length scale 2E / |a| = v^2 / |a| [-]
#: (``PHI_MAX_SUBSTEPS`` sub-steps per step at most). The adjoint's slope carries mu / v^3, whose
#: relative rate of change along the track is 3 |a| / v^2: braking to the stop below 4 m/s it changes
#: by a factor of 3 to 4 over a 20 m step, and one RK4 step put the adjoint's zero (where the final
#: braking meets the service braking curve) millimetres off, moving with the step (freight: the final
#: phase ended 1.1 ms later at 10 m than at 20 m, and the line's holding speed moved by 1e-6 with it,
#: issue 13).
#: At cruising speeds (20 m/s, 0.05 m/s^2: a scale of 8 km) one step is one sub-step, as before.
PHI_LENGTH_SCALE_FRACTION = 0.02
PHI_MAX_SUBSTEPS = 256


@njit(cache=True)
def phi_advance(phi, E0, E1, u, h, mode, line, P, curves, kinks, mu, Em):
    """phi after a step h [m] from offset u along ``mode`` (E0 -> E1, ``Em`` at the midpoint; kinks
    ``kinks``; line = (a0, a1, b0, b1)): ``phi_step``, divided into sub-steps where the speed
    changes fast against the step (``PHI_LENGTH_SCALE_FRACTION``), E at the sub-steps' ends and
    midpoints integrated in the regime (``step_energy``)."""
    b0, b1 = line[2], line[3]
    n = 1
    if mode != CRUISE and h > 0.0:
        # the length scale at the slower end of the step (the adjoint's slope is steepest there)
        Elow, ulow = (E0, u) if E0 <= E1 else (E1, u + h)
        a = abs(acceleration(mode, Elow, ulow, line, P, curves))
        if Elow > 0.0 and a > 0.0:
            n = int(np.ceil(h * a / (PHI_LENGTH_SCALE_FRACTION * 2.0 * Elow)))
            n = min(max(n, 1), PHI_MAX_SUBSTEPS)
    if n == 1:
        return phi_step(phi, E0, E1, u, h, b0, b1, P, mu, Em)
    d = h / n
    E = E0
    for k in range(n):
        uk = u + k * d
        Ek_mid = step_energy(E, uk, 0.5 * d, mode, line, P, curves, kinks)
        Ek1 = E1 if k == n - 1 else step_energy(E, uk, d, mode, line, P, curves, kinks)
        if Ek1 <= 0.0 or Ek_mid <= 0.0:
            break  # (the step ends at rest: the adjoint is not followed into standstill)
        phi = phi_step(phi, E, Ek1, uk, d, b0, b1, P, mu, Ek_mid)
        E = Ek1
    return phi


@njit(cache=True)
def ceiling_at(u, w, k, Cr, US, vcap, line, P, curves, bk):
    """The speed ceiling [m/s] at offset u of interval k (limit, or braking curve to the stop)."""
    if u < US[k]:
        return vcap
    Eb = step_energy(0.5 * Cr[k] * Cr[k], w, u - w, BRAKE, line, P, curves, bk)
    return np.sqrt(2.0 * Eb) if Eb > 0.0 else 0.0


@njit(cache=True)
def final_phase(
    x, a0, a1, b0, b1, vcap, tscale, i_start, u_start, v_start, t_start, i_end,
    P, curves, tk, bk, Cr, US, mu, inv_eta_t, eta_r, has_regen, h_max,
    out_s, out_v, out_t, out_m, n, force_mode, v_hold, phi_start, stop_mode, sk, rk,
):  # fmt: skip
    """``final_phase_regen`` without the regenerative holding arc: (n, status, position)."""
    n, status, s_event, _, _ = final_phase_regen(
        x, a0, a1, b0, b1, vcap, tscale, i_start, u_start, v_start, t_start, i_end,
        P, curves, tk, bk, Cr, US, mu, inv_eta_t, eta_r, has_regen, h_max,
        out_s, out_v, out_t, out_m, n, force_mode, v_hold, phi_start, stop_mode, sk, rk, -1.0, np.inf,
    )  # fmt: skip
    return n, status, s_event


#: The adjoint entering the regenerative holding arc reaches eta_r at the holding speed W (its
#: minimum on a descent is there); it is taken to enter it when it reaches eta_r no more than this
#: fraction below W [-] (the coasting point's search then lands on that edge: the adjoint's minimum
#: is then within ~1e-6 of eta_r).
W_ENTRY_FRACTION = 1e-3


@njit(cache=True)
def final_phase_regen(
    x, a0, a1, b0, b1, vcap, tscale, i_start, u_start, v_start, t_start, i_end,
    P, curves, tk, bk, Cr, US, mu, inv_eta_t, eta_r, has_regen, h_max,
    out_s, out_v, out_t, out_m, n, force_mode, v_hold, phi_start, stop_mode, sk, rk, W, w_end,
):  # fmt: skip
    """``final_phase_modes`` with the braking curves ``Cr``/``US`` all of ``stop_mode`` (BRAKE:
    service braking; REGEN: regenerative braking only); ``sk``, their kinks, is ``bk`` or ``rk``."""
    curve_modes = np.full(len(Cr), stop_mode, dtype=np.int64)
    return final_phase_modes(
        x, a0, a1, b0, b1, vcap, tscale, i_start, u_start, v_start, t_start, i_end,
        P, curves, tk, bk, Cr, US, mu, inv_eta_t, eta_r, has_regen, h_max,
        out_s, out_v, out_t, out_m, n, force_mode, v_hold, phi_start, curve_modes, rk, W, w_end,
    )  # fmt: skip


@njit(cache=True)
def final_phase_modes(
    x, a0, a1, b0, b1, vcap, tscale, i_start, u_start, v_start, t_start, i_end,
    P, curves, tk, bk, Cr, US, mu, inv_eta_t, eta_r, has_regen, h_max,
    out_s, out_v, out_t, out_m, n, force_mode, v_hold, phi_start, curve_modes, rk, W, w_end,
):  # fmt: skip
    """From (x[i_start] + u_start, v_start), leaving the holding arc (phi just below 1/eta_t), drive
    by the adjoint to the stop at x[i_end], holding the speed limit ``vcap`` if the train reaches
    it. Appends points; returns (n, status): HIT_CEILING when the train meets the braking curve
    to the stop (it then follows it and stops exactly at x[i_end]), STOPPED_SHORT when it comes
    to rest before (the last point is where it stopped); and the position of that event.
    ``force_mode`` >= 0 replaces the adjoint's choice by a fixed regime (source 004's braking).
    The adjoint starts at ``phi_start``, by default (< 0) just below 1/eta_t: leaving a holding
    arc; leaving an arc held by braking on a descent it starts just below eta_r (or 0).
    ``Cr``/``US`` are the braking curves, those of interval k (indexed as ``Cr``) of the braking
    mode ``curve_modes[k]`` (BRAKE: service braking, kinks ``bk``; REGEN: regenerative braking
    only, kinks ``rk``); the run follows them where it meets them. A train with regeneration
    brakes to lower limits with its electric brake alone: along such an arc the adjoint lies in
    (0, eta_r], where friction braking (phi <= 0) is not optimal; the service brake's blend spends
    the difference in the friction brake (CN_Songjiazhuang_Yizhuang 3906-6272 m, KISS at +5 %:
    0.9 kWh).
    ``rk`` are the kinks of the regenerative curve (its steps integrated exactly, as the energy
    accounting does: across a kink the run would otherwise move with the step).
    With a regenerative holding speed ``W`` > 0 (mu = eta_r W^2 R'(W)), where the adjoint comes down
    to eta_r at W on a descent that needs braking to hold W, the run holds W with regenerative
    braking (the singular arc, phi = eta_r; as ``coast_excursion``) until ``w_end`` [m] or the
    descent's end, whichever comes first, then coasts on from phi just above eta_r. Returns
    (n, status, position, arc_start, arc_end): the arc's ends [m] (-1 if the run has none)."""
    phi = inv_eta_t * (1.0 - 1e-9) if phi_start < 0.0 else phi_start
    on_w = False
    arc_start = -1.0
    arc_end = -1.0
    just_cut = False
    E = 0.5 * v_start * v_start
    t = t_start
    u = u_start
    i = i_start
    while i < i_end:
        kk = i - (i_end - len(Cr))  # Cr and US are indexed from the section's first interval
        w = x[i + 1] - x[i]
        line = (a0[i], a1[i], b0[i], b1[i])
        P[P_TRACTION_SCALE] = tscale[i]
        jumped = False
        while u < w - 1e-12:
            if n >= len(out_s) - 8:
                # never write past the buffers: report the attempt as failed (stopped short)
                return n, STOPPED_SHORT, x[i] + u, arc_start, arc_end
            v = np.sqrt(2.0 * E) if E > 0.0 else 0.0
            if on_w and (x[i] + u >= w_end - 1e-9 or resistance_force(W, u + 2e-9, line, P) >= 0.0):
                # the arc ends (where asked, or where holding W stops needing braking): the adjoint
                # leaves eta_r upwards and the train coasts (below W it falls back to eta_r at once)
                on_w = False
                arc_end = x[i] + u
                phi = eta_r * (1.0 + 1e-9)
            if on_w:
                n, u, E, t, done, status = _regen_arc_step(
                    x, a0, a1, b0, b1, i, u, E, t, i_end, W, w_end, h_max, w, line, P, curves, bk, rk,
                    Cr, US, kk, curve_modes, out_s, out_v, out_t, out_m, n,
                )  # fmt: skip
                if done:
                    return n, status, u, arc_start, arc_end
                just_cut = False
                continue
            mode = mode_of(phi, inv_eta_t, eta_r, has_regen) if force_mode < 0 else force_mode
            if mode == TRACTION and v >= v_hold:
                # after a descent the adjoint climbs back to 1/eta_t while v > V; traction there
                # would only be braked away before the stop: the train coasts back down to V
                mode = COAST
                phi = inv_eta_t * (1.0 - 1e-9)
            at_limit = v >= vcap[i] - 1e-9
            if at_limit and (mode == TRACTION or (mode == COAST and resistance_force(v, u, line, P) < 0.0)):
                # the speed limit binds: hold it while the adjoint asks for traction, or while
                # coasting would speed the train up (downhill)
                mode = CRUISE
            h = min(h_max, w - u)
            if US[kk] > u:
                h = min(h, US[kk] - u)  # the braking curve part starts at US
            kinks = tk if mode == TRACTION else (rk if mode == REGEN else bk)
            if mode == CRUISE:
                if resistance_force(v, u, line, P) < 0.0:
                    h = _descent_end(v, u, h, line, P)
                E1, dt = E, h / v
            else:
                E1, dt = step_energy_time(E, u, h, mode, line, P, curves, kinks)
            if E1 <= 0.0:
                # comes to rest inside the step
                hs = distance_to_speed(E, u, 0.0, mode, line, P, curves)
                if not np.isfinite(hs) or hs > h:
                    hs = h
                _, dts = rk4_energy_time(E, u, hs, mode, line, P, curves)
                n = _emit(out_s, out_v, out_t, out_m, n, x[i] + u, v, t, mode)
                n = _emit(out_s, out_v, out_t, out_m, n, x[i] + u + hs, 0.0, t + dts, mode)
                if x[i] + u + hs >= x[i_end] - REST_AT_STOP_M:
                    return n, HIT_CEILING, x[i_end], arc_start, arc_end
                return n, STOPPED_SHORT, x[i] + u + hs, arc_start, arc_end
            v1 = np.sqrt(2.0 * E1)
            if mode != CRUISE and v1 > vcap[i] and v < vcap[i] and u + h <= US[kk]:
                # reaches the limit inside the step: stop the step there
                hc = distance_to_speed(E, u, 0.5 * vcap[i] * vcap[i], mode, line, P, curves)
                if np.isfinite(hc) and 0.0 < hc < h:
                    h = hc
                    E1, dt = step_energy_time(E, u, h, mode, line, P, curves, kinks)
                    v1 = vcap[i]
                    E1 = 0.5 * v1 * v1
            cut = False
            phi1 = phi
            if v > PHI_MIN_SPEED and force_mode < 0:
                # (a fixed regime does not follow the adjoint: its sub-steps would cost for nothing)
                Em = E if mode == CRUISE else step_energy(E, u, 0.5 * h, mode, line, P, curves, kinks)
                phi1 = phi_advance(phi, E, E1, u, h, mode, line, P, curves, kinks, mu, Em)
            if v1 >= v_hold and phi1 > inv_eta_t * (1.0 - 1e-9):
                phi1 = inv_eta_t * (1.0 - 1e-9)
            new_mode = mode_of(phi1, inv_eta_t, eta_r, has_regen)
            base_mode = mode_of(phi, inv_eta_t, eta_r, has_regen)
            if new_mode != base_mode and force_mode < 0:
                # the adjoint crosses a switching threshold inside the step: cut the step there
                lo_phi, hi_phi = min(phi, phi1), max(phi, phi1)
                if lo_phi < inv_eta_t <= hi_phi:
                    thr = inv_eta_t
                elif lo_phi <= eta_r < hi_phi and has_regen:
                    thr = eta_r
                else:
                    thr = 0.0
                frac = (thr - phi) / (phi1 - phi) if phi1 != phi else 1.0
                frac = min(max(frac, 0.0), 1.0)
                # the crossing located exactly (secant on the adjoint integrated over part of the
                # step): linear interpolation put it up to a metre off, moving with the step
                lo_h, hi_h = 0.0, h
                h_try = frac * h
                for _ in range(40):
                    if not 0.0 < h_try < h:
                        break
                    Et = E if mode == CRUISE else step_energy(E, u, h_try, mode, line, P, curves, kinks)
                    Emt = (
                        E if mode == CRUISE else step_energy(E, u, 0.5 * h_try, mode, line, P, curves, kinks)
                    )
                    g = phi_advance(phi, E, Et, u, h_try, mode, line, P, curves, kinks, mu, Emt) - thr
                    if (g > 0.0) == (phi > thr):
                        lo_h = h_try
                    else:
                        hi_h = h_try
                    if hi_h - lo_h < 1e-9:
                        break
                    # the adjoint is nearly linear over a step: a linear step on the bracket
                    h_try = 0.5 * (lo_h + hi_h) if g == 0.0 else h_try - g * h_try / (g + thr - phi)
                    if not lo_h < h_try < hi_h:
                        h_try = 0.5 * (lo_h + hi_h)
                h_exact = hi_h if hi_h < h else frac * h
                # near a singular arc the adjoint sits on a threshold: right after a cut, never cut
                # below MIN_SWITCH_STEP_M (slivers would only multiply points without progress)
                h_cut = max(h_exact, min(MIN_SWITCH_STEP_M, h)) if just_cut else h_exact
                if h_cut < 1e-9:
                    h_cut = min(1e-9, h)
                if h_cut < h:
                    h = h_cut
                    if mode == CRUISE:
                        E1, dt = E, h / v
                    else:
                        E1, dt = step_energy_time(E, u, h, mode, line, P, curves, kinks)
                    v1 = np.sqrt(2.0 * E1) if E1 > 0.0 else 0.0
                    phi1 = thr - 1e-12 if phi1 < phi else thr + 1e-12
                    cut = True
            # the braking curve to the stop (and to lower limits) must not be crossed
            cm = curve_modes[kk]
            ck = rk if cm == REGEN else bk
            if mode != cm and u + h > US[kk]:
                c1 = _curve_speed(u + h, w, Cr[kk], cm, line, P, curves, ck)
                if v1 > c1 + 1e-9:
                    hm = _meet_curve(E, u, u + h, mode, w, Cr[kk], cm, line, P, curves, kinks, ck)
                    Em, dtm = step_energy_time(E, u, hm - u, mode, line, P, curves, kinks)
                    n = _emit(out_s, out_v, out_t, out_m, n, x[i] + u, v, t, mode)
                    n, j, uj, tj, found = _brake_to_plateau(
                        x, a0, a1, b0, b1, i, hm, Em, t + dtm, i_end, P, curves, bk, rk, Cr, US, kk,
                        out_s, out_v, out_t, out_m, n, curve_modes,
                    )  # fmt: skip
                    if not found:
                        return n, HIT_CEILING, x[i] + hm, arc_start, arc_end
                    # down to a lower limit: the adjoint drives the run on from there
                    i, u, t = j, uj, tj
                    E = 0.5 * vcap[j] * vcap[j]
                    jumped = True
                    break
            if (
                W > 0.0 and force_mode < 0 and arc_start < 0.0 and phi > eta_r >= phi1 and has_regen
                and vcap[i] > W and v1 >= W * (1.0 - W_ENTRY_FRACTION)
                and resistance_force(W, u + h, line, P) < 0.0
            ):  # fmt: skip
                # the adjoint comes down to eta_r at W on a descent: the regenerative holding arc
                # (below W by at most W_ENTRY_FRACTION the train coasts up to W first)
                on_w = True
                arc_start = x[i] + u + h
                phi1 = eta_r
            n = _emit(out_s, out_v, out_t, out_m, n, x[i] + u, v, t, mode)
            E, t, u, phi = E1, t + dt, u + h, phi1
            just_cut = cut
        if not jumped:
            u = 0.0
            i += 1
    v_end = np.sqrt(2.0 * E) if E > 0.0 else 0.0
    n = _emit(out_s, out_v, out_t, out_m, n, x[i_end], v_end, t, curve_modes[len(Cr) - 1])
    return n, HIT_CEILING, x[i_end], arc_start, arc_end


@njit(cache=True)
def _regen_arc_step(
    x, a0, a1, b0, b1, i, u, E, t, i_end, W, w_end, h_max, w, line, P, curves, bk, rk, Cr, US, kk,
    curve_modes, out_s, out_v, out_t, out_m, n,
):  # fmt: skip
    """One step of the regenerative holding arc at W from offset u of interval i: coasting up to W,
    then holding it with braking, never past ``w_end`` nor where the hold stops needing braking
    (``_capped_coast_step``). Meeting the braking curve to the stop (or a lower limit) the run brakes
    along it to the stop: (n, u, E, t, done, status), with done True u is the position [m] where it
    met the curve (status STOPPED_SHORT, an unusable attempt, if the curve led to a lower limit)."""
    h = min(h_max, w - u, w_end - x[i] - u)
    if US[kk] > u:
        h = min(h, US[kk] - u)
    h = max(h, 1e-9)
    v = np.sqrt(2.0 * E) if E > 0.0 else 0.0
    mode, h, E1, dt = _capped_coast_step(E, v, u, h, W, line, P, curves, bk)
    cm = curve_modes[kk]
    ck = rk if cm == REGEN else bk
    if u + h > US[kk]:
        v1 = np.sqrt(2.0 * E1) if E1 > 0.0 else 0.0
        if v1 > _curve_speed(u + h, w, Cr[kk], cm, line, P, curves, ck) + 1e-9:
            if mode == CRUISE:
                hm = _held_speed_meets_curve(v, u, u + h, w, Cr[kk], cm, line, P, curves, ck, 1e-10)
                Em, dtm = E, (hm - u) / v
            else:
                hm = _meet_curve(E, u, u + h, COAST, w, Cr[kk], cm, line, P, curves, bk, ck)
                Em, dtm = step_energy_time(E, u, hm - u, COAST, line, P, curves, bk)
            n = _emit(out_s, out_v, out_t, out_m, n, x[i] + u, v, t, mode)
            n, _, _, _, found = _brake_to_plateau(
                x, a0, a1, b0, b1, i, hm, Em, t + dtm, i_end, P, curves, bk, rk, Cr, US, kk,
                out_s, out_v, out_t, out_m, n, curve_modes,
            )  # fmt: skip
            # (a lower limit below W on the descent: the arc never reaches it, its curve is the stop's)
            return n, x[i] + hm, Em, t + dtm, True, HIT_CEILING if not found else STOPPED_SHORT
    n = _emit(out_s, out_v, out_t, out_m, n, x[i] + u, v, t, mode)
    return n, u + h, E1, t + dt, False, 0


@njit(cache=True)
def _brake_to_plateau(
    x, a0, a1, b0, b1, i, u, E, t, i_end, P, curves, bk, rk, Cr, US, kk, out_s, out_v, out_t, out_m, n,
    curve_modes,
):  # fmt: skip
    """Maximum braking along the speed ceiling from (x[i] + u), in each interval k (indexed as
    ``Cr``) in the mode of its curve ``curve_modes[k]`` (service or regenerative), until it reaches
    the plateau of a lower limit. Returns (n, j, u_j, t_j, found): the plateau's start at offset
    u_j of interval j, or (found False) the stop at x[i_end], where the run then ends."""
    k = kk
    mode = curve_modes[k]
    for j in range(i, i_end):
        w = x[j + 1] - x[j]
        line = (a0[j], a1[j], b0[j], b1[j])
        if j > i and u < US[k] - 1e-9:  # (in the first interval the run is on the curve already)
            return n, j, u, t, True
        mode = curve_modes[k]
        if u < w:
            n = _emit(out_s, out_v, out_t, out_m, n, x[j] + u, np.sqrt(2.0 * E) if E > 0.0 else 0.0, t, mode)
            _, dt = step_energy_time(E, u, w - u, mode, line, P, curves, rk if mode == REGEN else bk)
            t += dt
        E = 0.5 * Cr[k] * Cr[k]
        u = 0.0
        k += 1
    n = _emit(out_s, out_v, out_t, out_m, n, x[i_end], 0.0, t, mode)
    return n, i_end, 0.0, t, False


#: Shortest piece a step is cut into at an adjoint switching threshold [m]: near a singular arc the
#: adjoint sits on a threshold and finer cuts would only multiply points.
MIN_SWITCH_STEP_M = 0.5


@njit(cache=True)
def _emit(out_s, out_v, out_t, out_m, n, s, v, t, m):
    if n >= len(out_s):
        return n  # full: the caller sees n == len(out_s) and discards the attempt
    out_s[n] = s
    out_v[n] = v
    out_t[n] = t
    out_m[n] = m
    return n + 1


@njit(cache=True)
def _curve_speed(u, w, Crk, brake_mode, line, P, curves, bk):
    """Speed [m/s] at offset u of the braking curve of ``brake_mode`` ending at (w, Crk)."""
    Eb = step_energy(0.5 * Crk * Crk, w, u - w, brake_mode, line, P, curves, bk)
    return np.sqrt(2.0 * Eb) if Eb > 0.0 else 0.0


@njit(cache=True)
def _held_speed_meets_curve(v, lo, hi, w, Crk, brake_mode, line, P, curves, bk, tol_m):
    """Offset in (lo, hi] where a speed v [m/s] held from offset lo meets the braking curve of
    ``brake_mode`` ending at (w, Crk), to ``tol_m`` [m]: the curve falls monotonically towards its
    end, so bisection on v >= curve speed (below it at lo, above it at hi)."""
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if v >= _curve_speed(mid, w, Crk, brake_mode, line, P, curves, bk):
            hi = mid
        else:
            lo = mid
        if hi - lo < tol_m:
            break
    return hi


@njit(cache=True)
def _brake_curve_speed(u, w, Crk, line, P, curves, bk):
    return _curve_speed(u, w, Crk, BRAKE, line, P, curves, bk)


@njit(cache=True)
def _meet_brake_curve(E, u, end, mode, w, Crk, line, P, curves, kinks, bk):
    return _meet_curve(E, u, end, mode, w, Crk, BRAKE, line, P, curves, kinks, bk)


@njit(cache=True)
def _meet_curve(E, u, end, mode, w, Crk, brake_mode, line, P, curves, kinks, bk):
    """Offset in (u, end] where the trajectory of ``mode`` from (u, E) meets the braking curve of
    ``brake_mode`` that ends at (w, Crk) (bisection; below it at u, above it at end)."""
    lo, hi = u, end
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        Em, _ = step_energy_time(E, u, mid - u, mode, line, P, curves, kinks)
        vm = np.sqrt(2.0 * Em) if Em > 0.0 else 0.0
        if vm >= _curve_speed(mid, w, Crk, brake_mode, line, P, curves, bk):
            hi = mid
        else:
            lo = mid
        if hi - lo < 1e-7:
            break
    return hi


#: The force a hold needs is read this far [m] ahead of the point where the regime is chosen: past the
#: rounding of a bound it was located on (1e-16 of a force of order 1e5 N), far below any stretch of
#: running that moves energy or time by 1e-9.
NEED_LOOKAHEAD_M = 1e-7


@njit(cache=True)
def need_ahead(need_u, need_e, span):
    """The force [N] needed to hold the speed NEED_LOOKAHEAD_M ahead of offset u, from its values at u
    (``need_u``) and ``span`` [m] further (``need_e``): linear along an interval (the grade and the
    tunnel factor are), so this is exact."""
    if span <= NEED_LOOKAHEAD_M:
        return need_e
    return need_u + (need_e - need_u) * (NEED_LOOKAHEAD_M / span)


@njit(cache=True)
def holding_segment(
    x, a0, a1, b0, b1, vhold, vtop, tscale, i0, i1, P, curves, tk, bk, rk, Cr, US, brake_modes,
    out_s, out_v, out_t, out_m, i_s=-1, u_s=0.0, v_s=0.0, t_s=0.0,
):  # fmt: skip
    """The holding phases of the optimal strategy from standstill at x[i0] to the stop at x[i1].

    Maximum traction up to the holding speed ``vhold`` (V, or the limit where lower); hold it with
    partial traction; where holding would need more than maximum traction (steep uphill) keep
    maximum traction; where it would need braking (steep downhill) coast instead and let the speed
    rise, up to ``vtop`` (the limit, or the regenerative holding speed W), where the train holds
    with braking; after such a descent coast back down to ``vhold``; follow the braking curves
    (``Cr``/``US``, computed for ``vtop`` with ``brake_modes[i]`` per interval) to lower limits
    and to the stop. Returns (n, status).
    With ``i_s`` >= 0 it starts from speed ``v_s`` at offset ``u_s`` of interval ``i_s``, time ``t_s``."""
    n = 0
    E = 0.5 * v_s * v_s if i_s >= 0 else 0.0
    t = t_s if i_s >= 0 else 0.0
    tol = 1e-7
    k_start = i_s - i0 if i_s >= 0 else 0
    for k in range(k_start, i1 - i0):
        i = i0 + k
        w = x[i + 1] - x[i]
        line = (a0[i], a1[i], b0[i], b1[i])
        P[P_TRACTION_SCALE] = tscale[i]
        vh, vt = vhold[i], vtop[i]
        brake_mode = brake_modes[i]
        bkk = bk if brake_mode == BRAKE else rk
        u = u_s if (i_s >= 0 and k == k_start) else 0.0
        for _guard in range(10000):
            if u >= w - 1e-12:
                break
            v = np.sqrt(2.0 * E) if E > 0.0 else 0.0
            in_curve = u >= US[k]
            end = w if in_curve else US[k]
            if in_curve and v >= _curve_speed(u, w, Cr[k], brake_mode, line, P, curves, bkk) - 1e-6:
                # on the braking curve: brake along it to the interval's end
                n = _emit(out_s, out_v, out_t, out_m, n, x[i] + u, v, t, brake_mode)
                _, dt = step_energy_time(E, u, w - u, brake_mode, line, P, curves, bkk)
                t += dt
                E = 0.5 * Cr[k] * Cr[k]
                u = w
                break
            need_u = resistance_force(v, u, line, P)
            need_e = resistance_force(v, end, line, P)
            # the regime is chosen by the force needed just ahead of u, not at u: where a hold ended
            # at u because that force crossed a bound (0 at a descent's end), it sits on the bound
            # to rounding and its sign at u said nothing; the train then coasted (or ran traction
            # clamped) to the next grid point, a switch that moved with the step (heavy_haul: 1.7e-6
            # of net energy on halving it)
            need_a = need_ahead(need_u, need_e, end - u)
            fmax = P[P_TRACTION_SCALE] * effort(v, curves[0], curves[1], curves[2], curves[3])
            at_hold = abs(v - vh) <= tol * max(1.0, vh)
            at_top = v >= vt - tol * max(1.0, vt)
            hold_lo, hold_hi = 1.0, -1.0  # empty: no holding
            if at_top and need_a <= 0.0:
                hold_lo, hold_hi = -np.inf, 0.0  # hold the top speed with braking
            elif at_hold and 0.0 <= need_a <= fmax:
                hold_lo, hold_hi = 0.0, fmax  # hold the holding speed with partial traction
            if hold_lo <= hold_hi:
                stop_at = end
                if need_e > hold_hi:
                    stop_at = u + (end - u) * (hold_hi - need_u) / (need_e - need_u)
                elif need_e < hold_lo:
                    stop_at = u + (end - u) * (hold_lo - need_u) / (need_e - need_u)
                if stop_at > u + 1e-9:
                    n = _emit(out_s, out_v, out_t, out_m, n, x[i] + u, v, t, CRUISE)
                    t += (stop_at - u) / v
                    u = stop_at
                    E = 0.5 * v * v
                    continue
            if v < vh - tol * max(1.0, vh) or (at_hold and need_a > 0.0):
                mode = TRACTION
                kinks = tk
                target = vh
            else:
                mode = COAST
                kinks = bk
                target = vh if (v > vh and need_a > 0.0) else vt
            E1, dt = step_energy_time(E, u, end - u, mode, line, P, curves, kinks)
            v1 = np.sqrt(2.0 * E1) if E1 > 0.0 else 0.0
            h = end - u
            # events: reaching the target speed, meeting the braking curve, coming to rest
            if (v < target and v1 > target) or (v > target and v1 < target):
                hc = distance_to_speed(E, u, 0.5 * target * target, mode, line, P, curves)
                if np.isfinite(hc) and 0.0 < hc < h:
                    h = hc
                    E1, dt = step_energy_time(E, u, h, mode, line, P, curves, kinks)
                    E1 = 0.5 * target * target
                    v1 = target
            if in_curve:
                vb = _curve_speed(u + h, w, Cr[k], brake_mode, line, P, curves, bkk)
                if v1 > vb + 1e-9:
                    hm = _meet_curve(E, u, u + h, mode, w, Cr[k], brake_mode, line, P, curves, kinks, bkk) - u
                    h = hm
                    E1, dt = step_energy_time(E, u, h, mode, line, P, curves, kinks)
            if E1 <= 0.0:
                return n, 1
            if v1 > vt + 1e-6 and not in_curve:
                E1 = 0.5 * vt * vt
            n = _emit(out_s, out_v, out_t, out_m, n, x[i] + u, v, t, mode)
            t += dt
            u += h
            E = E1
    n = _emit(out_s, out_v, out_t, out_m, n, x[i1], 0.0, t, 4)
    return n, 0


@njit(cache=True)
def _descent_end(v, u, h, line, P):
    """The step [m] from offset u, at most h, up to where holding speed v stops needing braking:
    the grade varies linearly along an interval, so the resistance at constant speed crosses zero
    at one point (a hold ended at the step's end instead moved with the step)."""
    r0 = resistance_force(v, u, line, P)
    r1 = resistance_force(v, u + h, line, P)
    if r0 < 0.0 <= r1:
        hc = h * (-r0) / (r1 - r0)
        if 1e-9 < hc < h:
            return hc
    return h


@njit(cache=True)
def _capped_coast_step(E, v, u, h, cap, line, P, curves, bk):
    """(mode, step, E, time) of a coasting step of at most h [m] from offset u that never exceeds the
    speed ``cap`` [m/s]: at the cap on a descent the train holds it with braking (CRUISE); reaching
    the cap the step ends there."""
    if v >= cap - 1e-9 and resistance_force(v, u, line, P) < 0.0:
        h = _descent_end(v, u, h, line, P)
        return CRUISE, h, E, h / v
    E1, dt = step_energy_time(E, u, h, COAST, line, P, curves, bk)
    E_cap = 0.5 * cap * cap
    if E_cap < E1:
        hc = distance_to_speed(E, u, E_cap, COAST, line, P, curves)
        if np.isfinite(hc) and 0.0 < hc < h:
            h = hc
            E1, dt = step_energy_time(E, u, h, COAST, line, P, curves, bk)
        E1 = min(E1, E_cap)
    return COAST, h, E1, dt


@njit(cache=True)
def held_adjoint(v, u, line, P, curves, inv_eta_t, eta_r):
    """The adjoint phi at which coasting and holding speed v [m/s] at offset u have the same
    Hamiltonian (the switching condition between them): with net resistance R at v, holding costs
    R / eta_t per metre where R > 0 (traction) and -eta_r min(-R, F_regen) where R < 0 (braking,
    the electric brake returning what it can), coasting phi R; hence phi = 1/eta_t, or
    eta_r min(-R, F_regen) / (-R) (Albrecht et al. 2016, Part 2: the value of the adjoint on an arc
    held by partial traction or by braking)."""
    res = resistance_force(v, u, line, P)
    if res >= 0.0:
        return inv_eta_t
    if eta_r <= 0.0:
        return 0.0
    regen = effort(v, curves[8], curves[9], curves[10], curves[11])
    return eta_r * min(-res, regen) / (-res)


@njit(cache=True)
def coast_excursion(
    x, a0, a1, b0, b1, vlim, W, tscale, i, u, v0, t, i_end, P, curves, bk, V, v_rejoin, mu, inv_eta_t, eta_r,
    h_max, out_s, out_v, out_t, out_m, Cr, US,
):  # fmt: skip
    """Leave the holding arc (or the traction arc below V) into coasting, ahead of a descent too
    steep to hold V on.

    Coasts and integrates the adjoint from phi = 1/eta_t until the speed comes back down to V
    after having been above it: the rejoin point q. Leaving a speed limit ``v_rejoin`` below V, the
    train rejoins where coasting brings it back up to that limit. The train holds the speed limit ``vlim`` with
    braking where coasting would exceed it, and the regenerative holding speed W once the adjoint
    has fallen to eta_r (the singular regenerative arc; above eta_r the optimal control coasts).
    The coast must stay below the service braking curves (``Cr``, ``US``, as ``ceiling_at``) to
    lower limits and the stop: an excursion that would cross one fails (status 2), it is not taken.
    Returns (n, status, residual, i_q, u_q, t_q, energy_j): status 0 rejoined, 1 came to
    rest or reached the end without rejoining, 2 crossed a braking curve; energy_j is the electrical energy of the path
    (regenerated while holding with braking, so <= 0).

    ``residual`` is the departure's switching condition, zero where the departure point is optimal
    (d(energy + mu x time)/dp = 0; Howlett, Pudney & Vu 2009, "Local energy minimization in optimal
    train control", Automatica 45; Albrecht et al. 2016, Part 2, speed limits on steep descents):
    leaving traction or holding means phi = 1/eta_t at p, and the adjoint integrated from there
    along the coast must arrive where the coast first reaches a speed held with braking (the limit,
    or W) at phi_r = eta_r min(-R, F_regen) / (-R), the marginal value of kinetic energy there
    (entering that arc dr earlier regenerates eta_r min(-R, F_regen) dr, and dr = M v dv / (-R)
    for a coast with net resistance R < 0): residual = phi(r) - phi_r. Without such an arc the
    coast rejoins the arc it rejoins (V, or the lower limit it left) with the value that arc
    needs (``held_adjoint``): residual = phi(q) - phi_q. NaN where the adjoint was not followed."""
    phi = inv_eta_t
    E = 0.5 * v0 * v0
    EV = 0.5 * V * V
    on_limit = v_rejoin < V * (1.0 - 1e-9)
    ER = 0.5 * v_rejoin * v_rejoin
    below = False
    above = False
    energy = 0.0
    entry = np.nan  # the residual where the coast first enters an arc held with braking
    n = 0
    for ii in range(i, i_end):
        w = x[ii + 1] - x[ii]
        line = (a0[ii], a1[ii], b0[ii], b1[ii])
        P[P_TRACTION_SCALE] = tscale[ii]
        uu = u if ii == i else 0.0
        while uu < w - 1e-12:
            v = np.sqrt(2.0 * E) if E > 0.0 else 0.0
            h = min(h_max, w - uu)
            cap = vlim[ii]
            if eta_r > 0.0 and phi <= eta_r * (1.0 + 1e-9) and cap > W:
                cap = W
            mode, h, E1, dt = _capped_coast_step(E, v, uu, h, cap, line, P, curves, bk)
            if E1 <= 0.0:
                return n, 1, -np.inf, ii, uu, t, energy
            v_ceiling = ceiling_at(uu + h, w, ii, Cr, US, vlim[ii], line, P, curves, bk)
            e_ceiling = 0.5 * v_ceiling * v_ceiling * (1.0 + 1e-6) + 1e-6
            if e_ceiling < E1:  # the coast crosses a braking curve
                return n, 2, -np.inf, ii, uu, t, energy
            if on_limit and below and E1 >= ER * (1.0 - 1e-12):
                # back up to the limit: the rejoin point, where the limit is held again
                hq = h
                if E1 > ER * (1.0 + 1e-12):
                    hq = distance_to_speed(E, uu, ER, COAST, line, P, curves)
                    if not np.isfinite(hq) or hq > h:
                        hq = h
                _, dtq = rk4_energy_time(E, uu, hq, COAST, line, P, curves)
                n = _emit(out_s, out_v, out_t, out_m, n, x[ii] + uu, v, t, mode)
                if np.isnan(entry) and v > PHI_MIN_SPEED:
                    Emq = step_energy(E, uu, 0.5 * hq, COAST, line, P, curves, bk)
                    phiq = phi_step(phi, E, ER, uu, hq, b0[ii], b1[ii], P, mu, Emq)
                    entry = phiq - held_adjoint(v_rejoin, uu + hq, line, P, curves, inv_eta_t, eta_r)
                return n, 0, entry, ii, uu + hq, t + dtq, energy
            if on_limit and E1 < ER * (1.0 - 1e-9):
                below = True
            if not on_limit and above and E1 < EV <= E:
                # back down to V inside this step: the rejoin point
                hq = distance_to_speed(E, uu, EV, COAST, line, P, curves)
                if not np.isfinite(hq) or hq > h:
                    hq = h
                _, dtq = rk4_energy_time(E, uu, hq, COAST, line, P, curves)
                Emq = step_energy(E, uu, 0.5 * hq, COAST, line, P, curves, bk)
                phiq = phi_step(phi, E, EV, uu, hq, b0[ii], b1[ii], P, mu, Emq)
                n = _emit(out_s, out_v, out_t, out_m, n, x[ii] + uu, v, t, mode)
                if np.isnan(entry):
                    entry = phiq - held_adjoint(V, uu + hq, line, P, curves, inv_eta_t, eta_r)
                return n, 0, entry, ii, uu + hq, t + dtq, energy
            if mode == CRUISE:
                if np.isnan(entry):
                    entry = phi - held_adjoint(v, uu, line, P, curves, inv_eta_t, eta_r)
                energy -= eta_r * _cruise_regen_work(v, uu, h, line, P, curves)
            if v > PHI_MIN_SPEED:
                # the midpoint's energy integrated (a linear one was O(h^2) and moved the departure
                # points that the adjoint locates, ``residual``, by millimetres with the step)
                Em = step_energy(E, uu, 0.5 * h, COAST, line, P, curves, bk) if mode == COAST else E
                phi = phi_step(phi, E, E1, uu, h, b0[ii], b1[ii], P, mu, Em)
            if mode == CRUISE and cap == W:
                phi = eta_r  # on the singular regenerative arc the adjoint stays at eta_r
            if E1 > EV * (1.0 + 1e-12):
                above = True
            n = _emit(out_s, out_v, out_t, out_m, n, x[ii] + uu, v, t, mode)
            E, t, uu = E1, t + dt, uu + h
    return n, 1, -np.inf, i_end - 1, x[i_end] - x[i_end - 1], t, energy


@njit(cache=True)
def point_forces(mode, v, u, line, P, curves):
    """(traction, regenerative braking) force [N] at speed v in a regime, as the run's energy
    accounting (``trainsim.sim.result``) counts them: holding takes what resistance needs, braking
    returns what the electric brake can take of it."""
    res = resistance_force(v, u, line, P)
    regen_cap = effort(v, curves[8], curves[9], curves[10], curves[11])
    if mode == TRACTION:
        return P[P_TRACTION_SCALE] * effort(v, curves[0], curves[1], curves[2], curves[3]), 0.0
    if mode == CRUISE:
        if res >= 0.0:
            return res, 0.0
        return 0.0, min(-res, regen_cap)
    if mode == BRAKE:
        if P[P_DECEL] > 0.0:
            f = P[P_INERTIAL_MASS] * P[P_DECEL] - res
            f = f if f > 0.0 else 0.0
        else:
            f = P[P_BRAKE_FRACTION] * effort(v, curves[4], curves[5], curves[6], curves[7])
        return 0.0, min(f, regen_cap)
    if mode == REGEN:
        return 0.0, regen_cap
    return 0.0, 0.0


@njit(cache=True)
def _cruise_regen_work(v, u, h, line, P, curves):
    """Regenerative braking work [J] of holding speed v from offset u over h [m]: Simpson's rule on
    the braking force (the grade varies along an interval; a step's first force alone was O(h))."""
    _, f0 = point_forces(CRUISE, v, u, line, P, curves)
    _, fm = point_forces(CRUISE, v, u + 0.5 * h, line, P, curves)
    _, f1 = point_forces(CRUISE, v, u + h, line, P, curves)
    return h / 6.0 * (f0 + 4.0 * fm + f1)


@njit(cache=True)
def path_energy(s, v, m, x, a0, a1, b0, b1, tscale, P, curves, inv_eta_t, eta_r, out, tk, bk, rk):
    """Cumulative electrical energy [J] (traction / eta_t - eta_r regenerated) along a run's
    points into ``out``: Simpson's rule on each stretch's forces in the regime of its first point,
    the midpoint speed integrated in that regime. (Trapezoids, O(h^2), made the departure points
    chosen with these costs move by metres with the step.)"""
    out[0] = 0.0
    i = 0
    for k in range(len(s) - 1):
        while i < len(x) - 2 and x[i + 1] <= s[k] + 1e-9:
            i += 1
        ds = s[k + 1] - s[k]
        if ds <= 0.0:
            out[k + 1] = out[k]
            continue
        line = (a0[i], a1[i], b0[i], b1[i])
        P[P_TRACTION_SCALE] = tscale[i]
        u0 = s[k] - x[i]
        mode = m[k]
        ft0, fr0 = point_forces(mode, v[k], u0, line, P, curves)
        ft1, fr1 = point_forces(mode, v[k + 1], u0 + ds, line, P, curves)
        vm = 0.5 * (v[k] + v[k + 1])
        if mode in (TRACTION, REGEN, BRAKE):
            kinks = tk if mode == TRACTION else (rk if mode == REGEN else bk)
            Em = step_energy(0.5 * v[k] * v[k], u0, 0.5 * ds, mode, line, P, curves, kinks)
            vm = np.sqrt(2.0 * Em) if Em > 0.0 else 0.0
        ftm, frm = point_forces(mode, vm, u0 + 0.5 * ds, line, P, curves)
        out[k + 1] = out[k] + ds / 6.0 * (
            (ft0 + 4.0 * ftm + ft1) * inv_eta_t - eta_r * (fr0 + 4.0 * frm + fr1)
        )


@njit(cache=True)
def coast_to_curve(
    x, a0, a1, b0, b1, vtop, tscale, i, u, v0, t, i_last, i0, P, curves, bk, rk, Cr, US, brake_modes,
    h_max, eta_r, out_s, out_v, out_t, out_m,
):  # fmt: skip
    """Coast from (x[i] + u, v0) until the trajectory meets the braking curve (``Cr``/``US``, in
    ``brake_modes``, indexed from interval ``i0``) that leads down to a lower limit; hold ``vtop``
    with braking where coasting downhill would exceed it. Returns (n, status, i_r, u_r, v_r, t_r,
    energy_j): status 0 met the curve at (i_r, u_r) before the end of interval ``i_last``; 1 came
    to rest or did not meet it (the coasting started too early). energy_j is the electrical energy
    of the coasting path (regenerated where holding vtop needs braking, so <= 0)."""
    E = 0.5 * v0 * v0
    energy = 0.0
    n = 0
    for ii in range(i, i_last + 1):
        k = ii - i0
        w = x[ii + 1] - x[ii]
        line = (a0[ii], a1[ii], b0[ii], b1[ii])
        P[P_TRACTION_SCALE] = tscale[ii]
        mode_b = brake_modes[ii]
        bkk = bk if mode_b == BRAKE else rk
        uu = u if ii == i else 0.0
        while uu < w - 1e-12:
            v = np.sqrt(2.0 * E) if E > 0.0 else 0.0
            h = min(h_max, w - uu)
            if US[k] > uu:
                h = min(h, US[k] - uu)
            mode, h, E1, dt = _capped_coast_step(E, v, uu, h, vtop[ii], line, P, curves, bk)
            if E1 <= 0.0:
                return n, 1, ii, uu, 0.0, t, energy
            if uu + h > US[k]:
                vb = _curve_speed(uu + h, w, Cr[k], mode_b, line, P, curves, bkk)
                v1 = np.sqrt(2.0 * E1)
                if v1 >= vb - 1e-9:
                    if mode == CRUISE:
                        hm = _held_speed_meets_curve(
                            v, uu, uu + h, w, Cr[k], mode_b, line, P, curves, bkk, 1e-7
                        )
                        dtm = (hm - uu) / v
                        Em = E
                    else:
                        hm = _meet_curve(E, uu, uu + h, COAST, w, Cr[k], mode_b, line, P, curves, bk, bkk)
                        Em, dtm = step_energy_time(E, uu, hm - uu, COAST, line, P, curves, bk)
                    n = _emit(out_s, out_v, out_t, out_m, n, x[ii] + uu, v, t, mode)
                    if mode == CRUISE:
                        energy -= eta_r * _cruise_regen_work(v, uu, hm - uu, line, P, curves)
                    return n, 0, ii, hm, np.sqrt(2.0 * Em) if Em > 0.0 else 0.0, t + dtm, energy
            if mode == CRUISE:
                energy -= eta_r * _cruise_regen_work(v, uu, h, line, P, curves)
            n = _emit(out_s, out_v, out_t, out_m, n, x[ii] + uu, v, t, mode)
            E, t, uu = E1, t + dt, uu + h
    return n, 1, i_last, x[i_last + 1] - x[i_last], np.sqrt(2.0 * E) if E > 0.0 else 0.0, t, energy


@njit(cache=True)
def state_at(s, v, t, m, x, a0, a1, b0, b1, tscale, i1, P, curves, tk, bk, s_c, rk):
    """(interval, offset [m], speed [m/s], time [s], index of the last point at or before) of the
    run (s, v, t, m) at s_c, integrating its regime from that last point (what the optimal
    strategy's searches ask of a run thousands of times per solve)."""
    j = np.searchsorted(s, s_c, side="right") - 1
    j = min(max(j, 0), len(s) - 2)
    i = min(np.searchsorted(x, s[j], side="right") - 1, i1 - 1)
    u0 = s[j] - x[i]
    h = s_c - s[j]
    mode = m[j]
    P[P_TRACTION_SCALE] = tscale[i]
    if h <= 0.0:
        return i, u0, v[j], t[j], j
    if mode in (CRUISE, DWELL):
        return i, u0 + h, v[j], (t[j] + h / v[j]) if v[j] > 0.0 else t[j], j
    line = (a0[i], a1[i], b0[i], b1[i])
    # (coasting has no kinks: any list works)
    kinks = tk if mode == TRACTION else (rk if mode == REGEN else bk)
    E1, dt = step_energy_time(0.5 * v[j] ** 2, u0, h, mode, line, P, curves, kinks)
    return i, u0 + h, np.sqrt(max(2.0 * E1, 0.0)), t[j] + dt, j
