# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True
"""Compiled (Cython) kernel of the fastest run: speed envelopes in the distance domain
(``fastest_segment``, ``braking_ceiling(_mixed)``, ``insert_kink_points`` and the integrators they
call, which the other compiled kernels cimport through ``_kernel_c.pxd``).

State: E = v^2 / 2 [m^2/s^2] over head position s [m], so that dE/ds = a is regular at standstill,
and time t with dt/ds = 1/v. Each grid interval has linear line-resistance laws (``Line``) and a
constant speed ceiling. The method (OSRD-style envelopes):

- a backward pass (``braking_ceiling_mixed_c``) builds the speed ceiling: the limits, and the
  braking curves integrated backwards from every drop of the limit and from the stop;
- a forward pass (``fastest_segment_c``) drives maximum traction under that ceiling, cruising at a
  limit while the traction can hold it, and brakes along the ceiling's braking curves;
- every event (a limit reached, the traction curve meeting a braking curve, a stall) is root-found
  inside its interval rather than left at a grid point.

The integrators: RK4 on dE/ds = a(E, s) in the distance domain, steps of at most one interval, slow
or strongly accelerated steps divided into sub-steps (``substeps``: near standstill E(s) meets the
square-root singularity of v); time from the cubic Hermite interpolant of E over each step
(``rk4_energy_time_1``), since ds / v is singular at rest (the fastest run integrates the steps
near standstill in the speed domain instead, ``speed_domain_step``); event distances by RK4 on
ds/dv = v / a in the speed domain (``distance_to_speed``: exact event location, no root finding). An
effort curve has kinks (table steps such as source 002's braking force jumping from 150 to 335 kN
between 5 and 6 km/h, the force and power caps): one RK4 step across a kink loses its accuracy, so
the kink-aware steps (``step_energy_c``, ``step_energy_time_c``) locate each kink in the speed domain
and restart there, and every piece between kinks evaluates the force on its own smooth branch
(``effort_branch`` in ``_forces.pxd``). Regime codes, parameter indices, tolerances and these
settings (LENGTH_SCALE_FRACTION, MAX_SUBSTEPS, TIME_SUBSTEPS, SPEED_DOMAIN_*) are those of
``trainsim.sim.codes`` (the compiled values are checked against it by a test).

Ported bit for bit from the numba kernel of the fastest run (issue 14, since removed): every
floating-point operation keeps the numba code's order and association (``a * b * c`` is
``(a * b) * c``; numba unrolled ``x**3`` with a constant exponent into ``x * (x * x)``;
``min(a, b)`` is ``b if b < a else a``, ``max(a, b)`` is ``b if b > a else a``, as numba evaluated
Python's min and max), and the module is compiled without fast-math or contraction into fused
multiply-adds (setup.py). The figures of the examples are those of the numba kernel, bit for bit
(``benchmarks/figures_snapshot.py``).

The ``def`` entry points take Python objects (arrays, the ``line`` 4-tuple, the 12-tuple of effort
curves, the parameter vector P); they check shapes and dtypes once, then run in C on pointers,
without the GIL and without reference counting.

A float division by zero gives inf or nan (numba raised ZeroDivisionError). The only unguarded
division that could meet a zero is the cruise's end where the traction stops holding the speed,
``(fmax - need_u) / (need_end - need_u)``, reached only when the resistance at both ends is the same
and above the traction by at most 1e-12 relative.
"""

from cpython.mem cimport PyMem_Free, PyMem_Malloc
from libc.math cimport INFINITY, isfinite, sqrt
from libc.stdint cimport int64_t

import numpy as np

# the structs, constants and inline helpers are declared in _kernel_c.pxd
from trainsim.sim._forces cimport (
    BRAKE,
    CRUISE,
    DWELL,
    N_PARAMS,
    P_BRAKE_FRACTION,
    P_DECEL,
    P_INERTIAL_MASS,
    P_TRACTION_SCALE,
    REGEN,
    TRACTION,
    Curve,
    effort,
    effort_branch,
    speed_domain_steps,
)

# Status of ``fastest_segment(..., grow=True)`` when its out arrays are full, and the settings of the
# speed-domain steps near standstill (trainsim.sim.codes; checked by a test)
cdef enum:
    STATUS_FULL = 2
    SLOW_STEP_SUBSTEPS = 32
    SLOW_STEP_SPEED_STEPS = 4
    SLOW_STEP_NEWTON = 8

cdef extern from *:
    """
    static const double TRAINSIM_SLOW_STEP_TOLERANCE = 1e-13;
    """
    const double SLOW_STEP_TOLERANCE "TRAINSIM_SLOW_STEP_TOLERANCE"


cdef struct StepKinks:
    # the kinks where one kink-aware step split (at most 64 pieces): offset into the interval [m],
    # speed [m/s], time since the step's start [s]
    double u[64]
    double v[64]
    double dt[64]
    int n


# ---------------------------------------------------------------------------------------------- forces


cdef double acceleration(
    long mode, double E, double u, const Line* line, const Ctx* c, double vref
) noexcept nogil:
    """dE/ds = acceleration [m/s^2] in regime ``mode`` at maximum effort, at E [m^2/s^2] and offset
    u [m] into the interval of ``line``: TRACTION with the traction curve times P[P_TRACTION_SCALE];
    BRAKE with the service braking curve times P[P_BRAKE_FRACTION], or the constant deceleration
    P[P_DECEL] [m/s^2] when that is > 0 (the resistance alone if it brakes harder); REGEN with the
    regenerative braking curve; any other regime (coasting) with the resistance alone. Divided by the
    inertial mass P[P_INERTIAL_MASS]. ``vref`` >= 0 selects the curves' smooth branch at that speed
    (``effort_branch``), < 0 the curve itself."""
    cdef double v = sqrt(2.0 * E) if E > 0.0 else 0.0
    cdef const double* P = c.P
    cdef double res = resistance_force(v, u, line, P)
    cdef double M = P[P_INERTIAL_MASS]
    cdef double a_res
    if mode == TRACTION:
        return (P[P_TRACTION_SCALE] * effort_branch(v, vref, &c.curves.traction) - res) / M
    if mode == BRAKE:
        if P[P_DECEL] > 0.0:
            a_res = res / M
            return -a_res if a_res > P[P_DECEL] else -P[P_DECEL]
        return -(P[P_BRAKE_FRACTION] * effort_branch(v, vref, &c.curves.brake) + res) / M
    if mode == REGEN:
        return -(effort_branch(v, vref, &c.curves.regen) + res) / M
    return -res / M


# ---------------------------------------------------------------------------------------- integrators


cdef inline double rk4_energy_1(
    double E, double u, double h, long mode, const Line* line, const Ctx* c, double vref, double k1
) noexcept nogil:
    """One RK4 step of E [m^2/s^2] over h [m] from offset u, with k1 the acceleration there."""
    cdef double k2 = acceleration(mode, E + 0.5 * h * k1, u + 0.5 * h, line, c, vref)
    cdef double k3 = acceleration(mode, E + 0.5 * h * k2, u + 0.5 * h, line, c, vref)
    cdef double k4 = acceleration(mode, E + h * k3, u + h, line, c, vref)
    return E + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


cdef double rk4_energy(
    double E, double u, double h, long mode, const Line* line, const Ctx* c, double vref
) noexcept nogil:
    """E [m^2/s^2] after a step h [m] (negative: backwards) from offset u; not clipped at 0. Slow
    steps are divided into sub-steps (``substeps``, LENGTH_SCALE_FRACTION)."""
    cdef double k1 = acceleration(mode, E, u, line, c, vref)
    return rk4_energy_from(E, u, h, mode, line, c, vref, k1, substeps(E, h, k1))


