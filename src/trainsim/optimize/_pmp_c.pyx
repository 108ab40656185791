# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True
"""Compiled (Cython) part of the energy-optimal strategy: the final phase of a section driven by the
adjoint of Pontryagin's principle, the holding phases, coasting excursions and the path energy.

Ported from the optimiser's numba kernel (issue 14; since removed), giving the same bits: every
floating-point operation keeps the numba code's order and association, ``min(a, b)`` is
``b if b < a else a`` and ``max(a, b)`` is ``b if b > a else a`` as numba evaluates them, and the
integrators are those of the compiled fastest-run kernel (``trainsim.sim._kernel_c``), cimported.

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

The ``def`` entry points take and return what the numba functions did (arrays: float64, regimes
int8, mode lists int64); they check shapes and dtypes once, then run in C without the GIL. The
module's state is none: the caller's parameter vector P has P_TRACTION_SCALE written per interval,
as before.

One difference from numba: a float division by zero raised ZeroDivisionError there and gives inf or
nan in C. The only unguarded division that can meet a zero is the secant step locating an adjoint
switching point, ``g * h / (g + thr - phi)`` (zero when the adjoint did not move over the trial
step); it is checked and raises ZeroDivisionError as numba did.
"""

from libc.math cimport INFINITY, NAN, ceil, fabs, isfinite, isnan, sqrt
from libc.stdint cimport int64_t

import numpy as np

from trainsim.sim._forces cimport (
    BRAKE,
    COAST,
    CRUISE,
    DWELL,
    N_PARAMS,
    P_BRAKE_FRACTION,
    P_DECEL,
    P_INERTIAL_MASS,
    P_MASS,
    P_R1,
    P_R2,
    P_TRACTION_SCALE,
    REGEN,
    TRACTION,
    Curves,
    curves_from,
    effort,
)
from trainsim._cbuffers cimport Arr, Kinks, _array, pmax as max2, pmin as min2, search_right
from trainsim.sim._kernel_c cimport (
    ET,
    Ctx,
    Line,
    Track,
    _kinks,
    _line,
    acceleration,
    distance_to_speed,
    line_of,
    resistance_force as line_resistance,
    rk4_energy_time,
    step_energy_c,
    step_energy_time_c,
)

# outcomes and settings of the final phase (their meaning is in the docstrings of the functions that
# use them)
HIT_CEILING = 1
STOPPED_SHORT = 2
#: Below this speed [m/s] the adjoint is not integrated further (mu / v^2 is singular at rest and
#: the control is maximum braking there anyway).
PHI_MIN_SPEED = 0.05
#: A final phase that comes to rest no farther than this before the stop arrives there (HIT_CEILING)
#: [m]: the run's outcome jumps where its shortfall crosses this, which the coasting point's search
#: aims at (``optimal.SectionSolver.plan``).
REST_AT_STOP_M = 1e-6
#: Longest RK4 step of the adjoint as a share of the motion's length scale 2E / |a| = v^2 / |a| [-]
#: (``PHI_MAX_SUBSTEPS`` sub-steps per step at most). The adjoint's slope carries mu / v^3, whose
#: relative rate of change along the track is 3 |a| / v^2: braking to the stop below 4 m/s it changes
#: by a factor of 3 to 4 over a 20 m step, and one RK4 step put the adjoint's zero millimetres off,
#: moving with the step (issue 13). At cruising speeds one step is one sub-step.
PHI_LENGTH_SCALE_FRACTION = 0.02
PHI_MAX_SUBSTEPS = 256
#: The adjoint entering the regenerative holding arc reaches eta_r at the holding speed W; it is
#: taken to enter it when it reaches eta_r no more than this fraction below W [-].
W_ENTRY_FRACTION = 1e-3
#: Shortest piece a step is cut into at an adjoint switching threshold [m]: near a singular arc the
#: adjoint sits on a threshold and finer cuts would only multiply points.
MIN_SWITCH_STEP_M = 0.5
#: The force a hold needs is read this far [m] ahead of the point where the regime is chosen: past the
#: rounding of a bound it was located on, far below any stretch that moves energy or time by 1e-9.
NEED_LOOKAHEAD_M = 1e-7

cdef enum:
    C_HIT_CEILING = 1
    C_STOPPED_SHORT = 2
    C_PHI_MAX_SUBSTEPS = 256

cdef double C_PHI_MIN_SPEED = 0.05
cdef double C_REST_AT_STOP_M = 1e-6
cdef double C_PHI_LENGTH_SCALE_FRACTION = 0.02
cdef double C_W_ENTRY_FRACTION = 1e-3
cdef double C_MIN_SWITCH_STEP_M = 0.5
cdef double C_NEED_LOOKAHEAD_M = 1e-7
# numba converted an out-of-range float to int64 as x86 does (INT64_MIN); at or beyond this the
# sub-step count therefore fell to 1 through max(n, 1)
cdef double INT64_LIMIT = 9.223372036854775807e18


cdef struct PO:
    # the trace being written: position [m], speed [m/s], time [s], regime code, capacity
    double* s
    double* v
    double* t
    signed char* m
    Py_ssize_t cap


cdef struct CS:
    # a capped coasting step: regime, length [m], energy per mass after it [m^2/s^2], time [s]
    long mode
    double h
    double E1
    double dt


cdef struct FP:
    # final_phase_modes' outcome
    Py_ssize_t n
    long status
    double pos
    double arc_start
    double arc_end
    bint zero_division


cdef struct BP:
    # _brake_to_plateau's outcome
    Py_ssize_t n
    Py_ssize_t j
    double u
    double t
    bint found


# ---------------------------------------------------------------------------------------- helpers

cdef inline double speed_of(double E) noexcept nogil:
    return sqrt(2.0 * E) if E > 0.0 else 0.0


cdef inline Py_ssize_t emit(PO* o, Py_ssize_t n, double s, double v, double t, long m) noexcept nogil:
    if n >= o.cap:
        return n  # full: the caller sees n == capacity and discards the attempt
    o.s[n] = s
    o.v[n] = v
    o.t[n] = t
    o.m[n] = <signed char>m
    return n + 1


cdef inline const Kinks* kinks_of(long mode, const Kinks* tk, const Kinks* bk, const Kinks* rk) noexcept nogil:
    return tk if mode == TRACTION else (rk if mode == REGEN else bk)


cdef inline long mode_of_c(double phi, double inv_eta_t, double eta_r, bint has_regen) noexcept nogil:
    if phi >= inv_eta_t:
        return TRACTION
    if phi > eta_r or (not has_regen and phi > 0.0):
        return COAST
    if phi > 0.0:
        return REGEN
    return BRAKE


cdef inline double phi_slope_c(
    double phi, double E, double u, double b0, double b1, const double* P, double mu
) noexcept nogil:
    cdef double v = sqrt(2.0 * E) if E > 0.0 else 0.0
    if v < C_PHI_MIN_SPEED:
        v = C_PHI_MIN_SPEED
    # slope of the running plus tunnel resistance over speed [N s/m]
    cdef double dR = P[P_R1] + 2.0 * P[P_R2] * v + 2.0 * P[P_MASS] * (b0 + b1 * u) * v
    return (phi * dR - mu / (v * v)) / (P[P_INERTIAL_MASS] * v)


cdef double phi_step_c(
    double phi, double E0, double E1, double u, double h, double b0, double b1, const double* P,
    double mu, double Em,
) noexcept nogil:
    if Em < 0.0:
        Em = 0.5 * (E0 + E1)
    cdef double k1 = phi_slope_c(phi, E0, u, b0, b1, P, mu)
    cdef double k2 = phi_slope_c(phi + 0.5 * h * k1, Em, u + 0.5 * h, b0, b1, P, mu)
    cdef double k3 = phi_slope_c(phi + 0.5 * h * k2, Em, u + 0.5 * h, b0, b1, P, mu)
    cdef double k4 = phi_slope_c(phi + h * k3, E1, u + h, b0, b1, P, mu)
    return phi + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


cdef double phi_advance_c(
    double phi, double E0, double E1, double u, double h, long mode, const Line* line, const Ctx* c,
    const Kinks* kinks, double mu, double Em,
) noexcept nogil:
    cdef double b0 = line.b0, b1 = line.b1, Elow, ulow, a, nd, d, E, uk, Ek_mid, Ek1
    cdef long n = 1, k
    if mode != CRUISE and h > 0.0:
        # the length scale at the slower end of the step (the adjoint's slope is steepest there)
        if E0 <= E1:
            Elow, ulow = E0, u
        else:
            Elow, ulow = E1, u + h
        a = fabs(acceleration(mode, Elow, ulow, line, c, -1.0))
        if Elow > 0.0 and a > 0.0:
            nd = ceil(h * a / (C_PHI_LENGTH_SCALE_FRACTION * 2.0 * Elow))
            n = 1 if not nd < INT64_LIMIT else <long>nd
            if n < 1:
                n = 1
            if n > C_PHI_MAX_SUBSTEPS:
                n = C_PHI_MAX_SUBSTEPS
    if n == 1:
        return phi_step_c(phi, E0, E1, u, h, b0, b1, c.P, mu, Em)
    d = h / n
    E = E0
    for k in range(n):
        uk = u + k * d
        Ek_mid = step_energy_c(E, uk, 0.5 * d, mode, line, c, kinks)
        Ek1 = E1 if k == n - 1 else step_energy_c(E, uk, d, mode, line, c, kinks)
        if Ek1 <= 0.0 or Ek_mid <= 0.0:
            break  # (the step ends at rest: the adjoint is not followed into standstill)
        phi = phi_step_c(phi, E, Ek1, uk, d, b0, b1, c.P, mu, Ek_mid)
        E = Ek1
    return phi


