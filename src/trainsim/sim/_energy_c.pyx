# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True
"""Work integrals of a run, exact between the events of the motion: the compiled (Cython) form of
``trainsim.sim.energy`` (see its docstring for the method). Every formula keeps the order and
association of the floating-point operations of the numba functions it was ported from (issue 14),
so that the works are the same bits (plain IEEE arithmetic: no fast-math, no fused multiply-add).

The loops run on C scalars and pointers into the caller's arrays, without the GIL; ``stretch_works``
checks its arguments once (converting only arrays of another dtype or layout).
"""

import numpy as np

from libc.math cimport INFINITY, ceil, fabs, sqrt
from cpython.buffer cimport PyBUF_C_CONTIGUOUS, PyBUF_FORMAT, PyBUF_WRITABLE, PyBuffer_Release, PyObject_GetBuffer
from libc.stdint cimport int64_t

from trainsim.sim._forces cimport (
    BRAKE, COAST, CRUISE, DWELL, FOLLOW, N_PARAMS, P_BRAKE_FRACTION, P_DECEL, P_INERTIAL_MASS, P_MASS,
    P_R0, P_R1, P_R2, REGEN, TRACTION, Branch, Curve, Curves, branch_at, curves_from, effort, effort_on,
    speed_domain_steps, speed_of,
)
from trainsim._cbuffers cimport MAX_HELD, Held, Kinks, is_format, next_kink, release, search_right

# The integration settings of trainsim.sim.energy (documented there; a test checks that they agree).
cdef extern from *:
    """
    static const double TRAINSIM_MAX_SUBSTEP_M = 10.0;
    static const double TRAINSIM_LENGTH_SCALE_FRACTION = 0.02;
    static const double TRAINSIM_MIN_SUBSTEP_M = 1e-4;
    static const long TRAINSIM_MAX_SUBSTEPS = 20000;
    static const double TRAINSIM_KINK_MARGIN_MPS = 1e-6;
    static const double TRAINSIM_OFF_REGIME_SPEED_MPS = 1e-5;
    static const double TRAINSIM_OFF_REGIME_RELATIVE = 1e-6;
    static const double TRAINSIM_POSITION_TOLERANCE = 1e-9;
    """
    const double MAX_SUBSTEP_M "TRAINSIM_MAX_SUBSTEP_M"
    const double LENGTH_SCALE_FRACTION "TRAINSIM_LENGTH_SCALE_FRACTION"
    const double MIN_SUBSTEP_M "TRAINSIM_MIN_SUBSTEP_M"
    const long MAX_SUBSTEPS "TRAINSIM_MAX_SUBSTEPS"
    const double KINK_MARGIN_MPS "TRAINSIM_KINK_MARGIN_MPS"
    const double OFF_REGIME_SPEED_MPS "TRAINSIM_OFF_REGIME_SPEED_MPS"
    const double OFF_REGIME_RELATIVE "TRAINSIM_OFF_REGIME_RELATIVE"
    const double POSITION_TOLERANCE "TRAINSIM_POSITION_TOLERANCE"

# columns of the works (trainsim.sim.energy.WORK_NAMES)
cdef enum:
    W_T = 0
    W_B = 1
    W_R = 2
    W_RUN = 3
    W_GRAD = 4
    W_CT = 5
    N_WORKS = 6

# indices of the forces evaluated at one state (acceleration first, then the works' integrands)
cdef enum:
    F_ACC = 0
    N_FORCES = 7

# Gauss-Legendre nodes and weights on [0, 1] (5 points), computed as energy.py computed them (x 0.5 + 0.5)
cdef double GL_X[5]
cdef double GL_W[5]
_nodes = (-0.9061798459386640, -0.5384693101056831, 0.0, 0.5384693101056831, 0.9061798459386640)
_weights = (0.2369268850561891, 0.4786286704993665, 0.5688888888888889, 0.4786286704993665, 0.2369268850561891)
for _q in range(5):
    GL_X[_q] = <double>_nodes[_q] * 0.5 + 0.5
    GL_W[_q] = <double>_weights[_q] * 0.5


cdef struct Law:
    # line resistance per unit mass on one piece, linear in the offset u into it (energy.LineLaws)
    double g0, g1, c0, c1, k0, k1, avail


