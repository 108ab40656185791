# cython: language_level=3
"""Declarations of the compiled fastest-run kernel (``_kernel_c.pyx``), for the other compiled
kernels that integrate the same single-point model: its structs, its small inline helpers and its
integrators (all C, no Python objects, nogil), and the readers of the kink and line-law arguments.
The structs hold pointers into arrays that the caller keeps alive for the length of the call."""

from libc.math cimport ceil, fabs
from libc.stdint cimport int64_t

from trainsim._cbuffers cimport Arr, Kinks, _array, next_kink, search_left, search_right
from trainsim.sim._forces cimport Curves, P_MASS, P_R0, P_R1, P_R2

# trainsim.sim.codes constants (checked against them by a test)
cdef extern from *:
    """
    static const double TRAINSIM_SPEED_TOLERANCE = 1e-7;
    static const double TRAINSIM_POSITION_TOLERANCE = 1e-9;
    static const double TRAINSIM_LENGTH_SCALE_FRACTION = 0.01;
    static const long TRAINSIM_MAX_SUBSTEPS = 64;
    static const long TRAINSIM_TIME_SUBSTEPS = 4;
    static const long TRAINSIM_STATUS_OK = 0;
    static const long TRAINSIM_STATUS_STALLED = 1;
    """
    const double SPEED_TOLERANCE "TRAINSIM_SPEED_TOLERANCE"
    const double POSITION_TOLERANCE "TRAINSIM_POSITION_TOLERANCE"
    const double LENGTH_SCALE_FRACTION "TRAINSIM_LENGTH_SCALE_FRACTION"
    const long MAX_SUBSTEPS "TRAINSIM_MAX_SUBSTEPS"
    const long TIME_SUBSTEPS "TRAINSIM_TIME_SUBSTEPS"
    const long STATUS_OK "TRAINSIM_STATUS_OK"
    const long STATUS_STALLED "TRAINSIM_STATUS_STALLED"


cdef struct Line:
    # line resistance laws of one grid interval: specific resistance a0 + a1 u [N/kg], v^2 coefficient
    # b0 + b1 u [N s^2/(kg m^2)] at offset u [m] into the interval
    double a0
    double a1
    double b0
    double b1


cdef struct Ctx:
    # what every integrator reads: the parameter vector P (P_TRACTION_SCALE is written per interval,
    # in the caller's array, as the numba kernel did) and the effort curves
    double* P
    const Curves* curves


cdef struct Track:
    const double* x  # grid [m], n + 1 points
    const double* a0
    const double* a1
    const double* b0
    const double* b1
    const double* vlim  # ceiling per interval [m/s]
    const double* tscale  # traction share per interval [-]
    Py_ssize_t n  # intervals


cdef struct Out:
    # trace being written: position [m], speed [m/s], time [s], regime code
    double* s
    double* v
    double* t
    signed char* m
    Py_ssize_t n
    Py_ssize_t cap
    bint overflow


cdef struct ET:
    double E  # [m^2/s^2]
    double dt  # [s]


cdef inline double resistance_force(double v, double u, const Line* line, const double* P) noexcept nogil:
    """Running plus line resistance [N] at speed v [m/s] and offset u [m] into the interval of
    ``line``: running resistance P[P_R0] + P[P_R1] v + P[P_R2] v^2 plus the mass P[P_MASS] times the
    specific resistance a0 + a1 u [N/kg] and the v^2 coefficient b0 + b1 u [N s^2/(kg m^2)] (ratios of
    the weight times the route's g)."""
    cdef double running = P[P_R0] + P[P_R1] * v + P[P_R2] * v * v
    return running + P[P_MASS] * ((line.a0 + line.a1 * u) + (line.b0 + line.b1 * u) * v * v)


cdef inline long substeps(double E, double h, double a) noexcept nogil:
    """Number of RK4 sub-steps for a step h [m] from E [m^2/s^2] with acceleration a [m/s^2] there:
    each sub-step at most LENGTH_SCALE_FRACTION of the motion's length scale 2E / |a| = v^2 / |a|
    (within about that distance E(s) meets the square-root singularity of standstill), at most
    MAX_SUBSTEPS. Only slow, strongly braked or accelerated steps are divided: at 20 m/s and 1 m/s^2
    the scale is 400 m."""
    a = fabs(a)
    if not (a > 0.0 and E > 0.0):
        return 1
    cdef long n = <long>ceil(fabs(h) * a / (LENGTH_SCALE_FRACTION * 2.0 * E))
    if n < 1:
        n = 1
    return n if n < MAX_SUBSTEPS else MAX_SUBSTEPS


