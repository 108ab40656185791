# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True
"""Compiled (Cython) point and stretch arrays of a run: forces, powers, line currents and their peaks,
and the per-interval line laws of the kernel grid.

One pass over the points of a run evaluates what ``result._trace_and_peaks_numpy`` evaluates with
numpy (kept as the reference the tests compare against): at every point the forces of its regime at
its speed with the line resistance just right of it, the accelerations, the mechanical, electrical
and paper-convention powers and the line currents (I = P / (U cos phi), source 002 eq. 15); at every
stretch the end powers of its regime at both of its ends with the line resistance at its middle,
whose currents enter the running peaks. Every expression is written in the order numpy evaluates it
(a + b * c + d * e * f is (a + (b * c)) + ((d * e) * f) in C as in Python), without contraction into
fused multiply-adds or any fast-math licence, so that the arrays are the same bits; with
``with_trace`` false only the peaks are stored, which is what a summary needs. ``kernel_grid`` builds
the kernel grid of a run (``profile.compile_route``) from the laws' breakpoints and the stops and
evaluates its per-interval line laws the same way (``interval_laws``, for a given grid).

A line law is passed as ``(x, left, right, steps)``, the arrays of a ``profile.PiecewiseLinear`` and
whether it is piecewise constant (``profile._law_arrays``); an effort curve as
``EffortCurve.as_arrays()``. The loops run on C pointers into those arrays without the GIL: nothing
in them is reference-counted. The arrays belong to the caller, who holds them for the whole call.
"""

from libc.math cimport INFINITY, NAN, ceil, fabs, sqrt
from libc.stdlib cimport free, malloc, qsort
from libc.stdint cimport int64_t
from cpython.buffer cimport PyBUF_C_CONTIGUOUS, PyBUF_FORMAT, PyBUF_WRITABLE, PyObject_GetBuffer

import numpy as np

from trainsim.sim._forces cimport (
    BRAKE,
    CRUISE,
    DWELL,
    FOLLOW,
    POWER_CAP_MIN_SPEED,
    REGEN,
    TRACTION,
    Curve,
    curve_from,
)
from trainsim._cbuffers cimport MAX_HELD, Held, is_format, release, search_left, search_right

#: The rows of ``run_arrays``'s point arrays: acceleration [m/s^2], forces [N], speed limit [m/s],
#: powers [W], line currents [A] (the ``result.Trace`` fields of the same names).
TRACE_ROWS = (
    "acceleration_mps2",
    "traction_force_n",
    "braking_force_n",
    "regenerative_braking_force_n",
    "friction_braking_force_n",
    "running_resistance_n",
    "gradient_resistance_n",
    "curve_resistance_n",
    "tunnel_resistance_n",
    "speed_limit_mps",
    "mechanical_power_w",
    "electrical_power_w",
    "line_current_a",
    "paper_power_w",
    "paper_line_current_a",
)
cdef enum:
    N_ROWS = 15  # len(TRACE_ROWS)

#: The order of the laws ``run_arrays`` takes in its ``laws`` tuple.
RUN_LAWS = ("gradient", "curve", "tunnel", "tunnel_v2", "availability", "voltage", "ceiling")
_RUN_LAW_LABELS = tuple(f"law {name}" for name in RUN_LAWS)
#: The order of the laws ``kernel_grid`` and ``interval_laws`` take.
GRID_LAWS = ("gradient", "curve", "tunnel", "tunnel_v2", "ceiling", "available")
_GRID_LAW_LABELS = tuple(f"law {name}" for name in GRID_LAWS)


cdef struct Law:
    const double* x  # breakpoints [m], increasing, n + 1 of them
    const double* left  # value at x[k] from the right, n of them
    const double* right  # value at x[k + 1] from the left, n of them
    Py_ssize_t n  # pieces
    bint steps  # piecewise constant: left == right on every piece
    bint ordered  # x[k] <= x[k + 1] for every k (so no NaN): ``piecewise_value_seq`` may walk
    Py_ssize_t hint  # search_right's answer for the last position looked up by piecewise_value_seq
    bint constant  # one piece, piecewise constant: the same value everywhere (a route without curves)


cdef struct Mech:
    double inertial_mass  # rho m [kg]
    double decel  # constant service deceleration [m/s^2] (braking fraction applied)
    double fraction  # share of the service braking curve used [-]
    bint has_decel  # brakes at that constant deceleration
    bint has_service  # has a service braking curve
    bint has_regen  # has a regenerative braking curve


cdef struct Electric:
    bint is_elec
    double eta_t  # traction efficiency [-]
    double eta_r  # regenerative efficiency x receptivity [-]
    double aux_w  # auxiliary power [W]
    double pf  # power factor [-]


cdef struct CurveHint:
    Py_ssize_t k  # search_right's answer for the last speed looked up
    bint ordered  # the curve's starts are ordered (no NaN): ``curve_value_seq`` may walk


cdef struct Train:
    CurveHint traction_hint
    CurveHint service_hint
    CurveHint regen_hint
    Mech mech
    Electric electric
    double c0  # running resistance c0 [N]
    double c1  # [N s/m]
    double c2  # [N s^2/m^2]
    double weight  # m g [N]
    Curve traction
    Curve service
    Curve regen


cdef struct RunLaws:
    Law grad
    Law curve
    Law tun
    Law tun2
    Law avail
    Law volt
    Law ceil


cdef struct RunPoints:
    const double* s
    const double* v
    const int64_t* regime
    const double* level
    const double* s_right  # NULL when not given


cdef inline double nmin(double a, double b) noexcept nogil:
    """min(a, b) with NaN propagated, the first NaN if both are (numpy's ``minimum``)."""
    if a != a:
        return a
    if b != b:
        return b
    return a if a <= b else b


cdef inline double nmax(double a, double b) noexcept nogil:
    """max(a, b) with NaN propagated, the first NaN if both are (numpy's ``maximum``)."""
    if a != a:
        return a
    if b != b:
        return b
    return a if a >= b else b


cdef inline double piecewise_value(const Law* f, double s) noexcept nogil:
    """Value of a ``PiecewiseLinear`` at position s [m], as its ``__call__`` computes it (the end
    values beyond the ends; NaN at NaN)."""
    if s != s:
        return NAN
    return value_in_piece(f, search_right(f.x, f.n + 1, s) - 1, s)


cdef inline Py_ssize_t search_right_from(const double* a, Py_ssize_t n, double s, Py_ssize_t* hint) noexcept nogil:
    """``search_right(a, n, s)`` on an ordered array without NaN, started from ``*hint`` (its answer
    for an earlier position, updated): the run's and the grid's positions increase, so the answer
    is usually the hint or a step beyond it, found without the bisection's log2(n) compares. The
    same index whatever the hint: a hint past s, or more than a few steps short of it, bisects."""
    cdef Py_ssize_t k = hint[0]
    cdef int steps = 0
    if k > n or (k > 0 and not (a[k - 1] <= s)):
        k = search_right(a, n, s)
    else:
        # a[:k] <= s (ordered): the answer is the first index from k on with a[index] > s
        while k < n and a[k] <= s:
            k += 1
            steps += 1
            if steps == 8:
                k = search_right(a, n, s)
                break
    hint[0] = k
    return k