cdef inline double rk4_energy_from(
    double E, double u, double h, long mode, const Line* line, const Ctx* c, double vref, double k1, long n
) noexcept nogil:
    """``rk4_energy`` in n sub-steps, with k1 the acceleration at the start."""
    cdef double d = h / n
    cdef long j
    for j in range(n):
        if j > 0:
            k1 = acceleration(mode, E, u, line, c, vref)
        E = rk4_energy_1(E, u, d, mode, line, c, vref, k1)
        u += d
    return E


cdef ET rk4_energy_time_1(
    double E, double u, double h, long mode, const Line* line, const Ctx* c, double vref, double k1
) noexcept nogil:
    """(E [m^2/s^2], elapsed time [s]) after one forward RK4 step h [m] from offset u.

    Time is the integral of ds / v, singular at standstill. E(s) over the step is taken as the
    cubic Hermite interpolant of its end values and slopes (k1 and the acceleration at the end), and
    on each of TIME_SUBSTEPS sub-intervals, where E is nearly linear, dt = 2 ds / (v_a + v_b), exact
    for linear E (constant acceleration)."""
    cdef double k2 = acceleration(mode, E + 0.5 * h * k1, u + 0.5 * h, line, c, vref)
    cdef double k3 = acceleration(mode, E + 0.5 * h * k2, u + 0.5 * h, line, c, vref)
    cdef double k4 = acceleration(mode, E + h * k3, u + h, line, c, vref)
    cdef double E1 = E + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    cdef double d1 = acceleration(mode, E1 if E1 > 0.0 else 0.0, u + h, line, c, vref)
    cdef double dt = 0.0
    cdef double v_prev = sqrt(2.0 * E) if E > 0.0 else 0.0
    cdef double x, x2, x3, h00, h10, h01, h11, Ej, vj
    cdef long j
    for j in range(1, TIME_SUBSTEPS + 1):
        x = (<double>j) / (<double>TIME_SUBSTEPS)
        # x**2 as x * x and x**3 as x * (x * x), as numba unrolled them (same bits)
        x2 = x * x
        x3 = x * x2
        h00 = 2.0 * x3 - 3.0 * x2 + 1.0
        h10 = x3 - 2.0 * x2 + x
        h01 = -2.0 * x3 + 3.0 * x2
        h11 = x3 - x2
        Ej = h00 * E + h10 * h * k1 + h01 * E1 + h11 * h * d1
        vj = sqrt(2.0 * Ej) if Ej > 0.0 else 0.0
        if v_prev + vj > 0.0:
            dt += 2.0 * (h / (<double>TIME_SUBSTEPS)) / (v_prev + vj)
        else:
            dt += INFINITY
        v_prev = vj
    cdef ET r
    r.E = E1
    r.dt = dt
    return r


cdef ET rk4_energy_time(
    double E, double u, double h, long mode, const Line* line, const Ctx* c, double vref
) noexcept nogil:
    """(E [m^2/s^2], elapsed time [s]) after a forward step h [m] from offset u; slow steps are
    divided into sub-steps (``substeps``, LENGTH_SCALE_FRACTION), each as ``rk4_energy_time_1``."""
    cdef double k1 = acceleration(mode, E, u, line, c, vref)
    return rk4_energy_time_from(E, u, h, mode, line, c, vref, k1, substeps(E, h, k1))


cdef inline ET rk4_energy_time_from(
    double E, double u, double h, long mode, const Line* line, const Ctx* c, double vref, double k1, long n
) noexcept nogil:
    """``rk4_energy_time`` in n sub-steps, with k1 the acceleration at the start (at E unclipped)."""
    cdef double d = h / n
    cdef double total = 0.0
    cdef long j
    cdef ET r
    for j in range(n):
        E = E if E > 0.0 else 0.0
        if j > 0:
            k1 = acceleration(mode, E, u, line, c, vref)
        r = rk4_energy_time_1(E, u, d, mode, line, c, vref, k1)
        E = r.E
        total += r.dt
        u += d
    r.E = E
    r.dt = total
    return r


cdef bint speed_domain_step(
    double E, double u, double h, long mode, const Line* line, const Ctx* c, double vref, double a0,
    ET* out,
) noexcept nogil:
    """(E [m^2/s^2], elapsed time [s] (negative backwards)) after a step h [m] (negative: backwards)
    from offset u, integrated in the speed domain (ds/dv = v / a, dt/dv = 1 / a, both regular at low speed,
    where E(s) has the square-root singularity of standstill just behind it): RK4 from v0 to the speed
    the constant acceleration a0 [m/s^2] (the acceleration at the start) reaches after h, in as many
    steps as ``speed_domain_steps`` gives for an event location over those speeds (at least
    SLOW_STEP_SPEED_STEPS), then Newton steps on the end speed (each one more RK4
    step from the last speed by (h - s) a / v) until the distance is h to SLOW_STEP_TOLERANCE
    relative. Into ``out``; False (``out`` not valid) when the acceleration changes sign or vanishes at
    some stage, when the step ends near standstill (the speed below half its start: v(s) has its
    square-root singularity there) or when Newton does not converge: the caller integrates in the
    distance domain then."""
    cdef double v = sqrt(2.0 * E) if E > 0.0 else 0.0
    cdef double v2_end = v * v + 2.0 * a0 * h
    if not (a0 != 0.0 and h != 0.0 and v2_end > 0.25 * v * v):
        return False
    cdef double sign = 1.0 if a0 > 0.0 else -1.0
    cdef double v_end = sqrt(v2_end)
    # as many steps as an event location over these speeds takes, and at least SLOW_STEP_SPEED_STEPS
    cdef double a_end = acceleration(mode, 0.5 * v_end * v_end, u + h, line, c, vref)
    cdef long n = speed_domain_steps(v, v_end, a0, a_end)
    if n < SLOW_STEP_SPEED_STEPS:
        n = SLOW_STEP_SPEED_STEPS
    cdef double dv = (v_end - v) / n
    cdef double s = 0.0, t = 0.0, a, vm, ve, a1, a2, a3, a4
    cdef long it
    for it in range(n + SLOW_STEP_NEWTON):
        if it >= n:
            if fabs(h - s) <= SLOW_STEP_TOLERANCE * fabs(h):
                out.E = 0.5 * v * v
                out.dt = t
                return True
            a = acceleration(mode, 0.5 * v * v, u + s, line, c, vref)
            if not (a * sign > 0.0 and v > 0.0):
                return False
            dv = (h - s) * a / v
        a1 = acceleration(mode, 0.5 * v * v, u + s, line, c, vref)
        if not a1 * sign > 0.0:
            return False
        vm = v + 0.5 * dv
        a2 = acceleration(mode, 0.5 * vm * vm, u + s + 0.5 * dv * v / a1, line, c, vref)
        if not a2 * sign > 0.0:
            return False
        a3 = acceleration(mode, 0.5 * vm * vm, u + s + 0.5 * dv * vm / a2, line, c, vref)
        if not a3 * sign > 0.0:
            return False
        ve = v + dv
        a4 = acceleration(mode, 0.5 * ve * ve, u + s + dv * vm / a3, line, c, vref)
        if not a4 * sign > 0.0:
            return False
        s += dv / 6.0 * (v / a1 + 2.0 * vm / a2 + 2.0 * vm / a3 + ve / a4)
        t += dv / 6.0 * (1.0 / a1 + 2.0 / a2 + 2.0 / a3 + 1.0 / a4)
        v = ve
    return False


