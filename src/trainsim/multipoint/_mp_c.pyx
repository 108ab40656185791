# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True
"""Compiled (Cython) multi-point kernel: vehicles on couplers, implicit midpoint steps solved by Newton
iterations with the Thomas algorithm, the controller that follows a reference, records and extremes.

The equations, the integrator and the layout of every parameter, state and record array are those of
``trainsim.multipoint.kernel`` (its module docstring and the column constants it defines; this module
does not repeat them). Every floating-point operation keeps the order and association of the Python
expressions it was ported from (``a * b * c`` is ``(a * b) * c``; ``x**3`` is ``x * (x * x)``;
``min(a, b)`` is ``b if b < a else a`` and ``max(a, b)`` is ``b if b > a else a``, Python's choice
when one is NaN), and the module is compiled without fast-math or contraction into fused
multiply-adds (setup.py), so that runs are bit for bit the ones of the numba kernel this replaced
(issue 14). A division by zero gives inf or NaN (``cdivision``), which Newton rejects as not finite.

The ``def`` entry points take and return what ``kernel`` documents for them; they read every array
once through the buffer protocol (C-contiguous, 8-byte floats, int64 indices, the reference's regimes
int8), check its shape, then run in C on pointers without the GIL.
"""

from cpython.buffer cimport PyBUF_C_CONTIGUOUS, PyBUF_FORMAT, PyBUF_WRITABLE, PyObject_GetBuffer
from libc.math cimport INFINITY, exp, fabs, isfinite, pow, sqrt, tanh as c_tanh
from libc.stdint cimport int8_t, int64_t

import numpy as np

from trainsim._cbuffers cimport MAX_HELD, Held, is_format, pmax, pmin, release, search_right
from trainsim.sim._forces cimport BRAKE, COAST, CRUISE, FOLLOW, REGEN, TRACTION

# The column and status constants of trainsim.multipoint.kernel (a test checks they agree); the regime
# codes are sim._forces's, those of trainsim.sim.codes.
cdef enum:
    V_MASS = 0
    V_INERTIAL = 1
    V_LENGTH = 2
    V_R0 = 3
    V_R1 = 4
    V_R2 = 5
    V_BRAKE = 6
    V_REGEN = 7
    V_CURVE = 8
    V_PROFILE = 9
    V_DELAY = 10
    N_V = 11
    C_KD = 0
    C_KB = 1
    C_CD = 2
    C_CB = 3
    C_HALF_SLACK = 4
    C_TD = 5
    C_TB = 6
    C_KS = 7
    C_EPS = 8
    C_MU = 9
    C_VF = 10
    N_C = 11
    S_STEP = 0
    S_VEPS = 1
    S_BRAKE_FRACTION = 2
    S_DECEL = 3
    S_BUILD_UP = 4
    S_TAU = 5
    S_LOOKAHEAD = 6
    S_REST_SPEED = 7
    S_STOP_WINDOW = 8
    S_RECORD_DT = 9
    S_ETA_T = 10
    S_ETA_R = 11
    S_SERVICE_CURVE = 12
    S_REGEN_CURVE = 13
    S_G = 14
    S_STALL_S = 15
    S_NEWTON_TOL = 16
    S_TRACK_PROFILE = 17
    S_RAMP = 18
    S_STEP_MIN = 19
    S_FORCE_TOL = 20
    N_S = 21
    K_FRICTION = 0
    K_BLEND = 1
    K_COMMAND = 2
    K_REGIME = 3
    N_K = 4
    A_TRACTION = 0
    A_FRICTION = 1
    A_ELECTRIC = 2
    A_RUNNING = 3
    A_GRADIENT = 4
    A_CURVE = 5
    A_TUNNEL = 6
    A_DAMPER = 7
    A_SPRING_WORK = 8
    A_HELD = 9
    N_WORKS = 10
    A_PEAK_POWER = 10
    A_SUBSTEPS = 11
    A_NEWTON = 12
    A_STEPS = 13
    A_REST_SINCE = 14
    A_H = 15
    A_NMEM = 16
    A_REJECTED = 17
    A_LAST_H = 18
    A_INTEGRATED = 19
    N_A = 20
    R_HEAD = 0
    R_SPEED = 1
    R_COMMAND = 2
    R_REGIME = 3
    R_TRACTION = 4
    R_ELECTRIC = 5
    R_FRICTION = 6
    R_RUNNING = 7
    R_GRADIENT = 8
    R_CURVE = 9
    R_TUNNEL = 10
    R_TRACTION_POWER = 11
    R_ELECTRIC_POWER = 12
    R_PEAK_POWER = 13
    R_KINETIC = 14
    R_SPRING = 15
    R_W0 = 16
    N_R = 26
    E_DRAFT = 0
    E_DRAFT_K = 1
    E_DRAFT_T = 2
    E_DRAFT_HEAD = 3
    E_BUFF = 4
    E_BUFF_K = 5
    E_BUFF_T = 6
    E_BUFF_HEAD = 7
    N_E = 8
    EK_DRAFT = 0
    EK_DRAFT_T = 1
    EK_DRAFT_HEAD = 2
    EK_BUFF = 3
    EK_BUFF_T = 4
    EK_BUFF_HEAD = 5
    N_EK = 6
    ST_TIME = 0
    ST_STOPPED = 1
    ST_STALLED = 2
    ST_RECORD_FULL = 3
    ST_HISTORY_FULL = 4
    ST_FAILED = 5
    ST_END_OF_ROUTE = 6
    MAX_NEWTON = 12
    DAMPED_FROM = 6
    N_PARTS = 7

#: A step is given up early when the Newton update of a damped iteration exceeds this multiple of what
#: halving it at every remaining iteration could still bring below the tolerance (``implicit_step_c``).
cdef double HOPELESS_MARGIN = 64.0

#: Below this speed the electric brake fades linearly to 0 at standstill [m/s] (kernel.ELECTRIC_FADE_MPS).
cdef double ELECTRIC_FADE_MPS = 1.0

#: The constants above, for the test that checks them against ``kernel`` and ``sim.codes``.
CONSTANTS = {
    "N_V": N_V, "V_DELAY": V_DELAY, "V_PROFILE": V_PROFILE, "V_CURVE": V_CURVE, "N_C": N_C, "C_VF": C_VF,
    "N_S": N_S, "S_FORCE_TOL": S_FORCE_TOL, "S_STEP_MIN": S_STEP_MIN, "S_RAMP": S_RAMP,
    "S_TRACK_PROFILE": S_TRACK_PROFILE, "N_K": N_K, "N_A": N_A, "A_INTEGRATED": A_INTEGRATED,
    "N_WORKS": N_WORKS, "N_R": N_R, "R_W0": R_W0, "R_SPRING": R_SPRING, "N_E": N_E, "N_EK": N_EK,
    "EK_BUFF_HEAD": EK_BUFF_HEAD, "ST_END_OF_ROUTE": ST_END_OF_ROUTE, "MAX_NEWTON": MAX_NEWTON,
    "DAMPED_FROM": DAMPED_FROM, "HOPELESS_MARGIN": HOPELESS_MARGIN,
    "TRACTION": TRACTION, "CRUISE": CRUISE, "COAST": COAST, "BRAKE": BRAKE, "REGEN": REGEN, "FOLLOW": FOLLOW,
    "ELECTRIC_FADE_MPS": ELECTRIC_FADE_MPS,
}


# ============================================================================ arrays of a call
cdef struct Bank:
    const double* cs  # interval starts [m/s]
    const double* cc  # law coefficients, 4 per interval
    const int64_t* coff  # first interval of each curve, n_curves + 1
    const double* cfc  # force caps [N]
    const double* cpc  # power caps [W]
    Py_ssize_t n_curves


cdef struct Prof:
    const int64_t* poff  # first node of each profile, n_profiles + 1
    const double* px  # nodes [m]
    const double* pval  # values, 4 per node
    Py_ssize_t n_profiles


cdef struct Steps:
    const double* x  # breakpoints [m]
    const double* val  # value on [x[k], x[k + 1])
    Py_ssize_t nx
    Py_ssize_t nval


cdef struct Ref:
    const double* s  # head positions [m]
    const double* v2  # squared speeds [m^2/s^2]
    const int8_t* m  # regime of the stretch from each point
    Py_ssize_t n
    double stop_at  # position of the stop [m]


cdef struct Ceiling:
    const double* x
    const double* left
    const double* right
    Py_ssize_t nleft


cdef struct Model:
    Py_ssize_t n  # vehicles
    const double* VP  # n x N_V
    const double* CP  # (n - 1) x N_C
    const double* SP  # N_S
    double* CMD  # N_K
    double* trac  # n
    double* elec  # n
    Bank bank
    Prof prof
    Steps avail
    int64_t* pcache  # n


cdef struct Work:
    double* xm
    double* F
    double* D
    double* Ts  # spring tensions of the couplings (n - 1)
    double* Td  # damper tensions (n - 1)
    double* m2h  # 2 m_i / h of the step (n)
    double* G
    double* diag
    double* off
    double* dw
    double* cprime
    double* parts  # n x N_PARTS


cdef struct CouplerForce:
    double spring  # [N]
    double damper  # [N]
    double k  # d tension / d delta [N/m]
    double c  # d tension / d rate [N s/m]


cdef struct Effort:
    double f  # [N]
    double df  # [N s/m]