cdef double ceiling_at_c(
    double u, double w, Py_ssize_t k, const double* Cr, const double* US, double vcap, const Line* line,
    const Ctx* c, const Kinks* bk,
) noexcept nogil:
    if u < US[k]:
        return vcap
    cdef double Eb = step_energy_c(0.5 * Cr[k] * Cr[k], w, u - w, BRAKE, line, c, bk)
    return sqrt(2.0 * Eb) if Eb > 0.0 else 0.0


cdef void point_forces_c(long mode, double v, double u, const Line* line, const Ctx* c, double* ft, double* fr) noexcept nogil:
    cdef const double* P = c.P
    cdef double res = line_resistance(v, u, line, P)
    cdef double regen_cap = effort(v, &c.curves.regen)
    cdef double f
    ft[0] = 0.0
    fr[0] = 0.0
    if mode == TRACTION:
        ft[0] = P[P_TRACTION_SCALE] * effort(v, &c.curves.traction)
    elif mode == CRUISE:
        if res >= 0.0:
            ft[0] = res
        else:
            fr[0] = min2(-res, regen_cap)
    elif mode == BRAKE:
        if P[P_DECEL] > 0.0:
            f = P[P_INERTIAL_MASS] * P[P_DECEL] - res
            f = f if f > 0.0 else 0.0
        else:
            f = P[P_BRAKE_FRACTION] * effort(v, &c.curves.brake)
        fr[0] = min2(f, regen_cap)
    elif mode == REGEN:
        fr[0] = regen_cap


cdef double cruise_regen_work(double v, double u, double h, const Line* line, const Ctx* c) noexcept nogil:
    cdef double ft, f0, fm, f1
    point_forces_c(CRUISE, v, u, line, c, &ft, &f0)
    point_forces_c(CRUISE, v, u + 0.5 * h, line, c, &ft, &fm)
    point_forces_c(CRUISE, v, u + h, line, c, &ft, &f1)
    return h / 6.0 * (f0 + 4.0 * fm + f1)


cdef double held_adjoint_c(
    double v, double u, const Line* line, const Ctx* c, double inv_eta_t, double eta_r
) noexcept nogil:
    cdef double res = line_resistance(v, u, line, c.P)
    if res >= 0.0:
        return inv_eta_t
    if eta_r <= 0.0:
        return 0.0
    cdef double regen = effort(v, &c.curves.regen)
    return eta_r * min2(-res, regen) / (-res)


cdef double descent_end(double v, double u, double h, const Line* line, const double* P) noexcept nogil:
    cdef double r0 = line_resistance(v, u, line, P)
    cdef double r1 = line_resistance(v, u + h, line, P)
    cdef double hc
    if r0 < 0.0 <= r1:
        hc = h * (-r0) / (r1 - r0)
        if 1e-9 < hc < h:
            return hc
    return h


cdef CS capped_coast_step(
    double E, double v, double u, double h, double cap, const Line* line, const Ctx* c, const Kinks* bk
) noexcept nogil:
    cdef CS r
    cdef ET et
    cdef double E_cap, hc
    if v >= cap - 1e-9 and line_resistance(v, u, line, c.P) < 0.0:
        h = descent_end(v, u, h, line, c.P)
        r.mode, r.h, r.E1, r.dt = CRUISE, h, E, h / v
        return r
    et = step_energy_time_c(E, u, h, COAST, line, c, bk)
    E_cap = 0.5 * cap * cap
    if E_cap < et.E:
        hc = distance_to_speed(E, u, E_cap, COAST, line, c)
        if isfinite(hc) and 0.0 < hc < h:
            h = hc
            et = step_energy_time_c(E, u, h, COAST, line, c, bk)
        et.E = min2(et.E, E_cap)
    r.mode, r.h, r.E1, r.dt = COAST, h, et.E, et.dt
    return r


cdef double curve_speed(
    double u, double w, double Crk, long brake_mode, const Line* line, const Ctx* c, const Kinks* bk
) noexcept nogil:
    cdef double Eb = step_energy_c(0.5 * Crk * Crk, w, u - w, brake_mode, line, c, bk)
    return sqrt(2.0 * Eb) if Eb > 0.0 else 0.0


cdef double held_speed_meets_curve(
    double v, double lo, double hi, double w, double Crk, long brake_mode, const Line* line, const Ctx* c,
    const Kinks* bk, double tol_m,
) noexcept nogil:
    cdef double mid
    cdef int _
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if v >= curve_speed(mid, w, Crk, brake_mode, line, c, bk):
            hi = mid
        else:
            lo = mid
        if hi - lo < tol_m:
            break
    return hi


cdef double meet_curve(
    double E, double u, double end, long mode, double w, double Crk, long brake_mode, const Line* line,
    const Ctx* c, const Kinks* kinks, const Kinks* bk,
) noexcept nogil:
    cdef double lo = u, hi = end, mid, vm
    cdef ET et
    cdef int _
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        et = step_energy_time_c(E, u, mid - u, mode, line, c, kinks)
        vm = sqrt(2.0 * et.E) if et.E > 0.0 else 0.0
        if vm >= curve_speed(mid, w, Crk, brake_mode, line, c, bk):
            hi = mid
        else:
            lo = mid
        if hi - lo < 1e-7:
            break
    return hi


cdef inline double need_ahead_c(double need_u, double need_e, double span) noexcept nogil:
    if span <= C_NEED_LOOKAHEAD_M:
        return need_e
    return need_u + (need_e - need_u) * (C_NEED_LOOKAHEAD_M / span)


# ----------------------------------------------------------------------------------- final phase

cdef BP brake_to_plateau(
    const Track* tr, Py_ssize_t i, double u, double E, double t, Py_ssize_t i_end, const Ctx* c,
    const Kinks* bk, const Kinks* rk, const double* Cr, const double* US, Py_ssize_t kk, PO* o,
    Py_ssize_t n, const int64_t* curve_modes,
) noexcept nogil:
    cdef BP r
    cdef Py_ssize_t k = kk, j
    cdef long mode = curve_modes[k]
    cdef double w
    cdef Line line
    for j in range(i, i_end):
        w = tr.x[j + 1] - tr.x[j]
        line = line_of(tr, j)
        if j > i and u < US[k] - 1e-9:  # (in the first interval the run is on the curve already)
            r.n, r.j, r.u, r.t, r.found = n, j, u, t, True
            return r
        mode = curve_modes[k]
        if u < w:
            n = emit(o, n, tr.x[j] + u, speed_of(E), t, mode)
            t += step_energy_time_c(E, u, w - u, mode, &line, c, rk if mode == REGEN else bk).dt
        E = 0.5 * Cr[k] * Cr[k]
        u = 0.0
        k += 1
    n = emit(o, n, tr.x[i_end], 0.0, t, mode)
    r.n, r.j, r.u, r.t, r.found = n, i_end, 0.0, t, False
    return r


cdef bint regen_arc_step(
    const Track* tr, Py_ssize_t i, double* u, double* E, double* t, Py_ssize_t i_end, double W,
    double w_end, double h_max, double w, const Line* line, const Ctx* c, const Kinks* bk, const Kinks* rk,
    const double* Cr, const double* US, Py_ssize_t kk, const int64_t* curve_modes, PO* o, Py_ssize_t* n,
    long* status,
) noexcept nogil:
    """One step of the regenerative holding arc: True when the run met the braking curve (u then
    holds the position [m] where it met it)."""
    cdef double uu = u[0], EE = E[0], tt = t[0], hm, Em, dtm, v1
    cdef double h = min2(min2(h_max, w - uu), w_end - tr.x[i] - uu)
    if US[kk] > uu:
        h = min2(h, US[kk] - uu)
    h = max2(h, 1e-9)
    cdef double v = speed_of(EE)
    cdef CS st = capped_coast_step(EE, v, uu, h, W, line, c, bk)
    cdef long cm = curve_modes[kk]
    cdef const Kinks* ck = rk if cm == REGEN else bk
    cdef ET et
    cdef BP bp
    if uu + st.h > US[kk]:
        v1 = speed_of(st.E1)
        if v1 > curve_speed(uu + st.h, w, Cr[kk], cm, line, c, ck) + 1e-9:
            if st.mode == CRUISE:
                hm = held_speed_meets_curve(v, uu, uu + st.h, w, Cr[kk], cm, line, c, ck, 1e-10)
                Em, dtm = EE, (hm - uu) / v
            else:
                hm = meet_curve(EE, uu, uu + st.h, COAST, w, Cr[kk], cm, line, c, bk, ck)
                et = step_energy_time_c(EE, uu, hm - uu, COAST, line, c, bk)
                Em, dtm = et.E, et.dt
            n[0] = emit(o, n[0], tr.x[i] + uu, v, tt, st.mode)
            bp = brake_to_plateau(tr, i, hm, Em, tt + dtm, i_end, c, bk, rk, Cr, US, kk, o, n[0], curve_modes)
            n[0] = bp.n
            # (a lower limit below W on the descent: the arc never reaches it, its curve is the stop's)
            u[0], E[0], t[0] = tr.x[i] + hm, Em, tt + dtm
            status[0] = C_HIT_CEILING if not bp.found else C_STOPPED_SHORT
            return True
    n[0] = emit(o, n[0], tr.x[i] + uu, v, tt, st.mode)
    u[0], E[0], t[0] = uu + st.h, st.E1, tt + st.dt
    status[0] = 0
    return False