cdef inline bint is_kink(double v, const Kinks* kinks) noexcept nogil:
    """Whether v [m/s] is one of the kink speeds (sorted), to within SPEED_TOLERANCE."""
    cdef Py_ssize_t j = search_left(kinks.v, kinks.n, v)
    if j < kinks.n and fabs(kinks.v[j] - v) <= SPEED_TOLERANCE:
        return True
    return j > 0 and fabs(kinks.v[j - 1] - v) <= SPEED_TOLERANCE


cdef inline Py_ssize_t kinks_between(double v0, double v1, const Kinks* kinks) noexcept nogil:
    """Number of kink speeds strictly between v0 and v1 (0, not -1, when v0 == v1 is a kink: that
    miscount once sized the output of ``insert_kink_points`` too small, and the trace lost its last
    points)."""
    # min and max as numba evaluated them: the first argument unless the second is strictly beyond
    cdef double lo = v1 if v1 < v0 else v0
    cdef double hi = v1 if v1 > v0 else v0
    cdef Py_ssize_t n = search_left(kinks.v, kinks.n, hi) - search_right(kinks.v, kinks.n, lo)
    return n if n > 0 else 0


cdef inline Line line_of(const Track* tr, Py_ssize_t i) noexcept nogil:
    cdef Line line
    line.a0 = tr.a0[i]
    line.a1 = tr.a1[i]
    line.b0 = tr.b0[i]
    line.b1 = tr.b1[i]
    return line


cdef inline void push(Out* o, double s, double v, double t, long m) noexcept nogil:
    """Append a trace point; past the arrays' end nothing is written and the overflow is flagged
    (the entry point raises; the numba kernel this was ported from wrote past the arrays)."""
    if o.n >= o.cap:
        o.overflow = True
        return
    o.s[o.n] = s
    o.v[o.n] = v
    o.t[o.n] = t
    o.m[o.n] = <signed char>m
    o.n += 1


# ---------------------------------------------------------------------- integrators (in _kernel_c.pyx)

cdef double acceleration(
    long mode, double E, double u, const Line* line, const Ctx* c, double vref
) noexcept nogil
cdef double rk4_energy(
    double E, double u, double h, long mode, const Line* line, const Ctx* c, double vref
) noexcept nogil
cdef ET rk4_energy_time(
    double E, double u, double h, long mode, const Line* line, const Ctx* c, double vref
) noexcept nogil
cdef double distance_to_speed(
    double E, double u, double Et, long mode, const Line* line, const Ctx* c
) noexcept nogil
cdef ET step_energy_time_c(
    double E, double u, double h, long mode, const Line* line, const Ctx* c, const Kinks* kinks
) noexcept nogil
cdef double step_energy_c(
    double E, double u, double h, long mode, const Line* line, const Ctx* c, const Kinks* kinks
) noexcept nogil
cdef double find_speed_crossing_split_c(
    double E, double u, double H, double target_E, long mode, const Line* line, const Ctx* c,
    const Kinks* kinks,
) noexcept nogil
cdef double find_curve_meeting(
    double E, double u, double Er, double w, const Line* line, const Ctx* c, const Kinks* tk,
    const Kinks* bk,
) noexcept nogil
cdef void braking_ceiling_mixed_c(
    const Track* tr, Py_ssize_t i0, Py_ssize_t i1, const Ctx* c, const Kinks* bk, const Kinks* rk,
    const int64_t* modes, long mode_all, double* Cr, double* Cl, double* US,
) noexcept nogil
cdef long fastest_segment_c(
    const Track* tr, Py_ssize_t i0, Py_ssize_t i1, double t0, const Ctx* c, const Kinks* tk,
    const Kinks* bk, Out* o, double* Cr, double* Cl, double* US, double* stall_at,
) noexcept nogil
cdef Py_ssize_t insert_kink_points_c(
    const Track* tr, const Ctx* c, const Kinks* tk, const Kinks* bk, const double* s, const double* v,
    const double* t, const signed char* m, Py_ssize_t n, Out* o,
) noexcept nogil


# ---- reading the arguments (Python objects; for the entry points of _kernel_c and optimize._pmp_c)

cdef inline Kinks _kinks(object k, str what="kink speeds") except *:
    cdef Arr a = _array(k, what, c'd')
    cdef Kinks out
    out.v = <const double*>a.data
    out.n = a.n
    return out


cdef inline Line _line(object line) except *:
    cdef Line out
    if len(line) != 4:
        raise ValueError(f"line laws of length {len(line)}: need (a0, a1, b0, b1)")
    out.a0, out.a1, out.b0, out.b1 = line
    return out
