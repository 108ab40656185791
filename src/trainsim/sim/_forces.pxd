# cython: language_level=3
"""Shared declarations of the compiled (Cython) hot path of the fastest run: the effort curves as
C structs and the force laws every integrator evaluates (the integrators are in ``_kernel_c.pyx``).
Ported bit for bit from the numba kernel (issue 14): the same formulas in the same order of
floating-point operations, no ``-ffast-math``, no fused multiply-add (the default x86-64 target has
none).

An effort curve is read from the tuple ``(starts, coefs, fcap, pcap)`` of
``EffortCurve.as_arrays()``; the structs hold pointers into those arrays, which the caller keeps
alive for the length of the call (the Python entry points hold the tuples).
"""

from libc.math cimport INFINITY, ceil, fabs, log, sqrt

from trainsim._cbuffers cimport search_left, search_right

# regimes, as trainsim.sim.codes numbers them (checked by a test)
cdef enum:
    TRACTION = 0
    CRUISE = 1
    COAST = 2
    BRAKE = 3
    DWELL = 4
    REGEN = 5
    FOLLOW = 6

# indices into the parameter vector P (trainsim.sim.codes.P_*)
cdef enum:
    P_INERTIAL_MASS = 0
    P_MASS = 1
    P_R0 = 2
    P_R1 = 3
    P_R2 = 4
    P_DECEL = 5
    P_BRAKE_FRACTION = 6
    P_TRACTION_SCALE = 7
    N_PARAMS = 8

# trainsim.model.effort.POWER_CAP_MIN_SPEED_MPS [m/s]; a test checks that the two agree
cdef extern from *:
    """
    static const double TRAINSIM_POWER_CAP_MIN_SPEED = 1e-3;
    """
    const double POWER_CAP_MIN_SPEED "TRAINSIM_POWER_CAP_MIN_SPEED"


cdef struct Curve:
    const double* starts  # interval start speeds [m/s], increasing, n of them
    const double* coefs  # n x 4 row-major: c0, c1, c2, ch of c0 + c1 v + c2 v^2 + ch / v [N]
    Py_ssize_t n
    double fcap  # force cap [N]
    double pcap  # power cap [W]


cdef struct Curves:
    Curve traction
    Curve brake
    Curve regen


cdef inline double law(double v, Py_ssize_t j, const double* coefs) noexcept nogil:
    """Interval j's law c0 + c1 v + c2 v^2 + ch / v [N] of a compiled EffortCurve at speed v [m/s]
    (inf at v = 0 when ch != 0)."""
    cdef const double* c = coefs + 4 * j
    cdef double f = c[0] + c[1] * v + c[2] * v * v
    if c[3] != 0.0:
        f += c[3] / v if v > 0.0 else INFINITY
    return f


cdef inline double effort(double v, const Curve* k) noexcept nogil:
    """Maximum force [N] of a compiled EffortCurve at speed v [m/s]: the law of the interval of v,
    capped by the force cap fcap [N] and the power cap pcap [W] (taken at v, at least
    POWER_CAP_MIN_SPEED), never negative."""
    cdef Py_ssize_t j = search_right(k.starts, k.n, v) - 1
    if j < 0:
        j = 0
    cdef double f = law(v, j, k.coefs)
    if f > k.fcap:
        f = k.fcap
    cdef double vp = v if v > POWER_CAP_MIN_SPEED else POWER_CAP_MIN_SPEED
    if f * vp > k.pcap:
        f = k.pcap / vp
    return f if f > 0.0 else 0.0


cdef inline double effort_branch(double v, double vref, const Curve* k) noexcept nogil:
    """Force [N] of a compiled EffortCurve at speed v [m/s] on the smooth branch that holds at the
    reference speed ``vref`` (its interval, and whichever of law, force cap, power cap or zero binds
    there), continued smoothly to v; with ``vref < 0`` the curve itself (``effort``).

    An integration between two kinks evaluates its stages on the branch of the piece it integrates:
    a stage that lands just beyond a kink (a table step such as source 002's braking force jumping
    from 150 to 335 kN between 5 and 6 km/h, or a cap) must not see the next branch, and a piece
    that starts exactly at a kink must see the branch it goes into."""
    if vref < 0.0:
        return effort(v, k)
    cdef Py_ssize_t j = search_right(k.starts, k.n, vref) - 1
    if j < 0:
        j = 0
    cdef double best = law(vref, j, k.coefs)
    cdef int branch = 0
    if k.fcap < best:
        best = k.fcap
        branch = 1
    cdef double vp = vref if vref > POWER_CAP_MIN_SPEED else POWER_CAP_MIN_SPEED
    if k.pcap / vp < best:
        best = k.pcap / vp
        branch = 2
    if not best > 0.0:
        return 0.0
    if branch == 1:
        return k.fcap
    if branch == 2:
        return k.pcap / (v if v > POWER_CAP_MIN_SPEED else POWER_CAP_MIN_SPEED)
    cdef double f = law(v, j, k.coefs)
    return f if f > 0.0 else 0.0