cdef FP final_phase_c(
    const Track* tr, Py_ssize_t i_start, double u_start, double v_start, double t_start, Py_ssize_t i_end,
    const Ctx* c, const Kinks* tk, const Kinks* bk, const Kinks* rk, const double* Cr, const double* US,
    Py_ssize_t nCr, double mu, double inv_eta_t, double eta_r, bint has_regen, double h_max, PO* o,
    Py_ssize_t n, long force_mode, double v_hold, double phi_start, const int64_t* curve_modes, double W,
    double w_end,
) noexcept nogil:
    """The final phase with a regime per interval (see the Python entry point ``final_phase_modes``)."""
    cdef FP r
    r.zero_division = False
    cdef const double* x = tr.x
    cdef const double* vcap = tr.vlim
    cdef double* P = c.P
    cdef double phi = inv_eta_t * (1.0 - 1e-9) if phi_start < 0.0 else phi_start
    cdef bint on_w = False, just_cut = False, jumped, at_limit, cut, done
    cdef double arc_start = -1.0, arc_end = -1.0
    cdef double E = 0.5 * v_start * v_start, t = t_start, u = u_start
    cdef Py_ssize_t i = i_start, kk
    cdef double w, v, h, E1, dt, hs, dts, v1, hc, phi1, Em, lo_phi, hi_phi, thr, frac, lo_h, hi_h, h_try
    cdef double Et, Emt, g, denom, h_exact, h_cut, c1, hm, dtm, v_end
    cdef long mode, new_mode, base_mode, cm, status
    cdef int _
    cdef const Kinks* kinks
    cdef const Kinks* ck
    cdef Line line
    cdef ET et
    cdef BP bp
    while i < i_end:
        kk = i - (i_end - nCr)  # Cr and US are indexed from the section's first interval
        w = x[i + 1] - x[i]
        line = line_of(tr, i)
        P[P_TRACTION_SCALE] = tr.tscale[i]
        jumped = False
        while u < w - 1e-12:
            if n >= o.cap - 8:
                # never write past the buffers: report the attempt as failed (stopped short)
                r.n, r.status, r.pos, r.arc_start, r.arc_end = n, C_STOPPED_SHORT, x[i] + u, arc_start, arc_end
                return r
            v = speed_of(E)
            if on_w and (x[i] + u >= w_end - 1e-9 or line_resistance(W, u + 2e-9, &line, P) >= 0.0):
                # the arc ends (where asked, or where holding W stops needing braking): the adjoint
                # leaves eta_r upwards and the train coasts (below W it falls back to eta_r at once)
                on_w = False
                arc_end = x[i] + u
                phi = eta_r * (1.0 + 1e-9)
            if on_w:
                done = regen_arc_step(
                    tr, i, &u, &E, &t, i_end, W, w_end, h_max, w, &line, c, bk, rk, Cr, US, kk, curve_modes,
                    o, &n, &status,
                )
                if done:
                    r.n, r.status, r.pos, r.arc_start, r.arc_end = n, status, u, arc_start, arc_end
                    return r
                just_cut = False
                continue
            mode = mode_of_c(phi, inv_eta_t, eta_r, has_regen) if force_mode < 0 else force_mode
            if mode == TRACTION and v >= v_hold:
                # after a descent the adjoint climbs back to 1/eta_t while v > V; traction there
                # would only be braked away before the stop: the train coasts back down to V
                mode = COAST
                phi = inv_eta_t * (1.0 - 1e-9)
            at_limit = v >= vcap[i] - 1e-9
            if at_limit and (mode == TRACTION or (mode == COAST and line_resistance(v, u, &line, P) < 0.0)):
                # the speed limit binds: hold it while the adjoint asks for traction, or while
                # coasting would speed the train up (downhill)
                mode = CRUISE
            h = min2(h_max, w - u)
            if US[kk] > u:
                h = min2(h, US[kk] - u)  # the braking curve part starts at US
            kinks = kinks_of(mode, tk, bk, rk)
            if mode == CRUISE:
                if line_resistance(v, u, &line, P) < 0.0:
                    h = descent_end(v, u, h, &line, P)
                E1, dt = E, h / v
            else:
                et = step_energy_time_c(E, u, h, mode, &line, c, kinks)
                E1, dt = et.E, et.dt
            if E1 <= 0.0:
                # comes to rest inside the step
                hs = distance_to_speed(E, u, 0.0, mode, &line, c)
                if not isfinite(hs) or hs > h:
                    hs = h
                dts = rk4_energy_time(E, u, hs, mode, &line, c, -1.0).dt
                n = emit(o, n, x[i] + u, v, t, mode)
                n = emit(o, n, x[i] + u + hs, 0.0, t + dts, mode)
                r.n, r.arc_start, r.arc_end = n, arc_start, arc_end
                if x[i] + u + hs >= x[i_end] - C_REST_AT_STOP_M:
                    r.status, r.pos = C_HIT_CEILING, x[i_end]
                else:
                    r.status, r.pos = C_STOPPED_SHORT, x[i] + u + hs
                return r
            v1 = sqrt(2.0 * E1)
            if mode != CRUISE and v1 > vcap[i] and v < vcap[i] and u + h <= US[kk]:
                # reaches the limit inside the step: stop the step there
                hc = distance_to_speed(E, u, 0.5 * vcap[i] * vcap[i], mode, &line, c)
                if isfinite(hc) and 0.0 < hc < h:
                    h = hc
                    et = step_energy_time_c(E, u, h, mode, &line, c, kinks)
                    E1, dt = et.E, et.dt
                    v1 = vcap[i]
                    E1 = 0.5 * v1 * v1
            cut = False
            phi1 = phi
            if v > C_PHI_MIN_SPEED and force_mode < 0:
                # (a fixed regime does not follow the adjoint: its sub-steps would cost for nothing)
                Em = E if mode == CRUISE else step_energy_c(E, u, 0.5 * h, mode, &line, c, kinks)
                phi1 = phi_advance_c(phi, E, E1, u, h, mode, &line, c, kinks, mu, Em)
            if v1 >= v_hold and phi1 > inv_eta_t * (1.0 - 1e-9):
                phi1 = inv_eta_t * (1.0 - 1e-9)
            new_mode = mode_of_c(phi1, inv_eta_t, eta_r, has_regen)
            base_mode = mode_of_c(phi, inv_eta_t, eta_r, has_regen)
            if new_mode != base_mode and force_mode < 0:
                # the adjoint crosses a switching threshold inside the step: cut the step there
                lo_phi, hi_phi = min2(phi, phi1), max2(phi, phi1)
                if lo_phi < inv_eta_t <= hi_phi:
                    thr = inv_eta_t
                elif lo_phi <= eta_r < hi_phi and has_regen:
                    thr = eta_r
                else:
                    thr = 0.0
                frac = (thr - phi) / (phi1 - phi) if phi1 != phi else 1.0
                frac = min2(max2(frac, 0.0), 1.0)
                # the crossing located exactly (secant on the adjoint integrated over part of the
                # step): linear interpolation put it up to a metre off, moving with the step
                lo_h, hi_h = 0.0, h
                h_try = frac * h
                for _ in range(40):
                    if not 0.0 < h_try < h:
                        break
                    Et = E if mode == CRUISE else step_energy_c(E, u, h_try, mode, &line, c, kinks)
                    Emt = E if mode == CRUISE else step_energy_c(E, u, 0.5 * h_try, mode, &line, c, kinks)
                    g = phi_advance_c(phi, E, Et, u, h_try, mode, &line, c, kinks, mu, Emt) - thr
                    if (g > 0.0) == (phi > thr):
                        lo_h = h_try
                    else:
                        hi_h = h_try
                    if hi_h - lo_h < 1e-9:
                        break
                    # the adjoint is nearly linear over a step: a linear step on the bracket
                    if g == 0.0:
                        h_try = 0.5 * (lo_h + hi_h)
                    else:
                        denom = g + thr - phi
                        if denom == 0.0:
                            r.zero_division = True  # (numba raised ZeroDivisionError here)
                            r.n, r.status, r.pos, r.arc_start, r.arc_end = n, 0, 0.0, arc_start, arc_end
                            return r
                        h_try = h_try - g * h_try / denom
                    if not lo_h < h_try < hi_h:
                        h_try = 0.5 * (lo_h + hi_h)
                h_exact = hi_h if hi_h < h else frac * h
                # near a singular arc the adjoint sits on a threshold: right after a cut, never cut
                # below MIN_SWITCH_STEP_M (slivers would only multiply points without progress)
                h_cut = max2(h_exact, min2(C_MIN_SWITCH_STEP_M, h)) if just_cut else h_exact
                if h_cut < 1e-9:
                    h_cut = min2(1e-9, h)
                if h_cut < h:
                    h = h_cut
                    if mode == CRUISE:
                        E1, dt = E, h / v
                    else:
                        et = step_energy_time_c(E, u, h, mode, &line, c, kinks)
                        E1, dt = et.E, et.dt
                    v1 = speed_of(E1)
                    phi1 = thr - 1e-12 if phi1 < phi else thr + 1e-12
                    cut = True
            # the braking curve to the stop (and to lower limits) must not be crossed
            cm = curve_modes[kk]
            ck = rk if cm == REGEN else bk
            if mode != cm and u + h > US[kk]:
                c1 = curve_speed(u + h, w, Cr[kk], cm, &line, c, ck)
                if v1 > c1 + 1e-9:
                    hm = meet_curve(E, u, u + h, mode, w, Cr[kk], cm, &line, c, kinks, ck)
                    et = step_energy_time_c(E, u, hm - u, mode, &line, c, kinks)
                    Em, dtm = et.E, et.dt
                    n = emit(o, n, x[i] + u, v, t, mode)
                    bp = brake_to_plateau(tr, i, hm, Em, t + dtm, i_end, c, bk, rk, Cr, US, kk, o, n, curve_modes)
                    n = bp.n
                    if not bp.found:
                        r.n, r.status, r.pos, r.arc_start, r.arc_end = n, C_HIT_CEILING, x[i] + hm, arc_start, arc_end
                        return r
                    # down to a lower limit: the adjoint drives the run on from there
                    i, u, t = bp.j, bp.u, bp.t
                    E = 0.5 * vcap[bp.j] * vcap[bp.j]
                    jumped = True
                    break
            if (
                W > 0.0 and force_mode < 0 and arc_start < 0.0 and phi > eta_r >= phi1 and has_regen
                and vcap[i] > W and v1 >= W * (1.0 - C_W_ENTRY_FRACTION)
                and line_resistance(W, u + h, &line, P) < 0.0
            ):
                # the adjoint comes down to eta_r at W on a descent: the regenerative holding arc
                # (below W by at most W_ENTRY_FRACTION the train coasts up to W first)
                on_w = True
                arc_start = x[i] + u + h
                phi1 = eta_r
            n = emit(o, n, x[i] + u, v, t, mode)
            E, t, u, phi = E1, t + dt, u + h, phi1
            just_cut = cut
        if not jumped:
            u = 0.0
            i += 1
    v_end = speed_of(E)
    n = emit(o, n, x[i_end], v_end, t, curve_modes[nCr - 1])
    r.n, r.status, r.pos, r.arc_start, r.arc_end = n, C_HIT_CEILING, x[i_end], arc_start, arc_end
    return r