cdef struct Line:
    const double* x  # breakpoints, n_pieces + 1 of them
    Py_ssize_t n_x
    const double* g0
    const double* g1
    const double* c0
    const double* c1
    const double* k0
    const double* k1
    const double* avail
    Py_ssize_t n_pieces


cdef struct Branches:
    Branch traction, brake, regen  # each curve's branch at the piece's reference speed
    bint blend_at_ref  # service braking blended as at the reference speed (vref >= 0, no constant deceleration)
    bint demand_limited  # ... and there the regenerative force is limited by the demand


cdef inline void prepare(
    int mode, double level, const double* P, const Curves* c, double vref, Branches* br
) noexcept nogil:
    """The branches ``forces_on`` evaluates along a piece of reference speed vref [m/s] (-1: the
    curves themselves), chosen once per piece instead of at every stage (the same forces, bit for bit)."""
    # a curve the mode does not evaluate gets no branch (-1: none chosen)
    branch_at(vref if mode == TRACTION else -1.0, &c.traction, &br.traction)
    branch_at(vref if mode == BRAKE else -1.0, &c.brake, &br.brake)
    branch_at(vref if mode == BRAKE or mode == REGEN else -1.0, &c.regen, &br.regen)
    br.blend_at_ref = vref >= 0.0 and mode == BRAKE and P[P_DECEL] == 0.0
    br.demand_limited = False
    cdef double demand_ref
    if br.blend_at_ref:
        # the blend's branch at the reference speed: regenerative force limited by the demand or not
        demand_ref = level * P[P_BRAKE_FRACTION] * effort_on(vref, &br.brake, &c.brake)
        br.demand_limited = demand_ref < effort_on(vref, &br.regen, &c.regen)


cdef inline void forces_on(
    int mode, double E, double u, const Law* lw, double level, const double* P, const Curves* c,
    const Branches* br, double* out,
) noexcept nogil:
    """(acceleration [m/s^2], traction, braking, regenerative, running, gradient, curve+tunnel [N])
    into ``out``, as ``energy._forces``, on the branches ``prepare`` chose."""
    cdef double v = speed_of(E)
    cdef double m = P[P_MASS]
    cdef double running = P[P_R0] + P[P_R1] * v + P[P_R2] * v * v
    cdef double grad = m * (lw.g0 + lw.g1 * u)
    cdef double ct = m * ((lw.c0 + lw.c1 * u) + (lw.k0 + lw.k1 * u) * v * v)
    cdef double res = running + grad + ct
    cdef double ft = 0.0, fb = 0.0, fr = 0.0, need, cap
    if mode == TRACTION:
        ft = level * lw.avail * effort_on(v, &br.traction, &c.traction)
    elif mode == BRAKE:
        if P[P_DECEL] > 0.0:
            need = P[P_INERTIAL_MASS] * P[P_DECEL] - res
            fb = level * need if need > 0.0 else 0.0
        else:
            fb = level * P[P_BRAKE_FRACTION] * effort_on(v, &br.brake, &c.brake)
    elif mode == REGEN:
        fb = effort_on(v, &br.regen, &c.regen)
    if fb > 0.0:
        cap = effort_on(v, &br.regen, &c.regen)
        if br.blend_at_ref:
            fr = fb if br.demand_limited else cap
        else:
            fr = fb if fb < cap else cap
    out[0] = (ft - fb - res) / P[P_INERTIAL_MASS]
    out[1] = ft
    out[2] = fb
    out[3] = fr
    out[4] = running
    out[5] = grad
    out[6] = ct


cdef inline void forces(
    int mode, double E, double u, const Law* lw, double level, const double* P, const Curves* c,
    double vref, double* out,
) noexcept nogil:
    """``forces_on`` with the branches at vref [m/s] chosen for this one evaluation."""
    cdef Branches br
    prepare(mode, level, P, c, vref, &br)
    forces_on(mode, E, u, lw, level, P, c, &br, out)


cdef inline double acceleration_on(
    int mode, double E, double u, const Law* lw, double level, const double* P, const Curves* c,
    const Branches* br,
) noexcept nogil:
    cdef double f[N_FORCES]
    forces_on(mode, E, u, lw, level, P, c, br, f)
    return f[F_ACC]


cdef inline double acceleration(
    int mode, double E, double u, const Law* lw, double level, const double* P, const Curves* c, double vref
) noexcept nogil:
    cdef Branches br
    prepare(mode, level, P, c, vref, &br)
    return acceleration_on(mode, E, u, lw, level, P, c, &br)