cdef struct Line:
    double g  # gradient ratio
    double c  # curve ratio
    double tu  # tunnel ratio
    double b2  # tunnel v^2 coefficient [s^2/m^2]


cdef struct Command:
    double u
    int regime
    double vc


# ============================================================================ smoothed piecewise laws
cdef inline double tanh_c(double z) noexcept nogil:
    """tanh(z), without the library call where it rounds to +-1 (|z| >= 22: 1 - tanh(z) < 1e-19)."""
    if z >= 22.0:
        return 1.0
    if z <= -22.0:
        return -1.0
    return c_tanh(z)


cdef inline double ramp(double z, double eps) noexcept nogil:
    """max(z, 0) with the kink rounded over [-eps, eps] by a quadratic (C1)."""
    if z <= -eps:
        return 0.0
    if z >= eps:
        return z
    return (z + eps) * (z + eps) / (4.0 * eps)


cdef inline double ramp_slope(double z, double eps) noexcept nogil:
    """d ramp / dz."""
    if z <= -eps:
        return 0.0
    if z >= eps:
        return 1.0
    return (z + eps) / (2.0 * eps)


cdef inline double ramp_curvature(double z, double eps) noexcept nogil:
    """d^2 ramp / dz^2."""
    if z <= -eps or z >= eps:
        return 0.0
    return 0.5 / eps


cdef inline double ramp_integral(double z, double eps) noexcept nogil:
    """Integral of ramp from -inf to z."""
    cdef double y
    if z <= -eps:
        return 0.0
    if z >= eps:
        return 0.5 * z * z + eps * eps / 6.0
    y = z + eps
    return y * (y * y) / (12.0 * eps)


cdef inline CouplerForce coupler_force_c(double delta, double rate, const double* cp) noexcept nogil:
    """Tension of a coupling ."""
    cdef double kd = cp[C_KD], kb = cp[C_KB], cd = cp[C_CD], cb = cp[C_CB]
    cdef double hs = cp[C_HALF_SLACK], td = cp[C_TD], tb = cp[C_TB], ks = cp[C_KS], eps = cp[C_EPS]
    cdef double zd = delta - hs
    cdef double zb = -delta - hs
    cdef double spring = (
        kd * ramp(zd, eps)
        + (ks - kd) * ramp(zd - td, eps)
        - kb * ramp(zb, eps)
        - (ks - kb) * ramp(zb - tb, eps)
    )
    cdef double hd = ramp_slope(zd, eps)
    cdef double hb = ramp_slope(zb, eps)
    cdef double c = cd * hd + cb * hb
    cdef double damper = c * rate
    cdef double k_spring = (
        kd * hd + (ks - kd) * ramp_slope(zd - td, eps) + kb * hb + (ks - kb) * ramp_slope(zb - tb, eps)
    )
    cdef double k = k_spring + rate * (cd * ramp_curvature(zd, eps) - cb * ramp_curvature(zb, eps))
    cdef double mu = cp[C_MU]
    cdef double vf, th, size
    cdef CouplerForce r
    if mu > 0.0:
        # wedge friction of the draft gears 
        vf = cp[C_VF]
        th = tanh_c(rate / vf)
        size = sqrt(spring * spring + 1.0) - 1.0
        damper += mu * size * th
        c += mu * size * (1.0 - th * th) / vf
        k += mu * th * k_spring * spring / (size + 1.0)
    r.spring = spring
    r.damper = damper
    r.k = k
    r.c = c
    return r


cdef double coupler_energy_c(double delta, const double* cp) noexcept nogil:
    """Potential energy stored in a coupling's springs [J]."""
    cdef double kd = cp[C_KD], kb = cp[C_KB]
    cdef double hs = cp[C_HALF_SLACK], td = cp[C_TD], tb = cp[C_TB], ks = cp[C_KS], eps = cp[C_EPS]
    cdef double zd = delta - hs
    cdef double zb = -delta - hs
    return (
        kd * ramp_integral(zd, eps)
        + (ks - kd) * ramp_integral(zd - td, eps)
        + kb * ramp_integral(zb, eps)
        + (ks - kb) * ramp_integral(zb - tb, eps)
    )


# ============================================================================ effort curves, profiles
cdef inline Effort effort_slope(double v, Py_ssize_t c, const Bank* bank, double vsel) noexcept nogil:
    """Force [N] and slope d F / d v [N s/m] of curve ``c`` of the bank at speed v >= 0 [m/s] (the law
    of ``effort`` in ``sim/_forces.pxd``). The law's interval is the one of speed ``vsel`` if >= 0: within
    a step the integrator keeps the interval of the step's start, since a law may jump where two
    intervals meet and Newton's method finds no root on a jump."""
    cdef int64_t lo = bank.coff[c]
    cdef int64_t hi = bank.coff[c + 1]
    cdef int64_t j = lo
    cdef double sel = v if vsel < 0.0 else vsel
    cdef Effort r
    while j + 1 < hi and bank.cs[j + 1] <= sel:
        j += 1
    cdef const double* co = bank.cc + 4 * j
    cdef double c0 = co[0], c1 = co[1], c2 = co[2], ch = co[3]
    cdef double f = c0 + c1 * v + c2 * v * v
    cdef double df = c1 + 2.0 * c2 * v
    if ch != 0.0:
        if v > 0.0:
            f += ch / v
            df -= ch / (v * v)
        else:
            f = INFINITY
            df = 0.0
    if f > bank.cfc[c]:
        f = bank.cfc[c]
        df = 0.0
    if v > 0.0 and f * v > bank.cpc[c]:
        f = bank.cpc[c] / v
        df = -bank.cpc[c] / (v * v)
    if f <= 0.0:
        r.f = 0.0
        r.df = 0.0
        return r
    r.f = f
    r.df = df
    return r


cdef inline Line profile_at(Py_ssize_t p, double s, const Prof* prof, int64_t* cache, Py_ssize_t i) noexcept nogil:
    """Line-resistance profile ``p`` at position s; ``cache[i]`` keeps vehicle i's last piece."""
    cdef int64_t lo = prof.poff[p]
    cdef int64_t hi = prof.poff[p + 1]
    cdef int64_t j = cache[i]
    cdef const double* px = prof.px
    cdef double x0, x1, f
    cdef const double* a
    cdef const double* b
    cdef Line r
    if j < lo or j > hi - 2:
        j = lo
    while j < hi - 2 and px[j + 1] <= s:
        j += 1
    while j > lo and px[j] > s:
        j -= 1
    cache[i] = j
    x0 = px[j]
    x1 = px[j + 1]
    if s <= x0:
        f = 0.0
    elif s >= x1:
        f = 1.0
    else:
        f = (s - x0) / (x1 - x0)
    a = prof.pval + 4 * j
    b = a + 4
    r.g = a[0] + (b[0] - a[0]) * f
    r.c = a[1] + (b[1] - a[1]) * f
    r.tu = a[2] + (b[2] - a[2]) * f
    r.b2 = a[3] + (b[3] - a[3]) * f
    return r


cdef inline double step_value(double s, const Steps* st) noexcept nogil:
    """Value of a piecewise constant function at s."""
    cdef Py_ssize_t k = search_right(st.x, st.nx, s) - 1
    if k < 0:
        k = 0
    if k > st.nval - 1:
        k = st.nval - 1
    return st.val[k]


cdef double linear_value(double s, const Ceiling* ce) noexcept nogil:
    """A ``PiecewiseLinear`` at s, the value from the right at a breakpoint."""
    cdef Py_ssize_t k = search_right(ce.x, ce.nleft + 1, s) - 1
    if k < 0:
        k = 0
    if k > ce.nleft - 1:
        k = ce.nleft - 1
    cdef double x0 = ce.x[k]
    cdef double f = (s - x0) / (ce.x[k + 1] - x0)
    if f < 0.0:
        f = 0.0
    if f > 1.0:
        f = 1.0
    return ce.left[k] + (ce.right[k] - ce.left[k]) * f