# --------------------------------------------------------------------------------- entry points

# (``Arr``, ``_array``: trainsim/_cbuffers.pxd, as ``sim._kernel_c``)


cdef const double* _d(object a, str what, Py_ssize_t need, Py_ssize_t* n=NULL) except NULL:
    """Read-only float64 data of at least ``need`` values."""
    cdef Arr r = _array(a, what, c'd')
    if r.n < need:
        raise ValueError(f"{what} of length {r.n}: need at least {need}")
    if n != NULL:
        n[0] = r.n
    return <const double*>r.data if r.n > 0 else <const double*>&INT64_LIMIT


cdef Track _track(x, a0, a1, b0, b1, vlim, tscale, Py_ssize_t need) except *:
    """The track arrays (grid x [m], line laws, a ceiling per interval [m/s] or None, traction share),
    checked to cover ``need`` intervals."""
    cdef Track tr
    cdef Py_ssize_t nx
    tr.x = _d(x, "track x", need + 1, &nx)
    tr.a0 = _d(a0, "track a0", need)
    tr.a1 = _d(a1, "track a1", need)
    tr.b0 = _d(b0, "track b0", need)
    tr.b1 = _d(b1, "track b1", need)
    tr.vlim = _d(vlim, "speed ceiling per interval", need) if vlim is not None else NULL
    tr.tscale = _d(tscale, "traction share tscale", need)
    tr.n = nx - 1
    return tr


cdef int _ctx(object P, object curves, Curves* cv, Ctx* c) except -1:
    cdef Arr ap = _array(P, "parameter vector P", c'd', 1, True)
    if ap.n != N_PARAMS:
        raise ValueError(f"parameter vector P of length {ap.n}: need {N_PARAMS} (trainsim.sim.codes)")
    curves_from(curves, cv)
    c.P = <double*>ap.data
    c.curves = cv
    return 0


cdef PO _out(out_s, out_v, out_t, out_m) except *:
    cdef Arr os_ = _array(out_s, "out_s", c'd', 1, True), ov = _array(out_v, "out_v", c'd', 1, True)
    cdef Arr ot = _array(out_t, "out_t", c'd', 1, True), om = _array(out_m, "out_m", c'b', 1, True)
    if ov.n != os_.n or ot.n != os_.n or om.n != os_.n:
        raise ValueError(f"the out arrays s, v, t, m of lengths {os_.n}, {ov.n}, {ot.n}, {om.n}: need one length")
    cdef PO o
    o.s, o.v, o.t, o.m, o.cap = <double*>os_.data, <double*>ov.data, <double*>ot.data, <signed char*>om.data, os_.n
    return o


def mode_of(double phi, double inv_eta_t, double eta_r, bint has_regen):
    """The regime the adjoint phi selects (codes of ``trainsim.sim.codes``)."""
    return mode_of_c(phi, inv_eta_t, eta_r, has_regen)


def phi_slope(double phi, double E, double u, double b0, double b1, P, double mu):
    """dphi/ds [1/m] at kinetic energy per mass E [m^2/s^2] and offset u [m]."""
    cdef Arr ap = _array(P, "parameter vector P", c'd')
    if ap.n != N_PARAMS:
        raise ValueError(f"parameter vector P of length {ap.n}: need {N_PARAMS}")
    return phi_slope_c(phi, E, u, b0, b1, <const double*>ap.data, mu)


def phi_step(double phi, double E0, double E1, double u, double h, double b0, double b1, P, double mu, double Em=-1.0):
    """RK4 for phi over a step h [m]; E at the midpoint ``Em`` (by default (< 0) E varying linearly:
    an O(h^2) error that moved the switching points with the step)."""
    cdef Arr ap = _array(P, "parameter vector P", c'd')
    if ap.n != N_PARAMS:
        raise ValueError(f"parameter vector P of length {ap.n}: need {N_PARAMS}")
    return phi_step_c(phi, E0, E1, u, h, b0, b1, <const double*>ap.data, mu, Em)


def phi_advance(double phi, double E0, double E1, double u, double h, long mode, line, P, curves, kinks, double mu, double Em):
    """phi after a step h [m] from offset u along ``mode`` (E0 -> E1, ``Em`` at the midpoint; kinks
    ``kinks``; line = (a0, a1, b0, b1)): ``phi_step``, divided into sub-steps where the speed
    changes fast against the step (``PHI_LENGTH_SCALE_FRACTION``), E at the sub-steps' ends and
    midpoints integrated in the regime (``step_energy``)."""
    cdef Curves cv
    cdef Ctx c
    _ctx(P, curves, &cv, &c)
    cdef Line ln = _line(line)
    cdef Kinks k = _kinks(kinks, "kinks")
    return phi_advance_c(phi, E0, E1, u, h, mode, &ln, &c, &k, mu, Em)


def ceiling_at(double u, double w, Py_ssize_t k, Cr, US, double vcap, line, P, curves, bk):
    """The speed ceiling [m/s] at offset u of interval k (limit, or braking curve to the stop)."""
    cdef Curves cv
    cdef Ctx c
    _ctx(P, curves, &cv, &c)
    cdef Line ln = _line(line)
    cdef Kinks kb = _kinks(bk, "braking kinks bk")
    if k < 0:
        raise ValueError(f"interval k = {k}: need k >= 0")
    return ceiling_at_c(u, w, 0, _d(Cr, "Cr", k + 1) + k, _d(US, "US", k + 1) + k, vcap, &ln, &c, &kb)


def _curve_speed(double u, double w, double Crk, long brake_mode, line, P, curves, bk):
    """Speed [m/s] at offset u of the braking curve of ``brake_mode`` ending at (w, Crk)."""
    cdef Curves cv
    cdef Ctx c
    _ctx(P, curves, &cv, &c)
    cdef Line ln = _line(line)
    cdef Kinks kb = _kinks(bk, "braking kinks bk")
    return curve_speed(u, w, Crk, brake_mode, &ln, &c, &kb)


def held_adjoint(double v, double u, line, P, curves, double inv_eta_t, double eta_r):
    """The adjoint phi at which coasting and holding speed v [m/s] at offset u have the same
    Hamiltonian (the switching condition between them): with net resistance R at v, holding costs
    R / eta_t per metre where R > 0 (traction) and -eta_r min(-R, F_regen) where R < 0 (braking,
    the electric brake returning what it can), coasting phi R; hence phi = 1/eta_t, or
    eta_r min(-R, F_regen) / (-R) (Albrecht et al. 2016, Part 2)."""
    cdef Curves cv
    cdef Ctx c
    _ctx(P, curves, &cv, &c)
    cdef Line ln = _line(line)
    return held_adjoint_c(v, u, &ln, &c, inv_eta_t, eta_r)