cdef inline double rk4_works(
    double E, double u, double h, long n, int mode, const Law* lw, double level, const double* P,
    const Curves* c, double* W, double vref,
) noexcept nogil:
    """Integrate E and the works over [u, u + h] with n RK4 sub-steps, adding the works to W;
    returns E at the end (not clipped at 0) (``energy._rk4_works``)."""
    cdef double d = h / n
    cdef double f1[N_FORCES]
    cdef double f2[N_FORCES]
    cdef double f3[N_FORCES]
    cdef double f4[N_FORCES]
    cdef double E2, E3, E4
    cdef long i
    cdef int q
    cdef Branches br
    prepare(mode, level, P, c, vref, &br)
    for i in range(n):
        forces_on(mode, E if E > 0.0 else 0.0, u, lw, level, P, c, &br, f1)
        E2 = E + 0.5 * d * f1[0]
        forces_on(mode, E2 if E2 > 0.0 else 0.0, u + 0.5 * d, lw, level, P, c, &br, f2)
        E3 = E + 0.5 * d * f2[0]
        forces_on(mode, E3 if E3 > 0.0 else 0.0, u + 0.5 * d, lw, level, P, c, &br, f3)
        E4 = E + d * f3[0]
        forces_on(mode, E4 if E4 > 0.0 else 0.0, u + d, lw, level, P, c, &br, f4)
        for q in range(N_WORKS):
            W[q] += d / 6.0 * (f1[q + 1] + 2.0 * f2[q + 1] + 2.0 * f3[q + 1] + f4[q + 1])
        E = E + d / 6.0 * (f1[0] + 2.0 * f2[0] + 2.0 * f3[0] + f4[0])
        u += d
    return E


cdef double distance_to_speed(
    double E, double u, double Et, int mode, const Law* lw, double level, const double* P, const Curves* c
) noexcept nogil:
    """Distance [m] from (u, E) along ``mode`` until E reaches Et, RK4 on ds/dv = v / a in the speed
    domain; inf when the acceleration vanishes or changes sign on the way (``energy._distance_to_speed``)."""
    cdef double v_from = speed_of(E)
    cdef double v_to = speed_of(Et)
    cdef double vref = 0.5 * (v_from + v_to)
    cdef Branches br
    prepare(mode, level, P, c, vref, &br)
    cdef long n = speed_domain_steps(
        v_from,
        v_to,
        acceleration_on(mode, E, u, lw, level, P, c, &br),
        acceleration_on(mode, Et, u, lw, level, P, c, &br),
    )
    cdef double dv = (v_to - v_from) / n
    cdef double v = v_from, s = 0.0, sign = 0.0, vj, sj, a
    cdef double r[4]
    cdef long i
    cdef int j
    for i in range(n):
        for j in range(4):
            if j == 0:
                vj = v
                sj = s
            elif j == 3:
                vj = v + dv
                sj = s + dv * r[2]
            else:
                vj = v + 0.5 * dv
                sj = s + 0.5 * dv * r[j - 1]
            a = acceleration_on(mode, 0.5 * vj * vj, u + sj, lw, level, P, c, &br)
            if sign == 0.0:
                sign = 1.0 if a > 0.0 else -1.0
            if a * sign <= 0.0:
                return INFINITY
            r[j] = vj / a
        s += dv / 6.0 * (r[0] + 2.0 * r[1] + 2.0 * r[2] + r[3])
        v += dv
    return s


cdef inline long substeps(
    double E, double u, double h, int mode, const Law* lw, double level, const double* P, const Curves* c
) noexcept nogil:
    """RK4 sub-steps over a length h [m] from (u, E) (``energy._substeps``)."""
    cdef double a = fabs(acceleration(mode, E, u, lw, level, P, c, -1.0))
    cdef double d = MAX_SUBSTEP_M, scale
    if a > 0.0:
        scale = LENGTH_SCALE_FRACTION * 2.0 * E / a
        if scale < d:
            d = scale if scale > MIN_SUBSTEP_M else MIN_SUBSTEP_M
    cdef long n = <long>ceil(h / d)
    if n < 1:
        n = 1
    return n if n < MAX_SUBSTEPS else MAX_SUBSTEPS