cdef inline double piecewise_value_seq(Law* f, double s) noexcept nogil:
    """``piecewise_value`` for positions looked up in (mostly) increasing order: the same value."""
    if s != s:
        return NAN
    if f.constant:
        # value_in_piece's answer on the only piece, without the search (half the look-ups of a run
        # on a line without curves or tunnels)
        return f.left[0] + 0.0
    if not f.ordered:
        return value_in_piece(f, search_right(f.x, f.n + 1, s) - 1, s)
    return value_in_piece(f, search_right_from(f.x, f.n + 1, s, &f.hint) - 1, s)


cdef inline double value_in_piece(const Law* f, Py_ssize_t k, double s) noexcept nogil:
    """The law's value at s [m] on piece k (clamped to the pieces, so the end values beyond the ends)."""
    if k < 0:
        k = 0
    if k > f.n - 1:
        k = f.n - 1
    if f.steps:
        # + 0.0: -0.0 becomes 0.0, as left + 0 x frac does
        return f.left[k] + 0.0
    cdef double x0 = f.x[k]
    cdef double frac = nmin(nmax((s - x0) / (f.x[k + 1] - x0), 0.0), 1.0)
    return f.left[k] + (f.right[k] - f.left[k]) * frac


cdef inline double curve_value(double v, const Curve* k) noexcept nogil:
    """Force [N] of an ``EffortCurve`` at speed v [m/s], as its ``__call__`` computes it (the law, the
    hyperbolic term c3 / v, the force cap, the power cap P / max(v, 1 mm/s), then the clip at 0).
    ``_forces.effort`` compares F v with the power cap instead: the same force but for the last bit,
    which is why the trace has its own."""
    return curve_in_piece(v, k, search_right(k.starts, k.n, v) - 1)


cdef inline double curve_value_seq(double v, const Curve* k, CurveHint* h) noexcept nogil:
    """``curve_value`` for speeds looked up in (mostly) slowly changing order, the piece found from
    the last one (``search_right_from``) where the curve's starts are ordered: the same force."""
    if not h.ordered:
        return curve_value(v, k)
    return curve_in_piece(v, k, search_right_from(k.starts, k.n, v, &h.k) - 1)


cdef inline double curve_in_piece(double v, const Curve* k, Py_ssize_t j) noexcept nogil:
    """``curve_value`` at v [m/s] on piece j (the first piece below it)."""
    if j < 0:
        j = 0
    cdef const double* c = k.coefs + 4 * j
    cdef double f = c[0] + c[1] * v + c[2] * v * v
    f = f + (c[3] / v if c[3] != 0.0 else 0.0)
    cdef double power = k.pcap / nmax(v, POWER_CAP_MIN_SPEED)
    return nmax(nmin(nmin(f, k.fcap), power), 0.0)


cdef inline void regime_forces(
    int64_t mode,
    double v,
    double running,
    double line,
    double level,
    double avail,
    double inertia,
    Train* tr,
    double* ft_out,
    double* fb_out,
) noexcept nogil:
    """(traction, braking) force [N] in regime ``mode`` at speed v [m/s], with running and line
    resistance [N], the driver's level, the available share of tractive effort and the force the
    stretch's acceleration needs (FOLLOW) [N] (``result._regime_forces``)."""
    cdef double ft = 0.0, fb = 0.0, need
    cdef const Mech* m = &tr.mech
    if mode == TRACTION:
        ft = level * avail * curve_value_seq(v, &tr.traction, &tr.traction_hint)
    elif mode == CRUISE:
        need = running + line
        ft = nmax(need, 0.0)
        fb = nmax(-need, 0.0)
    elif mode == BRAKE:
        if m.has_decel:
            fb = level * nmax(m.inertial_mass * m.decel - running - line, 0.0)
        elif m.has_service:
            fb = level * m.fraction * curve_value_seq(v, &tr.service, &tr.service_hint)
    elif mode == REGEN:
        if m.has_regen:
            fb = curve_value_seq(v, &tr.regen, &tr.regen_hint)
    elif mode == FOLLOW:
        need = inertia + running + line
        ft = nmax(need, 0.0)
        fb = nmax(-need, 0.0)
    ft_out[0] = ft
    fb_out[0] = fb


cdef inline void fold_peak(double* best, double x) noexcept nogil:
    """``best`` = the larger of ``best`` and x, NaN ignored (numpy's ``nanmax``: NaN until a number)."""
    if x == x and (best[0] != best[0] or x > best[0]):
        best[0] = x