cdef double rk4_energy_s(
    double E, double u, double h, long mode, const Line* line, const Ctx* c, double vref, bint slow
) noexcept nogil:
    """``rk4_energy`` (forwards or backwards); with ``slow``, as ``rk4_energy_time_s``."""
    cdef double a0
    cdef long n
    cdef ET r
    if slow and E > 0.0:
        a0 = acceleration(mode, E, u, line, c, vref)
        n = substeps(E, h, a0)
        if n >= SLOW_STEP_SUBSTEPS and speed_domain_step(E, u, h, mode, line, c, vref, a0, &r):
            return r.E
        return rk4_energy_from(E, u, h, mode, line, c, vref, a0, n)
    return rk4_energy(E, u, h, mode, line, c, vref)


cdef ET rk4_energy_time_s(
    double E, double u, double h, long mode, const Line* line, const Ctx* c, double vref, bint slow
) noexcept nogil:
    """``rk4_energy_time``; with ``slow``, a step that it would divide into SLOW_STEP_SUBSTEPS sub-steps
    or more (near standstill) is integrated in the speed domain instead (``speed_domain_step``, which
    declines a step that ends near standstill), with far fewer force evaluations."""
    cdef double a0
    cdef long n
    cdef ET r
    if slow and E > 0.0:
        a0 = acceleration(mode, E, u, line, c, vref)
        n = substeps(E, h, a0)
        if n >= SLOW_STEP_SUBSTEPS and speed_domain_step(E, u, h, mode, line, c, vref, a0, &r):
            return r
        # the start's acceleration is the distance domain's k1: not evaluated twice
        return rk4_energy_time_from(E, u, h, mode, line, c, vref, a0, n)
    return rk4_energy_time(E, u, h, mode, line, c, vref)


cdef double distance_to_speed(
    double E, double u, double Et, long mode, const Line* line, const Ctx* c
) noexcept nogil:
    """Signed distance [m] from (u, E) along ``mode`` until E reaches Et [m^2/s^2], integrating
    ds/dv = v / a(v, s) by RK4 in the speed domain (exact event location, no root finding; regular
    down to standstill, and exact for a constant force), in ``speed_domain_steps`` steps. The law must
    be smooth between E and Et (no kink inside; it is evaluated on the branch of the speeds in
    between, vref their mean). Returns inf when the acceleration vanishes or changes sign on the
    way, i.e. Et is never reached."""
    cdef double v_from = sqrt(2.0 * E) if E > 0.0 else 0.0
    cdef double v_to = sqrt(2.0 * Et) if Et > 0.0 else 0.0
    cdef double vref = 0.5 * (v_from + v_to)
    cdef long n = speed_domain_steps(
        v_from,
        v_to,
        acceleration(mode, E, u, line, c, vref),
        acceleration(mode, Et, u, line, c, vref),
    )
    cdef double dv = (v_to - v_from) / n
    cdef double v = v_from
    cdef double s = 0.0
    cdef double sign = 0.0
    cdef double a1, a2, a3, a4, r1, r2, r3, r4, vm, ve
    cdef long k
    for k in range(n):
        a1 = acceleration(mode, 0.5 * v * v, u + s, line, c, vref)
        if sign == 0.0:
            sign = 1.0 if a1 > 0.0 else -1.0
        if a1 * sign <= 0.0:
            return INFINITY
        r1 = v / a1
        vm = v + 0.5 * dv
        a2 = acceleration(mode, 0.5 * vm * vm, u + s + 0.5 * dv * r1, line, c, vref)
        if a2 * sign <= 0.0:
            return INFINITY
        r2 = vm / a2
        a3 = acceleration(mode, 0.5 * vm * vm, u + s + 0.5 * dv * r2, line, c, vref)
        if a3 * sign <= 0.0:
            return INFINITY
        r3 = vm / a3
        ve = v + dv
        a4 = acceleration(mode, 0.5 * ve * ve, u + s + dv * r3, line, c, vref)
        if a4 * sign <= 0.0:
            return INFINITY
        r4 = ve / a4
        s += dv / 6.0 * (r1 + 2.0 * r2 + 2.0 * r3 + r4)
        v = ve
    return s


# ------------------------------------------------------------------------------------------------ kinks


cdef ET step_energy_time_c(
    double E, double u, double h, long mode, const Line* line, const Ctx* c, const Kinks* kinks
) noexcept nogil:
    """(E [m^2/s^2], elapsed time [s]) after a step h [m] from offset u, restarted at every kink
    of the effort curve on the way: one RK4 step across a kink (e.g. source 002's braking force
    jumping from 150 to 335 kN between 5 and 6 km/h) loses its accuracy, so the kink is located in
    the speed domain (``distance_to_speed``) and the step split there. A kink just beyond the step's
    end speed is looked for too (RK4 across it can land on either side), and a piece that starts at
    a kink or ends at one is integrated again on its own branch (vref the mean of its end speeds).
    At most 64 pieces."""
    return step_energy_time_k(E, u, h, mode, line, c, kinks, NULL, False)


cdef ET step_energy_time_k(
    double E, double u, double h, long mode, const Line* line, const Ctx* c, const Kinks* kinks,
    StepKinks* sk, bint slow,
) noexcept nogil:
    """``step_energy_time_c``, recording in ``sk`` (unless NULL) the kinks where it split the step:
    their offsets [m], speeds [m/s] and times since the step's start [s], in the order met (one pass:
    the kink points of the trace come from here instead of being located a second time)."""
    cdef double remaining = h
    cdef double total_dt = 0.0
    cdef bint split = is_kink(sqrt(2.0 * E) if E > 0.0 else 0.0, kinks)
    cdef ET r, rk
    cdef double v0, v1, v_far, vk, hk
    cdef bint rising
    cdef int it
    if sk != NULL:
        sk.n = 0
    for it in range(64):
        r = rk4_energy_time_s(E, u, remaining, mode, line, c, -1.0, slow)
        v0 = sqrt(2.0 * E) if E > 0.0 else 0.0
        v1 = sqrt(2.0 * r.E) if r.E > 0.0 else 0.0
        rising = v1 > v0
        v_far = v1 + 0.5 * (v1 - v0) + 1e-6 if rising else v1 - 0.5 * (v0 - v1) - 1e-6
        vk = next_kink(v0, rising, v_far, kinks)
        hk = INFINITY
        if vk >= 0.0:
            hk = distance_to_speed(E, u, 0.5 * vk * vk, mode, line, c)
        if not (hk * remaining > 0.0 and fabs(hk) < fabs(remaining) - POSITION_TOLERANCE):
            if split or vk >= 0.0:
                r = rk4_energy_time_s(E, u, remaining, mode, line, c, 0.5 * (v0 + v1), slow)
            r.dt = total_dt + r.dt
            return r
        split = True
        rk = rk4_energy_time_s(E, u, hk, mode, line, c, 0.5 * (v0 + vk), slow)
        total_dt += rk.dt
        E = 0.5 * vk * vk
        u += hk
        remaining -= hk
        if sk != NULL:
            sk.u[sk.n] = u
            sk.v[sk.n] = vk
            sk.dt[sk.n] = total_dt
            sk.n += 1
    r.dt = total_dt + r.dt
    return r