cdef double dynamic_piece(
    double E, double u, double h, int mode, const Law* lw, double level, const double* P, const Curves* c,
    const Kinks* kinks, double* W, double v_hint,
) noexcept nogil:
    """Works over [u, u + h] along ``mode`` from E, restarted at every kink speed between the start
    speed and ``v_hint`` (``energy._dynamic_piece``)."""
    cdef double remaining = h
    cdef double v0 = speed_of(E)
    cdef bint rising = v_hint > v0
    # the trace's end speed is exact to about 1e-8 m/s: a kink within KINK_MARGIN_MPS of it is the end
    cdef double margin = KINK_MARGIN_MPS * (1.0 + v_hint)
    cdef double v_far = v_hint + margin if rising else v_hint - margin
    cdef Py_ssize_t n_tries = kinks.n + 2, attempt
    cdef double vk, hk, h_piece, vref, v_end, E_piece
    cdef bint final
    cdef long n
    for attempt in range(n_tries + 1):
        vk = -1.0
        hk = INFINITY
        if attempt == n_tries:
            # kinks left after every try: the rest in one piece, on no particular branch
            final = True
            h_piece = remaining
            vref = -1.0
        else:
            vk = next_kink(v0, rising, v_far, kinks)
            if vk >= 0.0 and fabs(vk - v_hint) > margin:
                hk = distance_to_speed(E, u, 0.5 * vk * vk, mode, lw, level, P, c)
            # no kink inside: one smooth piece to the end (a kink at its very end is not crossed)
            final = not (0.0 < hk < remaining - POSITION_TOLERANCE)
            if final:
                v_end = v_hint
                if vk >= 0.0 and ((v_hint > vk) if rising else (v_hint < vk)):
                    v_end = vk
                h_piece = remaining
                vref = 0.5 * (v0 + v_end)
            else:
                h_piece = hk
                vref = 0.5 * (v0 + vk)
        n = substeps(E, u, h_piece, mode, lw, level, P, c)
        E_piece = rk4_works(E, u, h_piece, n, mode, lw, level, P, c, W, vref)
        if final:
            return E_piece
        E = 0.5 * vk * vk
        v0 = vk
        u += hk
        remaining -= hk
    return E


cdef inline double integral_min_linear(double b_a, double b_b, double cap, double h) noexcept nogil:
    """Integral over a length h [m] of min(b, cap) for b linear from b_a to b_b (both >= 0) [N m]
    (``energy._integral_min_linear``)."""
    if b_a <= cap and b_b <= cap:
        return 0.5 * (b_a + b_b) * h
    if b_a >= cap and b_b >= cap:
        return cap * h
    cdef double z = h * (cap - b_a) / (b_b - b_a)
    if b_a < cap:
        return 0.5 * (b_a + cap) * z + cap * (h - z)
    return cap * z + 0.5 * (cap + b_b) * (h - z)


cdef double cruise_piece(
    double E, double u, double h, const Law* lw, const double* P, const Curves* c, double* W
) noexcept nogil:
    """Works over [u, u + h] at constant speed, the holding force split at its zero and the
    regenerative part where braking crosses the capacity (``energy._cruise_piece``)."""
    cdef double fa[N_FORCES]
    cdef double fb[N_FORCES]
    forces(COAST, E, u, lw, 1.0, P, c, -1.0, fa)
    forces(COAST, E, u + h, lw, 1.0, P, c, -1.0, fb)
    cdef double need_a = -fa[0] * P[P_INERTIAL_MASS]
    cdef double need_b = -fb[0] * P[P_INERTIAL_MASS]
    cdef double cap = effort(speed_of(E), &c.regen)
    cdef double z
    W[W_RUN] += 0.5 * (fa[4] + fb[4]) * h
    W[W_GRAD] += 0.5 * (fa[5] + fb[5]) * h
    W[W_CT] += 0.5 * (fa[6] + fb[6]) * h
    if need_a >= 0.0 and need_b >= 0.0:
        W[W_T] += 0.5 * (need_a + need_b) * h
    elif need_a <= 0.0 and need_b <= 0.0:
        W[W_B] -= 0.5 * (need_a + need_b) * h
        W[W_R] += integral_min_linear(-need_a, -need_b, cap, h)
    else:
        z = h * need_a / (need_a - need_b)  # where the holding force changes sign
        if need_a > 0.0:
            W[W_T] += 0.5 * need_a * z
            W[W_B] -= 0.5 * need_b * (h - z)
            W[W_R] += integral_min_linear(0.0, -need_b, cap, h - z)
        else:
            W[W_T] += 0.5 * need_b * (h - z)
            W[W_B] -= 0.5 * need_a * z
            W[W_R] += integral_min_linear(-need_a, 0.0, cap, z)
    return E