def point_forces(long mode, double v, double u, line, P, curves):
    """(traction, regenerative braking) force [N] at speed v in a regime, as the run's energy
    accounting (``trainsim.sim.result``) counts them: holding takes what resistance needs, braking
    returns what the electric brake can take of it."""
    cdef Curves cv
    cdef Ctx c
    _ctx(P, curves, &cv, &c)
    cdef Line ln = _line(line)
    cdef double ft, fr
    point_forces_c(mode, v, u, &ln, &c, &ft, &fr)
    return ft, fr


def resistance_force(double v, double u, line, P):
    """Running plus line resistance [N] at speed v [m/s] and offset u [m] into the interval of
    ``line = (a0, a1, b0, b1)``, as the adjoint and the holding phases evaluate it (the sim kernel's
    law, for tests and callers that check a run's forces)."""
    cdef Arr ap = _array(P, "parameter vector P", c'd')
    if ap.n != N_PARAMS:
        raise ValueError(f"parameter vector P of length {ap.n}: need {N_PARAMS}")
    cdef Line ln = _line(line)
    return line_resistance(v, u, &ln, <const double*>ap.data)


def need_ahead(double need_u, double need_e, double span):
    """The force [N] needed to hold the speed NEED_LOOKAHEAD_M ahead of offset u, from its values at u
    (``need_u``) and ``span`` [m] further (``need_e``): linear along an interval, so this is exact."""
    return need_ahead_c(need_u, need_e, span)


def final_phase_modes(
    x, a0, a1, b0, b1, vcap, tscale, Py_ssize_t i_start, double u_start, double v_start, double t_start,
    Py_ssize_t i_end, P, curves, tk, bk, Cr, US, double mu, double inv_eta_t, double eta_r, bint has_regen,
    double h_max, out_s, out_v, out_t, out_m, Py_ssize_t n, long force_mode, double v_hold, double phi_start,
    curve_modes, rk, double W, double w_end,
):
    """From (x[i_start] + u_start, v_start), leaving the holding arc (phi just below 1/eta_t), drive
    by the adjoint to the stop at x[i_end], holding the speed limit ``vcap`` if the train reaches
    it. Appends points; returns (n, status, position, arc_start, arc_end): HIT_CEILING when the train
    meets the braking curve to the stop (it then follows it and stops exactly at x[i_end]),
    STOPPED_SHORT when it comes to rest before (the last point is where it stopped); the position of
    that event; the ends [m] of the regenerative holding arc (-1 if the run has none).
    ``force_mode`` >= 0 replaces the adjoint's choice by a fixed regime (source 004's braking).
    The adjoint starts at ``phi_start``, by default (< 0) just below 1/eta_t: leaving a holding
    arc; leaving an arc held by braking on a descent it starts just below eta_r (or 0).
    ``Cr``/``US`` are the braking curves, those of interval k (indexed as ``Cr``, from interval
    i_end - len(Cr)) of the braking mode ``curve_modes[k]`` (BRAKE: service braking, kinks ``bk``;
    REGEN: regenerative braking only, kinks ``rk``); the run follows them where it meets them. A
    train with regeneration brakes to lower limits with its electric brake alone: along such an arc
    the adjoint lies in (0, eta_r], where friction braking (phi <= 0) is not optimal.
    With a regenerative holding speed ``W`` > 0 (mu = eta_r W^2 R'(W)), where the adjoint comes down
    to eta_r at W on a descent that needs braking to hold W, the run holds W with regenerative
    braking (the singular arc, phi = eta_r) until ``w_end`` [m] or the descent's end, whichever comes
    first, then coasts on from phi just above eta_r."""
    cdef Track tr = _track(x, a0, a1, b0, b1, vcap, tscale, i_end)
    cdef Curves cv
    cdef Ctx c
    _ctx(P, curves, &cv, &c)
    cdef Kinks ktk = _kinks(tk, "traction kinks tk"), kbk = _kinks(bk, "braking kinks bk")
    cdef Kinks krk = _kinks(rk, "regenerative kinks rk")
    cdef Py_ssize_t nCr, nUS
    cdef const double* pCr = _d(Cr, "Cr", 1, &nCr)
    cdef const double* pUS = _d(US, "US", nCr, &nUS)
    cdef Arr am = _array(curve_modes, "curve_modes", c'q')
    if am.n < nCr:
        raise ValueError(f"curve_modes of length {am.n}: need one per braking curve ({nCr})")
    if not (0 <= i_start and i_end - nCr <= i_start <= i_end and nCr <= i_end):
        raise ValueError(f"intervals i_start {i_start}, i_end {i_end} with {nCr} braking curves: need "
                         "i_end - len(Cr) <= i_start <= i_end")
    cdef PO o = _out(out_s, out_v, out_t, out_m)
    if not 0 <= n <= o.cap:
        raise ValueError(f"start index n = {n} outside the out arrays (length {o.cap})")
    cdef FP r
    with nogil:
        r = final_phase_c(
            &tr, i_start, u_start, v_start, t_start, i_end, &c, &ktk, &kbk, &krk, pCr, pUS, nCr, mu,
            inv_eta_t, eta_r, has_regen, h_max, &o, n, force_mode, v_hold, phi_start,
            <const int64_t*>am.data, W, w_end,
        )
    if r.zero_division:
        raise ZeroDivisionError("float division by zero (secant step of the adjoint's switching point)")
    return r.n, r.status, r.pos, r.arc_start, r.arc_end


def final_phase_regen(
    x, a0, a1, b0, b1, vcap, tscale, i_start, u_start, v_start, t_start, i_end,
    P, curves, tk, bk, Cr, US, mu, inv_eta_t, eta_r, has_regen, h_max,
    out_s, out_v, out_t, out_m, n, force_mode, v_hold, phi_start, long stop_mode, sk, rk, W, w_end,
):
    """``final_phase_modes`` with the braking curves ``Cr``/``US`` all of ``stop_mode`` (BRAKE:
    service braking; REGEN: regenerative braking only); ``sk``, their kinks, is ``bk`` or ``rk``."""
    curve_modes = np.full(len(Cr), stop_mode, dtype=np.int64)
    return final_phase_modes(
        x, a0, a1, b0, b1, vcap, tscale, i_start, u_start, v_start, t_start, i_end,
        P, curves, tk, bk, Cr, US, mu, inv_eta_t, eta_r, has_regen, h_max,
        out_s, out_v, out_t, out_m, n, force_mode, v_hold, phi_start, curve_modes, rk, W, w_end,
    )


def final_phase(
    x, a0, a1, b0, b1, vcap, tscale, i_start, u_start, v_start, t_start, i_end,
    P, curves, tk, bk, Cr, US, mu, inv_eta_t, eta_r, has_regen, h_max,
    out_s, out_v, out_t, out_m, n, force_mode, v_hold, phi_start, stop_mode, sk, rk,
):
    """``final_phase_regen`` without the regenerative holding arc: (n, status, position)."""
    n, status, s_event, _, _ = final_phase_regen(
        x, a0, a1, b0, b1, vcap, tscale, i_start, u_start, v_start, t_start, i_end,
        P, curves, tk, bk, Cr, US, mu, inv_eta_t, eta_r, has_regen, h_max,
        out_s, out_v, out_t, out_m, n, force_mode, v_hold, phi_start, stop_mode, sk, rk, -1.0, np.inf,
    )
    return n, status, s_event


# ------------------------------------------------------------------------- excursions and holding