# ============================================================================ forces
cdef void vehicle_forces_c(
    const Model* md, const double* xm, const double* w, const double* v0, const double* bm,
    double* out, double* D, bint detail, double* parts,
) noexcept nogil:
    """External force on every vehicle [N] at midpoint positions ``xm`` and speeds ``w`` into ``out``,
    minus its derivative with respect to the vehicle's own speed into ``D``; with ``detail`` the
    parts (traction, electric brake, friction brake, running, gradient, curve, tunnel) into
    ``parts`` (n x 7), signed so that part x displacement is the work done by (traction) or against
    (the others) the train.

    ``v0`` are the speeds at the start of the step: the effort laws keep the interval of ``v0``, and
    the direction factor tanh(v / v_eps) of the dry-friction forces (running, curve and tunnel
    resistance, brakes) is taken at the end-of-step speed ``2 w - v0``. That part of the scheme is
    backward Euler, which damps the stiff friction law near standstill (the midpoint rule alone would
    let a held vehicle's speed flip sign from step to step); the kinetic-energy change of a step is
    still exactly the work of the applied forces over the step's displacement ``h w``.

    Braking with the blend flag: the command's full level is the service braking force (share
    ``S_BRAKE_FRACTION`` of the service curve) met by the electric brake first and by the friction
    brakes for the rest; in the regenerative-braking regime (``CMD[K_REGIME] == REGEN``) it is the
    larger of that and the electric brake's curve, as the single-point model's REGEN regime brakes."""
    cdef const double* SP = md.SP
    cdef const double* VP
    cdef const double* trac = md.trac
    cdef const double* elec = md.elec
    cdef double veps = SP[S_VEPS]
    cdef double frac = SP[S_BRAKE_FRACTION]
    cdef double decel = SP[S_DECEL]
    cdef double g = SP[S_G]
    cdef Py_ssize_t sc = <Py_ssize_t>SP[S_SERVICE_CURVE]
    cdef Py_ssize_t rc = <Py_ssize_t>SP[S_REGEN_CURVE]
    cdef bint blend = md.CMD[K_BLEND] > 0.5
    cdef bint electric_regime = blend and <int>md.CMD[K_REGIME] == REGEN and rc >= 0
    cdef Py_ssize_t i, c
    cdef double v, av, sgn, dsgn, m, L, r, dr, running, drun, weight, grad, curve, tun, tunnel
    cdef double curve_tunnel, dct, traction, dtr, a, electric, friction, dbr, need, demand, d_demand
    cdef double regen, d_regen, share_r, want, sub, rest, braking, d
    cdef Line ln
    cdef Effort e, es, er
    for i in range(md.n):
        VP = md.VP + N_V * i
        v = w[i]
        av = fabs(v)
        sgn = tanh_c((2.0 * v - v0[i]) / veps)
        dsgn = 2.0 * (1.0 - sgn * sgn) / veps
        m = VP[V_MASS]
        L = VP[V_LENGTH]
        r = VP[V_R0] + VP[V_R1] * av + VP[V_R2] * av * av
        dr = VP[V_R1] + 2.0 * VP[V_R2] * av
        running = r * sgn
        drun = dr * fabs(sgn) + r * dsgn
        ln = profile_at(<Py_ssize_t>VP[V_PROFILE], xm[i], &md.prof, md.pcache, i)
        weight = m * g
        grad = weight * ln.g
        curve = weight * ln.c * sgn
        tun = weight * (ln.tu + ln.b2 * v * v)
        tunnel = tun * sgn
        curve_tunnel = curve + tunnel
        dct = weight * ln.c * dsgn + weight * 2.0 * ln.b2 * av * fabs(sgn) + tun * dsgn
        traction = 0.0
        dtr = 0.0
        c = <Py_ssize_t>VP[V_CURVE]
        if c >= 0 and trac[i] > 0.0:
            e = effort_slope(av, c, &md.bank, fabs(v0[i]))
            a = trac[i] * step_value(xm[i] - 0.5 * L, &md.avail)
            traction = a * e.f
            dtr = a * e.df * (1.0 if v >= 0.0 else -1.0)
        electric = 0.0
        friction = 0.0
        dbr = 0.0
        if decel > 0.0:
            if bm[i] > 0.0:
                need = VP[V_INERTIAL] * decel * frac - running - grad - curve_tunnel
                if need > 0.0:
                    friction = bm[i] * need
        elif bm[i] > 0.0 or (elec[i] > 0.0 and VP[V_REGEN] > 0.0):
            es = effort_slope(av, sc, &md.bank, fabs(v0[i]))
            demand = frac * es.f
            d_demand = frac * es.df
            regen = 0.0
            d_regen = 0.0
            if rc >= 0:
                er = effort_slope(av, rc, &md.bank, fabs(v0[i]))
                regen = er.f
                d_regen = er.df
                if av < ELECTRIC_FADE_MPS:
                    # the electric brake fades out towards standstill; the friction brakes take over
                    d_regen = d_regen * av / ELECTRIC_FADE_MPS + regen / ELECTRIC_FADE_MPS
                    regen = regen * (av / ELECTRIC_FADE_MPS)
            if electric_regime and regen > demand:
                demand = regen
                d_demand = d_regen
            share_r = VP[V_REGEN]
            if share_r > 0.0 and elec[i] > 0.0 and rc >= 0:
                if blend:
                    want = elec[i] * demand
                    if want < regen:
                        electric = share_r * want
                        dbr += share_r * elec[i] * d_demand
                    else:
                        electric = share_r * regen
                        dbr += share_r * d_regen
                else:
                    electric = share_r * elec[i] * regen
                    dbr += share_r * elec[i] * d_regen
            if bm[i] > 0.0:
                sub = regen if blend else 0.0
                rest = bm[i] * demand - sub
                if rest > 0.0:
                    friction = VP[V_BRAKE] * rest
                    dbr += VP[V_BRAKE] * (bm[i] * d_demand - (d_regen if blend else 0.0))
        braking = electric + friction
        out[i] = traction - braking * sgn - running - grad - curve_tunnel
        d = drun + dct + braking * dsgn + dbr * fabs(sgn) - dtr
        D[i] = d if d > 0.0 else 0.0
        if detail:
            parts[N_PARTS * i + 0] = traction
            parts[N_PARTS * i + 1] = electric * sgn
            parts[N_PARTS * i + 2] = friction * sgn
            parts[N_PARTS * i + 3] = running
            parts[N_PARTS * i + 4] = grad
            parts[N_PARTS * i + 5] = curve
            parts[N_PARTS * i + 6] = tunnel


cdef inline void thomas_c(
    Py_ssize_t n, const double* diag, const double* off, const double* rhs, double* out, double* cprime
) noexcept nogil:
    """Solve the symmetric tridiagonal system (diagonal ``diag``, off-diagonal ``off``) for ``rhs``."""
    cdef Py_ssize_t i
    cdef double den
    if n == 1:
        out[0] = rhs[0] / diag[0]
        return
    cprime[0] = off[0] / diag[0]
    out[0] = rhs[0] / diag[0]
    for i in range(1, n):
        den = diag[i] - off[i - 1] * cprime[i - 1]
        if i < n - 1:
            cprime[i] = off[i] / den
        out[i] = (rhs[i] - off[i - 1] * out[i - 1]) / den
    for i in range(n - 2, -1, -1):
        out[i] -= cprime[i] * out[i + 1]


# ============================================================================ one implicit step
cdef int implicit_step_c(
    const Model* md, const double* x0, const double* v0, double h, double* w, const double* bm, Work* ws
) noexcept nogil:
    """Solve the implicit midpoint step of length h from (x0, v0) for the midpoint speeds ``w`` (given
    as the initial guess): the number of Newton iterations, -1 without convergence. On return the work
    arrays hold the forces of the last iteration, whose speeds differ from the solution by less than
    the tolerance (the energy accounting uses them: its error is of the order of the Newton residual)."""
    cdef Py_ssize_t n = md.n
    cdef const double* VP = md.VP
    cdef double tol = md.SP[S_NEWTON_TOL]
    cdef double veps = md.SP[S_VEPS]
    cdef double hh = 0.5 * h
    cdef int it
    cdef Py_ssize_t i
    cdef double T_front, T_back, kc_front, kc_back, k_pos, mi, dg, damping, big, w_new, ve_old, ve_new
    cdef CouplerForce f
    # 2 m_i / h does not change within a step: one division per vehicle and step, not per iteration
    for i in range(n):
        ws.m2h[i] = 2.0 * VP[N_V * i + V_INERTIAL] / h
    for it in range(MAX_NEWTON):
        for i in range(n):
            ws.xm[i] = x0[i] + hh * w[i]
        vehicle_forces_c(md, ws.xm, w, v0, bm, ws.F, ws.D, True, ws.parts)
        # one pass: the coupling behind vehicle i (its tension and its Jacobian term, carried on as the
        # next vehicle's front coupling) and vehicle i's row of the residual and of the Jacobian
        T_front = 0.0
        kc_front = 0.0
        kc_back = 0.0
        for i in range(n):
            if i < n - 1:
                f = coupler_force_c(
                    ws.xm[i] - VP[N_V * i + V_LENGTH] - ws.xm[i + 1], w[i] - w[i + 1], md.CP + N_C * i
                )
                ws.Ts[i] = f.spring
                ws.Td[i] = f.damper
                k_pos = f.k if f.k > 0.0 else 0.0
                T_back = f.spring + f.damper
                kc_back = hh * k_pos + f.c
            else:
                T_back = 0.0
            mi = VP[N_V * i + V_INERTIAL]
            ws.G[i] = 2.0 * mi * (w[i] - v0[i]) / h - (ws.F[i] + T_front - T_back)
            dg = ws.m2h[i] + ws.D[i]
            if i > 0:
                dg += kc_front
            if i < n - 1:
                dg += kc_back
                ws.off[i] = -kc_back
            ws.diag[i] = dg
            T_front = T_back
            kc_front = kc_back
        thomas_c(n, ws.diag, ws.off, ws.G, ws.dw, ws.cprime)
        # Newton can cycle next to a kink of a force law; after a few full steps, half steps
        damping = 1.0 if it < DAMPED_FROM else 0.5
        big = 0.0
        for i in range(n):
            w_new = w[i] - damping * ws.dw[i]
            # an update that would carry a vehicle's end speed across 0 from outside the dry-friction
            # zone stops it at 0 first
            ve_old = 2.0 * w[i] - v0[i]
            ve_new = 2.0 * w_new - v0[i]
            if ve_old * ve_new < 0.0 and fabs(ve_old) > 2.0 * veps:
                w_new = 0.5 * v0[i]
            if fabs(w_new - w[i]) > big:
                big = fabs(w_new - w[i])
            w[i] = w_new
        if not isfinite(big):
            return -1
        if big < tol:
            return it + 1
        # The damped iterations converge linearly, halving the update at best (measured on the examples:
        # every step that converged after the 7th iteration had at iteration it an update below
        # tol 2^(11 - it), at most 0.995 times that). An update HOPELESS_MARGIN times larger cannot reach
        # the tolerance within MAX_NEWTON: the step is halved now instead of after the last iteration
        # (the same halving, without the iterations whose result was discarded).
        if it >= DAMPED_FROM + 1 and big > tol * (HOPELESS_MARGIN * <double>(1 << (MAX_NEWTON - 1 - it))):
            return -1
    return -1