cdef struct Need:
    double need, run, grad, ct, cap


cdef inline Need follow_need(
    double E0, double a, double u0, double u, const Law* lw, const double* P, const Curves* c
) noexcept nogil:
    """Force a prescribed profile needs at offset u (v^2/2 = E0 + a (u - u0)), its resistance parts
    and the regenerative capacity [N] (``energy._follow_need``)."""
    cdef double E = E0 + a * (u - u0)
    cdef double f[N_FORCES]
    forces(COAST, E if E > 0.0 else 0.0, u, lw, 1.0, P, c, -1.0, f)
    cdef Need out
    out.need = P[P_INERTIAL_MASS] * (a - f[0])
    out.run = f[4]
    out.grad = f[5]
    out.ct = f[6]
    out.cap = effort(speed_of(E), &c.regen)
    return out


cdef double follow_piece(
    double E0, double a, double u, double h, const Law* lw, const double* P, const Curves* c, double* W
) noexcept nogil:
    """Works of a prescribed profile (E = E0 + a (x - u)) over [u, u + h]: 5-point Gauss-Legendre on
    sub-pieces of at most ``MAX_SUBSTEP_M``, split where the needed force changes sign (bisection);
    returns E at u + h (``energy._follow_piece``)."""
    cdef long n = <long>ceil(h / MAX_SUBSTEP_M)
    if n < 1:
        n = 1
    cdef double d = h / n
    cdef double lo, hi, na, nb, x0, x1, f0, xm, fm, a0, b0, x, w, minus_need
    cdef double cuts[3]
    cdef int m, it, p, q
    cdef long j
    cdef Need nd
    for j in range(n):
        lo = u + j * d
        hi = lo + d
        # split at one sign change of the need inside (a smooth need changes sign at most once here)
        na = follow_need(E0, a, u, lo, lw, P, c).need
        nb = follow_need(E0, a, u, hi, lw, P, c).need
        cuts[0] = lo
        cuts[1] = hi
        cuts[2] = hi
        m = 2
        if na * nb < 0.0:
            x0 = lo
            x1 = hi
            f0 = na
            for it in range(100):
                xm = 0.5 * (x0 + x1)
                fm = follow_need(E0, a, u, xm, lw, P, c).need
                if (fm < 0.0) == (f0 < 0.0):
                    x0 = xm
                    f0 = fm
                else:
                    x1 = xm
                if x1 - x0 < 1e-12:
                    break
            cuts[1] = 0.5 * (x0 + x1)
            cuts[2] = hi
            m = 3
        for p in range(m - 1):
            a0 = cuts[p]
            b0 = cuts[p + 1]
            for q in range(5):
                x = a0 + (b0 - a0) * GL_X[q]
                w = (b0 - a0) * GL_W[q]
                nd = follow_need(E0, a, u, x, lw, P, c)
                W[W_RUN] += w * nd.run
                W[W_GRAD] += w * nd.grad
                W[W_CT] += w * nd.ct
                if nd.need > 0.0:
                    W[W_T] += w * nd.need
                else:
                    W[W_B] -= w * nd.need
                    # Python's min(-need, cap): cap only when strictly smaller
                    minus_need = -nd.need
                    W[W_R] += w * (nd.cap if nd.cap < minus_need else minus_need)
    return E0 + a * h