cdef void push_step_kinks(
    Out* o, const StepKinks* sk, double x0, double u0, double u1, double v0, double v1, double t0, long mode
) noexcept nogil:
    """Push the kink points ``sk`` of a step taken as the stretch from offset u0 to u1 [m] of the
    interval starting at x0 [m], at speeds v0 to v1 [m/s] as recorded, starting at time t0 [s]: those
    strictly inside the stretch in speed and in distance, up to the first that is not (the points
    ``insert_kink_points_c`` would add to that stretch, located once)."""
    cdef double lo = v1 if v1 < v0 else v0
    cdef double hi = v1 if v1 > v0 else v0
    cdef int q
    for q in range(sk.n):
        if not (lo < sk.v[q] < hi and u0 < sk.u[q] < u1):
            break
        push(o, x0 + sk.u[q], sk.v[q], t0 + sk.dt[q], mode)


cdef double step_energy_c(
    double E, double u, double h, long mode, const Line* line, const Ctx* c, const Kinks* kinks
) noexcept nogil:
    """E [m^2/s^2] after a kink-aware step h [m] (negative: backwards) from offset u; like
    ``step_energy_time_c`` without the time, for the backward braking curves."""
    return step_energy_k(E, u, h, mode, line, c, kinks, False)


cdef double step_energy_k(
    double E, double u, double h, long mode, const Line* line, const Ctx* c, const Kinks* kinks, bint slow
) noexcept nogil:
    """``step_energy_c``; with ``slow``, its steps near standstill in the speed domain (``rk4_energy_s``)."""
    cdef double remaining = h
    cdef double E1 = E
    cdef bint split = is_kink(sqrt(2.0 * E) if E > 0.0 else 0.0, kinks)
    cdef double v0, v1, v_far, vk, hk
    cdef bint rising
    cdef int it
    for it in range(64):
        E1 = rk4_energy_s(E, u, remaining, mode, line, c, -1.0, slow)
        v0 = sqrt(2.0 * E) if E > 0.0 else 0.0
        v1 = sqrt(2.0 * E1) if E1 > 0.0 else 0.0
        rising = v1 > v0
        v_far = v1 + 0.5 * (v1 - v0) + 1e-6 if rising else v1 - 0.5 * (v0 - v1) - 1e-6
        vk = next_kink(v0, rising, v_far, kinks)
        hk = INFINITY
        if vk >= 0.0:
            hk = distance_to_speed(E, u, 0.5 * vk * vk, mode, line, c)
        if not (hk * remaining > 0.0 and fabs(hk) < fabs(remaining) - POSITION_TOLERANCE):
            if split or vk >= 0.0:
                E1 = rk4_energy_s(E, u, remaining, mode, line, c, 0.5 * (v0 + v1), slow)
            return E1
        split = True
        E = 0.5 * vk * vk
        u += hk
        remaining -= hk
    return E1


cdef double find_speed_crossing_split_c(
    double E, double u, double H, double target_E, long mode, const Line* line, const Ctx* c,
    const Kinks* kinks,
) noexcept nogil:
    """Signed distance [m] in (0, H] (H may be negative) where E reaches target_E along ``mode``,
    chaining speed-domain integrations (``distance_to_speed``) across the kinks in between; H if it
    is not reached."""
    cdef double v_t = sqrt(2.0 * target_E) if target_E > 0.0 else 0.0
    cdef double v = sqrt(2.0 * E) if E > 0.0 else 0.0
    cdef bint rising = v_t > v
    cdef double total = 0.0
    cdef double vk, Ek, hk
    cdef int it
    for it in range(64):
        vk = next_kink(v, rising, v_t, kinks)
        Ek = 0.5 * vk * vk if vk >= 0.0 else target_E
        hk = distance_to_speed(E, u + total, Ek, mode, line, c)
        if not isfinite(hk):
            return H
        total += hk
        if vk < 0.0:
            break
        E = Ek
        v = vk
    if total * H <= 0.0 or fabs(total) > fabs(H):
        return H
    return total


cdef double find_curve_meeting(
    double E, double u, double Er, double w, const Line* line, const Ctx* c, const Kinks* tk,
    const Kinks* bk,
) noexcept nogil:
    """Offset [m] in (u, w] where the traction curve from (u, E) meets the braking curve ending at
    (w, Er) (Illinois method on their difference, both curves by kink-aware steps; to within
    POSITION_TOLERANCE, at most 100 iterations)."""
    return find_curve_meeting_k(E, u, Er, w, line, c, tk, bk, False)


cdef double find_curve_meeting_k(
    double E, double u, double Er, double w, const Line* line, const Ctx* c, const Kinks* tk,
    const Kinks* bk, bint slow,
) noexcept nogil:
    """``find_curve_meeting``; with ``slow``, its steps near standstill in the speed domain."""
    cdef double lo = u, hi = w
    cdef double f_lo = E - step_energy_k(Er, w, u - w, BRAKE, line, c, bk, slow)
    cdef double f_hi = step_energy_k(E, u, w - u, TRACTION, line, c, tk, slow) - Er
    cdef int side = 0
    cdef double x = hi
    cdef double f
    cdef int it
    for it in range(100):
        if f_hi == f_lo:
            break
        x = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
        f = step_energy_k(E, u, x - u, TRACTION, line, c, tk, slow) - step_energy_k(
            Er, w, x - w, BRAKE, line, c, bk, slow
        )
        if (f > 0.0) == (f_hi > 0.0):
            hi = x
            f_hi = f
            if side == 1:
                f_lo *= 0.5
            side = 1
        else:
            lo = x
            f_lo = f
            if side == -1:
                f_hi *= 0.5
            side = -1
        if fabs(hi - lo) < POSITION_TOLERANCE or f == 0.0:
            break
    return x


# --------------------------------------------------------------------------------------------- passes


cdef void braking_ceiling_mixed_c(
    const Track* tr, Py_ssize_t i0, Py_ssize_t i1, const Ctx* c, const Kinks* bk, const Kinks* rk,
    const int64_t* modes, long mode_all, double* Cr, double* Cl, double* US,
) noexcept nogil:
    """Backward pass from standstill at x[i1] to x[i0]: the speed ceiling made of the limits and
    the braking curves to every lower limit and to the stop. For interval k = i - i0 it is the limit
    vlim[i] on offsets below US[k] [m] and the braking curve ending at (width, Cr[k]) above; Cl[k] is
    its value at the interval's start [m/s]. Interval i brakes in mode ``modes[i]`` (BRAKE: service
    braking, with the kinks ``bk``; REGEN: regenerative braking only, for energy-efficient approaches
    to lower limits, with the kinks ``rk``); with ``modes`` NULL every interval's mode is
    ``mode_all``. Writes Cr, Cl, US (i1 - i0 values each)."""
    braking_ceiling_k(tr, i0, i1, c, bk, rk, modes, mode_all, Cr, Cl, US, False)


cdef void braking_ceiling_k(
    const Track* tr, Py_ssize_t i0, Py_ssize_t i1, const Ctx* c, const Kinks* bk, const Kinks* rk,
    const int64_t* modes, long mode_all, double* Cr, double* Cl, double* US, bint slow,
) noexcept nogil:
    """``braking_ceiling_mixed_c``; with ``slow``, its steps near standstill in the speed domain."""
    cdef Py_ssize_t m_int = i1 - i0
    cdef double c_next = 0.0
    cdef Py_ssize_t k, i
    cdef double w, cr, Er, El, vl, vlim_i, h
    cdef Line line
    cdef long mode
    cdef const Kinks* kinks
    for k in range(m_int - 1, -1, -1):
        i = i0 + k
        w = tr.x[i + 1] - tr.x[i]
        vlim_i = tr.vlim[i]
        cr = c_next if c_next < vlim_i else vlim_i
        Er = 0.5 * cr * cr
        line = line_of(tr, i)
        mode = modes[i] if modes != NULL else mode_all
        kinks = bk if mode == BRAKE else rk
        if cr >= vlim_i and (
            acceleration(mode, Er, 0.0, &line, c, -1.0) < 0.0
            and acceleration(mode, Er, w, &line, c, -1.0) < 0.0
        ):
            # braking backwards from the limit only rises above it: the whole interval is at the limit
            US[k] = w
            Cl[k] = vlim_i
            Cr[k] = cr
            c_next = vlim_i
            continue
        El = step_energy_k(Er, w, -w, mode, &line, c, kinks, slow)
        vl = sqrt(2.0 * El) if El > 0.0 else 0.0
        if vl <= vlim_i:
            US[k] = 0.0
            Cl[k] = vl
        else:
            if cr >= vlim_i - SPEED_TOLERANCE:
                US[k] = w
            else:
                h = find_speed_crossing_split_c(Er, w, -w, 0.5 * vlim_i * vlim_i, mode, &line, c, kinks)
                US[k] = w + h
            Cl[k] = vlim_i
        Cr[k] = cr
        c_next = Cl[k]