cdef void coast_excursion_c(
    const Track* tr, double W, Py_ssize_t i, double u, double v0, double t, Py_ssize_t i_end, const Ctx* c,
    const Kinks* bk, double V, double v_rejoin, double mu, double inv_eta_t, double eta_r, double h_max,
    PO* o, const double* Cr, const double* US, Py_ssize_t* n_out, long* status, double* residual,
    Py_ssize_t* i_q, double* u_q, double* t_q, double* energy_j,
) noexcept nogil:
    cdef const double* x = tr.x
    cdef double* P = c.P
    cdef double phi = inv_eta_t, E = 0.5 * v0 * v0, EV = 0.5 * V * V
    cdef bint on_limit = v_rejoin < V * (1.0 - 1e-9)
    cdef double ER = 0.5 * v_rejoin * v_rejoin
    cdef bint below = False, above = False
    cdef double energy = 0.0, entry = NAN  # the residual where the coast first enters an arc held with braking
    cdef Py_ssize_t n = 0, ii
    cdef double w, uu, v, h, cap, v_ceiling, e_ceiling, hq, dtq, Emq, phiq, Em
    cdef Line line
    cdef CS st
    for ii in range(i, i_end):
        w = x[ii + 1] - x[ii]
        line = line_of(tr, ii)
        P[P_TRACTION_SCALE] = tr.tscale[ii]
        uu = u if ii == i else 0.0
        while uu < w - 1e-12:
            v = speed_of(E)
            h = min2(h_max, w - uu)
            cap = tr.vlim[ii]
            if eta_r > 0.0 and phi <= eta_r * (1.0 + 1e-9) and cap > W:
                cap = W
            st = capped_coast_step(E, v, uu, h, cap, &line, c, bk)
            h = st.h
            if st.E1 <= 0.0:
                n_out[0], status[0], residual[0], i_q[0], u_q[0], t_q[0], energy_j[0] = n, 1, -INFINITY, ii, uu, t, energy
                return
            v_ceiling = ceiling_at_c(uu + h, w, ii, Cr, US, tr.vlim[ii], &line, c, bk)
            e_ceiling = 0.5 * v_ceiling * v_ceiling * (1.0 + 1e-6) + 1e-6
            if e_ceiling < st.E1:  # the coast crosses a braking curve
                n_out[0], status[0], residual[0], i_q[0], u_q[0], t_q[0], energy_j[0] = n, 2, -INFINITY, ii, uu, t, energy
                return
            if on_limit and below and st.E1 >= ER * (1.0 - 1e-12):
                # back up to the limit: the rejoin point, where the limit is held again
                hq = h
                if st.E1 > ER * (1.0 + 1e-12):
                    hq = distance_to_speed(E, uu, ER, COAST, &line, c)
                    if not isfinite(hq) or hq > h:
                        hq = h
                dtq = rk4_energy_time(E, uu, hq, COAST, &line, c, -1.0).dt
                n = emit(o, n, x[ii] + uu, v, t, st.mode)
                if isnan(entry) and v > C_PHI_MIN_SPEED:
                    Emq = step_energy_c(E, uu, 0.5 * hq, COAST, &line, c, bk)
                    phiq = phi_step_c(phi, E, ER, uu, hq, tr.b0[ii], tr.b1[ii], P, mu, Emq)
                    entry = phiq - held_adjoint_c(v_rejoin, uu + hq, &line, c, inv_eta_t, eta_r)
                n_out[0], status[0], residual[0], i_q[0], u_q[0], t_q[0], energy_j[0] = n, 0, entry, ii, uu + hq, t + dtq, energy
                return
            if on_limit and st.E1 < ER * (1.0 - 1e-9):
                below = True
            if not on_limit and above and st.E1 < EV <= E:
                # back down to V inside this step: the rejoin point
                hq = distance_to_speed(E, uu, EV, COAST, &line, c)
                if not isfinite(hq) or hq > h:
                    hq = h
                dtq = rk4_energy_time(E, uu, hq, COAST, &line, c, -1.0).dt
                Emq = step_energy_c(E, uu, 0.5 * hq, COAST, &line, c, bk)
                phiq = phi_step_c(phi, E, EV, uu, hq, tr.b0[ii], tr.b1[ii], P, mu, Emq)
                n = emit(o, n, x[ii] + uu, v, t, st.mode)
                if isnan(entry):
                    entry = phiq - held_adjoint_c(V, uu + hq, &line, c, inv_eta_t, eta_r)
                n_out[0], status[0], residual[0], i_q[0], u_q[0], t_q[0], energy_j[0] = n, 0, entry, ii, uu + hq, t + dtq, energy
                return
            if st.mode == CRUISE:
                if isnan(entry):
                    entry = phi - held_adjoint_c(v, uu, &line, c, inv_eta_t, eta_r)
                energy -= eta_r * cruise_regen_work(v, uu, h, &line, c)
            if v > C_PHI_MIN_SPEED:
                # the midpoint's energy integrated (a linear one was O(h^2) and moved the departure
                # points that the adjoint locates, ``residual``, by millimetres with the step)
                Em = step_energy_c(E, uu, 0.5 * h, COAST, &line, c, bk) if st.mode == COAST else E
                phi = phi_step_c(phi, E, st.E1, uu, h, tr.b0[ii], tr.b1[ii], P, mu, Em)
            if st.mode == CRUISE and cap == W:
                phi = eta_r  # on the singular regenerative arc the adjoint stays at eta_r
            if st.E1 > EV * (1.0 + 1e-12):
                above = True
            n = emit(o, n, x[ii] + uu, v, t, st.mode)
            E, t, uu = st.E1, t + st.dt, uu + h
    n_out[0], status[0], residual[0], i_q[0], u_q[0], t_q[0], energy_j[0] = (
        n, 1, -INFINITY, i_end - 1, x[i_end] - x[i_end - 1], t, energy
    )


def coast_excursion(
    x, a0, a1, b0, b1, vlim, double W, tscale, Py_ssize_t i, double u, double v0, double t, Py_ssize_t i_end,
    P, curves, bk, double V, double v_rejoin, double mu, double inv_eta_t, double eta_r, double h_max,
    out_s, out_v, out_t, out_m, Cr, US,
):
    """Leave the holding arc (or the traction arc below V) into coasting, ahead of a descent too
    steep to hold V on.

    Coasts and integrates the adjoint from phi = 1/eta_t until the speed comes back down to V
    after having been above it: the rejoin point q. Leaving a speed limit ``v_rejoin`` below V, the
    train rejoins where coasting brings it back up to that limit. The train holds the speed limit
    ``vlim`` with braking where coasting would exceed it, and the regenerative holding speed W once
    the adjoint has fallen to eta_r (the singular regenerative arc; above eta_r the optimal control
    coasts). The coast must stay below the service braking curves (``Cr``, ``US``, indexed by
    interval, as ``ceiling_at``) to lower limits and the stop: an excursion that would cross one fails
    (status 2), it is not taken.
    Returns (n, status, residual, i_q, u_q, t_q, energy_j): status 0 rejoined, 1 came to rest or
    reached the end without rejoining, 2 crossed a braking curve; energy_j is the electrical energy
    of the path (regenerated while holding with braking, so <= 0).

    ``residual`` is the departure's switching condition, zero where the departure point is optimal
    (d(energy + mu x time)/dp = 0; Howlett, Pudney & Vu 2009, Automatica 45; Albrecht et al. 2016,
    Part 2): leaving traction or holding means phi = 1/eta_t at p, and the adjoint integrated from
    there along the coast must arrive where the coast first reaches a speed held with braking (the
    limit, or W) at phi_r = eta_r min(-R, F_regen) / (-R); without such an arc the coast rejoins the
    arc it rejoins with the value that arc needs (``held_adjoint``). NaN where the adjoint was not
    followed."""
    cdef Track tr = _track(x, a0, a1, b0, b1, vlim, tscale, i_end)
    cdef Curves cv
    cdef Ctx c
    _ctx(P, curves, &cv, &c)
    cdef Kinks kbk = _kinks(bk, "braking kinks bk")
    cdef const double* pCr = _d(Cr, "Cr", i_end)
    cdef const double* pUS = _d(US, "US", i_end)
    if not 0 <= i < i_end:
        raise ValueError(f"interval i = {i}: need 0 <= i < i_end = {i_end}")
    cdef PO o = _out(out_s, out_v, out_t, out_m)
    cdef Py_ssize_t n, i_q
    cdef long status
    cdef double residual, u_q, t_q, energy
    with nogil:
        coast_excursion_c(
            &tr, W, i, u, v0, t, i_end, &c, &kbk, V, v_rejoin, mu, inv_eta_t, eta_r, h_max, &o, pCr, pUS,
            &n, &status, &residual, &i_q, &u_q, &t_q, &energy,
        )
    return n, status, residual, i_q, u_q, t_q, energy


cdef void coast_to_curve_c(
    const Track* tr, Py_ssize_t i, double u, double v0, double t, Py_ssize_t i_last, Py_ssize_t i0,
    const Ctx* c, const Kinks* bk, const Kinks* rk, const double* Cr, const double* US,
    const int64_t* brake_modes, double h_max, double eta_r, PO* o, Py_ssize_t* n_out, long* status,
    Py_ssize_t* i_r, double* u_r, double* v_r, double* t_r, double* energy_j,
) noexcept nogil:
    cdef const double* x = tr.x
    cdef double E = 0.5 * v0 * v0, energy = 0.0, w, uu, v, h, vb, v1, hm, dtm, Em
    cdef Py_ssize_t n = 0, ii, k
    cdef long mode_b
    cdef const Kinks* bkk
    cdef Line line
    cdef CS st
    cdef ET et
    for ii in range(i, i_last + 1):
        k = ii - i0
        w = x[ii + 1] - x[ii]
        line = line_of(tr, ii)
        c.P[P_TRACTION_SCALE] = tr.tscale[ii]
        mode_b = brake_modes[ii]
        bkk = bk if mode_b == BRAKE else rk
        uu = u if ii == i else 0.0
        while uu < w - 1e-12:
            v = speed_of(E)
            h = min2(h_max, w - uu)
            if US[k] > uu:
                h = min2(h, US[k] - uu)
            st = capped_coast_step(E, v, uu, h, tr.vlim[ii], &line, c, bk)
            h = st.h
            if st.E1 <= 0.0:
                n_out[0], status[0], i_r[0], u_r[0], v_r[0], t_r[0], energy_j[0] = n, 1, ii, uu, 0.0, t, energy
                return
            if uu + h > US[k]:
                vb = curve_speed(uu + h, w, Cr[k], mode_b, &line, c, bkk)
                v1 = sqrt(2.0 * st.E1)
                if v1 >= vb - 1e-9:
                    if st.mode == CRUISE:
                        hm = held_speed_meets_curve(v, uu, uu + h, w, Cr[k], mode_b, &line, c, bkk, 1e-7)
                        dtm = (hm - uu) / v
                        Em = E
                    else:
                        hm = meet_curve(E, uu, uu + h, COAST, w, Cr[k], mode_b, &line, c, bk, bkk)
                        et = step_energy_time_c(E, uu, hm - uu, COAST, &line, c, bk)
                        Em, dtm = et.E, et.dt
                    n = emit(o, n, x[ii] + uu, v, t, st.mode)
                    if st.mode == CRUISE:
                        energy -= eta_r * cruise_regen_work(v, uu, hm - uu, &line, c)
                    n_out[0], status[0], i_r[0], u_r[0], v_r[0], t_r[0], energy_j[0] = (
                        n, 0, ii, hm, speed_of(Em), t + dtm, energy
                    )
                    return
            if st.mode == CRUISE:
                energy -= eta_r * cruise_regen_work(v, uu, h, &line, c)
            n = emit(o, n, x[ii] + uu, v, t, st.mode)
            E, t, uu = st.E1, t + st.dt, uu + h
    n_out[0], status[0], i_r[0], u_r[0], v_r[0], t_r[0], energy_j[0] = (
        n, 1, i_last, x[i_last + 1] - x[i_last], speed_of(E), t, energy
    )