cdef double piece_loop(
    Py_ssize_t k, const double* s, const double* v, int mode, double level, const Line* line,
    const double* P, const Curves* c, const Kinks* tk, const Kinks* bk, const Kinks* rk, double* row,
    double acc_follow,
) noexcept nogil:
    """Integrate stretch k piece by piece of the line laws; returns E at its end (``energy._piece_loop``)."""
    cdef Py_ssize_t n_pieces = line.n_pieces, i, attempt
    cdef double E = 0.5 * v[k] * v[k]
    cdef double pos = s[k], end, u, h
    cdef Law lw
    cdef Kinks none
    none.v = NULL
    none.n = 0
    cdef const Kinks* kinks
    for attempt in range(n_pieces + 2):
        i = search_right(line.x, line.n_x, pos) - 1
        if i < 0:
            i = 0
        if i > n_pieces - 1:
            i = n_pieces - 1
        end = s[k + 1]
        if i + 1 < line.n_x - 1 and line.x[i + 1] < end - POSITION_TOLERANCE:
            end = line.x[i + 1]
        u = pos - line.x[i]
        h = end - pos
        lw.g0 = line.g0[i]
        lw.g1 = line.g1[i]
        lw.c0 = line.c0[i]
        lw.c1 = line.c1[i]
        lw.k0 = line.k0[i]
        lw.k1 = line.k1[i]
        lw.avail = line.avail[i]
        if mode == CRUISE:
            E = cruise_piece(E, u, h, &lw, P, c, row)
        elif mode == FOLLOW:
            E = follow_piece(E, acc_follow, u, h, &lw, P, c, row)
        else:
            if mode == TRACTION:
                kinks = tk
            elif mode == BRAKE:
                kinks = bk
            elif mode == REGEN:
                kinks = rk
            else:
                kinks = &none
            E = dynamic_piece(E, u, h, mode, &lw, level, P, c, kinks, row, v[k + 1])
        pos = end
        if pos >= s[k + 1] - POSITION_TOLERANCE:
            break
    return E


cdef void all_stretches(
    Py_ssize_t n, const double* s, const double* v, const int64_t* regime, const double* level,
    const Line* line, const double* P, const Curves* c, const Kinks* tk, const Kinks* bk, const Kinks* rk,
    double* W, double* v_end, unsigned char* off,
) noexcept nogil:
    """The loop of ``stretch_works`` over the stretches (W zeroed, n rows of N_WORKS)."""
    cdef Py_ssize_t k
    cdef int mode, attempt, q
    cdef double h_total, acc_follow, ve, E, v_max, tol
    cdef double* row
    for k in range(n):
        mode = <int>regime[k]
        row = W + N_WORKS * k
        h_total = s[k + 1] - s[k]
        if mode == DWELL or not h_total > 0.0:
            v_end[k] = v[k + 1] if mode == DWELL else v[k]
            continue
        acc_follow = (0.5 * v[k + 1] * v[k + 1] - 0.5 * v[k] * v[k]) / h_total
        ve = 0.0
        for attempt in range(2):
            E = piece_loop(
                k, s, v, mode if attempt == 0 else FOLLOW, level[k] if attempt == 0 else 1.0,
                line, P, c, tk, bk, rk, row, acc_follow,
            )
            if attempt == 1:
                break
            ve = speed_of(E)
            # Python's max(v[k], v[k + 1]): the second only when strictly greater
            v_max = v[k + 1] if v[k + 1] > v[k] else v[k]
            tol = (OFF_REGIME_SPEED_MPS + OFF_REGIME_RELATIVE * v_max) * v_max + 1e-12
            if not (mode != FOLLOW and fabs(E - 0.5 * v[k + 1] * v[k + 1]) > tol):
                break
            # the recorded motion is not this regime's: integrated as that motion instead
            off[k] = 1
            for q in range(N_WORKS):
                row[q] = 0.0
        v_end[k] = ve


# ---- entry point: arguments checked once, then the loops above ----

# Arrays are read through the buffer protocol rather than typed memoryviews: the same pointers without
# the memoryview support code Cython would generate into this module (most of its C source and compile
# time) and with less work per call. Every buffer a call takes is held until the call returns.
# (``Held``, ``release``, ``is_format``: trainsim/_cbuffers.pxd)


def _converted(str name, object a, bint integer):
    """``a`` as a C-contiguous 1-d array of float64 (int64 with ``integer``), or a ValueError naming
    ``name`` and what is allowed (the slow path, for anything the buffer protocol does not give as is)."""
    dtype = np.int64 if integer else np.float64
    arr = np.asarray(a)
    allowed = "iub" if integer else "iubf"
    if arr.dtype.kind not in allowed:
        kinds = "integers" if integer else "real numbers"
        raise ValueError(f"stretch_works: {name} must be an array of {kinds}, got {arr.dtype}")
    if arr.ndim != 1:
        raise ValueError(f"stretch_works: {name} must be 1-d, got shape {arr.shape}")
    return np.ascontiguousarray(arr, dtype=dtype)