# ============================================================================ brake command history
cdef double history_value(double t, const double* hist, Py_ssize_t nh) noexcept nogil:
    """Friction brake command at time t from the history (rows of time, value)."""
    cdef Py_ssize_t lo, hi, mid
    if nh <= 1 or t >= hist[2 * (nh - 1)]:
        return hist[2 * (nh - 1) + 1]
    lo = 0
    hi = nh - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if hist[2 * mid] <= t:
            lo = mid
        else:
            hi = mid
    return hist[2 * lo + 1]


# ============================================================================ controller
cdef double reference_speed(double s, const Ref* ref) noexcept nogil:
    """Reference speed at head position s [m/s]."""
    cdef Py_ssize_t n = ref.n
    if s <= ref.s[0]:
        return sqrt(pmax(ref.v2[0], 0.0))
    if s >= ref.s[n - 1]:
        return sqrt(pmax(ref.v2[n - 1], 0.0))
    cdef Py_ssize_t k = search_right(ref.s, n, s) - 1
    cdef double ds = ref.s[k + 1] - ref.s[k]
    if ds <= 0.0:
        return sqrt(pmax(ref.v2[k + 1], 0.0))
    cdef double f = (s - ref.s[k]) / ds
    return sqrt(pmax(ref.v2[k] + (ref.v2[k + 1] - ref.v2[k]) * f, 0.0))


cdef double reference_acceleration(double s, const Ref* ref) noexcept nogil:
    """Acceleration of the reference at head position s [m/s^2]."""
    cdef Py_ssize_t n = ref.n
    if s < ref.s[0] or s >= ref.s[n - 1]:
        return 0.0
    cdef Py_ssize_t k = search_right(ref.s, n, s) - 1
    cdef double ds = ref.s[k + 1] - ref.s[k]
    if ds <= 0.0:
        return 0.0
    return 0.5 * (ref.v2[k + 1] - ref.v2[k]) / ds


cdef int reference_regime(double s, const Ref* ref) noexcept nogil:
    """Regime of the reference stretch containing head position s."""
    cdef Py_ssize_t n = ref.n
    if s >= ref.s[n - 1]:
        return ref.m[n - 2] if n > 1 else ref.m[0]
    cdef Py_ssize_t k = search_right(ref.s, n, s) - 1
    if k < 0:
        k = 0
    while k + 1 < n - 1 and ref.s[k + 1] <= s:
        k += 1
    return ref.m[k]


cdef Command control_c(
    const Model* md, const double* x, const double* v, const Ref* ref, const Ceiling* ceiling
) noexcept nogil:
    """Command in [-1, 1], regime and mean speed that follow the reference profile.

    The regime is the reference's at the head (braking when the reference brakes one mean brake delay
    ahead). The controller asks for the force that holds the present mean speed (from the vehicles'
    own resistances) plus the force that closes the speed error in ``S_TAU`` seconds, as a command:
    traction (up to full) towards the speed ceiling (or the reference speed), cruising at the
    reference speed, coasting unless above the ceiling, full service braking eased when below the
    braking curve."""
    cdef const double* SP = md.SP
    cdef const double* VP
    cdef Py_ssize_t n = md.n
    cdef double mtot = 0.0, mom = 0.0, resist = 0.0, fmax = 0.0
    cdef double veps = SP[S_VEPS]
    cdef double g = SP[S_G]
    cdef Py_ssize_t i, c, rc
    cdef double mi, av, sgn, r, vc, s, bmax, v_ref, ceil, ahead, rate, base, ease, u, want, target
    cdef double preview
    cdef int regime, regime_ahead
    cdef bint short
    cdef Line ln
    cdef Effort e
    cdef Command out
    for i in range(n):
        VP = md.VP + N_V * i
        mi = VP[V_INERTIAL]
        mtot += mi
        mom += mi * v[i]
        av = fabs(v[i])
        sgn = tanh_c(v[i] / veps)
        r = VP[V_R0] + VP[V_R1] * av + VP[V_R2] * av * av
        ln = profile_at(<Py_ssize_t>VP[V_PROFILE], x[i], &md.prof, md.pcache, i)
        resist += r * sgn + VP[V_MASS] * g * (ln.g + (ln.c + ln.tu + ln.b2 * v[i] * v[i]) * sgn)
        c = <Py_ssize_t>VP[V_CURVE]
        if c >= 0:
            e = effort_slope(av, c, &md.bank, -1.0)
            fmax += e.f * step_value(x[i] - 0.5 * VP[V_LENGTH], &md.avail)
    vc = mom / mtot
    s = x[0]
    if SP[S_DECEL] > 0.0:
        bmax = mtot * SP[S_DECEL] * SP[S_BRAKE_FRACTION]
    else:
        e = effort_slope(fabs(vc), <Py_ssize_t>SP[S_SERVICE_CURVE], &md.bank, -1.0)
        bmax = SP[S_BRAKE_FRACTION] * e.f
    regime = reference_regime(s, ref)
    v_ref = reference_speed(s, ref)
    ceil = linear_value(s, ceiling)
    ahead = s + pmax(vc, 0.0) * SP[S_LOOKAHEAD]
    if SP[S_LOOKAHEAD] > 0.0 and ahead > s:
        regime_ahead = reference_regime(ahead, ref)
        if regime_ahead == BRAKE or regime_ahead == REGEN:
            if regime_ahead == BRAKE or regime != BRAKE:
                regime = regime_ahead
            v_ref = pmin(v_ref, reference_speed(ahead, ref))
    rate = mtot / SP[S_TAU]
    if regime == BRAKE or regime == REGEN:
        # full service braking (or the full electric brake alone in REGEN), eased below the curve
        base = -1.0
        rc = <Py_ssize_t>SP[S_REGEN_CURVE]
        if regime == REGEN and rc >= 0 and bmax > 0.0:
            e = effort_slope(fabs(vc), rc, &md.bank, -1.0)
            if SP[S_DECEL] <= 0.0:
                bmax = pmax(bmax, e.f)
            base = -pmin(1.0, e.f / bmax)
        ease = rate * (pmin(v_ref, ceil) - pmax(vc, 0.0))
        u = base + (ease / bmax if bmax > 0.0 else 0.0)
        if s >= ref.stop_at - SP[S_STOP_WINDOW] and vc < 0.5:
            u = -1.0
        elif u > 0.0:
            # no traction while braking, except to draw up to a stop the train came to rest short of
            short = ref.stop_at - s > SP[S_STOP_WINDOW] and vc < 0.5 * v_ref
            if short:
                want = resist + ease
                u = want / fmax if fmax > 0.0 else 0.0
            else:
                u = 0.0
    else:
        if regime == TRACTION:
            if SP[S_TRACK_PROFILE] > 0.5:
                preview = s + pmax(vc, 1.0) * SP[S_TAU]
                target = pmin(pmax(v_ref, reference_speed(preview, ref)), ceil)
            else:
                target = ceil
            want = resist + rate * (target - vc)
        elif regime == CRUISE or regime == FOLLOW:
            target = pmin(v_ref, ceil)
            want = resist + rate * (target - vc)
            if regime == FOLLOW:
                want += mtot * reference_acceleration(s, ref)
        else:
            target = ceil
            want = resist + rate * (target - vc)
        if want >= 0.0:
            u = want / fmax if fmax > 0.0 else 0.0
        else:
            u = want / bmax if bmax > 0.0 else -1.0
        if regime == COAST and u > 0.0:
            u = 0.0
    if u > 1.0:
        u = 1.0
    if u < -1.0:
        u = -1.0
    out.u = u
    out.regime = regime
    out.vc = vc
    return out


# ============================================================================ the main loop
cdef double force_error(
    const double* Tend, Py_ssize_t nc, const double* tmem, const double* tmem_t, int nmem, double t1
) noexcept nogil:
    """Largest deviation of the coupler forces at the end of a step (time t1) from their quadratic
    extrapolation through the ends of the three previous steps [N] (``tmem`` is 3 x nc): a third
    difference (about h^3 d3T/dt3), small while the forces vary smoothly, large at impacts."""
    if nmem < 3:
        return 0.0
    cdef double ta = tmem_t[0], tb = tmem_t[1], tc = tmem_t[2]
    cdef double la = (t1 - tb) * (t1 - tc) / ((ta - tb) * (ta - tc))
    cdef double lb = (t1 - ta) * (t1 - tc) / ((tb - ta) * (tb - tc))
    cdef double lc = (t1 - ta) * (t1 - tb) / ((tc - ta) * (tc - tb))
    cdef double err = 0.0, e
    cdef Py_ssize_t k
    for k in range(nc):
        e = fabs(Tend[k] - (la * tmem[k] + lb * tmem[nc + k] + lc * tmem[2 * nc + k]))
        if e > err:
            err = e
    return err