cdef long fastest_segment_c(
    const Track* tr, Py_ssize_t i0, Py_ssize_t i1, double t0, const Ctx* c, const Kinks* tk,
    const Kinks* bk, Out* o, double* Cr, double* Cl, double* US, double* stall_at,
) noexcept nogil:
    """Fastest run from standstill at x[i0] to standstill at x[i1] [m], starting at time t0 [s]:
    the braking ceiling (``braking_ceiling_mixed_c``, service braking), then maximum traction
    forwards under it, cruising at a limit as long as the traction can hold the speed, the meeting
    with a braking curve root-found (``find_curve_meeting``), braking along the ceiling's curves. The
    points (s, v, t, regime of the stretch that starts there) are appended to ``o``, ending with a
    DWELL point at the stop. Returns STATUS_OK, or STATUS_STALLED with the stall position [m] in
    ``stall_at`` (the traction cannot overcome the resistance). Writes P[P_TRACTION_SCALE] per
    interval. Cr, Cl, US: scratch of i1 - i0 values each."""
    return fastest_segment_k(tr, i0, i1, t0, c, tk, bk, o, Cr, Cl, US, stall_at, False, False)


cdef long fastest_segment_k(
    const Track* tr, Py_ssize_t i0, Py_ssize_t i1, double t0, const Ctx* c, const Kinks* tk,
    const Kinks* bk, Out* o, double* Cr, double* Cl, double* US, double* stall_at, bint kink_points,
    bint slow,
) noexcept nogil:
    """``fastest_segment_c``; with ``kink_points``, also a point wherever a traction or braking
    stretch crosses a kink of its effort curve, taken from the kink-aware steps that located it
    (``step_energy_time_k``; the points ``insert_kink_points_c`` adds to the trace without them);
    with ``slow``, accelerating steps near standstill in the speed domain (``rk4_energy_time_s``)."""
    cdef Py_ssize_t m_int = i1 - i0
    cdef double* P = c.P
    braking_ceiling_k(tr, i0, i1, c, bk, bk, NULL, BRAKE, Cr, Cl, US, slow)
    cdef double v = 0.0
    cdef double t = t0
    cdef Py_ssize_t k, i
    cdef double w, vl_i, u, E, end, need_u, need_end, fmax, stop_at, h, v1, Er, Eb, xm, xi
    cdef Line line
    cdef ET r, rm
    # kinks of the trial step (r) and of the step taken instead (rm); NULL: none recorded
    cdef StepKinks ka, kb
    cdef StepKinks* pa = &ka if kink_points else NULL
    cdef StepKinks* pb = &kb if kink_points else NULL
    for k in range(m_int):
        i = i0 + k
        xi = tr.x[i]
        w = tr.x[i + 1] - xi
        line = line_of(tr, i)
        vl_i = tr.vlim[i]
        P[P_TRACTION_SCALE] = tr.tscale[i]
        u = 0.0
        while u < w:
            E = 0.5 * v * v
            if u < US[k]:
                end = US[k]
                if v >= vl_i - SPEED_TOLERANCE:
                    v = vl_i
                    # cruise as long as the traction can hold the speed
                    need_u = resistance_force(v, u, &line, P)
                    need_end = resistance_force(v, end, &line, P)
                    fmax = P[P_TRACTION_SCALE] * effort(v, &c.curves.traction)
                    if need_u > fmax * (1.0 + 1e-12):
                        stop_at = u
                    elif need_end > fmax:
                        stop_at = u + (end - u) * (fmax - need_u) / (need_end - need_u)
                    else:
                        stop_at = end
                    if stop_at > u:
                        push(o, xi + u, v, t, CRUISE)
                        t += (stop_at - u) / v
                        u = stop_at
                        continue
                # traction towards the end of this part
                r = step_energy_time_k(E, u, end - u, TRACTION, &line, c, tk, pa, slow)
                if r.E <= 0.0:
                    h = find_speed_crossing_split_c(E, u, end - u, 0.0, TRACTION, &line, c, tk)
                    push(o, xi + u, v, t, TRACTION)
                    if kink_points:
                        stretch_kink_points(&line, c, tk, TRACTION, xi, u, v, 0.0, t, h, o)
                    push(o, xi + u + h, 0.0, t + (2.0 * h / v if v > 0 else 0.0), TRACTION)
                    stall_at[0] = xi + u + h
                    return STATUS_STALLED
                v1 = sqrt(2.0 * r.E)
                push(o, xi + u, v, t, TRACTION)
                if v1 > vl_i and v < vl_i:
                    h = find_speed_crossing_split_c(E, u, end - u, 0.5 * vl_i * vl_i, TRACTION, &line, c, tk)
                    rm = step_energy_time_k(E, u, h, TRACTION, &line, c, tk, pb, slow)
                    if kink_points:
                        push_step_kinks(o, pb, xi, u, u + h, v, vl_i, t, TRACTION)
                    t += rm.dt
                    u += h
                    v = vl_i
                else:
                    if kink_points:
                        push_step_kinks(o, pa, xi, u, end, v, vl_i if vl_i < v1 else v1, t, TRACTION)
                    t += r.dt
                    u = end
                    v = vl_i if vl_i < v1 else v1
            else:
                # under the braking curve that ends at (w, Cr[k])
                Er = 0.5 * Cr[k] * Cr[k]
                Eb = step_energy_k(Er, w, u - w, BRAKE, &line, c, bk, slow)
                if Eb * (1.0 - 1e-9) - 1e-12 > E:
                    r = step_energy_time_k(E, u, w - u, TRACTION, &line, c, tk, pa, slow)
                    push(o, xi + u, v, t, TRACTION)
                    if Er < r.E:
                        xm = find_curve_meeting_k(E, u, Er, w, &line, c, tk, bk, slow)
                        rm = step_energy_time_k(E, u, xm - u, TRACTION, &line, c, tk, pb, slow)
                        if kink_points:
                            push_step_kinks(
                                o, pb, xi, u, xm, v, sqrt(2.0 * rm.E) if rm.E > 0 else 0.0, t, TRACTION
                            )
                        t += rm.dt
                        u = xm
                        v = sqrt(2.0 * rm.E) if rm.E > 0 else 0.0
                        continue
                    if r.E <= 0.0:
                        stall_at[0] = xi + u
                        return STATUS_STALLED
                    if kink_points:
                        push_step_kinks(o, pa, xi, u, w, v, sqrt(2.0 * r.E), t, TRACTION)
                    t += r.dt
                    u = w
                    v = sqrt(2.0 * r.E)
                else:
                    push(o, xi + u, v, t, BRAKE)
                    r = step_energy_time_k(0.5 * v * v, u, w - u, BRAKE, &line, c, bk, pa, slow)
                    if kink_points:
                        push_step_kinks(o, pa, xi, u, w, v, Cr[k], t, BRAKE)
                    t += r.dt
                    u = w
                    v = Cr[k]
    push(o, tr.x[i1], 0.0, t, DWELL)
    stall_at[0] = 0.0
    return STATUS_OK