cdef void run_loop(
    Py_ssize_t n,
    const double* s,
    const double* v,
    const int64_t* regime,
    const double* level,
    const double* s_right,
    double s_end,
    RunLaws* L,
    Train* tr,
    bint with_trace,
    double* out,
    double* peak,
    double* peak_paper,
    const int64_t* bounds,
    Py_ssize_t n_sections,
    double* section_peaks,
) noexcept nogil:
    """The points' rows (``out``, N_ROWS x n, row-major, written only ``with_trace``) and peaks: per
    point (``peak``, ``peak_paper``) or, where ``peak`` is NULL, only their largest values ignoring
    NaN (numpy's ``nanmax``; NaN if all are) over each section's points ``bounds[2k] ..
    bounds[2k + 1]`` (inclusive, increasing) and over all points, in ``section_peaks`` (current of each
    section, paper current of each section, then the two over all points). Without ``s_right`` the
    line laws are read at min(s + 1e-7, s_end)."""
    cdef const Mech* mech = &tr.mech
    cdef const Electric* e = &tr.electric
    cdef double m_inertial = mech.inertial_mass
    cdef double c0 = tr.c0, c1 = tr.c1, c2 = tr.c2, weight = tr.weight
    cdef double eta_t = e.eta_t, eta_r = e.eta_r, aux_w = e.aux_w, pf = e.pf
    cdef Py_ssize_t i
    cdef int64_t r
    cdef double vi, sr, running, grad, curve, tunnel, line, inertia, ds, acc_stretch, avail
    cdef double ft, fb, cap, fr, p_trac, el_power, paper_power, current, paper_current
    cdef double u, safe, end_current, end_paper, v0, v1, mid, vm, line_mid, avail_mid, run0, run1
    cdef double f0t, f0b, f1t, f1b, rg0, rg1, u_mid, safe_mid, end_power, pk, pk_paper
    cdef Py_ssize_t sec = 0, j
    cdef double* all_peaks = section_peaks + 2 * n_sections
    if peak == NULL:
        for i in range(2 * n_sections + 2):
            section_peaks[i] = NAN
    for i in range(n):
        vi = v[i]
        sr = s_right[i] if s_right != NULL else nmin(s[i] + 1e-7, s_end)
        r = regime[i]
        running = (c0 + c1 * vi + c2 * vi * vi) * (1.0 if vi > 0.0 else 0.0)
        grad = weight * piecewise_value_seq(&L.grad, sr)
        curve = weight * piecewise_value_seq(&L.curve, sr)
        tunnel = weight * (piecewise_value_seq(&L.tun, sr) + piecewise_value_seq(&L.tun2, sr) * vi * vi)
        line = grad + curve + tunnel
        inertia = 0.0
        # the stretch's acceleration enters only a prescribed profile's forces (FOLLOW): its division
        # is skipped elsewhere (regime_forces reads ``inertia`` in FOLLOW only, here and at the ends)
        if i < n - 1 and r == FOLLOW:
            ds = s[i + 1] - s[i]
            acc_stretch = (v[i + 1] * v[i + 1] - vi * vi) / (2.0 * ds) if ds > 0.0 else 0.0
            inertia = m_inertial * acc_stretch
        avail = piecewise_value_seq(&L.avail, sr)
        regime_forces(r, vi, running, line, level[i], avail, inertia, tr, &ft, &fb)
        cap = curve_value_seq(vi, &tr.regen, &tr.regen_hint) if mech.has_regen else 0.0
        fr = nmin(fb, cap)
        p_trac = ft * vi / eta_t
        el_power = p_trac + aux_w - fr * vi * eta_r
        paper_power = ft * vi * eta_t
        current = NAN
        paper_current = NAN
        if e.is_elec:
            u = piecewise_value_seq(&L.volt, sr)
            safe = u if u > 0.0 else 1.0
            current = el_power / (safe * pf) if u > 0.0 else 0.0
            paper_current = paper_power / (safe * pf) if u > 0.0 else 0.0
            end_current = -INFINITY
            end_paper = -INFINITY
            if i < n - 1:
                # a point carries the forces of the stretch it starts, so the end of a traction stretch
                # (full effort at its highest speed, often the peak) is only seen from the stretch
                v0 = vi
                v1 = v[i + 1]
                mid = 0.5 * (s[i] + s[i + 1])
                vm = sqrt(0.5 * (v0 * v0 + v1 * v1))
                line_mid = (
                    weight * piecewise_value_seq(&L.grad, mid)
                    + weight * piecewise_value_seq(&L.curve, mid)
                    + weight * (piecewise_value_seq(&L.tun, mid) + piecewise_value_seq(&L.tun2, mid) * vm * vm)
                )
                avail_mid = piecewise_value_seq(&L.avail, mid)
                run0 = c0 + c1 * v0 + c2 * v0 * v0
                run1 = c0 + c1 * v1 + c2 * v1 * v1
                regime_forces(r, v0, run0, line_mid, level[i], avail_mid, inertia, tr, &f0t, &f0b)
                regime_forces(r, v1, run1, line_mid, level[i], avail_mid, inertia, tr, &f1t, &f1b)
                rg0 = nmin(f0b, curve_value_seq(v0, &tr.regen, &tr.regen_hint)) if mech.has_regen else 0.0
                rg1 = nmin(f1b, curve_value_seq(v1, &tr.regen, &tr.regen_hint)) if mech.has_regen else 0.0
                u_mid = piecewise_value_seq(&L.volt, mid)
                safe_mid = u_mid if u_mid > 0.0 else 1.0
                end_power = nmax(f0t * v0 / eta_t - rg0 * v0 * eta_r, f1t * v1 / eta_t - rg1 * v1 * eta_r)
                if u_mid > 0.0:
                    end_current = (end_power + aux_w) / (safe_mid * pf)
                    end_paper = eta_t * nmax(f0t * v0, f1t * v1) / (safe_mid * pf)
                else:
                    end_current = 0.0
                    end_paper = 0.0
            pk = nmax(current, end_current)
            pk_paper = nmax(paper_current, end_paper)
            if peak != NULL:
                peak[i] = pk
                peak_paper[i] = pk_paper
            else:
                fold_peak(&all_peaks[0], pk)
                fold_peak(&all_peaks[1], pk_paper)
                while sec < n_sections and i > bounds[2 * sec + 1]:
                    sec += 1
                # a section's last point is the next one's first where the train does not dwell
                j = sec
                while j < n_sections and bounds[2 * j] <= i:
                    fold_peak(&section_peaks[j], pk)
                    fold_peak(&section_peaks[n_sections + j], pk_paper)
                    j += 1
        elif peak != NULL:
            peak[i] = NAN
            peak_paper[i] = NAN
        if with_trace:
            out[i] = 0.0 if r == DWELL else (ft - fb - running - line) / m_inertial
            out[n + i] = ft
            out[2 * n + i] = fb
            out[3 * n + i] = fr
            out[4 * n + i] = fb - fr
            out[5 * n + i] = running
            out[6 * n + i] = grad
            out[7 * n + i] = curve
            out[8 * n + i] = tunnel
            out[9 * n + i] = piecewise_value_seq(&L.ceil, sr)
            out[10 * n + i] = ft * vi
            out[11 * n + i] = el_power
            out[12 * n + i] = current
            out[13 * n + i] = paper_power
            out[14 * n + i] = paper_current


cdef inline void inside_law(Law* f, double lo, double hi, double span, double eps, double* f0_out,
                            double* slope_out) noexcept nogil:
    """(value at the interval's start, slope) of the line through a law's values at lo and hi,
    just inside an interval that starts eps before lo and whose inside is ``span`` long."""
    cdef double f0 = piecewise_value_seq(f, lo)
    cdef double slope = (piecewise_value_seq(f, hi) - f0) / span
    f0_out[0] = f0 - slope * eps
    slope_out[0] = slope


cdef void interval_loop(
    Py_ssize_t n,
    const double* x,
    Law* laws,  # gradient, curve, tunnel, tunnel_v2, ceiling, available
    double g,
    double* a0,
    double* a1,
    double* b0,
    double* b1,
    double* vlim,
    double* scale,
) noexcept nogil:
    cdef Py_ssize_t i
    cdef double left, right, absleft, eps, span, lo, hi, mid
    cdef double g0, g1, c0, c1, t0, t1, k0, k1
    for i in range(n):
        left = x[i]
        right = x[i + 1]
        # Python's max(1.0, |left|): |left| only when strictly larger (so 1.0 for a NaN)
        absleft = fabs(left)
        eps = 1e-9 * (absleft if absleft > 1.0 else 1.0)
        span = nmax(right - left - 2.0 * eps, 1e-12)
        lo = left + eps
        hi = right - eps
        inside_law(&laws[0], lo, hi, span, eps, &g0, &g1)
        inside_law(&laws[1], lo, hi, span, eps, &c0, &c1)
        inside_law(&laws[2], lo, hi, span, eps, &t0, &t1)
        inside_law(&laws[3], lo, hi, span, eps, &k0, &k1)
        a0[i] = g * (g0 + c0 + t0)
        a1[i] = g * (g1 + c1 + t1)
        b0[i] = g * k0
        b1[i] = g * k1
        mid = 0.5 * (left + right)
        vlim[i] = piecewise_value_seq(&laws[4], mid)
        scale[i] = piecewise_value_seq(&laws[5], mid)


# ---- entry points: arguments checked once, then the loops above ----


# Arrays are read through the buffer protocol rather than typed memoryviews: the same pointers, without
# the memoryview support code Cython would generate into this module (three quarters of its C source,
# most of its compile time). Every buffer a call takes is held until the call returns.
# (``Held``, ``release``, ``is_format``: trainsim/_cbuffers.pxd)