cdef struct Records:
    double* t
    double* x  # cap x n
    double* v
    double* a
    double* T  # cap x nc
    double* agg  # cap x N_R
    Py_ssize_t cap
    Py_ssize_t nc


cdef Py_ssize_t record_c(
    const Model* md, Py_ssize_t nrec, double t, const double* x, const double* v, const double* a_last,
    const double* parts, double* acc, Records* rec,
) noexcept nogil:
    """Store the state at time t as record ``nrec``."""
    cdef Py_ssize_t n = md.n
    cdef Py_ssize_t i, k, j
    cdef double mtot = 0.0, mom = 0.0, kinetic = 0.0, mi, spring = 0.0, delta
    cdef double tr = 0.0, el = 0.0, fr = 0.0, ru = 0.0, gr = 0.0, cu = 0.0, tu = 0.0, ptr = 0.0, pel = 0.0
    cdef const double* p
    cdef CouplerForce f
    rec.t[nrec] = t
    for i in range(n):
        rec.x[nrec * n + i] = x[i]
        rec.v[nrec * n + i] = v[i]
        rec.a[nrec * n + i] = a_last[i]
        mi = md.VP[N_V * i + V_INERTIAL]
        mtot += mi
        mom += mi * v[i]
        kinetic += 0.5 * mi * v[i] * v[i]
    for k in range(n - 1):
        delta = x[k] - md.VP[N_V * k + V_LENGTH] - x[k + 1]
        f = coupler_force_c(delta, v[k] - v[k + 1], md.CP + N_C * k)
        rec.T[nrec * rec.nc + k] = f.spring + f.damper
        spring += coupler_energy_c(delta, md.CP + N_C * k)
    cdef double* agg = rec.agg + N_R * nrec
    agg[R_HEAD] = x[0]
    agg[R_SPEED] = mom / mtot
    agg[R_COMMAND] = md.CMD[K_COMMAND]
    agg[R_REGIME] = md.CMD[K_REGIME]
    for i in range(n):
        p = parts + N_PARTS * i
        tr += p[0]
        el += fabs(p[1])
        fr += fabs(p[2])
        ru += p[3]
        gr += p[4]
        cu += p[5]
        tu += p[6]
        ptr += p[0] * v[i]
        pel += p[1] * v[i]
    agg[R_TRACTION] = tr
    agg[R_ELECTRIC] = el
    agg[R_FRICTION] = fr
    agg[R_RUNNING] = ru
    agg[R_GRADIENT] = gr
    agg[R_CURVE] = cu
    agg[R_TUNNEL] = tu
    agg[R_TRACTION_POWER] = ptr
    agg[R_ELECTRIC_POWER] = pel
    agg[R_PEAK_POWER] = acc[A_PEAK_POWER]
    acc[A_PEAK_POWER] = -INFINITY
    agg[R_KINETIC] = kinetic
    agg[R_SPRING] = spring
    for j in range(N_WORKS):
        agg[R_W0 + j] = acc[A_TRACTION + j]
    return nrec + 1


cdef struct State:
    double* x
    double* v
    double* b
    double* tt
    double* a_last
    double* next_rec
    double* tmem  # 3 x nc
    double* tmem_t  # 3


cdef struct Loop:
    double* w
    double* bm
    double* tgt
    double* x1
    double* v1
    double* Tend  # nc


cdef int run_c(
    const Model* md, int mode, double t_end, State* st, const Ref* ref, const Ceiling* ceiling,
    double* hist, Py_ssize_t hist_cap, Py_ssize_t* nh_io, double* acc, Records* rec, Py_ssize_t* nrec_io,
    double* ext, Py_ssize_t n_ext, double route_end, Work* ws, Loop* lp,
) noexcept nogil:
    """Integrate until ``t_end`` or an event (mode 0: fixed commands in CMD / trac / elec; mode 1:
    follow the reference and stop at its end); returns the status.

    Step size: at most ``S_STEP``; with a force tolerance ``S_FORCE_TOL`` > 0 a step whose coupler
    forces leave their extrapolation (``force_error``) by more than the tolerance is repeated shorter,
    and the next step is sized for the tolerance (third-order law), down to ``S_STEP_MIN``. A step
    whose Newton iterations do not converge is halved."""
    cdef Py_ssize_t n = md.n
    cdef Py_ssize_t nc = rec.nc
    cdef const double* SP = md.SP
    cdef const double* VP = md.VP
    cdef double* CMD = md.CMD
    cdef double* x = st.x
    cdef double* v = st.v
    cdef double* b = st.b
    cdef double* a_last = st.a_last
    cdef double* w = lp.w
    cdef double* bm = lp.bm
    cdef double* tgt = lp.tgt
    cdef double* x1 = lp.x1
    cdef double* v1 = lp.v1
    cdef double* Tend = lp.Tend
    cdef double* parts = ws.parts
    cdef Py_ssize_t nh = nh_io[0]
    cdef Py_ssize_t nrec = nrec_io[0]
    cdef double h_max = SP[S_STEP]
    cdef double h_min = SP[S_STEP_MIN]
    cdef double tol = SP[S_FORCE_TOL]
    cdef double build = SP[S_BUILD_UP]
    cdef double eta_t = SP[S_ETA_T]
    cdef double eta_r = SP[S_ETA_R]
    cdef double rest_speed = SP[S_REST_SPEED]
    cdef double t = st.tt[0]
    cdef int status = ST_TIME
    cdef int its = 0
    cdef double h, u, u_max, err, tm, decay, target, dx, p_tr, p_el, ddelta, line_power, grow, tension
    cdef double mom, mtot, stop_at
    cdef bint at_rest, per_coupling
    cdef Py_ssize_t i, k, j
    cdef Command cmd
    cdef CouplerForce f
    cdef const double* p
    if acc[A_H] <= 0.0:
        acc[A_H] = h_max if tol <= 0.0 else pmax(h_min, 0.25 * h_max)
    per_coupling = n_ext >= N_E + N_EK * (n - 1)
    while t < t_end - 1e-12:
        h = pmin(acc[A_H], t_end - t)
        if tol > 0.0 and acc[A_NMEM] < 3:
            # no error estimate yet (start, or after a dwell): small steps until there is one
            h = pmin(h, 4.0 * h_min)
        # ---- command for this step
        if mode == 1:
            cmd = control_c(md, x, v, ref, ceiling)
            u = cmd.u
            if SP[S_RAMP] > 0.0 and u > 0.0:
                # the effort rises gradually: by the time since the previous command at most
                u_max = pmax(CMD[K_COMMAND], 0.0) + acc[A_LAST_H] / SP[S_RAMP]
                if u > u_max:
                    u = u_max
            CMD[K_COMMAND] = u
            CMD[K_REGIME] = cmd.regime
            CMD[K_BLEND] = 1.0
            CMD[K_FRICTION] = -u if u < 0.0 else 0.0
            for i in range(n):
                md.trac[i] = u if (u > 0.0 and VP[N_V * i + V_CURVE] >= 0) else 0.0
                md.elec[i] = -u if u < 0.0 else 0.0
        # ---- brake command history (only changes are stored)
        if fabs(hist[2 * (nh - 1) + 1] - CMD[K_FRICTION]) > 1e-12:
            if nh >= hist_cap:
                status = ST_HISTORY_FULL
                break
            hist[2 * nh] = t
            hist[2 * nh + 1] = CMD[K_FRICTION]
            nh += 1
        # ---- one step, shortened until Newton converges and the force error is within tolerance
        err = 0.0
        tm = t
        while True:
            tm = t + 0.5 * h
            decay = exp(-0.5 * h / build) if build > 0.0 else 0.0
            for i in range(n):
                target = history_value(tm - VP[N_V * i + V_DELAY], hist, nh)
                tgt[i] = target
                if build > 0.0:
                    bm[i] = target + (b[i] - target) * decay
                else:
                    bm[i] = target
                w[i] = v[i] + 0.5 * h * a_last[i]
            its = implicit_step_c(md, x, v, h, w, bm, ws)
            if its < 0:
                if h <= h_min * 1.000001:
                    break
                h = pmax(0.5 * h, h_min)
                acc[A_SUBSTEPS] += 1
                continue
            acc[A_NEWTON] += its
            for i in range(n):
                x1[i] = x[i] + h * w[i]
                v1[i] = 2.0 * w[i] - v[i]
            for k in range(n - 1):
                f = coupler_force_c(x1[k] - VP[N_V * k + V_LENGTH] - x1[k + 1], v1[k] - v1[k + 1], md.CP + N_C * k)
                Tend[k] = f.spring + f.damper
            if tol > 0.0:
                err = force_error(Tend, nc, st.tmem, st.tmem_t, <int>acc[A_NMEM], t + h)
                if err > tol and h > h_min * 1.000001:
                    h = pmax(h_min, h * pmax(0.2, 0.9 * pow(tol / err, 1.0 / 3.0)))
                    acc[A_REJECTED] += 1
                    continue
            break
        if its < 0:
            status = ST_FAILED
            break
        acc[A_STEPS] += 1
        # ---- accept: energy accounting with the midpoint forces (exact for the midpoint rule)
        p_tr = 0.0
        p_el = 0.0
        for i in range(n):
            dx = h * w[i]
            p = parts + N_PARTS * i
            acc[A_TRACTION] += p[0] * dx
            acc[A_ELECTRIC] += p[1] * dx
            acc[A_FRICTION] += p[2] * dx
            acc[A_RUNNING] += p[3] * dx
            acc[A_GRADIENT] += p[4] * dx
            acc[A_CURVE] += p[5] * dx
            acc[A_TUNNEL] += p[6] * dx
            p_tr += p[0] * w[i]
            p_el += p[1] * w[i]
        for k in range(n - 1):
            ddelta = h * (w[k] - w[k + 1])
            acc[A_DAMPER] += ws.Td[k] * ddelta
            acc[A_SPRING_WORK] -= ws.Ts[k] * ddelta
        line_power = p_tr / eta_t - p_el * eta_r
        if line_power > acc[A_PEAK_POWER]:
            acc[A_PEAK_POWER] = line_power
        decay = exp(-h / build) if build > 0.0 else 0.0
        for i in range(n):
            a_last[i] = (v1[i] - v[i]) / h
            x[i] = x1[i]
            v[i] = v1[i]
            target = tgt[i]
            if build > 0.0:
                b[i] = target + (b[i] - target) * decay
            else:
                b[i] = target
        t += h
        st.tt[0] = t
        acc[A_LAST_H] = h
        acc[A_INTEGRATED] += h
        # ---- size of the next step
        if tol > 0.0:
            grow = 2.0 if err <= 0.0 else pmin(2.0, 0.9 * pow(tol / err, 1.0 / 3.0))
            acc[A_H] = pmin(h_max, pmax(h_min, h * pmax(grow, 0.2)))
        else:
            acc[A_H] = h_max
        for j in range(2):
            st.tmem_t[j] = st.tmem_t[j + 1]
            for k in range(n - 1):
                st.tmem[j * nc + k] = st.tmem[(j + 1) * nc + k]
        st.tmem_t[2] = t
        for k in range(n - 1):
            st.tmem[2 * nc + k] = Tend[k]
        if acc[A_NMEM] < 3:
            acc[A_NMEM] += 1
        # ---- extremes of the coupler forces at the end of the step
        for k in range(n - 1):
            tension = Tend[k]
            if tension > ext[E_DRAFT]:
                ext[E_DRAFT] = tension
                ext[E_DRAFT_K] = k
                ext[E_DRAFT_T] = t
                ext[E_DRAFT_HEAD] = x[0]
            if tension < ext[E_BUFF]:
                ext[E_BUFF] = tension
                ext[E_BUFF_K] = k
                ext[E_BUFF_T] = t
                ext[E_BUFF_HEAD] = x[0]
            if per_coupling:
                j = N_E + N_EK * k
                if tension > ext[j + EK_DRAFT]:
                    ext[j + EK_DRAFT] = tension
                    ext[j + EK_DRAFT_T] = t
                    ext[j + EK_DRAFT_HEAD] = x[0]
                if tension < ext[j + EK_BUFF]:
                    ext[j + EK_BUFF] = tension
                    ext[j + EK_BUFF_T] = t
                    ext[j + EK_BUFF_HEAD] = x[0]
        # ---- events: at rest when the mean speed is below the rest speed and no vehicle faster
        # than 10 x that (vehicles still creep while compressed couplers relax against the brakes)
        at_rest = True
        mom = 0.0
        mtot = 0.0
        for i in range(n):
            mom += VP[N_V * i + V_INERTIAL] * v[i]
            mtot += VP[N_V * i + V_INERTIAL]
            if fabs(v[i]) > 10.0 * rest_speed:
                at_rest = False
        if fabs(mom / mtot) > rest_speed:
            at_rest = False
        if mode == 1:
            stop_at = ref.stop_at
            if at_rest and x[0] >= stop_at - SP[S_STOP_WINDOW]:
                status = ST_STOPPED
            if at_rest and CMD[K_COMMAND] >= 1.0:
                if acc[A_REST_SINCE] < 0.0:
                    acc[A_REST_SINCE] = t
                elif t - acc[A_REST_SINCE] > SP[S_STALL_S]:
                    status = ST_STALLED
            else:
                acc[A_REST_SINCE] = -1.0
        if x[0] >= route_end:
            status = ST_END_OF_ROUTE
        # ---- record
        if t >= st.next_rec[0] - 1e-9 or status != ST_TIME:
            if nrec >= rec.cap:
                status = ST_RECORD_FULL
                break
            nrec = record_c(md, nrec, t, x, v, a_last, parts, acc, rec)
            st.next_rec[0] = pmax(st.next_rec[0] + SP[S_RECORD_DT], t)
        if status != ST_TIME:
            break
    nh_io[0] = nh
    nrec_io[0] = nrec
    return status