cdef void stretch_kink_points(
    const Line* line, const Ctx* c, const Kinks* kinks, long mode, double x0, double u, double v0,
    double v1, double t0, double length, Out* o,
) noexcept nogil:
    """Push a point wherever the stretch in ``mode`` from offset u [m] of the interval starting at
    x0 [m], at speed v0 and time t0, to speed v1 [m/s] after ``length`` [m] crosses a kink of its
    effort curve: located by ``distance_to_speed``, its time by ``rk4_energy_time`` on the piece's
    branch; at most ``kinks_between`` points."""
    cdef Py_ssize_t nk = kinks_between(v0, v1, kinks)
    cdef Py_ssize_t q
    cdef double E = 0.5 * v0 * v0
    cdef double time = t0, remaining = length, vc = v0, vk, hk
    cdef bint rising = v1 > v0
    cdef ET r
    for q in range(nk):
        vk = next_kink(vc, rising, v1, kinks)
        if vk < 0.0:
            break
        hk = distance_to_speed(E, u, 0.5 * vk * vk, mode, line, c)
        if not (0.0 < hk < remaining):
            break
        r = rk4_energy_time(E, u, hk, mode, line, c, 0.5 * (vc + vk))
        E = 0.5 * vk * vk
        u += hk
        remaining -= hk
        time += r.dt
        vc = vk
        push(o, x0 + u, vk, time, mode)


cdef Py_ssize_t insert_kink_points_c(
    const Track* tr, const Ctx* c, const Kinks* tk, const Kinks* bk, const double* s, const double* v,
    const double* t, const signed char* m, Py_ssize_t n, Out* o,
) noexcept nogil:
    """Copy the trace (s, v, t, m) of n points into ``o``, adding a point wherever a traction or
    braking stretch crosses a kink of its effort curve (``stretch_kink_points``), so that trapezoidal
    work integrals over the trace are exact at kinks. ``o`` is sized by ``kinks_between``'s count,
    and never more points are added. Writes P[P_TRACTION_SCALE]. Returns the points written.
    (The fastest run has its kernel emit these points as it steps: ``fastest_segment_k``.)"""
    cdef Py_ssize_t n_int = tr.n
    cdef Py_ssize_t k, i, ix
    cdef const Kinks* kinks
    cdef long mode
    cdef Line line
    for k in range(n):
        push(o, s[k], v[k], t[k], m[k])
        mode = m[k]
        if k == n - 1 or (mode != TRACTION and mode != BRAKE):
            continue
        kinks = tk if mode == TRACTION else bk
        if kinks_between(v[k], v[k + 1], kinks) == 0:
            continue
        i = search_right(tr.x, n_int + 1, s[k]) - 1
        if i > n_int - 1:
            i = n_int - 1
        # index -1 is the last element, as numba indexed it (a point before the grid's start): each
        # array wraps by its own length
        ix = i if i >= 0 else i + n_int + 1
        if i < 0:
            i += n_int
        c.P[P_TRACTION_SCALE] = tr.tscale[i]
        line = line_of(tr, i)
        stretch_kink_points(
            &line, c, kinks, mode, tr.x[ix], s[k] - tr.x[ix], v[k], v[k + 1], t[k], s[k + 1] - s[k], o
        )
    return o.n


# ----------------------------------------------------------------------------------- Python entry points
# The arrays are read through the buffer protocol once per call (a typed memoryview per argument cost
# about 1 us each, twice numba's whole dispatch): pointer and shape checked, the buffer released at
# once. The pointers stay valid for the call because the caller holds the arrays and numpy frees an
# array's data only with the array.

# (``Arr``, ``_array``: trainsim/_cbuffers.pxd; ``_kinks``, ``_line``: _kernel_c.pxd)


cdef int _curves(object curves, Curves* out) except -1:
    """Fill ``out`` from the kernel's 12-tuple ``(ts, tc, tf, tp, bs, bc, bf, bp, rs, rc, rf, rp)``
    (as ``_forces.curves_from``, with the cheaper array access above)."""
    if len(curves) != 12:
        raise ValueError(
            f"effort curves of length {len(curves)}: need the 12-tuple of three (starts, coefs, fcap, pcap)"
        )
    cdef Curve* k
    cdef Arr st, co
    cdef int q
    for q in range(3):
        k = &out.traction if q == 0 else &out.brake if q == 1 else &out.regen
        st = _array(curves[4 * q], "effort curve starts", c'd')
        co = _array(curves[4 * q + 1], "effort curve coefficients", c'd', 2)
        if st.n == 0 or co.n != st.n or co.cols != 4:
            raise ValueError(
                f"effort curve arrays of shapes ({st.n},) and ({co.n}, {co.cols}): "
                "need (n,) and (n, 4), n >= 1"
            )
        k.starts = <const double*>st.data
        k.coefs = <const double*>co.data
        k.n = st.n
        k.fcap = curves[4 * q + 2]
        k.pcap = curves[4 * q + 3]
    return 0


cdef Track _track(x, a0, a1, b0, b1, vlim, tscale, Py_ssize_t need) except *:
    """The compiled track's arrays as a Track (``vlim`` may be None); raises unless x has one more
    point than the interval arrays and they hold at least ``need`` intervals."""
    cdef Arr ax = _array(x, "track x", c'd'), aa0 = _array(a0, "track a0", c'd')
    cdef Arr aa1 = _array(a1, "track a1", c'd'), ab0 = _array(b0, "track b0", c'd')
    cdef Arr ab1 = _array(b1, "track b1", c'd'), ats = _array(tscale, "track traction_scale", c'd')
    cdef Arr avl
    avl.data = NULL
    avl.n = aa0.n
    if vlim is not None:
        avl = _array(vlim, "track vlim", c'd')
    cdef Py_ssize_t n = aa0.n
    if aa1.n != n or ab0.n != n or ab1.n != n or ats.n != n or avl.n != n or ax.n != n + 1:
        raise ValueError(
            f"track arrays of lengths x {ax.n}, a0 {n}, a1 {aa1.n}, b0 {ab0.n}, b1 {ab1.n}, "
            f"traction_scale {ats.n}, vlim {avl.n}: need one length n for the intervals and n + 1 for x"
        )
    if n < need:
        raise ValueError(f"the track has {n} intervals, the call needs {need}")
    cdef Track tr
    tr.x = <const double*>ax.data
    tr.a0 = <const double*>aa0.data
    tr.a1 = <const double*>aa1.data
    tr.b0 = <const double*>ab0.data
    tr.b1 = <const double*>ab1.data
    tr.vlim = <const double*>avl.data
    tr.tscale = <const double*>ats.data
    tr.n = n
    return tr


cdef int _ctx(object P, object curves, Curves* cv, Ctx* c) except -1:
    """The parameter vector (written: P_TRACTION_SCALE) and the curves as a Ctx."""
    cdef Arr ap = _array(P, "parameter vector P", c'd', 1, True)
    if ap.n != N_PARAMS:
        raise ValueError(f"parameter vector P of length {ap.n}: need {N_PARAMS} (trainsim.sim.codes)")
    _curves(curves, cv)
    c.P = <double*>ap.data
    c.curves = cv
    return 0