def coast_to_curve(
    x, a0, a1, b0, b1, vtop, tscale, Py_ssize_t i, double u, double v0, double t, Py_ssize_t i_last,
    Py_ssize_t i0, P, curves, bk, rk, Cr, US, brake_modes, double h_max, double eta_r, out_s, out_v, out_t,
    out_m,
):
    """Coast from (x[i] + u, v0) until the trajectory meets the braking curve (``Cr``/``US``, in
    ``brake_modes``, indexed from interval ``i0``) that leads down to a lower limit; hold ``vtop``
    with braking where coasting downhill would exceed it. Returns (n, status, i_r, u_r, v_r, t_r,
    energy_j): status 0 met the curve at (i_r, u_r) before the end of interval ``i_last``; 1 came
    to rest or did not meet it (the coasting started too early). energy_j is the electrical energy
    of the coasting path (regenerated where holding vtop needs braking, so <= 0)."""
    cdef Track tr = _track(x, a0, a1, b0, b1, vtop, tscale, i_last + 1)
    cdef Curves cv
    cdef Ctx c
    _ctx(P, curves, &cv, &c)
    cdef Kinks kbk = _kinks(bk, "braking kinks bk"), krk = _kinks(rk, "regenerative kinks rk")
    if not 0 <= i0 <= i <= i_last:
        raise ValueError(f"intervals i0 {i0}, i {i}, i_last {i_last}: need 0 <= i0 <= i <= i_last")
    cdef const double* pCr = _d(Cr, "Cr", i_last + 1 - i0)
    cdef const double* pUS = _d(US, "US", i_last + 1 - i0)
    cdef Arr am = _array(brake_modes, "brake_modes", c'q')
    if am.n < i_last + 1:
        raise ValueError(f"brake_modes of length {am.n}: need one per interval up to {i_last}")
    cdef PO o = _out(out_s, out_v, out_t, out_m)
    cdef Py_ssize_t n, i_r
    cdef long status
    cdef double u_r, v_r, t_r, energy
    with nogil:
        coast_to_curve_c(
            &tr, i, u, v0, t, i_last, i0, &c, &kbk, &krk, pCr, pUS, <const int64_t*>am.data, h_max, eta_r,
            &o, &n, &status, &i_r, &u_r, &v_r, &t_r, &energy,
        )
    return n, status, i_r, u_r, v_r, t_r, energy


cdef void path_energy_c(
    const double* s, const double* v, const signed char* m, Py_ssize_t ns, const Track* tr, Py_ssize_t nx,
    const Ctx* c, double inv_eta_t, double eta_r, double* out, const Kinks* tk, const Kinks* bk,
    const Kinks* rk,
) noexcept nogil:
    cdef Py_ssize_t i = 0, k
    cdef double ds, u0, vm, Em, ft0, fr0, ft1, fr1, ftm, frm
    cdef long mode
    cdef Line line
    out[0] = 0.0
    for k in range(ns - 1):
        while i < nx - 2 and tr.x[i + 1] <= s[k] + 1e-9:
            i += 1
        ds = s[k + 1] - s[k]
        if ds <= 0.0:
            out[k + 1] = out[k]
            continue
        line = line_of(tr, i)
        c.P[P_TRACTION_SCALE] = tr.tscale[i]
        u0 = s[k] - tr.x[i]
        mode = m[k]
        point_forces_c(mode, v[k], u0, &line, c, &ft0, &fr0)
        point_forces_c(mode, v[k + 1], u0 + ds, &line, c, &ft1, &fr1)
        vm = 0.5 * (v[k] + v[k + 1])
        if mode == TRACTION or mode == REGEN or mode == BRAKE:
            Em = step_energy_c(0.5 * v[k] * v[k], u0, 0.5 * ds, mode, &line, c, kinks_of(mode, tk, bk, rk))
            vm = sqrt(2.0 * Em) if Em > 0.0 else 0.0
        point_forces_c(mode, vm, u0 + 0.5 * ds, &line, c, &ftm, &frm)
        out[k + 1] = out[k] + ds / 6.0 * (
            (ft0 + 4.0 * ftm + ft1) * inv_eta_t - eta_r * (fr0 + 4.0 * frm + fr1)
        )


def path_energy(s, v, m, x, a0, a1, b0, b1, tscale, P, curves, double inv_eta_t, double eta_r, out, tk, bk, rk):
    """Cumulative electrical energy [J] (traction / eta_t - eta_r regenerated) along a run's
    points into ``out``: Simpson's rule on each stretch's forces in the regime of its first point,
    the midpoint speed integrated in that regime. (Trapezoids, O(h^2), made the departure points
    chosen with these costs move by metres with the step.)"""
    cdef Py_ssize_t nx
    _d(x, "track x", 2, &nx)
    cdef Track tr = _track(x, a0, a1, b0, b1, None, tscale, nx - 1)
    cdef Curves cv
    cdef Ctx c
    _ctx(P, curves, &cv, &c)
    cdef Arr as_ = _array(s, "s", c'd'), av = _array(v, "v", c'd'), am = _array(m, "regimes m", c'b')
    cdef Arr ao = _array(out, "out", c'd', 1, True)
    if as_.n < 1 or av.n != as_.n or am.n != as_.n or ao.n != as_.n:
        raise ValueError(f"s, v, m, out of lengths {as_.n}, {av.n}, {am.n}, {ao.n}: need one length >= 1")
    cdef Kinks ktk = _kinks(tk, "traction kinks tk"), kbk = _kinks(bk, "braking kinks bk")
    cdef Kinks krk = _kinks(rk, "regenerative kinks rk")
    with nogil:
        path_energy_c(
            <const double*>as_.data, <const double*>av.data, <const signed char*>am.data, as_.n, &tr, nx, &c,
            inv_eta_t, eta_r, <double*>ao.data, &ktk, &kbk, &krk,
        )


def state_at(s, v, t, m, x, a0, a1, b0, b1, tscale, Py_ssize_t i1, P, curves, tk, bk, double s_c, rk):
    """(interval, offset [m], speed [m/s], time [s], index of the last point at or before) of the
    run (s, v, t, m) at s_c, integrating its regime from that last point (what the optimal
    strategy's searches ask of a run thousands of times per solve)."""
    cdef Arr as_ = _array(s, "s", c'd'), av = _array(v, "v", c'd'), at = _array(t, "t", c'd')
    cdef Arr am = _array(m, "regimes m", c'b')
    if as_.n < 2 or av.n != as_.n or at.n != as_.n or am.n != as_.n:
        raise ValueError(f"s, v, t, m of lengths {as_.n}, {av.n}, {at.n}, {am.n}: need one length >= 2")
    cdef Py_ssize_t nx
    _d(x, "track x", 2, &nx)
    if not 1 <= i1 <= nx - 1:
        raise ValueError(f"i1 = {i1}: need 1 <= i1 <= {nx - 1}")
    cdef Track tr = _track(x, a0, a1, b0, b1, None, tscale, i1)
    cdef Curves cv
    cdef Ctx c
    _ctx(P, curves, &cv, &c)
    cdef Kinks ktk = _kinks(tk, "traction kinks tk"), kbk = _kinks(bk, "braking kinks bk")
    cdef Kinks krk = _kinks(rk, "regenerative kinks rk")
    cdef const double* ps = <const double*>as_.data
    cdef const double* pv = <const double*>av.data
    cdef const double* pt = <const double*>at.data
    cdef const signed char* pm = <const signed char*>am.data
    cdef Py_ssize_t j = search_right(ps, as_.n, s_c) - 1, i
    j = min(max(j, 0), as_.n - 2)
    i = min(search_right(tr.x, nx, ps[j]) - 1, i1 - 1)
    cdef double u0 = ps[j] - tr.x[i], h = s_c - ps[j]
    cdef long mode = pm[j]
    c.P[P_TRACTION_SCALE] = tr.tscale[i]
    if h <= 0.0:
        return i, u0, pv[j], pt[j], j
    if mode == CRUISE or mode == DWELL:
        return i, u0 + h, pv[j], (pt[j] + h / pv[j]) if pv[j] > 0.0 else pt[j], j
    cdef Line line = line_of(&tr, i)
    # (coasting has no kinks: any list works)
    cdef ET et = step_energy_time_c(0.5 * (pv[j] * pv[j]), u0, h, mode, &line, &c, kinks_of(mode, &ktk, &kbk, &krk))
    return i, u0 + h, sqrt(max2(2.0 * et.E, 0.0)), pt[j] + et.dt, j