cdef void* hold(Held* held, str what, str part, object a, bint integer, bint writable, Py_ssize_t* n) except? NULL:
    """Data pointer of ``a``, a C-contiguous buffer of 8-byte floats (integers with ``integer``), and
    its element count in ``n``, -1 unless it is 1-D; the buffer is held in ``held`` until ``release``.
    An error names ``what`` and ``part`` (joined only then: this runs some thirty times a call)."""
    if held.count >= MAX_HELD:
        raise RuntimeError(f"internal: more than {MAX_HELD} arrays held")
    cdef Py_buffer* view = &held.views[held.count]
    kind = "int64" if integer else "float64"
    try:
        PyObject_GetBuffer(a, view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (PyBUF_WRITABLE if writable else 0))
    except (TypeError, ValueError, BufferError) as err:
        raise ValueError(f"{what}{part}: need a C-contiguous {kind} array ({err})") from None
    held.count += 1
    # a buffer without a format (unsigned bytes; never given here) passes the format check for float64
    if view.itemsize != 8 or not (
        is_format(view.format, c'q' if integer else c'd') or (view.format == NULL and not integer)
    ):
        fmt = view.format.decode("ascii", "replace") if view.format != NULL else "B"
        raise ValueError(f"{what}{part}: need a C-contiguous {kind} array, got items of format {fmt!r}")
    n[0] = view.len // 8 if view.ndim == 1 else -1
    return view.buf


cdef object _vector(str name, object a, object dtype):
    """``a`` as a C-contiguous 1-D array of ``dtype`` (no copy when it already is one); only real
    numbers (integers for an integer dtype) are taken."""
    arr = np.asarray(a)
    allowed = "iu" if np.dtype(dtype).kind in "iu" else "iuf"
    if arr.ndim != 1 or arr.dtype.kind not in allowed:
        kinds = "integers" if allowed == "iu" else "real numbers"
        raise ValueError(f"{name}: need a 1-D array of {kinds}, got shape {arr.shape} of {arr.dtype}")
    return np.ascontiguousarray(arr, dtype=dtype)


cdef int law_from(Held* held, str name, object arrays, Law* out) except -1:
    """Fill ``out`` from ``(x, left, right, steps)``, C-contiguous float64 arrays as
    ``profile._law_arrays`` makes them."""
    if not isinstance(arrays, tuple) or len(arrays) != 4:
        raise ValueError(f"{name}: need a tuple (x, left, right, steps), got {type(arrays).__name__}")
    x, left, right, steps = arrays
    cdef Py_ssize_t nx, nl, nr
    out.x = <const double*>hold(held, name, ": x", x, False, False, &nx)
    out.left = <const double*>hold(held, name, ": left", left, False, False, &nl)
    out.right = <const double*>hold(held, name, ": right", right, False, False, &nr)
    if nl < 1 or nr != nl or nx != nl + 1:
        raise ValueError(
            f"{name}: arrays of shapes {np.shape(x)}, {np.shape(left)}, {np.shape(right)}: "
            "need n + 1 breakpoints and n left and right values, n >= 1"
        )
    out.n = nl
    out.steps = bool(steps)
    out.constant = out.steps and out.n == 1
    out.hint = 0
    out.ordered = True
    cdef Py_ssize_t k
    for k in range(nx - 1):
        if not (out.x[k] <= out.x[k + 1]):
            out.ordered = False
            break
    return 0


cdef int curve_checked(str name, object arrays, Curve* out) except -1:
    if not isinstance(arrays, tuple) or len(arrays) != 4:
        raise ValueError(f"{name} curve: need a tuple (starts, coefs, fcap, pcap), got {type(arrays).__name__}")
    try:
        return curve_from(arrays, out)
    except (TypeError, ValueError) as err:
        raise ValueError(f"{name} curve: {err}") from None


cdef tuple _sized(str name, object values, Py_ssize_t size):
    if not isinstance(values, tuple) or len(values) != size:
        raise ValueError(f"{name}: need a tuple of {size} values, got {values!r}")
    return values


def run_arrays(
    s,
    v,
    regime,
    level,
    s_right,
    tuple laws,
    resist,
    double weight,
    mech,
    electric,
    tuple traction,
    tuple service,
    tuple regen,
    bint with_trace,
):
    """Point arrays of a run and the line-current peaks.

    ``s``, ``v``, ``level``, ``s_right``: positions [m], speeds [m/s], driver levels [-] and the
    positions just right of each point [m]; ``regime``: the regime code of the stretch each point
    starts (``codes``). ``laws`` = (gradient, curve, tunnel, tunnel_v2, availability, voltage,
    ceiling) as ``(x, left, right, steps)`` (``RUN_LAWS``); ``resist`` = running resistance (c0 [N],
    c1 [N s/m], c2 [N s^2/m^2]); ``weight`` = m g [N]; ``mech`` = (inertial mass [kg], constant
    service deceleration [m/s^2], braking fraction, brakes at that constant deceleration, has a
    service braking curve, has a regenerative curve); ``electric`` = (has electrics, traction
    efficiency, regenerative efficiency x receptivity, auxiliary power [W], power factor); the three
    curves as ``EffortCurve.as_arrays()`` (any valid curve where the train has none).

    Returns ``(arrays, peak_current, peak_paper_current)``: ``arrays`` of shape (15, n), rows as
    ``TRACE_ROWS``; (15, 0) without ``with_trace``. The peaks [A] hold, at each point, the larger of
    its own current and that of the stretch it starts at either end (NaN without electrics)."""
    points = _points(s, v, regime, level, s_right)
    s_a, v_a, regime_a, level_a, s_right_a = points
    cdef Py_ssize_t n = s_a.shape[0]
    cdef Train tr
    train_from(&tr, laws, resist, weight, mech, electric, traction, service, regen)

    out = np.empty((N_ROWS, n if with_trace else 0))
    peak = np.empty(n)
    peak_paper = np.empty(n)
    if n == 0:
        return out, peak, peak_paper
    cdef Held held
    held.count = 0
    cdef RunLaws L
    cdef RunPoints P
    cdef Py_ssize_t size
    cdef double* rows = NULL
    cdef double* pp
    cdef double* ppp
    try:
        hold_run(&held, laws, points, &L, &P)
        if with_trace:
            rows = <double*>hold(&held, "rows", "", out, False, True, &size)
        pp = <double*>hold(&held, "peak", "", peak, False, True, &size)
        ppp = <double*>hold(&held, "paper peak", "", peak_paper, False, True, &size)
        with nogil:
            run_loop(n, P.s, P.v, P.regime, P.level, P.s_right, 0.0, &L, &tr, with_trace, rows, pp, ppp, NULL, 0, NULL)
    finally:
        release(&held)
    return out, peak, peak_paper