def fastest_segment(
    x, a0, a1, b0, b1, vlim, tscale, Py_ssize_t i0, Py_ssize_t i1, double t0, P, curves, tk, bk,
    out_s, out_v, out_t, out_m, Py_ssize_t n, *, bint kink_points=False, bint grow=False,
    bint slow_steps=False,
):
    """Fastest run from standstill at x[i0] to standstill at x[i1] [m], starting at time t0 [s];
    appends points to the out arrays (float64, regimes int8) from index n. Returns
    ``(new n, status, position of a stall [m])`` (STATUS_OK and 0.0, or STATUS_STALLED); see
    ``fastest_segment_c``. Writes P[P_TRACTION_SCALE] per interval.

    ``kink_points``: also a point wherever a traction or braking stretch crosses a kink of its effort
    curve (what ``insert_kink_points`` adds afterwards, found here by the steps that locate the kinks
    anyway). ``grow``: out arrays too short give ``(n, STATUS_FULL, nan)`` (n as given: nothing
    past it is valid) for the caller to run the segment again with longer ones, instead of an error.
    ``slow_steps``: accelerating steps near standstill integrated in the speed domain
    (``rk4_energy_time_s``: the same motion with a fraction of the force evaluations)."""
    cdef Track tr = _track(x, a0, a1, b0, b1, vlim, tscale, i1)
    cdef Curves cv
    cdef Ctx c
    _ctx(P, curves, &cv, &c)
    if not 0 <= i0 <= i1:
        raise ValueError(f"segment from interval {i0} to {i1}: need 0 <= i0 <= i1")
    cdef Arr os_ = _array(out_s, "out_s", c'd', 1, True), ov = _array(out_v, "out_v", c'd', 1, True)
    cdef Arr ot = _array(out_t, "out_t", c'd', 1, True), om = _array(out_m, "out_m", c'b', 1, True)
    cdef Py_ssize_t cap = os_.n
    if ov.n != cap or ot.n != cap or om.n != cap:
        raise ValueError(
            f"the out arrays s, v, t, m of lengths {cap}, {ov.n}, {ot.n}, {om.n}: need one length"
        )
    if not 0 <= n <= cap:
        raise ValueError(f"start index n = {n} outside the out arrays (length {cap})")
    cdef Kinks ktk = _kinks(tk, "traction kinks tk"), kbk = _kinks(bk, "braking kinks bk")
    cdef Out o
    o.s = <double*>os_.data
    o.v = <double*>ov.data
    o.t = <double*>ot.data
    o.m = <signed char*>om.data
    o.n = n
    o.cap = cap
    o.overflow = False
    cdef Py_ssize_t m_int = i1 - i0
    cdef double* sc = <double*>PyMem_Malloc((3 * m_int + 1) * sizeof(double))
    if sc == NULL:
        raise MemoryError()
    cdef double stall_at = 0.0
    cdef long status
    try:
        with nogil:
            status = fastest_segment_k(
                &tr, i0, i1, t0, &c, &ktk, &kbk, &o, sc, sc + m_int, sc + 2 * m_int, &stall_at, kink_points,
                slow_steps,
            )
    finally:
        PyMem_Free(sc)
    if o.overflow and grow:
        return n, STATUS_FULL, float("nan")
    if o.overflow:
        raise ValueError(f"the out arrays (length {cap}) are too short for the segment's trace")
    return o.n, status, stall_at


cdef tuple _braking_ceiling(
    const Track* tr, Py_ssize_t i0, Py_ssize_t i1, object P, object curves, object bk, object rk,
    const int64_t* modes, long mode,
):
    cdef Curves cv
    cdef Ctx c
    _ctx(P, curves, &cv, &c)
    if not 0 <= i0 <= i1:
        raise ValueError(f"intervals from {i0} to {i1}: need 0 <= i0 <= i1")
    cdef Kinks kb = _kinks(bk, "braking kinks bk"), kr = _kinks(rk, "regenerative kinks rk")
    cdef Py_ssize_t m_int = i1 - i0
    Cr = np.empty(m_int)
    Cl = np.empty(m_int)
    US = np.empty(m_int)
    cdef double* pr = <double*>_array(Cr, "Cr", c'd', 1, True).data
    cdef double* pl = <double*>_array(Cl, "Cl", c'd', 1, True).data
    cdef double* pu = <double*>_array(US, "US", c'd', 1, True).data
    if m_int > 0:
        with nogil:
            braking_ceiling_mixed_c(tr, i0, i1, &c, &kb, &kr, modes, mode, pr, pl, pu)
    return Cr, Cl, US


def braking_ceiling_mixed(x, a0, a1, b0, b1, vlim, Py_ssize_t i0, Py_ssize_t i1, P, curves, bk, rk, modes):
    """``(Cr, Cl, US)`` of the backward pass from standstill at x[i1] to x[i0], each interval in its
    mode ``modes[i]`` (int64, BRAKE or REGEN), ``bk`` and ``rk`` the kinks of the service and of the
    regenerative braking curve; see ``braking_ceiling_mixed_c`` for the result."""
    cdef Track tr = _track(x, a0, a1, b0, b1, vlim, a0, i1)
    cdef Arr am = _array(modes, "modes", c'q')
    if am.n < i1:
        raise ValueError(f"modes of length {am.n}: need one per interval up to {i1}")
    return _braking_ceiling(&tr, i0, i1, P, curves, bk, rk, <const int64_t*>am.data, BRAKE)


def braking_ceiling(x, a0, a1, b0, b1, vlim, Py_ssize_t i0, Py_ssize_t i1, P, curves, bk, long mode=BRAKE):
    """``(Cr, Cl, US)`` of the backward pass in one ``mode`` (BRAKE or REGEN) with ``bk`` that
    curve's kinks; see ``braking_ceiling_mixed_c`` for the result."""
    cdef Track tr = _track(x, a0, a1, b0, b1, vlim, a0, i1)
    return _braking_ceiling(&tr, i0, i1, P, curves, bk, bk, NULL, mode)


def insert_kink_points(x, a0, a1, b0, b1, tscale, P, curves, tk, bk, s, v, t, m):
    """The trace (s [m], v [m/s], t [s], regime m as int8) with a point added wherever a traction or
    braking stretch crosses a kink of its effort curve, so that trapezoidal work integrals over the
    trace are exact at kinks (new arrays; writes P[P_TRACTION_SCALE]); see ``insert_kink_points_c``."""
    cdef Track tr = _track(x, a0, a1, b0, b1, None, tscale, 1)
    cdef Curves cv
    cdef Ctx c
    _ctx(P, curves, &cv, &c)
    cdef Arr as_ = _array(s, "trace s", c'd'), av = _array(v, "trace v", c'd')
    cdef Arr at = _array(t, "trace t", c'd'), am = _array(m, "trace regimes m", c'b')
    cdef Py_ssize_t n = as_.n
    if av.n != n or at.n != n or am.n != n:
        raise ValueError(f"trace arrays of lengths s {n}, v {av.n}, t {at.n}, m {am.n}: need one length")
    cdef const double* ps = <const double*>as_.data
    cdef const double* pv = <const double*>av.data
    cdef const double* pt = <const double*>at.data
    cdef const signed char* pm = <const signed char*>am.data
    cdef Kinks ktk = _kinks(tk, "traction kinks tk"), kbk = _kinks(bk, "braking kinks bk")
    cdef Py_ssize_t extra = 0, k
    with nogil:
        for k in range(n - 1):
            if pm[k] == TRACTION:
                extra += kinks_between(pv[k], pv[k + 1], &ktk)
            elif pm[k] == BRAKE:
                extra += kinks_between(pv[k], pv[k + 1], &kbk)
    out_s = np.empty(n + extra)
    out_v = np.empty(n + extra)
    out_t = np.empty(n + extra)
    out_m = np.empty(n + extra, dtype=np.int8)
    cdef Out o
    o.s = <double*>_array(out_s, "out_s", c'd', 1, True).data
    o.v = <double*>_array(out_v, "out_v", c'd', 1, True).data
    o.t = <double*>_array(out_t, "out_t", c'd', 1, True).data
    o.m = <signed char*>_array(out_m, "out_m", c'b', 1, True).data
    o.n = 0
    o.cap = n + extra
    o.overflow = False
    cdef Py_ssize_t j = 0
    with nogil:
        j = insert_kink_points_c(&tr, &c, &ktk, &kbk, ps, pv, pt, pm, n, &o)
    return out_s[:j], out_v[:j], out_t[:j], out_m[:j]