# ============================================================================ reading the arrays
# Arrays are read through the buffer protocol rather than typed memoryviews (as sim/_trace_c): the same
# pointers without the memoryview support code. Every buffer a call takes is held until it returns.
# (``Held``, ``release``, ``is_format``: trainsim/_cbuffers.pxd; run holds 9 state + 6 model + 5 bank
# + 3 profile + 2 availability + 3 reference + 3 ceiling + history + accumulators + 6 records
# + extremes + work = 41)


cdef void* hold(
    Held* held, str name, object a, char kind, bint writable, int ndim, Py_ssize_t rows, Py_ssize_t cols
) except NULL:
    """Data pointer of ``a``, a C-contiguous array of ``kind`` (``d``: float64, ``q``: int64, ``b``:
    int8) with ``ndim`` dimensions, ``rows`` rows (-1: any) and ``cols`` columns (2-D; -1: any), held
    in ``held`` until ``release``. Errors name the argument and what is allowed."""
    if held.count >= MAX_HELD:
        raise RuntimeError(f"internal: more than {MAX_HELD} arrays held")
    cdef Py_buffer* view = &held.views[held.count]
    kindname = {c'd': "float64", c'q': "int64", c'b': "int8"}[kind]
    shape = ("(n,)" if rows < 0 else f"({rows},)") if ndim == 1 else (
        f"({'n' if rows < 0 else rows}, {'m' if cols < 0 else cols})"
    )
    want = f"a C-contiguous{' writable' if writable else ''} {kindname} array of shape {shape}"
    try:
        PyObject_GetBuffer(a, view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (PyBUF_WRITABLE if writable else 0))
    except (TypeError, ValueError, BufferError) as err:
        raise ValueError(f"{name}: need {want} ({err})") from None
    held.count += 1
    if not is_format(view.format, kind):
        fmt = view.format.decode("ascii", "replace") if view.format != NULL else "B"
        raise ValueError(f"{name}: need {want}, got items of format {fmt!r}")
    got = tuple(view.shape[k] for k in range(view.ndim))
    if view.ndim != ndim or (rows >= 0 and got[0] != rows) or (ndim == 2 and cols >= 0 and got[1] != cols):
        raise ValueError(f"{name}: need {want}, got shape {got}")
    if view.len == 0:
        # a zero-size buffer may carry no pointer; nothing is read through it
        return <void*>held
    return view.buf


cdef Py_ssize_t rows_of(Held* held) noexcept:
    """Rows of the buffer held last."""
    return held.views[held.count - 1].shape[0]


cdef int bank_from(Held* held, object bank, Bank* out) except -1:
    if not isinstance(bank, tuple) or len(bank) != 5:
        raise ValueError(f"bank: need a tuple (starts, coefficients, offsets, force caps, power caps), got {bank!r:.60}")
    cs, cc, coff, cfc, cpc = bank
    out.cs = <const double*>hold(held, "bank starts", cs, c'd', False, 1, -1, -1)
    cdef Py_ssize_t ns = rows_of(held)
    out.cc = <const double*>hold(held, "bank coefficients", cc, c'd', False, 2, ns, 4)
    out.coff = <const int64_t*>hold(held, "bank offsets", coff, c'q', False, 1, -1, -1)
    out.n_curves = rows_of(held) - 1
    out.cfc = <const double*>hold(held, "bank force caps", cfc, c'd', False, 1, out.n_curves, -1)
    out.cpc = <const double*>hold(held, "bank power caps", cpc, c'd', False, 1, out.n_curves, -1)
    cdef Py_ssize_t k
    for k in range(out.n_curves + 1):
        if not (0 <= out.coff[k] <= ns) or (k > 0 and out.coff[k] <= out.coff[k - 1]):
            raise ValueError(f"bank offsets: need increasing offsets from 0 to {ns}, one interval per curve at least")
    return 0


cdef int prof_from(Held* held, object prof, Prof* out) except -1:
    if not isinstance(prof, tuple) or len(prof) != 3:
        raise ValueError(f"prof: need a tuple (offsets, nodes, values), got {prof!r:.60}")
    poff, px, pval = prof
    out.poff = <const int64_t*>hold(held, "prof offsets", poff, c'q', False, 1, -1, -1)
    out.n_profiles = rows_of(held) - 1
    out.px = <const double*>hold(held, "prof nodes", px, c'd', False, 1, -1, -1)
    cdef Py_ssize_t nx = rows_of(held)
    out.pval = <const double*>hold(held, "prof values", pval, c'd', False, 2, nx, 4)
    cdef Py_ssize_t k
    for k in range(out.n_profiles + 1):
        if not (0 <= out.poff[k] <= nx) or (k > 0 and out.poff[k] < out.poff[k - 1] + 2):
            raise ValueError(f"prof offsets: need offsets from 0 to {nx}, two nodes per profile at least")
    return 0