def run_peaks(
    s,
    v,
    regime,
    level,
    double s_end,
    tuple laws,
    resist,
    double weight,
    mech,
    electric,
    tuple traction,
    tuple service,
    tuple regen,
    sections,
):
    """The line-current peaks of a run without its point arrays (a summary): the arguments of
    ``run_arrays`` but ``s_right``, read as min(s + 1e-7, ``s_end`` [m]), and ``sections``, an int64
    array of shape (k, 2), each row the first and the last point of a section (inclusive, in
    increasing order). Returns ``(section_peak, section_paper_peak, peak, paper_peak)`` [A]: per
    section and over all points, the largest of what ``run_arrays`` gives per point, NaN ignored
    (``np.nanmax``; NaN where every value is, and without electrics). Nothing per point is stored."""
    points = _points(s, v, regime, level, None)
    cdef Py_ssize_t n = points[0].shape[0]
    cdef Train tr
    train_from(&tr, laws, resist, weight, mech, electric, traction, service, regen)
    bounds = np.ascontiguousarray(sections, dtype=np.int64)
    if bounds.ndim != 2 or bounds.shape[1] != 2:
        raise ValueError(f"sections: need an array of shape (k, 2), got shape {bounds.shape}")
    cdef Py_ssize_t n_sections = bounds.shape[0], k
    flat = bounds.ravel()
    for k in range(2 * n_sections):
        if not (0 <= flat[k] < n) or (k > 0 and flat[k] < flat[k - 1]):
            raise ValueError(
                f"sections: need increasing point indices in 0 .. {n - 1}, got {bounds.tolist()}"
            )
    result = np.empty(2 * n_sections + 2)
    cdef Held held
    held.count = 0
    cdef RunLaws L
    cdef RunPoints P
    cdef Py_ssize_t size
    cdef double* out
    cdef const int64_t* bp
    try:
        out = <double*>hold(&held, "result", "", result, False, True, &size)
        if n == 0:
            for k in range(2 * n_sections + 2):
                out[k] = NAN
        else:
            hold_run(&held, laws, points, &L, &P)
            bp = <const int64_t*>hold(&held, "sections", "", flat, True, False, &size)
            with nogil:
                run_loop(n, P.s, P.v, P.regime, P.level, NULL, s_end, &L, &tr, False, NULL, NULL, NULL,
                         bp, n_sections, out)
    finally:
        release(&held)
    return (
        result[:n_sections],
        result[n_sections : 2 * n_sections],
        float(result[2 * n_sections]),
        float(result[2 * n_sections + 1]),
    )


cdef tuple _points(s, v, regime, level, s_right):
    """The run's point arrays as C-contiguous arrays of their types, checked to be of one length."""
    s_a = _vector("s", s, np.float64)
    cdef Py_ssize_t n = s_a.shape[0]
    v_a = _vector("v", v, np.float64)
    regime_a = _vector("regime", regime, np.int64)
    level_a = _vector("level", level, np.float64)
    s_right_a = None if s_right is None else _vector("s_right", s_right, np.float64)
    for name, arr in (("v", v_a), ("regime", regime_a), ("level", level_a), ("s_right", s_right_a)):
        if arr is not None and arr.shape[0] != n:
            raise ValueError(f"{name}: length {arr.shape[0]}, need the length of s ({n})")
    return s_a, v_a, regime_a, level_a, s_right_a


cdef int train_from(Train* tr, tuple laws, resist, double weight, mech, electric, tuple traction,
                    tuple service, tuple regen) except -1:
    """Fill ``tr`` from ``run_arrays``'s arguments (see there), checking them and the number of laws."""
    if len(laws) != 7:
        raise ValueError(f"laws: need 7 laws {RUN_LAWS}, got {len(laws)}")
    tr.c0, tr.c1, tr.c2 = _sized("resist (c0, c1, c2)", resist, 3)
    tr.weight = weight
    m = _sized("mech", mech, 6)
    tr.mech.inertial_mass = m[0]
    tr.mech.decel = m[1]
    tr.mech.fraction = m[2]
    tr.mech.has_decel = m[3]
    tr.mech.has_service = m[4]
    tr.mech.has_regen = m[5]
    el = _sized("electric", electric, 5)
    tr.electric.is_elec = el[0]
    tr.electric.eta_t = el[1]
    tr.electric.eta_r = el[2]
    tr.electric.aux_w = el[3]
    tr.electric.pf = el[4]
    curve_checked("traction", traction, &tr.traction)
    curve_checked("service braking", service, &tr.service)
    curve_checked("regenerative braking", regen, &tr.regen)
    hint_for(&tr.traction, &tr.traction_hint)
    hint_for(&tr.service, &tr.service_hint)
    hint_for(&tr.regen, &tr.regen_hint)
    return 0


cdef void hint_for(const Curve* c, CurveHint* h) noexcept:
    """A fresh hint for the curve c: walked only where its starts are ordered (so without NaN)."""
    cdef Py_ssize_t k
    h.k = 0
    h.ordered = True
    for k in range(c.n - 1):
        if not (c.starts[k] <= c.starts[k + 1]):
            h.ordered = False
            break


cdef int hold_run(Held* held, tuple laws, tuple points, RunLaws* L, RunPoints* P) except -1:
    """Hold the seven laws and the point arrays (``_points``) of a run for the call."""
    cdef Py_ssize_t size
    law_from(held, _RUN_LAW_LABELS[0], laws[0], &L.grad)
    law_from(held, _RUN_LAW_LABELS[1], laws[1], &L.curve)
    law_from(held, _RUN_LAW_LABELS[2], laws[2], &L.tun)
    law_from(held, _RUN_LAW_LABELS[3], laws[3], &L.tun2)
    law_from(held, _RUN_LAW_LABELS[4], laws[4], &L.avail)
    law_from(held, _RUN_LAW_LABELS[5], laws[5], &L.volt)
    law_from(held, _RUN_LAW_LABELS[6], laws[6], &L.ceil)
    P.s = <const double*>hold(held, "s", "", points[0], False, False, &size)
    P.v = <const double*>hold(held, "v", "", points[1], False, False, &size)
    P.regime = <const int64_t*>hold(held, "regime", "", points[2], True, False, &size)
    P.level = <const double*>hold(held, "level", "", points[3], False, False, &size)
    P.s_right = NULL
    if points[4] is not None:
        P.s_right = <const double*>hold(held, "s_right", "", points[4], False, False, &size)
    return 0


def interval_laws(x, tuple gradient, tuple curve, tuple tunnel, tuple tunnel_v2, tuple ceiling,
                  tuple available, double g):
    """Per-interval laws of a kernel grid ``x`` [m] (``profile.compile_route``): specific line
    resistance a0 + a1 u [N/kg] and v^2 coefficient b0 + b1 u [N s^2/(kg m^2)] over the offset u into
    each interval, each law read just inside the interval so that a jump at a grid point belongs to
    the interval on its right, and the speed ceiling [m/s] and available share of tractive effort
    at the interval's middle. Laws as ``(x, left, right, steps)``; g [m/s^2]. Returns the six arrays
    (a0, a1, b0, b1, vlim, scale), one entry per interval."""
    x_a = _vector("x", x, np.float64)
    if x_a.shape[0] < 1:
        raise ValueError("x: need at least one grid point, got none")
    cdef Py_ssize_t n = x_a.shape[0] - 1
    results = tuple(np.empty(n) for _ in range(6))
    cdef Held held
    held.count = 0
    cdef Law laws[6]
    cdef double* outs[6]
    cdef const double* xp
    cdef Py_ssize_t size
    cdef int k
    try:
        law_from(&held, "law gradient", gradient, &laws[0])
        law_from(&held, "law curve", curve, &laws[1])
        law_from(&held, "law tunnel", tunnel, &laws[2])
        law_from(&held, "law tunnel_v2", tunnel_v2, &laws[3])
        law_from(&held, "law ceiling", ceiling, &laws[4])
        law_from(&held, "law available", available, &laws[5])
        if n == 0:
            return results
        xp = <const double*>hold(&held, "x", "", x_a, False, False, &size)
        for k in range(6):
            outs[k] = <double*>hold(&held, "result", "", results[k], False, True, &size)
        with nogil:
            interval_loop(n, xp, laws, g, outs[0], outs[1], outs[2], outs[3], outs[4], outs[5])
    finally:
        release(&held)
    return results