def acceleration_of(long mode, double E, double u, line, P, curves, double vref=-1.0):
    """dE/ds [m/s^2] of the cdef ``acceleration`` (for the optimiser and tests)."""
    cdef Curves cv
    cdef Ctx c
    _ctx(P, curves, &cv, &c)
    cdef Line ln = _line(line)
    return acceleration(mode, E, u, &ln, &c, vref)


def rk4_energy_of(double E, double u, double h, long mode, line, P, curves, double vref=-1.0):
    """E [m^2/s^2] after the RK4 step of the cdef ``rk4_energy`` (for tests)."""
    cdef Curves cv
    cdef Ctx c
    _ctx(P, curves, &cv, &c)
    cdef Line ln = _line(line)
    return rk4_energy(E, u, h, mode, &ln, &c, vref)


def rk4_energy_time_of(double E, double u, double h, long mode, line, P, curves, double vref=-1.0):
    """(E [m^2/s^2], elapsed time [s]) of the cdef ``rk4_energy_time`` (for tests)."""
    cdef Curves cv
    cdef Ctx c
    _ctx(P, curves, &cv, &c)
    cdef Line ln = _line(line)
    cdef ET r = rk4_energy_time(E, u, h, mode, &ln, &c, vref)
    return r.E, r.dt


def rk4_energy_time_slow_of(double E, double u, double h, long mode, line, P, curves, double vref=-1.0):
    """(E [m^2/s^2], elapsed time [s]) of the cdef ``rk4_energy_time_s`` with speed-domain steps near
    standstill, and whether the speed domain was used (for tests)."""
    cdef Curves cv
    cdef Ctx c
    _ctx(P, curves, &cv, &c)
    cdef Line ln = _line(line)
    cdef ET r = rk4_energy_time_s(E, u, h, mode, &ln, &c, vref, True)
    cdef ET q
    cdef double a0 = acceleration(mode, E, u, &ln, &c, vref)
    cdef bint used = (
        E > 0.0 and substeps(E, h, a0) >= SLOW_STEP_SUBSTEPS
        and speed_domain_step(E, u, h, mode, &ln, &c, vref, a0, &q)
    )
    return r.E, r.dt, used


def rk4_energy_slow_of(double E, double u, double h, long mode, line, P, curves, double vref=-1.0):
    """(E [m^2/s^2], whether the speed domain was used) of the cdef ``rk4_energy_s`` (forwards or
    backwards; for tests)."""
    cdef Curves cv
    cdef Ctx c
    _ctx(P, curves, &cv, &c)
    cdef Line ln = _line(line)
    cdef ET q
    cdef double a0 = acceleration(mode, E, u, &ln, &c, vref)
    cdef bint used = (
        E > 0.0 and substeps(E, h, a0) >= SLOW_STEP_SUBSTEPS
        and speed_domain_step(E, u, h, mode, &ln, &c, vref, a0, &q)
    )
    return rk4_energy_s(E, u, h, mode, &ln, &c, vref, True), used


def distance_to_speed_of(double E, double u, double Et, long mode, line, P, curves):
    """Signed distance [m] of the cdef ``distance_to_speed`` (inf: never reached; for tests)."""
    cdef Curves cv
    cdef Ctx c
    _ctx(P, curves, &cv, &c)
    cdef Line ln = _line(line)
    return distance_to_speed(E, u, Et, mode, &ln, &c)


def step_energy_time(double E, double u, double h, long mode, line, P, curves, kinks):
    """(E [m^2/s^2], elapsed time [s]) after a kink-aware step h [m]; see ``step_energy_time_c``."""
    cdef Curves cv
    cdef Ctx c
    _ctx(P, curves, &cv, &c)
    cdef Line ln = _line(line)
    cdef Kinks k = _kinks(kinks)
    cdef ET r = step_energy_time_c(E, u, h, mode, &ln, &c, &k)
    return r.E, r.dt


def step_energy(double E, double u, double h, long mode, line, P, curves, kinks):
    """E [m^2/s^2] after a kink-aware step h [m] (negative: backwards); see ``step_energy_c``."""
    cdef Curves cv
    cdef Ctx c
    _ctx(P, curves, &cv, &c)
    cdef Line ln = _line(line)
    cdef Kinks k = _kinks(kinks)
    return step_energy_c(E, u, h, mode, &ln, &c, &k)


def find_speed_crossing_split(
    double E, double u, double H, double target_E, long mode, line, P, curves, kinks
):
    """Signed distance [m] in (0, H] where E reaches target_E, H if it is not reached; see
    ``find_speed_crossing_split_c``."""
    cdef Curves cv
    cdef Ctx c
    _ctx(P, curves, &cv, &c)
    cdef Line ln = _line(line)
    cdef Kinks k = _kinks(kinks)
    return find_speed_crossing_split_c(E, u, H, target_E, mode, &ln, &c, &k)


def find_curve_meeting_of(double E, double u, double Er, double w, line, P, curves, tk, bk):
    """Offset [m] of the cdef ``find_curve_meeting`` (for tests)."""
    cdef Curves cv
    cdef Ctx c
    _ctx(P, curves, &cv, &c)
    cdef Line ln = _line(line)
    cdef Kinks kt = _kinks(tk, "traction kinks tk"), kb = _kinks(bk, "braking kinks bk")
    return find_curve_meeting(E, u, Er, w, &ln, &c, &kt, &kb)


def kinks_between_of(double v0, double v1, kinks):
    """Kink speeds strictly between v0 and v1 (``kinks_between`` of ``_kernel_c.pxd``; for tests)."""
    cdef Kinks k = _kinks(kinks)
    return kinks_between(v0, v1, &k)


def compiled_constants():
    """The tolerances and step settings compiled into this module (checked by a test against
    ``trainsim.sim.codes``)."""
    return {
        "SPEED_TOLERANCE": SPEED_TOLERANCE,
        "POSITION_TOLERANCE": POSITION_TOLERANCE,
        "LENGTH_SCALE_FRACTION": LENGTH_SCALE_FRACTION,
        "MAX_SUBSTEPS": MAX_SUBSTEPS,
        "TIME_SUBSTEPS": TIME_SUBSTEPS,
        "STATUS_OK": STATUS_OK,
        "STATUS_STALLED": STATUS_STALLED,
        "STATUS_FULL": STATUS_FULL,
        "SLOW_STEP_SUBSTEPS": SLOW_STEP_SUBSTEPS,
        "SLOW_STEP_SPEED_STEPS": SLOW_STEP_SPEED_STEPS,
        "SLOW_STEP_NEWTON": SLOW_STEP_NEWTON,
        "SLOW_STEP_TOLERANCE": SLOW_STEP_TOLERANCE,
    }