cdef int avail_from(Held* held, object avail, Steps* out) except -1:
    if not isinstance(avail, tuple) or len(avail) != 2:
        raise ValueError(f"avail: need a tuple (breakpoints, values), got {avail!r:.60}")
    ax, aval = avail
    out.x = <const double*>hold(held, "avail breakpoints", ax, c'd', False, 1, -1, -1)
    out.nx = rows_of(held)
    out.val = <const double*>hold(held, "avail values", aval, c'd', False, 1, -1, -1)
    out.nval = rows_of(held)
    if out.nval < 1:
        raise ValueError("avail values: need at least one value")
    return 0


cdef int model_from(
    Held* held, Py_ssize_t n, object VP, object CP, object SP, object CMD, object trac, object elec,
    object bank, object prof, object avail, object pcache, Model* md,
) except -1:
    md.n = n
    md.VP = <const double*>hold(held, "VP", VP, c'd', False, 2, n, N_V)
    md.CP = <const double*>hold(held, "CP", CP, c'd', False, 2, n - 1 if n > 1 else -1, N_C)
    md.SP = <const double*>hold(held, "SP", SP, c'd', False, 1, N_S, -1)
    md.CMD = <double*>hold(held, "CMD", CMD, c'd', True, 1, N_K, -1)
    md.trac = <double*>hold(held, "trac", trac, c'd', True, 1, n, -1)
    md.elec = <double*>hold(held, "elec", elec, c'd', True, 1, n, -1)
    bank_from(held, bank, &md.bank)
    prof_from(held, prof, &md.prof)
    avail_from(held, avail, &md.avail)
    md.pcache = <int64_t*>hold(held, "pcache", pcache, c'q', True, 1, n, -1)
    cdef Py_ssize_t i, c, p
    for i in range(n):
        c = <Py_ssize_t>md.VP[N_V * i + V_CURVE]
        p = <Py_ssize_t>md.VP[N_V * i + V_PROFILE]
        if c >= md.bank.n_curves or c < -1:
            raise ValueError(f"VP[{i}, V_CURVE] = {c}: need -1 or a curve of the bank, 0 .. {md.bank.n_curves - 1}")
        if not 0 <= p < md.prof.n_profiles:
            raise ValueError(f"VP[{i}, V_PROFILE] = {p}: need a profile, 0 .. {md.prof.n_profiles - 1}")
    for name, k in (("S_SERVICE_CURVE", S_SERVICE_CURVE), ("S_REGEN_CURVE", S_REGEN_CURVE)):
        c = <Py_ssize_t>md.SP[k]
        if c >= md.bank.n_curves or c < (0 if k == S_SERVICE_CURVE else -1):
            raise ValueError(f"SP[{name}] = {c}: need a curve of the bank, 0 .. {md.bank.n_curves - 1}")
    return 0


# ============================================================================ entry points
def tanh(double z) -> float:
    """np.tanh(z), without the library call where it rounds to +-1 (|z| >= 22)."""
    return tanh_c(z)


cdef const double* coupler_row(Held* held, object cp) except NULL:
    return <const double*>hold(held, "cp", cp, c'd', False, 1, N_C, -1)


def coupler_force(double delta, double rate, cp) -> tuple:
    """Tension of a coupling [N] at extension ``delta`` [m] and rate [m/s] with parameters ``cp`` (a
    row of ``N_C``): ``(spring, damper, d tension / d delta, d tension / d rate)``."""
    cdef Held held
    held.count = 0
    cdef CouplerForce f
    try:
        f = coupler_force_c(delta, rate, coupler_row(&held, cp))
    finally:
        release(&held)
    return f.spring, f.damper, f.k, f.c


def coupler_energy(double delta, cp) -> float:
    """Potential energy stored in a coupling's springs [J] at extension ``delta`` [m]."""
    cdef Held held
    held.count = 0
    cdef double e
    try:
        e = coupler_energy_c(delta, coupler_row(&held, cp))
    finally:
        release(&held)
    return e


def thomas(diag, off, rhs, out, cprime) -> None:
    """Solve the symmetric tridiagonal system (diagonal ``diag`` of n, off-diagonal ``off`` of n - 1 or
    more) for ``rhs`` into ``out``; ``cprime`` (n) is work space."""
    cdef Held held
    held.count = 0
    cdef Py_ssize_t n
    cdef const double* d
    cdef const double* o
    cdef const double* r
    cdef double* o_
    cdef double* c
    try:
        d = <const double*>hold(&held, "diag", diag, c'd', False, 1, -1, -1)
        n = rows_of(&held)
        if n < 1:
            raise ValueError("diag: need at least one element")
        o = <const double*>hold(&held, "off", off, c'd', False, 1, -1, -1)
        if rows_of(&held) < n - 1:
            raise ValueError(f"off: need at least {n - 1} elements, got {rows_of(&held)}")
        r = <const double*>hold(&held, "rhs", rhs, c'd', False, 1, n, -1)
        o_ = <double*>hold(&held, "out", out, c'd', True, 1, n, -1)
        c = <double*>hold(&held, "cprime", cprime, c'd', True, 1, n, -1)
        with nogil:
            thomas_c(n, d, o, r, o_, c)
    finally:
        release(&held)


def vehicle_forces(xm, w, v0, VP, SP, CMD, trac, elec, bm, bank, prof, avail, pcache, out, D, bint detail, parts) -> None:
    """External force on every vehicle [N] into ``out`` and minus its derivative with respect to the
    vehicle's own speed into ``D``, with ``detail`` the parts into ``parts`` (n x 7), at midpoint
    positions ``xm`` and speeds ``w`` of a step from speeds ``v0``, brake levels ``bm`` (see
    ``vehicle_forces_c``)."""
    cdef Held held
    held.count = 0
    cdef Model md
    cdef Py_ssize_t n
    cdef const double* pw
    cdef const double* px
    cdef const double* pv0
    cdef const double* pbm
    cdef double* pout
    cdef double* pD
    cdef double* pparts
    try:
        pw = <const double*>hold(&held, "w", w, c'd', False, 1, -1, -1)
        n = rows_of(&held)
        if n < 1:
            raise ValueError("w: need at least one vehicle")
        px = <const double*>hold(&held, "xm", xm, c'd', False, 1, n, -1)
        pv0 = <const double*>hold(&held, "v0", v0, c'd', False, 1, n, -1)
        pbm = <const double*>hold(&held, "bm", bm, c'd', False, 1, n, -1)
        pout = <double*>hold(&held, "out", out, c'd', True, 1, n, -1)
        pD = <double*>hold(&held, "D", D, c'd', True, 1, n, -1)
        pparts = <double*>hold(&held, "parts", parts, c'd', True, 2, n, N_PARTS)
        model_from(&held, n, VP, np.zeros((max(n - 1, 0), N_C)), SP, CMD, trac, elec, bank, prof, avail, pcache, &md)
        with nogil:
            vehicle_forces_c(&md, px, pw, pv0, pbm, pout, pD, detail, pparts)
    finally:
        release(&held)


def implicit_step(x0, v0, double h, w, bm, VP, CP, SP, CMD, trac, elec, bank, prof, avail, pcache, Ts, Td) -> int:
    """One implicit midpoint step of length h [s] from positions ``x0`` [m] and speeds ``v0`` [m/s] with
    brake levels ``bm``: the midpoint speeds ``w`` (the initial guess on entry) are solved for in place;
    returns the number of Newton iterations, -1 without convergence (the step would be halved). The
    couplings' spring and damper tensions [N] of the last iteration go into ``Ts`` and ``Td`` (n - 1)."""
    cdef Held held
    held.count = 0
    cdef Model md
    cdef Work ws
    cdef Py_ssize_t n, nc
    cdef int its
    cdef const double* px0
    cdef const double* pv0
    cdef const double* pbm
    cdef double* pw
    cdef double* pTs
    cdef double* pTd
    cdef double* work
    try:
        px0 = <const double*>hold(&held, "x0", x0, c'd', False, 1, -1, -1)
        n = rows_of(&held)
        if n < 1:
            raise ValueError("x0: need at least one vehicle")
        nc = n - 1 if n > 1 else 1
        pv0 = <const double*>hold(&held, "v0", v0, c'd', False, 1, n, -1)
        pw = <double*>hold(&held, "w", w, c'd', True, 1, n, -1)
        pbm = <const double*>hold(&held, "bm", bm, c'd', False, 1, n, -1)
        pTs = <double*>hold(&held, "Ts", Ts, c'd', True, 1, nc, -1)
        pTd = <double*>hold(&held, "Td", Td, c'd', True, 1, nc, -1)
        model_from(&held, n, VP, CP, SP, CMD, trac, elec, bank, prof, avail, pcache, &md)
        work_array = np.zeros(15 * n + nc)
        work = <double*>hold(&held, "work", work_array, c'd', True, 1, -1, -1)
        ws.xm = work
        ws.F = work + n
        ws.D = work + 2 * n
        ws.G = work + 3 * n
        ws.diag = work + 4 * n
        ws.dw = work + 5 * n
        ws.cprime = work + 6 * n
        ws.m2h = work + 7 * n
        ws.parts = work + 8 * n
        ws.off = work + 15 * n
        ws.Ts = pTs
        ws.Td = pTd
        with nogil:
            its = implicit_step_c(&md, px0, pv0, h, pw, pbm, &ws)
    finally:
        release(&held)
    return its