def cumulative_rows(tuple stretches):
    """The running totals of per-stretch quantities, one row each: row k is 0 at the first point and,
    at point i + 1, the sum of stretches 0 .. i of ``stretches[k]`` added in order (the bits of
    ``np.concatenate([[0.0], np.cumsum(x)])``: numpy's accumulation is sequential too), in one
    (len(stretches), n + 1) block. Every array must have the same length n."""
    cdef Py_ssize_t rows = len(stretches), n = 0, k, i, size
    if rows >= MAX_HELD:
        raise ValueError(f"stretches: at most {MAX_HELD - 1} arrays, got {rows}")
    arrays = [_vector(f"stretches[{k}]", stretches[k], np.float64) for k in range(rows)]
    for k in range(rows):
        if arrays[k].shape[0] != arrays[0].shape[0]:
            raise ValueError(
                f"stretches[{k}]: length {arrays[k].shape[0]}, need the length of stretches[0] "
                f"({arrays[0].shape[0]})"
            )
    if rows:
        n = arrays[0].shape[0]
    out = np.empty((rows, n + 1 if rows else 0))
    cdef Held held
    held.count = 0
    cdef const double* src
    cdef double* dst
    cdef double total
    try:
        if rows:
            dst = <double*>hold(&held, "rows", "", out, False, True, &size)
        for k in range(rows):
            src = <const double*>hold(&held, "stretches", "", arrays[k], False, False, &size)
            with nogil:
                dst[0] = 0.0
                if n > 0:
                    # np.cumsum starts from the first value itself, not from 0 + it (-0.0 stays -0.0)
                    total = src[0]
                    dst[1] = total
                    for i in range(1, n):
                        total = total + src[i]
                        dst[i + 1] = total
            dst += n + 1
    finally:
        release(&held)
    return out


cdef enum:
    NOT_FINITE = 1
    NEGATIVE_SPEED = 2
    POSITION_DECREASING = 4
    TIME_DECREASING = 8

#: The bits of ``point_problems``'s answer, in the order ``result._invariant_violations`` names them.
PROBLEM_NOT_FINITE = NOT_FINITE
PROBLEM_NEGATIVE_SPEED = NEGATIVE_SPEED
PROBLEM_POSITION_DECREASING = POSITION_DECREASING
PROBLEM_TIME_DECREASING = TIME_DECREASING


def point_problems(s, v, t, double tolerance):
    """What is wrong with a run's points, in one pass: a bit set (``PROBLEM_*``) for a position, speed
    or time that is not finite, a negative speed, a position or a time falling by more than
    ``tolerance`` from one point to the next (a difference that is NaN falls by nothing, as numpy's
    comparison says). s, v, t of one length."""
    points = [_vector(name, a, np.float64) for name, a in (("s", s), ("v", v), ("t", t))]
    cdef Py_ssize_t n = points[0].shape[0], i, size
    for name, arr in zip(("v", "t"), points[1:]):
        if arr.shape[0] != n:
            raise ValueError(f"{name}: length {arr.shape[0]}, need the length of s ({n})")
    cdef Held held
    held.count = 0
    cdef const double* sp
    cdef const double* vp
    cdef const double* tp
    cdef int found = 0
    try:
        sp = <const double*>hold(&held, "s", "", points[0], False, False, &size)
        vp = <const double*>hold(&held, "v", "", points[1], False, False, &size)
        tp = <const double*>hold(&held, "t", "", points[2], False, False, &size)
        with nogil:
            for i in range(n):
                # x - x is 0 for a finite x and NaN for NaN and the infinities
                if not (sp[i] - sp[i] == 0.0 and vp[i] - vp[i] == 0.0 and tp[i] - tp[i] == 0.0):
                    found |= NOT_FINITE
                if vp[i] < 0.0:
                    found |= NEGATIVE_SPEED
                if i > 0 and sp[i] - sp[i - 1] < -tolerance:
                    found |= POSITION_DECREASING
                if i > 0 and tp[i] - tp[i - 1] < -tolerance:
                    found |= TIME_DECREASING
    finally:
        release(&held)
    return found


def ceiling_law(starts, ends, limits, double length, double lo, double hi, double vmax):
    """The breakpoints and piece values of the speed ceiling over head position on [lo, hi] [m]
    (``profile.speed_ceiling``): ``limits[k]`` [m/s] holds from ``starts[k]`` until the rear of a train
    ``length`` [m] long has cleared ``ends[k]``, the train's ``vmax`` [m/s] elsewhere. Breakpoints: lo,
    hi and every start, end and cleared end strictly between them, sorted, each once; a piece takes the
    lowest limit whose span [start, cleared end) holds its middle (NaN propagated, as ``np.minimum``).
    Returns ``(x, left, right)``, left and right equal and separate arrays, or None when lo or hi is
    not a number."""
    a_arr = _vector("starts", starts, np.float64)
    b_arr = _vector("ends", ends, np.float64)
    v_arr = _vector("limits", limits, np.float64)
    cdef Py_ssize_t m = a_arr.shape[0], k, i, j, j0, j1, n_x, size
    if b_arr.shape[0] != m or v_arr.shape[0] != m:
        raise ValueError(f"starts, ends, limits: lengths {m}, {b_arr.shape[0]}, {v_arr.shape[0]}; need one length")
    if lo != lo or hi != hi:
        return None
    cdef Held held
    held.count = 0
    cdef const double* a
    cdef const double* b
    cdef const double* vals
    cdef double* x = <double*>malloc((2 + 3 * m) * sizeof(double))
    cdef double* mid = <double*>malloc((2 + 3 * m) * sizeof(double))
    cdef double* out_l
    cdef double* out_r
    cdef double c
    cdef double cands[3]
    try:
        if x == NULL or mid == NULL:
            raise MemoryError()
        a = <const double*>hold(&held, "starts", "", a_arr, False, False, &size)
        b = <const double*>hold(&held, "ends", "", b_arr, False, False, &size)
        vals = <const double*>hold(&held, "limits", "", v_arr, False, False, &size)
        x[0] = lo
        x[1] = hi
        n_x = 2
        for k in range(m):
            cands[0] = a[k]
            cands[1] = b[k]
            cands[2] = b[k] + length
            for i in range(3):
                c = cands[i]
                if c > lo and c < hi:
                    x[n_x] = c
                    n_x += 1
        n_x = sorted_unique(x, n_x)
        x_out = np.empty(n_x)
        left = np.empty(n_x - 1)
        right = np.empty(n_x - 1)
        out_l = <double*>hold(&held, "x", "", x_out, False, True, &size)
        for i in range(n_x):
            out_l[i] = x[i]
        out_l = <double*>hold(&held, "left", "", left, False, True, &size)
        out_r = <double*>hold(&held, "right", "", right, False, True, &size)
        for i in range(n_x - 1):
            mid[i] = 0.5 * (x[i] + x[i + 1])
            out_l[i] = vmax
        for k in range(m):
            # the pieces whose middles lie in [start, cleared end): one slice, mid increasing
            j0 = search_left(mid, n_x - 1, a[k])
            j1 = search_left(mid, n_x - 1, b[k] + length)
            for j in range(j0, j1):
                out_l[j] = nmin(out_l[j], vals[k])
        for i in range(n_x - 1):
            out_r[i] = out_l[i]
    finally:
        release(&held)
        free(x)
        free(mid)
    return x_out, left, right


cdef struct Keyed:
    double key
    Py_ssize_t index