# Which smooth branch of a curve holds at a reference speed (``Branch.which``).
cdef enum:
    BRANCH_LAW = 0  # the interval's law (clipped at 0)
    BRANCH_FCAP = 1  # the force cap
    BRANCH_PCAP = 2  # the power cap
    BRANCH_ZERO = 3  # no force at the reference speed
    BRANCH_CURVE = 4  # no reference speed (vref < 0): the curve itself, ``effort``


cdef struct Branch:
    Py_ssize_t j  # the interval of the curve at the reference speed
    int which  # BRANCH_*


cdef inline void branch_at(double vref, const Curve* k, Branch* b) noexcept nogil:
    """The branch ``effort_branch(v, vref, k)`` evaluates, chosen once: an integration along one
    piece evaluates the same branch at every stage (``effort_on``), so it need not choose it again."""
    b.j = 0
    if vref < 0.0:
        b.which = BRANCH_CURVE
        return
    cdef Py_ssize_t j = search_right(k.starts, k.n, vref) - 1
    if j < 0:
        j = 0
    cdef double best = law(vref, j, k.coefs)
    cdef int branch = BRANCH_LAW
    if k.fcap < best:
        best = k.fcap
        branch = BRANCH_FCAP
    cdef double vp = vref if vref > POWER_CAP_MIN_SPEED else POWER_CAP_MIN_SPEED
    if k.pcap / vp < best:
        best = k.pcap / vp
        branch = BRANCH_PCAP
    b.j = j
    b.which = branch if best > 0.0 else BRANCH_ZERO


cdef inline double effort_on(double v, const Branch* b, const Curve* k) noexcept nogil:
    """``effort_branch(v, vref, k)`` [N] with the branch ``branch_at(vref, k, b)`` chose: the same bits."""
    if b.which == BRANCH_CURVE:
        return effort(v, k)
    if b.which == BRANCH_ZERO:
        return 0.0
    if b.which == BRANCH_FCAP:
        return k.fcap
    if b.which == BRANCH_PCAP:
        return k.pcap / (v if v > POWER_CAP_MIN_SPEED else POWER_CAP_MIN_SPEED)
    cdef double f = law(v, b.j, k.coefs)
    return f if f > 0.0 else 0.0


cdef inline double speed_of(double E) noexcept nogil:
    """v = sqrt(2 E) [m/s], 0 at or below standstill."""
    return sqrt(2.0 * E) if E > 0.0 else 0.0


# trainsim.sim.codes.SPEED_DOMAIN_STEP [m/s] (speed change covered by one RK4 step of a speed-domain
# integration), SPEED_DOMAIN_MIN_STEPS (the fewest steps) and SPEED_DOMAIN_STEPS_PER_LOG (extra steps
# per unit of |ln(a_end / a_start)|), checked by a test
cdef extern from *:
    """
    static const double TRAINSIM_SPEED_DOMAIN_STEP = 0.05;
    static const long TRAINSIM_SPEED_DOMAIN_MIN_STEPS = 3;
    static const double TRAINSIM_SPEED_DOMAIN_STEPS_PER_LOG = 12.0;
    """
    const double SPEED_DOMAIN_STEP "TRAINSIM_SPEED_DOMAIN_STEP"
    const long SPEED_DOMAIN_MIN_STEPS "TRAINSIM_SPEED_DOMAIN_MIN_STEPS"
    const double SPEED_DOMAIN_STEPS_PER_LOG "TRAINSIM_SPEED_DOMAIN_STEPS_PER_LOG"


cdef inline long speed_domain_steps(double v_from, double v_to, double a_from, double a_to) noexcept nogil:
    """RK4 steps for a speed-domain integration from v_from to v_to [m/s] with accelerations a_from,
    a_to [m/s^2] at its ends: one per SPEED_DOMAIN_STEP of speed; when both have the same sign, at
    most 8 of those plus SPEED_DOMAIN_STEPS_PER_LOG per unit of |ln(a_to / a_from)|, since a force
    that changes steeply with speed (source 002's braking force, 150 to 335 kN between 5 and 6 km/h)
    puts a pole of ds/dv = v / a(v) close to the interval, where a nearly constant one (most tables)
    needs only the fewest steps. Between SPEED_DOMAIN_MIN_STEPS and 128 (SPEED_DOMAIN_MAX_STEPS)."""
    cdef double n = fabs(v_to - v_from) / SPEED_DOMAIN_STEP
    if a_from * a_to > 0.0:
        n = (n if n < 8.0 else 8.0) + SPEED_DOMAIN_STEPS_PER_LOG * fabs(log(a_to / a_from))
    cdef long k = <long>ceil(n)
    if k < SPEED_DOMAIN_MIN_STEPS:
        k = SPEED_DOMAIN_MIN_STEPS
    return k if k < 128 else 128


cdef int curve_from(object arrays, Curve* out) except -1
cdef int curves_from(object curves, Curves* out) except -1