cdef void* hold(Held* held, list keep, str name, object a, bint integer, bint output, Py_ssize_t* n) except NULL:
    """Data pointer of ``a`` as a C-contiguous 1-d float64 (int64 with ``integer``) array, converted
    first when it is not one (the converted array kept alive in ``keep``), its length in ``n``; the
    buffer is held in ``held`` until ``release``. ``output``: an array made here, written to."""
    if held.count >= MAX_HELD:
        raise RuntimeError(f"internal: more than {MAX_HELD} arrays held")
    cdef Py_buffer* view = &held.views[held.count]
    cdef int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (PyBUF_WRITABLE if output else 0)
    cdef bint taken = False
    try:
        PyObject_GetBuffer(a, view, flags)
        taken = True
    except (TypeError, ValueError, BufferError):
        pass
    if taken and not output and (
        view.ndim != 1 or view.itemsize != 8 or not is_format(view.format, c'q' if integer else c'd')
    ):
        PyBuffer_Release(view)
        taken = False
    if not taken:
        # another dtype or shape: converted (or refused) on the slow path
        a = _converted(name, a, integer)
        keep.append(a)
        PyObject_GetBuffer(a, view, flags)
    held.count += 1
    n[0] = view.shape[0] if view.ndim == 1 else view.len // view.itemsize
    # an empty buffer may carry any pointer: never dereferenced (its length is 0), but kept non-NULL
    return view.buf if view.buf != NULL else <void*>view


cdef bint is_sorted(const double* a, Py_ssize_t n) noexcept nogil:
    """Whether a[0] <= a[1] <= ... (no NaN)."""
    cdef Py_ssize_t i
    for i in range(1, n):
        if not a[i] >= a[i - 1]:
            return False
    return True


LAW_NAMES = ("laws g0", "laws g1", "laws c0", "laws c1", "laws k0", "laws k1", "laws available")
KINK_NAMES = ("tk", "bk", "rk")


cdef object _stretch_works(Held* held, list keep, s, v, regime, level, lx, laws, P, curves, tk, bk, rk):
    cdef Py_ssize_t n_points, n_other, n_x, n_law, n_P, i
    cdef const double* s_p = <const double*>hold(held, keep, "s", s, False, False, &n_points)
    if n_points < 1:
        raise ValueError("stretch_works: s has 0 values, needs at least 1")
    cdef const double* v_p = <const double*>hold(held, keep, "v", v, False, False, &n_other)
    if n_other != n_points:
        raise ValueError(f"stretch_works: v has {n_other} values, needs {n_points} (one per point of s)")
    cdef const int64_t* regime_p = <const int64_t*>hold(held, keep, "regime", regime, True, False, &n_other)
    if n_other != n_points:
        raise ValueError(f"stretch_works: regime has {n_other} values, needs {n_points} (one per point of s)")
    cdef const double* level_p = <const double*>hold(held, keep, "level", level, False, False, &n_other)
    if n_other != n_points:
        raise ValueError(f"stretch_works: level has {n_other} values, needs {n_points} (one per point of s)")
    for i in range(n_points - 1):
        if regime_p[i] < TRACTION or regime_p[i] > FOLLOW:
            raise ValueError(
                f"stretch_works: regime codes must be {TRACTION}..{FOLLOW} (trainsim.sim.codes), "
                f"got {regime_p[i]} at point {i}"
            )

    cdef Line line
    line.x = <const double*>hold(held, keep, "lx", lx, False, False, &n_x)
    if n_x < 2 or not is_sorted(line.x, n_x):
        raise ValueError(f"stretch_works: lx must be at least 2 breakpoints sorted increasing, got {n_x}")
    line.n_x = n_x
    line.n_pieces = n_x - 1
    if not isinstance(laws, tuple) or len(laws) != 7:
        raise ValueError("stretch_works: laws must be the tuple (g0, g1, c0, c1, k0, k1, available)")
    cdef const double** law_p[7]
    law_p[:] = [&line.g0, &line.g1, &line.c0, &line.c1, &line.k0, &line.k1, &line.avail]
    for i in range(7):
        law_p[i][0] = <const double*>hold(held, keep, LAW_NAMES[i], laws[i], False, False, &n_law)
        if n_law != line.n_pieces:
            raise ValueError(
                f"stretch_works: {LAW_NAMES[i]} has {n_law} values, needs {line.n_pieces} (one per piece of lx)"
            )

    cdef const double* P_p = <const double*>hold(held, keep, "P", P, False, False, &n_P)
    if n_P < N_PARAMS:
        raise ValueError(f"stretch_works: P has {n_P} values, needs {N_PARAMS} (trainsim.sim.codes)")
    if not P_p[P_INERTIAL_MASS] > 0.0:
        raise ValueError(
            f"stretch_works: the inertial mass P[{P_INERTIAL_MASS}] must be > 0 kg, got {P_p[P_INERTIAL_MASS]}"
        )
    if not isinstance(curves, tuple) or len(curves) != 12:
        raise ValueError(
            "stretch_works: curves must be the 12-tuple (ts, tc, tf, tp, bs, bc, bf, bp, rs, rc, rf, rp)"
        )
    cdef Curves c
    curves_from(curves, &c)
    cdef Kinks kinks[3]
    for i, a in enumerate((tk, bk, rk)):
        kinks[i].v = <const double*>hold(held, keep, KINK_NAMES[i], a, False, False, &kinks[i].n)
        if not is_sorted(kinks[i].v, kinks[i].n):
            raise ValueError(f"stretch_works: {KINK_NAMES[i]} must be sorted increasing")

    cdef Py_ssize_t n = n_points - 1
    W = np.zeros((n, N_WORKS))
    v_end = np.empty(n)
    off = np.zeros(n, dtype=np.bool_)
    if n == 0:
        return W, v_end, off
    cdef double* W_p = <double*>hold(held, keep, "works", W, False, True, &n_other)
    cdef double* v_end_p = <double*>hold(held, keep, "end speeds", v_end, False, True, &n_other)
    cdef unsigned char* off_p = <unsigned char*>hold(held, keep, "off", off, False, True, &n_other)
    with nogil:
        all_stretches(
            n, s_p, v_p, regime_p, level_p, &line, P_p, &c, &kinks[0], &kinks[1], &kinks[2], W_p, v_end_p, off_p
        )
    return W, v_end, off