cdef int _compare_keyed(const void* a, const void* b) noexcept nogil:
    """Order by key, then by index: a stable sort through qsort."""
    cdef const Keyed* x = <const Keyed*>a
    cdef const Keyed* y = <const Keyed*>b
    if x.key != y.key:
        return (x.key > y.key) - (x.key < y.key)
    return (x.index > y.index) - (x.index < y.index)


def step_law(starts, ends, values, double lo, double hi):
    """The breakpoints and piece values of a piecewise constant function on [lo, hi] [m] that is
    ``values[k]`` on ``[starts[k], ends[k])`` and 0 elsewhere (sections that do not overlap): the
    breakpoints are lo, hi and every start and end clipped to [lo, hi], sorted, each once; a piece
    takes the value of the last section (by start) starting at or before its middle if the middle
    lies before that section's end (``profile.step_function``). Returns ``(x, left, right)``, left and
    right equal and separate arrays, or None when a position is not a number."""
    a_arr = _vector("starts", starts, np.float64)
    b_arr = _vector("ends", ends, np.float64)
    v_arr = _vector("values", values, np.float64)
    cdef Py_ssize_t m = a_arr.shape[0], k, i, n_x, j
    if b_arr.shape[0] != m or v_arr.shape[0] != m:
        raise ValueError(f"starts, ends, values: lengths {m}, {b_arr.shape[0]}, {v_arr.shape[0]}; need one length")
    if lo != lo or hi != hi:
        return None
    cdef Held held
    held.count = 0
    cdef const double* a
    cdef const double* b
    cdef const double* vals
    cdef double* x = <double*>malloc((2 + 2 * m) * sizeof(double))
    cdef Keyed* order = <Keyed*>malloc((m if m > 0 else 1) * sizeof(Keyed))
    cdef double* a_s = <double*>malloc((m if m > 0 else 1) * sizeof(double))
    cdef double* out_l
    cdef double* out_r
    cdef double c, mid, value
    cdef bint ordered = True
    try:
        if x == NULL or order == NULL or a_s == NULL:
            raise MemoryError()
        a = <const double*>hold(&held, "starts", "", a_arr, False, False, &k)
        b = <const double*>hold(&held, "ends", "", b_arr, False, False, &k)
        vals = <const double*>hold(&held, "values", "", v_arr, False, False, &k)
        x[0] = lo
        x[1] = hi
        for k in range(m):
            x[2 + k] = a[k]
            x[2 + m + k] = b[k]
        for k in range(2 + 2 * m):
            c = x[k]
            if c != c:
                return None
            # np.clip: the lower bound, then the upper one
            c = lo if c < lo else c
            x[k] = hi if c > hi else c
        n_x = sorted_unique(x, 2 + 2 * m)
        for k in range(m):
            order[k].key = a[k]
            order[k].index = k
            if k > 0 and a[k] < a[k - 1]:
                ordered = False
        if not ordered:
            qsort(order, m, sizeof(Keyed), _compare_keyed)
        for k in range(m):
            a_s[k] = order[k].key
        x_out = np.empty(n_x)
        left = np.zeros(max(n_x - 1, 0))
        right = np.zeros(max(n_x - 1, 0))
        out_l = <double*>hold(&held, "x", "", x_out, False, True, &k)
        for k in range(n_x):
            out_l[k] = x[k]
        if n_x > 1:
            out_l = <double*>hold(&held, "left", "", left, False, True, &k)
            out_r = <double*>hold(&held, "right", "", right, False, True, &k)
            for i in range(n_x - 1):
                mid = 0.5 * (x[i] + x[i + 1])
                j = search_right(a_s, m, mid) - 1
                if j >= 0 and mid < b[order[j].index]:
                    value = vals[order[j].index]
                    out_l[i] = value
                    out_r[i] = value
    finally:
        release(&held)
        free(x)
        free(order)
        free(a_s)
    return x_out, left, right


cdef int _compare_doubles(const void* a, const void* b) noexcept nogil:
    cdef double x = (<const double*>a)[0], y = (<const double*>b)[0]
    return (x > y) - (x < y)


cdef Py_ssize_t sorted_unique(double* a, Py_ssize_t n) noexcept nogil:
    """``np.unique`` in place on values without NaN: sorted (only when they are not already), equal
    values kept once; returns the count kept."""
    cdef Py_ssize_t i, m
    for i in range(1, n):
        if a[i] < a[i - 1]:
            qsort(a, n, sizeof(double), _compare_doubles)
            break
    if n == 0:
        return 0
    m = 1
    for i in range(1, n):
        if a[i] != a[m - 1]:
            a[m] = a[i]
            m += 1
    return m


cdef bint is_stop(double x, const double* stops, Py_ssize_t n_stops) noexcept nogil:
    """x equals one of the stops (``np.isin``, ``in`` a set of floats: equality)."""
    cdef Py_ssize_t k
    for k in range(n_stops):
        if x == stops[k]:
            return True
    return False


cdef struct Grading:
    double max_step  # longest step [m]
    double smallest  # the step next to standstill [m]
    double ratio  # ratio of successive graded steps [-], > 1


cdef Py_ssize_t graded_points(double a, double b, bint grade_left, bint grade_right, const Grading* gr,
                              double* out) noexcept nogil:
    """The interior points of the coarse interval [a, b] next to a stop (``profile._graded``'s numpy
    form in the tests): steps graded geometrically from ``smallest`` by ``ratio`` towards a graded end,
    then a uniform subdivision (numpy's ``linspace``: i x step + start) of at most ``max_step`` in
    between. Written in increasing order to ``out`` unless it is NULL; returns how many."""
    cdef double length = b - a, left_edge = a, right_edge = b, reach, h, last = 0.0, span, step, delta
    cdef Py_ssize_t count = 0, n_off = 0, k, n, i
    if grade_left or grade_right:
        reach = length / (2.0 if grade_left and grade_right else 1.0)
        reach = reach if reach < gr.max_step else gr.max_step  # Python's min(max_step, reach)
        h = gr.smallest
        while h < reach:
            last = h
            n_off += 1
            h *= gr.ratio
        if grade_left:
            if out != NULL:
                h = gr.smallest
                for k in range(n_off):
                    out[count + k] = a + h
                    h *= gr.ratio
            count += n_off
            left_edge = a + last
        if grade_right:
            right_edge = b - last
    span = right_edge - left_edge
    if span > 0.0:
        n = <Py_ssize_t>ceil(span / gr.max_step - 1e-9)
        if n >= 2:
            delta = right_edge - left_edge
            step = delta / <double>n
            if out != NULL:
                for i in range(1, n):
                    # numpy's linspace: i x step + start, or (i / n) x delta for a step that underflows
                    out[count + i - 1] = (<double>i * step if step != 0.0 else (<double>i / <double>n) * delta) + left_edge
            count += n - 1
    if grade_right:
        if out != NULL:
            # the offsets again, the largest first (increasing positions), each by the same products
            for k in range(n_off):
                h = gr.smallest
                for i in range(n_off - 1 - k):
                    h *= gr.ratio
                out[count + k] = b - h
        count += n_off
    return count