def record(nrec, t, x, v, a_last, VP, CP, CMD, parts, acc, rec_t, rec_x, rec_v, rec_a, rec_T, rec_agg) -> int:
    """Store the state at time t as record ``nrec`` (positions, speeds, accelerations, coupler forces
    and the aggregated columns ``kernel.R_*``, the forces from ``parts``); returns ``nrec + 1``."""
    cdef Held held
    held.count = 0
    cdef Model md
    cdef Records rec
    cdef Py_ssize_t n, k = nrec
    cdef double c_t = t
    cdef const double* px
    cdef const double* pv
    cdef const double* pa
    cdef const double* pparts
    cdef double* pacc
    try:
        px = <const double*>hold(&held, "x", x, c'd', False, 1, -1, -1)
        n = rows_of(&held)
        if n < 1:
            raise ValueError("x: need at least one vehicle")
        pv = <const double*>hold(&held, "v", v, c'd', False, 1, n, -1)
        pa = <const double*>hold(&held, "a_last", a_last, c'd', False, 1, n, -1)
        md.n = n
        md.VP = <const double*>hold(&held, "VP", VP, c'd', False, 2, n, N_V)
        md.CP = <const double*>hold(&held, "CP", CP, c'd', False, 2, n - 1 if n > 1 else -1, N_C)
        md.CMD = <double*>hold(&held, "CMD", CMD, c'd', True, 1, N_K, -1)
        pparts = <const double*>hold(&held, "parts", parts, c'd', False, 2, n, N_PARTS)
        pacc = <double*>hold(&held, "acc", acc, c'd', True, 1, N_A, -1)
        records_from(&held, n, rec_t, rec_x, rec_v, rec_a, rec_T, rec_agg, &rec)
        if not 0 <= k < rec.cap:
            raise ValueError(f"nrec = {k}: need 0 <= nrec < {rec.cap} (the records' capacity)")
        with nogil:
            k = record_c(&md, k, c_t, px, pv, pa, pparts, pacc, &rec)
    finally:
        release(&held)
    return k


cdef int records_from(
    Held* held, Py_ssize_t n, object rec_t, object rec_x, object rec_v, object rec_a, object rec_T,
    object rec_agg, Records* rec,
) except -1:
    rec.t = <double*>hold(held, "rec_t", rec_t, c'd', True, 1, -1, -1)
    rec.cap = rows_of(held)
    rec.nc = n - 1 if n > 1 else 1
    rec.x = <double*>hold(held, "rec_x", rec_x, c'd', True, 2, rec.cap, n)
    rec.v = <double*>hold(held, "rec_v", rec_v, c'd', True, 2, rec.cap, n)
    rec.a = <double*>hold(held, "rec_a", rec_a, c'd', True, 2, rec.cap, n)
    rec.T = <double*>hold(held, "rec_T", rec_T, c'd', True, 2, rec.cap, rec.nc)
    rec.agg = <double*>hold(held, "rec_agg", rec_agg, c'd', True, 2, rec.cap, N_R)
    return 0


def run(
    mode, t_end, state, VP, CP, SP, CMD, trac, elec, bank, prof, avail, ref, ceiling, hist, nh, acc,
    rec_t, rec_x, rec_v, rec_a, rec_T, rec_agg, nrec, ext, route_end,
) -> tuple:
    """Integrate until ``t_end`` (mode 0: fixed commands in CMD / trac / elec; mode 1: follow the
    reference ``ref`` = (positions, squared speeds, regimes int8, stop position) and stop at its end).
    ``state`` = (x, v, b, t, a, next_record_time, pcache, tmem, tmem_t): positions, speeds, brake
    levels, time (array of 1), last accelerations, next record time (array of 1), profile cache,
    coupler forces at the ends of the last three steps and their times; all updated in place, as are
    CMD, trac, elec, hist, acc, the records and ext. Returns ``(status, nh, nrec)`` (``kernel.ST_*``;
    ``ST_RECORD_FULL`` / ``ST_HISTORY_FULL``: grow that buffer and call again)."""
    cdef Held held
    held.count = 0
    cdef Model md
    cdef State st
    cdef Ref rf
    cdef Ceiling ce
    cdef Records rec
    cdef Work ws
    cdef Loop lp
    cdef Py_ssize_t n, nc, hist_cap, n_ext, k_nh = nh, k_nrec = nrec
    cdef int c_mode = mode, status
    cdef double c_t_end = t_end, c_route_end = route_end
    cdef double* work
    cdef double* phist
    cdef double* pacc
    cdef double* pext
    if c_mode != 0 and c_mode != 1:
        raise ValueError(f"mode = {mode}: need 0 (fixed commands) or 1 (follow the reference)")
    if not isinstance(state, tuple) or len(state) != 9:
        raise ValueError("state: need a tuple (x, v, b, t, a, next_record_time, pcache, tmem, tmem_t)")
    x, v, b, tt, a_last, next_rec, pcache, tmem, tmem_t = state
    try:
        st.x = <double*>hold(&held, "state x", x, c'd', True, 1, -1, -1)
        n = rows_of(&held)
        if n < 1:
            raise ValueError("state x: need at least one vehicle")
        nc = n - 1 if n > 1 else 1
        st.v = <double*>hold(&held, "state v", v, c'd', True, 1, n, -1)
        st.b = <double*>hold(&held, "state b", b, c'd', True, 1, n, -1)
        st.tt = <double*>hold(&held, "state t", tt, c'd', True, 1, 1, -1)
        st.a_last = <double*>hold(&held, "state a", a_last, c'd', True, 1, n, -1)
        st.next_rec = <double*>hold(&held, "state next_record_time", next_rec, c'd', True, 1, 1, -1)
        st.tmem = <double*>hold(&held, "state tmem", tmem, c'd', True, 2, 3, nc)
        st.tmem_t = <double*>hold(&held, "state tmem_t", tmem_t, c'd', True, 1, 3, -1)
        model_from(&held, n, VP, CP, SP, CMD, trac, elec, bank, prof, avail, pcache, &md)
        if not isinstance(ref, tuple) or len(ref) != 4:
            raise ValueError("ref: need a tuple (positions, squared speeds, regimes, stop position)")
        rf.s = <const double*>hold(&held, "ref positions", ref[0], c'd', False, 1, -1, -1)
        rf.n = rows_of(&held)
        if rf.n < 1:
            raise ValueError("ref positions: need at least one point")
        rf.v2 = <const double*>hold(&held, "ref squared speeds", ref[1], c'd', False, 1, rf.n, -1)
        rf.m = <const int8_t*>hold(&held, "ref regimes", ref[2], c'b', False, 1, rf.n, -1)
        rf.stop_at = ref[3]
        if not isinstance(ceiling, tuple) or len(ceiling) != 3:
            raise ValueError("ceiling: need a tuple (breakpoints, left values, right values)")
        ce.left = <const double*>hold(&held, "ceiling left", ceiling[1], c'd', False, 1, -1, -1)
        ce.nleft = rows_of(&held)
        if ce.nleft < 1:
            raise ValueError("ceiling left: need at least one piece")
        ce.right = <const double*>hold(&held, "ceiling right", ceiling[2], c'd', False, 1, ce.nleft, -1)
        ce.x = <const double*>hold(&held, "ceiling breakpoints", ceiling[0], c'd', False, 1, ce.nleft + 1, -1)
        phist = <double*>hold(&held, "hist", hist, c'd', True, 2, -1, 2)
        hist_cap = rows_of(&held)
        if not 1 <= k_nh <= hist_cap:
            raise ValueError(f"nh = {nh}: need 1 <= nh <= {hist_cap} (the history's rows)")
        pacc = <double*>hold(&held, "acc", acc, c'd', True, 1, N_A, -1)
        records_from(&held, n, rec_t, rec_x, rec_v, rec_a, rec_T, rec_agg, &rec)
        if not 0 <= k_nrec <= rec.cap:
            raise ValueError(f"nrec = {nrec}: need 0 <= nrec <= {rec.cap} (the records' capacity)")
        pext = <double*>hold(&held, "ext", ext, c'd', True, 1, -1, -1)
        n_ext = rows_of(&held)
        if n_ext < N_E:
            raise ValueError(f"ext: need at least {N_E} elements, got {n_ext}")
        # work space: 13 arrays of n, the parts (n x 7), 4 arrays of nc; zeroed as numba's parts were
        work_array = np.zeros(20 * n + 4 * nc)
        work = <double*>hold(&held, "work", work_array, c'd', True, 1, -1, -1)
        ws.xm = work
        ws.F = work + n
        ws.D = work + 2 * n
        ws.G = work + 3 * n
        ws.diag = work + 4 * n
        ws.dw = work + 5 * n
        ws.cprime = work + 6 * n
        ws.parts = work + 7 * n
        lp.w = work + 14 * n
        lp.bm = work + 15 * n
        lp.tgt = work + 16 * n
        lp.x1 = work + 17 * n
        lp.v1 = work + 18 * n
        ws.m2h = work + 19 * n
        ws.Ts = work + 20 * n
        ws.Td = ws.Ts + nc
        ws.off = ws.Td + nc
        lp.Tend = ws.off + nc
        with nogil:
            status = run_c(
                &md, c_mode, c_t_end, &st, &rf, &ce, phist, hist_cap, &k_nh, pacc, &rec, &k_nrec, pext, n_ext,
                c_route_end, &ws, &lp,
            )
    finally:
        release(&held)
    return status, k_nh, k_nrec