def stretch_works(s, v, regime, level, lx, laws, P, curves, tk, bk, rk):
    """Works [J] of every stretch of a run (one row per stretch, columns as
    ``energy.WORK_NAMES``), the speed at each stretch's end reached by integrating its regime from
    its start [m/s] (0 where the regime stops the train earlier), and whether the stretch was
    integrated as its recorded motion because its regime does not lead to its end.

    ``s`` [m], ``v`` [m/s], ``regime`` (codes of ``trainsim.sim.codes``) and ``level`` (the driver's
    command, 0..1) per point; ``lx`` [m] the breakpoints of the per-piece line laws ``laws`` =
    (g0, g1, c0, c1, k0, k1, available) (see ``energy.LineLaws``); ``P`` the kernel's parameter
    vector; ``curves`` the 12-tuple of the traction, service braking and regenerative curves;
    ``tk``, ``bk``, ``rk`` the sorted kink speeds [m/s] in traction, service braking and regenerative
    braking. 1-d float64 (int64 for ``regime``) C-contiguous arrays are read in place, others
    converted. Returns (works (n - 1, 6) float64, end speeds (n - 1,) float64, off (n - 1,) bool)."""
    cdef Held held
    held.count = 0
    keep = []
    try:
        return _stretch_works(&held, keep, s, v, regime, level, lx, laws, P, curves, tk, bk, rk)
    finally:
        release(&held)


def integration_settings():
    """The integration settings compiled into the extension (checked by a test against
    ``trainsim.sim.energy``): sub-steps, margins, tolerances and the Gauss-Legendre rule."""
    return {
        "MAX_SUBSTEP_M": MAX_SUBSTEP_M,
        "LENGTH_SCALE_FRACTION": LENGTH_SCALE_FRACTION,
        "MIN_SUBSTEP_M": MIN_SUBSTEP_M,
        "MAX_SUBSTEPS": MAX_SUBSTEPS,
        "KINK_MARGIN_MPS": KINK_MARGIN_MPS,
        "OFF_REGIME_SPEED_MPS": OFF_REGIME_SPEED_MPS,
        "OFF_REGIME_RELATIVE": OFF_REGIME_RELATIVE,
        "POSITION_TOLERANCE": POSITION_TOLERANCE,
        "N_WORKS": N_WORKS,
        "GL_X": [GL_X[q] for q in range(5)],
        "GL_W": [GL_W[q] for q in range(5)],
    }