def kernel_grid(tuple laws, stops, double max_step, double g, double tolerance, double smallest,
                double ratio):
    """The kernel grid of a run and its per-interval laws (``profile.compile_route``), in one call.

    ``laws`` = (gradient, curve, tunnel, tunnel_v2, ceiling, available) as ``(x, left, right,
    steps)``; ``stops`` the run's stops [m], increasing (the run goes from the first to the last).
    The coarse grid is every stop and every breakpoint of the laws between the first and the last
    stop, sorted, a point closer than ``tolerance`` [m] to the one before it left out. Each coarse
    interval is split uniformly into the fewest steps of at most ``max_step`` [m], except one that
    ends at a stop: there the steps grow from ``smallest`` [m] by ``ratio`` away from the stop and the
    rest is split uniformly. g [m/s^2] as ``interval_laws``. Returns ``(x, a0, a1, b0, b1, vlim,
    scale, stop_index)``: the grid [m], the six arrays of ``interval_laws`` and the grid index of
    each stop (the first grid point at or after stop - ``tolerance``); x is None when the grid is not
    strictly increasing (an input of NaN)."""
    stops_a = _vector("stops", stops, np.float64)
    cdef Py_ssize_t n_stops = stops_a.shape[0]
    if n_stops < 2:
        raise ValueError(f"stops: need at least two stops, got {n_stops}")
    if len(laws) != 6:
        raise ValueError(f"laws: need 6 laws (gradient, curve, tunnel, tunnel_v2, ceiling, available), got {len(laws)}")
    if not (max_step > 0.0 and smallest > 0.0 and ratio > 1.0):
        raise ValueError(
            f"grading: need max_step > 0, smallest > 0 and ratio > 1, got {max_step}, {smallest}, {ratio}"
        )
    cdef Grading gr
    gr.max_step = max_step
    gr.smallest = smallest
    gr.ratio = ratio
    cdef Held held
    held.count = 0
    cdef Law L[6]
    cdef const double* sp
    cdef Py_ssize_t size, k, j, i, n_cand, n_coarse, n_x, count, nk
    cdef double lo, hi, a, b, w, step
    cdef double* cand = NULL
    cdef double* xp
    cdef double* outs[6]
    cdef int64_t* idx
    cdef int q
    cdef bint left_stop, right_stop
    x = None
    try:
        for q in range(6):
            law_from(&held, _GRID_LAW_LABELS[q], laws[q], &L[q])
        sp = <const double*>hold(&held, "stops", "", stops_a, False, False, &size)
        lo = sp[0]
        hi = sp[n_stops - 1]
        n_cand = 2 + n_stops
        for q in range(6):
            n_cand += L[q].n + 1
        cand = <double*>malloc(n_cand * sizeof(double))
        if cand == NULL:
            raise MemoryError()
        # the coarse grid: the ends, the stops and the laws' breakpoints strictly inside
        cand[0] = lo
        cand[1] = hi
        n_cand = 2
        for k in range(n_stops):
            cand[n_cand] = sp[k]
            n_cand += 1
        for q in range(6):
            for k in range(L[q].n + 1):
                if L[q].x[k] > lo and L[q].x[k] < hi:
                    cand[n_cand] = L[q].x[k]
                    n_cand += 1
        for k in range(n_cand):
            if cand[k] != cand[k]:
                return None, None, None, None, None, None, None, None
        n_coarse = sorted_unique(cand, n_cand)
        j = 1
        for k in range(1, n_coarse):
            if cand[k] - cand[j - 1] > tolerance:
                cand[j] = cand[k]
                j += 1
        n_coarse = j
        # the points of each coarse interval: its start and its interior points, then the last point
        n_x = 1
        for k in range(n_coarse - 1):
            a = cand[k]
            b = cand[k + 1]
            left_stop = is_stop(a, sp, n_stops)
            right_stop = is_stop(b, sp, n_stops)
            if left_stop or right_stop:
                n_x += 1 + graded_points(a, b, left_stop, right_stop, &gr, NULL)
            else:
                n_x += max(<Py_ssize_t>ceil((b - a) / max_step - 1e-9), 1)
        x_full = np.empty(n_x)
        xp = <double*>hold(&held, "x", "", x_full, False, True, &size)
        count = 0
        for k in range(n_coarse - 1):
            a = cand[k]
            b = cand[k + 1]
            left_stop = is_stop(a, sp, n_stops)
            right_stop = is_stop(b, sp, n_stops)
            if left_stop or right_stop:
                xp[count] = a + 0.0
                count += 1 + graded_points(a, b, left_stop, right_stop, &gr, xp + count + 1)
            else:
                w = b - a
                nk = max(<Py_ssize_t>ceil(w / max_step - 1e-9), 1)
                step = w / <double>nk
                for i in range(nk):
                    xp[count + i] = a + <double>i * step
                count += nk
        xp[count] = cand[n_coarse - 1]
        n_x = sorted_unique(xp, n_x)
        for k in range(1, n_x):
            if not (xp[k] > xp[k - 1]):
                return None, None, None, None, None, None, None, None
        x = x_full[:n_x]
        results = tuple(np.empty(n_x - 1) for _ in range(6))
        stop_index = np.empty(n_stops, dtype=np.int64)
        for q in range(6):
            outs[q] = <double*>hold(&held, "result", "", results[q], False, True, &size)
        idx = <int64_t*>hold(&held, "stop_index", "", stop_index, True, True, &size)
        with nogil:
            interval_loop(n_x - 1, xp, L, g, outs[0], outs[1], outs[2], outs[3], outs[4], outs[5])
            for k in range(n_stops):
                idx[k] = search_left(xp, n_x, sp[k] - tolerance)
    finally:
        free(cand)
        release(&held)
    return (x, *results, stop_index)


def piecewise_value_at(tuple law, double s):
    """``piecewise_value`` of a law ``(x, left, right, steps)`` at s [m] (for tests)."""
    cdef Law f
    cdef Held held
    held.count = 0
    try:
        law_from(&held, "law", law, &f)
        return piecewise_value(&f, s)
    finally:
        release(&held)


def piecewise_values_seq(tuple law, s):
    """``piecewise_value_seq`` of a law ``(x, left, right, steps)`` at each of the positions s [m],
    looked up in the given order with one hint, as the loops do (for tests)."""
    cdef Law f
    cdef Held held
    held.count = 0
    s_a = np.ascontiguousarray(s, dtype=np.float64)
    out = np.empty(s_a.shape[0])
    cdef double[::1] sv = s_a
    cdef double[::1] ov = out
    cdef Py_ssize_t i
    try:
        law_from(&held, "law", law, &f)
        for i in range(sv.shape[0]):
            ov[i] = piecewise_value_seq(&f, sv[i])
    finally:
        release(&held)
    return out


def curve_values_seq(tuple curve, speeds):
    """``curve_value_seq`` of an effort curve ``as_arrays()`` at each of the speeds [m/s], looked up
    in the given order with one hint, as the loops do (for tests)."""
    cdef Curve k
    cdef CurveHint h
    curve_checked("effort", curve, &k)
    hint_for(&k, &h)
    v_a = np.ascontiguousarray(speeds, dtype=np.float64)
    out = np.empty(v_a.shape[0])
    cdef double[::1] vv = v_a
    cdef double[::1] ov = out
    cdef Py_ssize_t i
    for i in range(vv.shape[0]):
        ov[i] = curve_value_seq(vv[i], &k, &h)
    return out


def curve_value_at(double v, tuple curve):
    """``curve_value`` of an effort curve ``as_arrays()`` at v [m/s] (for tests)."""
    cdef Curve k
    curve_checked("effort", curve, &k)
    return curve_value(v, &k)