cdef long holding_segment_c(
    const Track* tr, const double* vhold, const double* vtop, Py_ssize_t i0, Py_ssize_t i1, const Ctx* c,
    const Kinks* tk, const Kinks* bk, const Kinks* rk, const double* Cr, const double* US,
    const int64_t* brake_modes, PO* o, Py_ssize_t i_s, double u_s, double v_s, double t_s, Py_ssize_t* n_out,
) noexcept nogil:
    cdef const double* x = tr.x
    cdef double* P = c.P
    cdef Py_ssize_t n = 0, k, i
    cdef double E = 0.5 * v_s * v_s if i_s >= 0 else 0.0
    cdef double t = t_s if i_s >= 0 else 0.0
    cdef double tol = 1e-7
    cdef Py_ssize_t k_start = i_s - i0 if i_s >= 0 else 0
    cdef double w, vh, vt, u, v, end, need_u, need_e, need_a, fmax, hold_lo, hold_hi, stop_at, target
    cdef double E1, dt, v1, h, hc, vb, hm
    cdef long brake_mode, mode
    cdef bint in_curve, at_hold, at_top
    cdef const Kinks* bkk
    cdef const Kinks* kinks
    cdef Line line
    cdef ET et
    cdef int _guard
    for k in range(k_start, i1 - i0):
        i = i0 + k
        w = x[i + 1] - x[i]
        line = line_of(tr, i)
        P[P_TRACTION_SCALE] = tr.tscale[i]
        vh, vt = vhold[i], vtop[i]
        brake_mode = brake_modes[i]
        bkk = bk if brake_mode == BRAKE else rk
        u = u_s if (i_s >= 0 and k == k_start) else 0.0
        for _guard in range(10000):
            if u >= w - 1e-12:
                break
            v = speed_of(E)
            in_curve = u >= US[k]
            end = w if in_curve else US[k]
            if in_curve and v >= curve_speed(u, w, Cr[k], brake_mode, &line, c, bkk) - 1e-6:
                # on the braking curve: brake along it to the interval's end
                n = emit(o, n, x[i] + u, v, t, brake_mode)
                t += step_energy_time_c(E, u, w - u, brake_mode, &line, c, bkk).dt
                E = 0.5 * Cr[k] * Cr[k]
                u = w
                break
            need_u = line_resistance(v, u, &line, P)
            need_e = line_resistance(v, end, &line, P)
            # the regime is chosen by the force needed just ahead of u, not at u: where a hold ended
            # at u because that force crossed a bound (0 at a descent's end), it sits on the bound
            # to rounding and its sign at u said nothing (heavy_haul: 1.7e-6 of net energy on
            # halving the step)
            need_a = need_ahead_c(need_u, need_e, end - u)
            fmax = P[P_TRACTION_SCALE] * effort(v, &c.curves.traction)
            at_hold = fabs(v - vh) <= tol * max2(1.0, vh)
            at_top = v >= vt - tol * max2(1.0, vt)
            hold_lo, hold_hi = 1.0, -1.0  # empty: no holding
            if at_top and need_a <= 0.0:
                hold_lo, hold_hi = -INFINITY, 0.0  # hold the top speed with braking
            elif at_hold and 0.0 <= need_a <= fmax:
                hold_lo, hold_hi = 0.0, fmax  # hold the holding speed with partial traction
            if hold_lo <= hold_hi:
                stop_at = end
                if need_e > hold_hi:
                    stop_at = u + (end - u) * (hold_hi - need_u) / (need_e - need_u)
                elif need_e < hold_lo:
                    stop_at = u + (end - u) * (hold_lo - need_u) / (need_e - need_u)
                if in_curve and v > curve_speed(stop_at, w, Cr[k], brake_mode, &line, c, bkk) + 1e-9:
                    # the braking curve falls below the held speed inside this interval: leave the
                    # hold where they meet (held to the interval's end, the run went on above the
                    # curve and was clamped to the lower limit past it: CH_Fribourg_Bern, the FLIRT
                    # entered the 100 km/h limit at 5790 m at 101.8 km/h; issue 16)
                    stop_at = held_speed_meets_curve(
                        v, u, stop_at, w, Cr[k], brake_mode, &line, c, bkk, 1e-10
                    )
                if stop_at > u + 1e-9:
                    n = emit(o, n, x[i] + u, v, t, CRUISE)
                    t += (stop_at - u) / v
                    u = stop_at
                    E = 0.5 * v * v
                    continue
            if v < vh - tol * max2(1.0, vh) or (at_hold and need_a > 0.0):
                mode = TRACTION
                kinks = tk
                target = vh
            else:
                mode = COAST
                kinks = bk
                target = vh if (v > vh and need_a > 0.0) else vt
            et = step_energy_time_c(E, u, end - u, mode, &line, c, kinks)
            E1, dt = et.E, et.dt
            v1 = speed_of(E1)
            h = end - u
            # events: reaching the target speed, meeting the braking curve, coming to rest
            if (v < target and v1 > target) or (v > target and v1 < target):
                hc = distance_to_speed(E, u, 0.5 * target * target, mode, &line, c)
                if isfinite(hc) and 0.0 < hc < h:
                    h = hc
                    et = step_energy_time_c(E, u, h, mode, &line, c, kinks)
                    dt = et.dt
                    E1 = 0.5 * target * target
                    v1 = target
            if in_curve:
                vb = curve_speed(u + h, w, Cr[k], brake_mode, &line, c, bkk)
                if v1 > vb + 1e-9:
                    hm = meet_curve(E, u, u + h, mode, w, Cr[k], brake_mode, &line, c, kinks, bkk) - u
                    h = hm
                    et = step_energy_time_c(E, u, h, mode, &line, c, kinks)
                    E1, dt = et.E, et.dt
            if E1 <= 0.0:
                n_out[0] = n
                return 1
            if v1 > vt + 1e-6 and not in_curve:
                E1 = 0.5 * vt * vt
            n = emit(o, n, x[i] + u, v, t, mode)
            t += dt
            u += h
            E = E1
    n = emit(o, n, x[i1], 0.0, t, DWELL)
    n_out[0] = n
    return 0


def holding_segment(
    x, a0, a1, b0, b1, vhold, vtop, tscale, Py_ssize_t i0, Py_ssize_t i1, P, curves, tk, bk, rk, Cr, US,
    brake_modes, out_s, out_v, out_t, out_m, Py_ssize_t i_s=-1, double u_s=0.0, double v_s=0.0,
    double t_s=0.0,
):
    """The holding phases of the optimal strategy from standstill at x[i0] to the stop at x[i1].

    Maximum traction up to the holding speed ``vhold`` (V, or the limit where lower); hold it with
    partial traction; where holding would need more than maximum traction (steep uphill) keep
    maximum traction; where it would need braking (steep downhill) coast instead and let the speed
    rise, up to ``vtop`` (the limit, or the regenerative holding speed W), where the train holds
    with braking; after such a descent coast back down to ``vhold``; follow the braking curves
    (``Cr``/``US``, computed for ``vtop`` with ``brake_modes[i]`` per interval, indexed from i0) to
    lower limits and to the stop. Returns (n, status).
    With ``i_s`` >= 0 it starts from speed ``v_s`` at offset ``u_s`` of interval ``i_s``, time ``t_s``."""
    cdef Track tr = _track(x, a0, a1, b0, b1, None, tscale, i1)
    if not 0 <= i0 <= i1 or (i_s >= 0 and not i0 <= i_s <= i1):
        raise ValueError(f"intervals i0 {i0}, i1 {i1}, start {i_s}: need 0 <= i0 <= i1 and i_s < 0 or in [i0, i1]")
    cdef const double* pvh = _d(vhold, "vhold", i1)
    cdef const double* pvt = _d(vtop, "vtop", i1)
    cdef Curves cv
    cdef Ctx c
    _ctx(P, curves, &cv, &c)
    cdef Kinks ktk = _kinks(tk, "traction kinks tk"), kbk = _kinks(bk, "braking kinks bk")
    cdef Kinks krk = _kinks(rk, "regenerative kinks rk")
    cdef const double* pCr = _d(Cr, "Cr", i1 - i0)
    cdef const double* pUS = _d(US, "US", i1 - i0)
    cdef Arr am = _array(brake_modes, "brake_modes", c'q')
    if am.n < i1:
        raise ValueError(f"brake_modes of length {am.n}: need one per interval up to {i1}")
    cdef PO o = _out(out_s, out_v, out_t, out_m)
    cdef Py_ssize_t n
    cdef long status
    with nogil:
        status = holding_segment_c(
            &tr, pvh, pvt, i0, i1, &c, &ktk, &kbk, &krk, pCr, pUS, <const int64_t*>am.data, &o, i_s, u_s,
            v_s, t_s, &n,
        )
    return n, status
