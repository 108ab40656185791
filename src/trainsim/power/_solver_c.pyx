# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True
"""Compiled (Cython) parts of the DC power solver (``power/solver.py``): the assembly of a step's nodes
and branches, the residuals, the dense stamping, the band solver, the compiled Newton and the CSC
pattern of the sparse path.

Each function does the operations of the numba function it replaced (issue 14), one by one in the
same order and association, without contraction into fused multiply-adds or any fast-math licence,
so that the results are the same bits: Python's ``max(acc, v)`` is ``v if v > acc else acc`` and
``min`` ``v if v < acc else acc`` (numba's rule, NaN kept where it is first), numpy's ``np.max`` of
floats returns the first NaN, ``np.sum`` adds in order from 0.0 (numba's sequential loop), and the
hyperbolic functions are the C library's, which numba called too. Divisions follow the error model
of each replaced function: the residuals and the Newton divided under numpy's model (inf or NaN on
a division by zero), which C gives; the assembly used Python's, which raised ZeroDivisionError on a
contact or rail resistance of 0 (which ``Network`` refuses): it still does, naming the track.

Arrays are read through the buffer protocol (C-contiguous float64 or int64, converted when of
another dtype or layout, refused when not 1-D real numbers, naming the argument) and held for the
call; the loops run on C pointers without the GIL.
"""

from libc.math cimport INFINITY, fabs, isfinite, sinh, sqrt, tanh
from libc.stdint cimport int64_t
from libc.string cimport memcpy, memset
from cpython.buffer cimport PyBUF_C_CONTIGUOUS, PyBUF_FORMAT, PyBUF_WRITABLE, PyObject_GetBuffer
from cpython.mem cimport PyMem_Free, PyMem_Malloc

from trainsim._cbuffers cimport MAX_HELD, Held, release

import numpy as np

# (``Held``, ``release``: trainsim/_cbuffers.pxd; newton_dc_dense holds 19 inputs and 8 relabelled
# or output arrays)


cdef void* hold(Held* held, object a, bint writable) except NULL:
    """Data pointer of ``a`` (made by :func:`_vector` or here: C-contiguous, 8-byte items), held
    until ``release``."""
    if held.count >= MAX_HELD:
        raise RuntimeError(f"internal: more than {MAX_HELD} arrays held")
    cdef Py_buffer* view = &held.views[held.count]
    PyObject_GetBuffer(a, view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (PyBUF_WRITABLE if writable else 0))
    held.count += 1
    if view.len == 0:
        # an empty array may have no data pointer; nothing is read from it
        return <void*>view
    return view.buf


cdef object _vector(str name, object a, bint integer):
    """``a`` as a C-contiguous 1-D array of int64 (``integer``) or float64, without a copy when it
    already is one; only integers (and booleans), or real numbers, are taken."""
    arr = np.asarray(a)
    allowed = "biu" if integer else "biuf"
    if arr.ndim != 1 or arr.dtype.kind not in allowed:
        kinds = "integers" if integer else "real numbers"
        raise ValueError(f"{name}: need a 1-D array of {kinds}, got shape {arr.shape} of {arr.dtype}")
    return np.ascontiguousarray(arr, dtype=np.int64 if integer else np.float64)


cdef inline const double* dvec(Held* held, str name, object a, Py_ssize_t* n) except NULL:
    arr = _vector(name, a, False)
    n[0] = arr.shape[0]
    return <const double*>hold(held, arr, False)


cdef inline const int64_t* ivec(Held* held, str name, object a, Py_ssize_t* n) except NULL:
    arr = _vector(name, a, True)
    n[0] = arr.shape[0]
    return <const int64_t*>hold(held, arr, False)


cdef int same_length(str name, Py_ssize_t got, str of, Py_ssize_t need) except -1:
    if got != need:
        raise ValueError(f"{name}: length {got}, need the length of {of} ({need})")
    return 0


cdef int nodes_below(str name, const int64_t* nodes, Py_ssize_t m, int64_t n) except -1:
    """Node ids are -1 (earth) or 0 .. n - 1: the loops index arrays with them unchecked."""
    cdef Py_ssize_t k
    for k in range(m):
        if nodes[k] < -1 or nodes[k] >= n:
            raise ValueError(f"{name}[{k}]: node {nodes[k]}, need -1 (earth) or 0 .. {n - 1}")
    return 0


cdef int matrix_nodes(str name, const int64_t* nodes, Py_ssize_t m, int64_t n) except -1:
    """Row or column indices of matrix entries: 0 .. n - 1 (earth has no entry)."""
    cdef Py_ssize_t k
    for k in range(m):
        if nodes[k] < 0 or nodes[k] >= n:
            raise ValueError(f"{name}[{k}]: {nodes[k]}, need a node 0 .. {n - 1}")
    return 0


# ----------------------------------------------------------------------------------------------------
# diode rounding


cdef inline double diode_forward(double x, double delta) noexcept nogil:
    if x >= delta:
        return x
    if x <= -delta:
        return 0.0
    cdef double t = x + delta
    return t * t / (4.0 * delta)


cdef inline double diode_slope(double x, double delta) noexcept nogil:
    if x >= delta:
        return 1.0
    if x <= -delta:
        return 0.0
    return (x + delta) / (2.0 * delta)


def diode_forward_scalar(double x, double delta):
    """A diode rectifier's current over its conductance [V] at x = E - U [V], max(x, 0) rounded over
    delta [V]: 0 for x <= -delta, (x + delta)^2 / (4 delta) inside, x for x >= delta
    (``solver._diode_forward`` of one value)."""
    return diode_forward(x, delta)


def diode_forward_slope_scalar(double x, double delta):
    """Derivative of :func:`diode_forward_scalar` with respect to x: 0, (x + delta) / (2 delta), 1."""
    return diode_slope(x, delta)


# ----------------------------------------------------------------------------------------------------
# sorting (stable merge sort of indices: the order of equal keys is the input order, as numba's
# mergesort; unique values and inverses do not depend on it anyway, but the first of equal values,
# -0.0 or 0.0, is the one kept)


cdef void merge_sort_double(const double* key, int64_t* idx, int64_t* tmp, Py_ssize_t n) noexcept nogil:
    cdef Py_ssize_t width = 1, lo, mid, hi, i, j, k
    for i in range(n):
        idx[i] = i
    while width < n:
        lo = 0
        while lo < n:
            mid = lo + width if lo + width < n else n
            hi = lo + 2 * width if lo + 2 * width < n else n
            i, j, k = lo, mid, lo
            while i < mid and j < hi:
                if key[idx[j]] < key[idx[i]]:
                    tmp[k] = idx[j]
                    j += 1
                else:
                    tmp[k] = idx[i]
                    i += 1
                k += 1
            while i < mid:
                tmp[k] = idx[i]
                i += 1
                k += 1
            while j < hi:
                tmp[k] = idx[j]
                j += 1
                k += 1
            lo = hi
        memcpy(idx, tmp, n * sizeof(int64_t))
        width *= 2


cdef void merge_sort_int(const int64_t* key, int64_t* idx, int64_t* tmp, Py_ssize_t n) noexcept nogil:
    cdef Py_ssize_t width = 1, lo, mid, hi, i, j, k
    for i in range(n):
        idx[i] = i
    while width < n:
        lo = 0
        while lo < n:
            mid = lo + width if lo + width < n else n
            hi = lo + 2 * width if lo + 2 * width < n else n
            i, j, k = lo, mid, lo
            while i < mid and j < hi:
                if key[idx[j]] < key[idx[i]]:
                    tmp[k] = idx[j]
                    j += 1
                else:
                    tmp[k] = idx[i]
                    i += 1
                k += 1
            while i < mid:
                tmp[k] = idx[i]
                i += 1
                k += 1
            while j < hi:
                tmp[k] = idx[j]
                j += 1
                k += 1
            lo = hi
        memcpy(idx, tmp, n * sizeof(int64_t))
        width *= 2


# ----------------------------------------------------------------------------------------------------
# assembly


cdef struct AsmIn:
    int64_t n_fixed
    Py_ssize_t m, n_tracks
    const int64_t* track
    const double* xt
    const double* fp
    const int64_t* fp_start
    const int64_t* cid
    const int64_t* rid
    const double* gs
    const double* ge
    const int64_t* g_start
    const double* r_contact
    const double* r_rail
    const double* g_rail
    double leak_s
    bint ideal
    double small


cdef struct AsmOut:
    int64_t* a
    int64_t* b
    double* y
    int64_t* train_c
    int64_t* train_r
    int64_t* rail
    int64_t* la
    int64_t* lb
    double* ll
    double* lr
    double* lg
    double* node_pos
    Py_ssize_t nb, nr, nl
    int64_t next_id


cdef Py_ssize_t assemble_loop(const AsmIn* q, AsmOut* o, void* scratch) noexcept nogil:
    """The nodes and branches (``assemble_dc_kernel``); -1, or the track whose resistance is 0 (the
    division by zero Python's error model raised on)."""
    cdef Py_ssize_t total = q.fp_start[q.n_tracks] + q.m
    cdef int64_t* sel = <int64_t*>scratch
    cdef int64_t* order = sel + total
    cdef int64_t* tmp = order + total
    cdef int64_t* inv = tmp + total
    cdef int64_t* cu = inv + total
    cdef int64_t* ru = cu + total
    cdef double* vals = <double*>(ru + total)
    cdef double* uniq = vals + total
    cdef double* shunt = uniq + total
    cdef char* is_new = <char*>(shunt + total)
    cdef Py_ssize_t ti, j, q_, nf, ns, nv, nu, k
    cdef int64_t f0, f1, next_id = q.n_fixed
    cdef double vj, x0, x1, r, g, alpha, longest, dx, ys, yh, div
    cdef bint cut, hit, linear
    for ti in range(q.n_tracks):
        f0 = q.fp_start[ti]
        f1 = q.fp_start[ti + 1]
        nf = f1 - f0
        ns = 0
        for k in range(q.m):
            if q.track[k] == ti:
                sel[ns] = k
                ns += 1
        nv = nf + ns
        for j in range(nf):
            vals[j] = q.fp[f0 + j]
        for j in range(ns):
            vals[nf + j] = q.xt[sel[j]]
        merge_sort_double(vals, order, tmp, nv)
        nu = -1
        for j in range(nv):
            vj = vals[order[j]]
            if nu < 0 or vj != uniq[nu]:
                nu += 1
                uniq[nu] = vj
            inv[order[j]] = nu
        nu += 1
        for j in range(nu):
            is_new[j] = 1
        for j in range(nf):
            is_new[inv[j]] = 0
            cu[inv[j]] = q.cid[f0 + j]
            ru[inv[j]] = q.rid[f0 + j]
        for j in range(nu):
            if is_new[j]:
                cu[j] = next_id
                next_id += 1
        for j in range(nu):
            if is_new[j]:
                if q.ideal:
                    ru[j] = -1
                else:
                    ru[j] = next_id
                    next_id += 1
        if not q.ideal:
            for j in range(nu):
                o.rail[o.nr] = ru[j]
                o.nr += 1
        for j in range(ns):
            o.train_c[sel[j]] = cu[inv[nf + j]]
            o.train_r[sel[j]] = ru[inv[nf + j]]
        for j in range(nu):
            o.node_pos[cu[j]] = uniq[j]
            if ru[j] >= 0:
                o.node_pos[ru[j]] = uniq[j]
        for j in range(nu - 1):
            x0 = uniq[j]
            x1 = uniq[j + 1]
            cut = False
            for q_ in range(q.g_start[ti], q.g_start[ti + 1]):
                # a section insulator (zero-length gap) cuts the segments that reach it from below
                if q.ge[q_] > q.gs[q_]:
                    hit = x0 < q.ge[q_] and x1 > q.gs[q_]
                else:
                    hit = x0 < q.gs[q_] and x1 >= q.gs[q_]
                cut = cut or hit
            if not cut:
                div = q.r_contact[ti] * (x1 - x0)
                if div == 0.0:
                    return ti
                o.a[o.nb] = cu[j]
                o.b[o.nb] = cu[j + 1]
                o.y[o.nb] = 1.0 / div
                o.nb += 1
        for j in range(nu):
            o.a[o.nb] = cu[j]
            o.b[o.nb] = ru[j]
            o.y[o.nb] = q.leak_s
            o.nb += 1
        if not q.ideal:
            r = q.r_rail[ti]
            g = q.g_rail[ti]
            alpha = sqrt(r * g)
            longest = 0.0
            for j in range(nu - 1):
                dx = uniq[j + 1] - uniq[j]
                longest = dx if dx > longest else longest
            linear = alpha * longest < q.small
            for j in range(nu):
                shunt[j] = 0.0
            for j in range(nu - 1):
                dx = uniq[j + 1] - uniq[j]
                if linear:
                    div = r * dx
                    if div == 0.0:
                        return ti
                    ys = 1.0 / div
                    yh = g * dx / 2
                else:
                    div = r * sinh(alpha * dx)
                    if div == 0.0 or r == 0.0:
                        return ti
                    ys = alpha / div
                    yh = alpha / r * tanh(alpha * dx / 2)
                o.a[o.nb] = ru[j]
                o.b[o.nb] = ru[j + 1]
                o.y[o.nb] = ys
                o.nb += 1
                shunt[j] += yh
                shunt[j + 1] += yh
                if g > 0:
                    o.la[o.nl] = ru[j]
                    o.lb[o.nl] = ru[j + 1]
                    o.ll[o.nl] = dx
                    o.lr[o.nl] = r
                    o.lg[o.nl] = g
                    o.nl += 1
            if g > 0:
                for j in range(nu):
                    o.a[o.nb] = ru[j]
                    o.b[o.nb] = -1
                    o.y[o.nb] = shunt[j]
                    o.nb += 1
    o.next_id = next_id
    return -1


def assemble_dc_kernel(
    n_fixed, track, xt, fp, fp_start, cid, rid, gs, ge, g_start, r_contact, r_rail, g_rail, double leak_s,
    bint ideal, double small,
):  # fmt: skip
    """:func:`solver.assemble`'s nodes and branches of a DC network: per track the fixed points
    ``fp[fp_start[t]:fp_start[t + 1]]`` [m] (contact and rail node ids ``cid``, ``rid``) and the
    trains' rounded positions ``xt`` [m] on ``track`` merged in order (sorted distinct values and
    inverse), new contact (and rail) node ids from ``n_fixed`` in that order, then the branches:
    contact segments (1 / (r_contact dx) [S]) not cut by a gap ``gs``..``ge`` [m] of the track
    (``g_start``), the contact-to-return leakage ``leak_s`` [S] at every node, the rails' exact
    pi-equivalents (``rail.leaky_rail_pi``; linear below alpha L = ``small``) and their shunts.
    Returns (a, b, y, train_c, train_r, rail, leaky a, leaky b, leaky length, leaky r, leaky g,
    next_id, each node's chainage) before earthed nodes and renumbering."""
    cdef Held held
    held.count = 0
    cdef AsmIn q
    cdef AsmOut o
    cdef Py_ssize_t nfp, n1, n2, n3, n4, ngs, nge, ngst
    cdef void* scratch = NULL
    cdef Py_ssize_t bad
    try:
        q.n_fixed = n_fixed
        if q.n_fixed < 0:
            raise ValueError(f"n_fixed: {n_fixed}, need >= 0")
        q.track = ivec(&held, "track", track, &q.m)
        q.xt = dvec(&held, "xt", xt, &n1)
        same_length("xt", n1, "track", q.m)
        q.fp = dvec(&held, "fp", fp, &nfp)
        q.fp_start = ivec(&held, "fp_start", fp_start, &n1)
        if n1 < 1:
            raise ValueError("fp_start: need the start of each track's fixed points and their end")
        q.n_tracks = n1 - 1
        for j in range(n1):
            if q.fp_start[j] < 0 or q.fp_start[j] > nfp or (j and q.fp_start[j] < q.fp_start[j - 1]):
                raise ValueError(f"fp_start: need increasing offsets 0 .. {nfp} into fp")
        if q.fp_start[0] != 0 or q.fp_start[q.n_tracks] != nfp:
            raise ValueError(f"fp_start: need offsets from 0 to len(fp) ({nfp})")
        q.cid = ivec(&held, "cid", cid, &n2)
        same_length("cid", n2, "fp", nfp)
        q.rid = ivec(&held, "rid", rid, &n2)
        same_length("rid", n2, "fp", nfp)
        q.gs = dvec(&held, "gs", gs, &ngs)
        q.ge = dvec(&held, "ge", ge, &nge)
        same_length("ge", nge, "gs", ngs)
        q.g_start = ivec(&held, "g_start", g_start, &ngst)
        same_length("g_start", ngst, "fp_start", n1)
        for j in range(ngst):
            if q.g_start[j] < 0 or q.g_start[j] > ngs or (j and q.g_start[j] < q.g_start[j - 1]):
                raise ValueError(f"g_start: need increasing offsets 0 .. {ngs} into gs")
        q.r_contact = dvec(&held, "r_contact", r_contact, &n3)
        same_length("r_contact", n3, "the tracks (len(fp_start) - 1)", q.n_tracks)
        q.r_rail = dvec(&held, "r_rail", r_rail, &n3)
        same_length("r_rail", n3, "the tracks (len(fp_start) - 1)", q.n_tracks)
        q.g_rail = dvec(&held, "g_rail", g_rail, &n3)
        same_length("g_rail", n3, "the tracks (len(fp_start) - 1)", q.n_tracks)
        for j in range(q.m):
            if q.track[j] < 0 or q.track[j] >= q.n_tracks:
                raise ValueError(f"track[{j}]: {q.track[j]}, need a track index 0 .. {q.n_tracks - 1}")
        for j in range(nfp):
            n4 = q.n_fixed
            if q.cid[j] < 0 or q.cid[j] >= n4 or q.rid[j] < -1 or q.rid[j] >= n4:
                raise ValueError(f"cid[{j}], rid[{j}]: nodes {q.cid[j]}, {q.rid[j]}, need ids below n_fixed")
        q.leak_s = leak_s
        q.ideal = ideal
        q.small = small
        total = nfp + q.m
        cap = 4 * total
        a_o = np.empty(cap, np.int64)
        b_o = np.empty(cap, np.int64)
        y_o = np.empty(cap)
        train_c = np.empty(q.m, np.int64)
        train_r = np.empty(q.m, np.int64)
        rail = np.empty(total, np.int64)
        la = np.empty(total, np.int64)
        lb = np.empty(total, np.int64)
        ll = np.empty(total)
        lr = np.empty(total)
        lg = np.empty(total)
        node_pos = np.full(q.n_fixed + 2 * q.m, np.nan)
        o.a = <int64_t*>hold(&held, a_o, True)
        o.b = <int64_t*>hold(&held, b_o, True)
        o.y = <double*>hold(&held, y_o, True)
        o.train_c = <int64_t*>hold(&held, train_c, True)
        o.train_r = <int64_t*>hold(&held, train_r, True)
        o.rail = <int64_t*>hold(&held, rail, True)
        o.la = <int64_t*>hold(&held, la, True)
        o.lb = <int64_t*>hold(&held, lb, True)
        o.ll = <double*>hold(&held, ll, True)
        o.lr = <double*>hold(&held, lr, True)
        o.lg = <double*>hold(&held, lg, True)
        o.node_pos = <double*>hold(&held, node_pos, True)
        o.nb = o.nr = o.nl = 0
        scratch = PyMem_Malloc((9 * 8 + 1) * (total + 1))
        if scratch == NULL:
            raise MemoryError()
        with nogil:
            bad = assemble_loop(&q, &o, scratch)
        if bad >= 0:
            raise ZeroDivisionError(
                f"float division by zero: track {bad}'s contact or rail resistance is 0 (r_contact, r_rail)"
            )
        nb, nr, nl, next_id = o.nb, o.nr, o.nl, o.next_id
    finally:
        PyMem_Free(scratch)
        release(&held)
    return (a_o[:nb].copy(), b_o[:nb].copy(), y_o[:nb].copy(), train_c, train_r, rail[:nr].copy(),
            la[:nl].copy(), lb[:nl].copy(), ll[:nl].copy(), lr[:nl].copy(), lg[:nl].copy(), next_id,
            node_pos[:next_id].copy())  # fmt: skip


# ----------------------------------------------------------------------------------------------------
# residuals


cdef struct Loads:
    Py_ssize_t m
    const int64_t* tc
    const int64_t* tr
    const double* traction
    const double* aux
    const double* regen
    double u_floor, min1, full, regen_full, regen_zero


cdef int loads_from(Held* held, Loads* L, tc, tr, traction_w, auxiliary_w, regen_w, double u_floor,
                    double min1_v, double full_v, double regen_full_v, double regen_zero_v) except -1:
    cdef Py_ssize_t k
    L.tc = ivec(held, "tc", tc, &L.m)
    L.tr = ivec(held, "tr", tr, &k)
    same_length("tr", k, "tc", L.m)
    L.traction = dvec(held, "traction_w", traction_w, &k)
    same_length("traction_w", k, "tc", L.m)
    L.aux = dvec(held, "auxiliary_w", auxiliary_w, &k)
    same_length("auxiliary_w", k, "tc", L.m)
    L.regen = dvec(held, "regen_w", regen_w, &k)
    same_length("regen_w", k, "tc", L.m)
    L.u_floor = u_floor
    L.min1 = min1_v
    L.full = full_v
    L.regen_full = regen_full_v
    L.regen_zero = regen_zero_v
    return 0


cdef void load_residual_loop(
    Py_ssize_t n, const double* v, const Loads* L, const int64_t* tc_bins, const int64_t* tr_bins,
    Py_ssize_t n0, const int64_t* rows0, const int64_t* cols0, const double* w0,
    Py_ssize_t n1, const int64_t* rows1, const int64_t* cols1, const double* w1, const double* j_src,
    double* f, double* uu, double* p, double* work,
) noexcept nogil:
    cdef double* inj = work
    cdef double* out = work + (n + 1)
    cdef double* lines = work + 2 * (n + 1)
    cdef double* subs = lines + n
    cdef Py_ssize_t k, i
    cdef double vc, vr, u, a, r
    cdef double ramp = L.full - L.min1
    cdef double regen_ramp = L.regen_zero - L.regen_full
    memset(work, 0, (4 * n + 2) * sizeof(double))
    for k in range(L.m):
        vc = v[L.tc[k]] if L.tc[k] >= 0 else 0.0
        vr = v[L.tr[k]] if L.tr[k] >= 0 else 0.0
        u = vc - vr
        u = u if u >= L.u_floor else L.u_floor
        a = (u - L.min1) / ramp
        a = 0.0 if 0.0 > a else a
        a = 1.0 if 1.0 < a else a
        r = (L.regen_zero - u) / regen_ramp
        r = 0.0 if 0.0 > r else r
        r = 1.0 if 1.0 < r else r
        uu[k] = u
        p[k] = L.traction[k] * a + L.aux[k] - L.regen[k] * r
    for k in range(n0):
        lines[rows0[k]] += w0[k] * v[cols0[k]]
    for k in range(n1):
        subs[rows1[k]] += w1[k] * v[cols1[k]]
    for k in range(L.m):
        inj[tc_bins[k]] += p[k] / uu[k]
    for k in range(L.m):
        out[tr_bins[k]] += p[k] / uu[k]
    for i in range(n):
        f[i] = (((lines[i] + subs[i]) - j_src[i]) + inj[i]) - out[i]


def dc_load_residual(
    v, tc, tr, tc_bins, tr_bins, rows0, cols0, w0, rows1, cols1, w1, j_src,
    traction_w, auxiliary_w, regen_w, double u_floor, double min1_v, double full_v, double regen_full_v,
    double regen_zero_v,
):  # fmt: skip
    """The DC residual of the lines, the linear sources and the trains [A] at potentials ``v`` [V]:
    ((L + S) - J) + A - B, L the bincount of ``w0 * v[cols0]`` over ``rows0`` (lines), S that of the
    sources' weights, J ``j_src``, A and B the trains' currents p / u binned at their contact and
    rail nodes (``tc_bins``, ``tr_bins``: earth sent to bin n), p = traction a(u) + aux - regen r(u)
    on the EN 50388 / EN 50163 ramps with u floored at ``u_floor`` [V]. Returns (f, uu, p)."""
    cdef Held held
    held.count = 0
    cdef Loads L
    cdef Py_ssize_t n, k, n0, n1
    cdef const double* vp
    cdef const int64_t* tcb
    cdef const int64_t* trb
    cdef const int64_t* r0
    cdef const int64_t* c0
    cdef const double* w0p
    cdef const int64_t* r1
    cdef const int64_t* c1
    cdef const double* w1p
    cdef const double* jp
    cdef double* fp_
    cdef double* uup
    cdef double* pp
    cdef void* work = NULL
    try:
        jp = dvec(&held, "j_src", j_src, &n)
        vp = dvec(&held, "v", v, &k)
        same_length("v", k, "j_src", n)
        loads_from(&held, &L, tc, tr, traction_w, auxiliary_w, regen_w, u_floor, min1_v, full_v,
                   regen_full_v, regen_zero_v)
        nodes_below("tc", L.tc, L.m, n)
        nodes_below("tr", L.tr, L.m, n)
        tcb = ivec(&held, "tc_bins", tc_bins, &k)
        same_length("tc_bins", k, "tc", L.m)
        nodes_below("tc_bins", tcb, k, n + 1)
        trb = ivec(&held, "tr_bins", tr_bins, &k)
        same_length("tr_bins", k, "tc", L.m)
        nodes_below("tr_bins", trb, k, n + 1)
        r0 = ivec(&held, "rows0", rows0, &n0)
        c0 = ivec(&held, "cols0", cols0, &k)
        same_length("cols0", k, "rows0", n0)
        w0p = dvec(&held, "w0", w0, &k)
        same_length("w0", k, "rows0", n0)
        r1 = ivec(&held, "rows1", rows1, &n1)
        c1 = ivec(&held, "cols1", cols1, &k)
        same_length("cols1", k, "rows1", n1)
        w1p = dvec(&held, "w1", w1, &k)
        same_length("w1", k, "rows1", n1)
        matrix_nodes("rows0", r0, n0, n)
        matrix_nodes("cols0", c0, n0, n)
        matrix_nodes("rows1", r1, n1, n)
        matrix_nodes("cols1", c1, n1, n)
        f = np.empty(n)
        uu = np.empty(L.m)
        p = np.empty(L.m)
        fp_ = <double*>hold(&held, f, True)
        uup = <double*>hold(&held, uu, True)
        pp = <double*>hold(&held, p, True)
        work = PyMem_Malloc((4 * n + 2) * sizeof(double))
        if work == NULL:
            raise MemoryError()
        with nogil:
            load_residual_loop(n, vp, &L, tcb, trb, n0, r0, c0, w0p, n1, r1, c1, w1p, jp, fp_, uup, pp,
                               <double*>work)
    finally:
        PyMem_Free(work)
        release(&held)
    return f, uu, p


cdef struct Dc:
    Py_ssize_t n, nbr, nsub, ndio
    const int64_t* a
    const int64_t* b
    const double* y
    const int64_t* sp
    const int64_t* sn
    const double* ys
    const double* e
    const int64_t* dp
    const int64_t* dn
    const double* de
    const double* dy
    Loads L
    double delta, reverse_share


cdef inline double at(const double* v, int64_t node) noexcept nogil:
    return v[node] if node >= 0 else 0.0


cdef inline Py_ssize_t slot(int64_t node, Py_ssize_t n) noexcept nogil:
    return node if node >= 0 else n


cdef inline double clip01(double x) noexcept nogil:
    """min(max(x, 0.0), 1.0) with Python's (numba's) rules: NaN stays NaN."""
    x = 0.0 if 0.0 > x else x
    return 1.0 if 1.0 < x else x


cdef void residual_full(const Dc* d, const double* v, double* f, double* uu, double* p) noexcept nogil:
    """f[0 .. n] (slot n: earth, dropped), uu and p of ``dc_residual_full``."""
    cdef Py_ssize_t n = d.n, k
    cdef double va, vb, i, u, sa, sr, x, forward
    cdef const Loads* L = &d.L
    cdef double ramp = L.full - L.min1
    cdef double regen_ramp = L.regen_zero - L.regen_full
    memset(f, 0, (n + 1) * sizeof(double))
    for k in range(d.nbr):
        va = at(v, d.a[k])
        vb = at(v, d.b[k])
        i = d.y[k] * (va - vb)
        f[slot(d.a[k], n)] += i
        f[slot(d.b[k], n)] -= i
    for k in range(d.nsub):
        va = at(v, d.sp[k])
        vb = at(v, d.sn[k])
        i = d.ys[k] * (va - vb) - d.ys[k] * d.e[k]
        f[slot(d.sp[k], n)] += i
        f[slot(d.sn[k], n)] -= i
    for k in range(L.m):
        u = at(v, L.tc[k]) - at(v, L.tr[k])
        u = u if u >= L.u_floor else L.u_floor
        sa = clip01((u - L.min1) / ramp)
        sr = clip01((L.regen_zero - u) / regen_ramp)
        uu[k] = u
        p[k] = L.traction[k] * sa + L.aux[k] - L.regen[k] * sr
        i = p[k] / u
        f[slot(L.tc[k], n)] += i
        f[slot(L.tr[k], n)] -= i
    for k in range(d.ndio):
        va = at(v, d.dp[k])
        vb = at(v, d.dn[k])
        x = d.de[k] - (va - vb)
        forward = diode_forward(x, d.delta)
        i = (forward + d.reverse_share * (x - forward)) * d.dy[k]
        f[slot(d.dn[k], n)] += i
        f[slot(d.dp[k], n)] -= i


cdef int dc_from(Held* held, Dc* d, Py_ssize_t n, a, b, y, sp_on, sn_on, ys_on, e_on, dp_, dn_, de, dy, tc,
                 tr, traction_w, auxiliary_w, regen_w, double u_floor, double min1_v, double full_v,
                 double regen_full_v, double regen_zero_v, double delta, double reverse_share) except -1:
    cdef Py_ssize_t k
    d.n = n
    d.a = ivec(held, "a", a, &d.nbr)
    d.b = ivec(held, "b", b, &k)
    same_length("b", k, "a", d.nbr)
    d.y = dvec(held, "y", y, &k)
    same_length("y", k, "a", d.nbr)
    d.sp = ivec(held, "sp_on", sp_on, &d.nsub)
    d.sn = ivec(held, "sn_on", sn_on, &k)
    same_length("sn_on", k, "sp_on", d.nsub)
    d.ys = dvec(held, "ys_on", ys_on, &k)
    same_length("ys_on", k, "sp_on", d.nsub)
    d.e = dvec(held, "e_on", e_on, &k)
    same_length("e_on", k, "sp_on", d.nsub)
    d.dp = ivec(held, "dp_", dp_, &d.ndio)
    d.dn = ivec(held, "dn_", dn_, &k)
    same_length("dn_", k, "dp_", d.ndio)
    d.de = dvec(held, "de", de, &k)
    same_length("de", k, "dp_", d.ndio)
    d.dy = dvec(held, "dy", dy, &k)
    same_length("dy", k, "dp_", d.ndio)
    loads_from(held, &d.L, tc, tr, traction_w, auxiliary_w, regen_w, u_floor, min1_v, full_v, regen_full_v,
               regen_zero_v)
    nodes_below("a", d.a, d.nbr, n)
    nodes_below("b", d.b, d.nbr, n)
    nodes_below("sp_on", d.sp, d.nsub, n)
    nodes_below("sn_on", d.sn, d.nsub, n)
    nodes_below("dp_", d.dp, d.ndio, n)
    nodes_below("dn_", d.dn, d.ndio, n)
    nodes_below("tc", d.L.tc, d.L.m, n)
    nodes_below("tr", d.L.tr, d.L.m, n)
    d.delta = delta
    d.reverse_share = reverse_share
    return 0


def dc_residual_full(
    v, a, b, y, sp_on, sn_on, ys_on, e_on, dp_, dn_, de, dy, tc, tr, traction_w, auxiliary_w, regen_w,
    double u_floor, double min1_v, double full_v, double regen_full_v, double regen_zero_v, double delta,
    double reverse_share,
):  # fmt: skip
    """The DC residual G V + I_trains(V) + I_diodes(V) - J [A] at potentials ``v`` [V] (node ids -1:
    earth): branches ``y`` [S] between ``a`` and ``b``, reversible sources (``ys_on`` [S], ``e_on``
    [V]), trains' constant-power loads on the ramps, diode rectifiers (``dy`` [S], ``de`` [V]) rounded
    over ``delta`` [V] with a reverse conductance share ``reverse_share``. Returns (f, uu, p): the
    residual, each train's floored voltage [V] and power [W]."""
    cdef Held held
    held.count = 0
    cdef Dc d
    cdef Py_ssize_t n
    cdef const double* vp
    cdef double* fp_
    cdef double* uup
    cdef double* pp
    try:
        vp = dvec(&held, "v", v, &n)
        dc_from(&held, &d, n, a, b, y, sp_on, sn_on, ys_on, e_on, dp_, dn_, de, dy, tc, tr, traction_w,
                auxiliary_w, regen_w, u_floor, min1_v, full_v, regen_full_v, regen_zero_v, delta, reverse_share)
        f = np.empty(n + 1)
        uu = np.empty(d.L.m)
        p = np.empty(d.L.m)
        fp_ = <double*>hold(&held, f, True)
        uup = <double*>hold(&held, uu, True)
        pp = <double*>hold(&held, p, True)
        with nogil:
            residual_full(&d, vp, fp_, uup, pp)
    finally:
        release(&held)
    return f[:n].copy(), uu, p


# ----------------------------------------------------------------------------------------------------
# dense band Newton


cdef void stamp(double* jac, Py_ssize_t n, const int64_t* a, const int64_t* b, const double* y,
                Py_ssize_t m) noexcept nogil:
    cdef Py_ssize_t k
    for k in range(m):
        if a[k] >= 0:
            jac[a[k] * n + a[k]] += y[k]
        if b[k] >= 0:
            jac[b[k] * n + b[k]] += y[k]
        if a[k] >= 0 and b[k] >= 0:
            jac[a[k] * n + b[k]] -= y[k]
            jac[b[k] * n + a[k]] -= y[k]


cdef bint band(double* mat, double* rhs, double* x, Py_ssize_t n, Py_ssize_t w) noexcept nogil:
    """Gaussian elimination with partial pivoting on a band of half-width w (``band_solve``); True
    when singular (x then unset)."""
    cdef Py_ssize_t k, i, j, p, last, right, top
    cdef double factor, acc, t
    for k in range(n):
        last = n - 1 if n - 1 < k + w else k + w
        p = k
        for i in range(k + 1, last + 1):
            if fabs(mat[i * n + k]) > fabs(mat[p * n + k]):
                p = i
        if mat[p * n + k] == 0.0 or not isfinite(mat[p * n + k]):
            return True
        right = n - 1 if n - 1 < k + 2 * w else k + 2 * w
        if p != k:
            for j in range(k, right + 1):
                t = mat[k * n + j]
                mat[k * n + j] = mat[p * n + j]
                mat[p * n + j] = t
            t = rhs[k]
            rhs[k] = rhs[p]
            rhs[p] = t
        for i in range(k + 1, last + 1):
            factor = mat[i * n + k] / mat[k * n + k]
            if factor != 0.0:
                for j in range(k + 1, right + 1):
                    mat[i * n + j] -= factor * mat[k * n + j]
                rhs[i] -= factor * rhs[k]
    for k in range(n - 1, -1, -1):
        acc = rhs[k]
        top = n - 1 if n - 1 < k + 2 * w else k + 2 * w
        for j in range(k + 1, top + 1):
            acc -= mat[k * n + j] * x[j]
        x[k] = acc / mat[k * n + k]
    return False


cdef inline double abs_max(const double* x, Py_ssize_t n) noexcept nogil:
    """np.max(np.abs(x)) as numba computes it (the first NaN met is returned); n >= 1."""
    cdef double m = fabs(x[0]), t
    cdef Py_ssize_t i
    if m != m:
        return m
    for i in range(1, n):
        t = fabs(x[i])
        if t != t:
            return t
        if t > m:
            m = t
    return m


cdef inline double norm2(const double* x, Py_ssize_t n) noexcept nogil:
    """np.sqrt(np.sum(x * x)) as numba computes it (a sum in order from 0.0)."""
    cdef double s = 0.0
    cdef Py_ssize_t i
    for i in range(n):
        s += x[i] * x[i]
    return sqrt(s)


cdef struct Outcome:
    Py_ssize_t its
    bint converged, singular


cdef void newton_core(
    const Dc* d, Py_ssize_t w, bint keep_curtailed, Py_ssize_t max_iterations, double tol, double ftol,
    double max_step, double* v_io, Outcome* out, double* work,
) noexcept nogil:
    """``newton_dc_core`` from the potentials in ``v_io``, where the final ones are left."""
    cdef Py_ssize_t n = d.n, m = d.L.m, nd = d.ndio, k, i, it, trial
    cdef const Loads* L = &d.L
    cdef double* g0 = work
    cdef double* jac = g0 + n * n
    cdef double* f = jac + n * n
    cdef double* f_try = f + (n + 1)
    cdef double* v_try = f_try + (n + 1)
    cdef double* uu = v_try + n
    cdef double* uu_try = uu + m
    cdef double* p = uu_try + m
    cdef double* p_try = p + m
    cdef double* di = p_try + m
    cdef double* gd = di + m
    cdef double* rhs = gd + nd
    cdef double* x = rhs + n
    cdef double* dv = x + n
    cdef double* du = dv + n
    cdef double* v = v_io
    cdef double* swap
    cdef double norm, u, sa, sr, dpk, va, vb, xx, slope, step, room, cand, lam, l2, scale, bound
    cdef double t_ramp = L.full - L.min1
    cdef double r_ramp = L.regen_zero - L.regen_full
    cdef bint accepted, singular
    cdef Py_ssize_t stalls = 0
    residual_full(d, v, f, uu, p)
    norm = abs_max(f, n) if n else 0.0
    memset(g0, 0, n * n * sizeof(double))
    stamp(g0, n, d.a, d.b, d.y, d.nbr)
    stamp(g0, n, d.sp, d.sn, d.ys, d.nsub)
    out.singular = False
    for it in range(1, max_iterations + 1):
        if norm < ftol:
            out.its, out.converged = it - 1, True
            break
        for k in range(m):
            u = uu[k]
            sa = 1.0 / t_ramp if (u > L.min1 and u < L.full) else 0.0
            sr = -1.0 / r_ramp if (u > L.regen_full and u < L.regen_zero) else 0.0
            dpk = L.traction[k] * sa - L.regen[k] * sr
            di[k] = dpk / u - p[k] / (u * u) if u > L.u_floor else 0.0
        for k in range(nd):
            va = at(v, d.dp[k])
            vb = at(v, d.dn[k])
            xx = d.de[k] - (va - vb)
            slope = diode_slope(xx, d.delta)
            gd[k] = d.dy[k] * (slope + d.reverse_share * (1.0 - slope))
        memcpy(jac, g0, n * n * sizeof(double))
        stamp(jac, n, L.tc, L.tr, di, m)
        stamp(jac, n, d.dp, d.dn, gd, nd)
        # a singular Jacobian: the caller falls back on the sparse path and its error
        memcpy(rhs, f, n * sizeof(double))
        singular = band(jac, rhs, x, n, w)
        if not singular:
            for i in range(n):
                if not isfinite(x[i]):
                    singular = True
                    break
        if singular:
            out.its, out.converged, out.singular = it, False, True
            break
        for i in range(n):
            dv[i] = -x[i]
        step = abs_max(dv, n)
        if step > max_step:
            # (``step`` stays the unlimited one in the stopping tests, as in the sparse path)
            scale = max_step / step
            for i in range(n):
                dv[i] *= scale
        for k in range(m):
            du[k] = at(dv, L.tc[k]) - at(dv, L.tr[k])
        room = INFINITY
        for k in range(m):
            if L.regen[k] > 0 and du[k] > 0 and uu[k] < L.regen_zero:
                cand = 0.9 * (L.regen_zero - uu[k]) / du[k]
                room = cand if cand < room else room
        if room < 1.0:
            for i in range(n):
                dv[i] *= room
            step *= room
            for k in range(m):
                du[k] *= room
        if keep_curtailed:
            room = INFINITY
            for k in range(m):
                if L.regen[k] > 0 and du[k] < 0 and uu[k] > L.regen_full:
                    cand = 0.9 * (uu[k] - L.regen_full) / -du[k]
                    room = cand if cand < room else room
            if room < 1.0:
                for i in range(n):
                    dv[i] *= room
                step *= room
        lam = 1.0
        l2 = norm2(f, n)
        accepted = False
        for trial in range(12):
            for i in range(n):
                v_try[i] = v[i] + lam * dv[i]
            residual_full(d, v_try, f_try, uu_try, p_try)
            if norm2(f_try, n) <= (1.0 - 1e-4 * lam) * l2 or lam * step < tol:
                accepted = True
                break
            lam *= 0.5
        if not accepted:
            stalls += 1
            if stalls % 3 == 0:
                lam = 1.0
                for i in range(n):
                    v_try[i] = v[i] + dv[i]
                residual_full(d, v_try, f_try, uu_try, p_try)
        norm = abs_max(f_try, n) if n else 0.0
        swap = v
        v = v_try
        v_try = swap
        swap = f
        f = f_try
        f_try = swap
        swap = uu
        uu = uu_try
        uu_try = swap
        swap = p
        p = p_try
        p_try = swap
        bound = 1e3 * ftol * lam
        bound = bound if bound > ftol else ftol
        if lam * step < tol and norm < bound:
            out.its, out.converged = it, True
            break
    else:
        out.its, out.converged = max_iterations, norm < ftol
    if v != v_io:
        memcpy(v_io, v, n * sizeof(double))


cdef Py_ssize_t work_size(const Dc* d):
    return 2 * d.n * d.n + 2 * (d.n + 1) + 4 * d.n + 6 * d.L.m + d.ndio + 1


def newton_dc_core(
    v, Py_ssize_t w, a, b, y, sp_on, sn_on, ys_on, e_on, dp_, dn_, de, dy, tc, tr, traction_w, auxiliary_w,
    regen_w, double u_floor, double min1_v, double full_v, double regen_full_v, double regen_zero_v,
    double delta, double reverse_share, bint keep_curtailed, Py_ssize_t max_iterations, double tol,
    double ftol, double max_step,
):  # fmt: skip
    """The iteration of :func:`newton_dc_dense` from potentials ``v`` [V] on unknowns whose Jacobian has
    half-bandwidth ``w``. Returns (V, iterations, converged, singular)."""
    cdef Held held
    held.count = 0
    cdef Dc d
    cdef Outcome res
    cdef Py_ssize_t n
    cdef double* vp
    cdef double* work = NULL
    if w < 0:
        raise ValueError(f"w: {w}, need a half-bandwidth >= 0")
    try:
        v_out = np.array(_vector("v", v, False))
        n = v_out.shape[0]
        vp = <double*>hold(&held, v_out, True)
        dc_from(&held, &d, n, a, b, y, sp_on, sn_on, ys_on, e_on, dp_, dn_, de, dy, tc, tr, traction_w,
                auxiliary_w, regen_w, u_floor, min1_v, full_v, regen_full_v, regen_zero_v, delta, reverse_share)
        work = <double*>PyMem_Malloc(work_size(&d) * sizeof(double))
        if work == NULL:
            raise MemoryError()
        with nogil:
            newton_core(&d, w, keep_curtailed, max_iterations, tol, ftol, max_step, vp, &res, work)
    finally:
        PyMem_Free(work)
        release(&held)
    return v_out, res.its, res.converged, res.singular


cdef object relabelled(Held* held, str name, object nodes, const int64_t* place, Py_ssize_t n_place,
                       const int64_t** out):
    cdef Py_ssize_t m, k
    cdef const int64_t* src = ivec(held, name, nodes, &m)
    nodes_below(name, src, m, n_place)
    arr = np.empty(m, np.int64)
    cdef int64_t* dst = <int64_t*>hold(held, arr, True)
    for k in range(m):
        dst[k] = place[src[k]] if src[k] >= 0 else -1
    out[0] = dst
    return arr


cdef inline int64_t widest(int64_t w, const int64_t* a, const int64_t* b, Py_ssize_t m) noexcept nogil:
    cdef Py_ssize_t k
    cdef int64_t t
    for k in range(m):
        if a[k] >= 0 and b[k] >= 0:
            t = a[k] - b[k] if a[k] >= b[k] else b[k] - a[k]
            w = t if t > w else w
    return w


def newton_dc_dense(
    v0, place, a, b, y, sp_on, sn_on, ys_on, e_on, dp_, dn_, de, dy, tc, tr, traction_w, auxiliary_w,
    regen_w, double u_floor, double min1_v, double full_v, double regen_full_v, double regen_zero_v,
    double delta, double reverse_share, bint keep_curtailed, Py_ssize_t max_iterations, double tol,
    double ftol, double max_step,
):  # fmt: skip
    """``solver._newton_dc`` for networks without wayside storage or regulation curves: Newton from
    potentials ``v0`` [V] with the step limited to ``max_step`` [V], the fraction to the boundary of
    regeneration (and of curtailment with ``keep_curtailed``), backtracking with the occasional full
    step, stopping when a step is below ``tol`` [V] and the residual below ``ftol`` [A] (or the
    residual alone, before a step). The unknowns are renumbered by ``place`` (along the line), so
    that the Jacobian is a band, solved by :func:`band_solve`. Returns (V, iterations, converged,
    singular)."""
    cdef Held held
    held.count = 0
    cdef Dc d
    cdef Outcome res
    cdef Py_ssize_t n, k
    cdef const double* v0p
    cdef const int64_t* pl
    cdef double* vp
    cdef double* op
    cdef double* work = NULL
    cdef int64_t w
    try:
        v0p = dvec(&held, "v0", v0, &n)
        pl = ivec(&held, "place", place, &k)
        same_length("place", k, "v0", n)
        for k in range(n):
            if pl[k] < 0 or pl[k] >= n:
                raise ValueError(f"place[{k}]: {pl[k]}, need a place 0 .. {n - 1}")
        dc_from(&held, &d, n, a, b, y, sp_on, sn_on, ys_on, e_on, dp_, dn_, de, dy, tc, tr, traction_w,
                auxiliary_w, regen_w, u_floor, min1_v, full_v, regen_full_v, regen_zero_v, delta, reverse_share)
        keep = (relabelled(&held, "a", a, pl, n, &d.a), relabelled(&held, "b", b, pl, n, &d.b),
                relabelled(&held, "sp_on", sp_on, pl, n, &d.sp), relabelled(&held, "sn_on", sn_on, pl, n, &d.sn),
                relabelled(&held, "dp_", dp_, pl, n, &d.dp), relabelled(&held, "dn_", dn_, pl, n, &d.dn),
                relabelled(&held, "tc", tc, pl, n, &d.L.tc), relabelled(&held, "tr", tr, pl, n, &d.L.tr))
        v = np.empty(n)
        vp = <double*>hold(&held, v, True)
        out = np.empty(n)
        op = <double*>hold(&held, out, True)
        work = <double*>PyMem_Malloc(work_size(&d) * sizeof(double))
        if work == NULL:
            raise MemoryError()
        with nogil:
            for k in range(n):
                vp[pl[k]] = v0p[k]
            w = widest(0, d.a, d.b, d.nbr)
            w = widest(w, d.sp, d.sn, d.nsub)
            w = widest(w, d.dp, d.dn, d.ndio)
            w = widest(w, d.L.tc, d.L.tr, d.L.m)
            newton_core(&d, w, keep_curtailed, max_iterations, tol, ftol, max_step, vp, &res, work)
            for k in range(n):
                op[k] = vp[pl[k]]
        del keep
    finally:
        PyMem_Free(work)
        release(&held)
    return out, res.its, res.converged, res.singular


cdef object square(str name, object mat):
    if not (isinstance(mat, np.ndarray) and mat.ndim == 2 and mat.shape[0] == mat.shape[1]
            and mat.dtype == np.float64 and mat.flags.c_contiguous and mat.flags.writeable):
        raise ValueError(f"{name}: need a writable C-contiguous square float64 array (changed in place), got "
                         f"{type(mat).__name__} {getattr(mat, 'shape', '')} {getattr(mat, 'dtype', '')}")
    return mat


def stamp_dense(jac, a, b, y):
    """Adds the two-terminal admittances ``y`` [S] between nodes ``a`` and ``b`` (-1 earth) to the
    dense square matrix ``jac`` (changed in place)."""
    cdef Held held
    held.count = 0
    cdef Py_ssize_t n, m, k
    cdef const int64_t* ap
    cdef const int64_t* bp
    cdef const double* yp
    cdef double* jp
    square("jac", jac)
    n = jac.shape[0]
    try:
        ap = ivec(&held, "a", a, &m)
        bp = ivec(&held, "b", b, &k)
        same_length("b", k, "a", m)
        yp = dvec(&held, "y", y, &k)
        same_length("y", k, "a", m)
        nodes_below("a", ap, m, n)
        nodes_below("b", bp, m, n)
        jp = <double*>hold(&held, jac, True)
        with nogil:
            stamp(jp, n, ap, bp, yp, m)
    finally:
        release(&held)


def relabel(nodes, place):
    """``place[nodes]`` with earth (-1) kept."""
    cdef Held held
    held.count = 0
    cdef Py_ssize_t n
    cdef const int64_t* pl
    cdef const int64_t* dst
    try:
        pl = ivec(&held, "place", place, &n)
        return relabelled(&held, "nodes", nodes, pl, n, &dst)
    finally:
        release(&held)


def half_bandwidth(pairs):
    """Largest |a - b| over the two-terminal elements (both ends nodes) of the (a, b) pairs."""
    cdef Held held
    cdef int64_t w = 0
    cdef Py_ssize_t m, k
    cdef const int64_t* ap
    cdef const int64_t* bp
    for j, pair in enumerate(pairs):
        held.count = 0
        try:
            a, b = pair
            ap = ivec(&held, f"pairs[{j}][0]", a, &m)
            bp = ivec(&held, f"pairs[{j}][1]", b, &k)
            same_length(f"pairs[{j}][1]", k, f"pairs[{j}][0]", m)
            w = widest(w, ap, bp, m)
        finally:
            release(&held)
    return w


def band_solve(mat, rhs, Py_ssize_t w):
    """Solution of mat x = rhs for a matrix whose entries vanish more than w off the diagonal:
    Gaussian elimination with partial pivoting (LAPACK gbsv's algorithm, on full storage: a row swap
    widens the upper band to 2 w), O(n w^2). Overwrites mat and rhs; returns (x, singular), x the
    overwritten rhs when singular (a zero or non-finite pivot)."""
    cdef Held held
    held.count = 0
    cdef Py_ssize_t n
    cdef double* mp
    cdef double* rp
    cdef double* xp
    cdef bint singular
    square("mat", mat)
    n = mat.shape[0]
    if not (isinstance(rhs, np.ndarray) and rhs.ndim == 1 and rhs.dtype == np.float64
            and rhs.flags.c_contiguous and rhs.flags.writeable):
        raise ValueError("rhs: need a writable C-contiguous 1-D float64 array (changed in place)")
    if rhs.shape[0] != n:
        raise ValueError(f"rhs: length {rhs.shape[0]}, need the order of mat ({n})")
    if w < 0:
        raise ValueError(f"w: {w}, need a half-bandwidth >= 0")
    x = np.empty(n)
    try:
        mp = <double*>hold(&held, mat, True)
        rp = <double*>hold(&held, rhs, True)
        xp = <double*>hold(&held, x, True)
        with nogil:
            singular = band(mp, rp, xp, n, w)
    finally:
        release(&held)
    return (rhs, True) if singular else (x, False)


# ----------------------------------------------------------------------------------------------------
# CSC pattern of the sparse path


def stamp_pattern(a, b, starts, n):
    """The COO entries of the two-terminal stamps of parts ``a[starts[k]:starts[k + 1]]`` - ``b[...]``
    (node ids, -1 earth) and their places in the CSC pattern of an n x n matrix.

    Per part, in this order: ``a`` to itself where ``a`` is a node, ``b`` to itself where ``b`` is,
    then ``a`` to ``b`` and ``b`` to ``a`` where both are (sign -1); ``take`` is the element index
    within its part. Returns (rows, cols, take, sign, bounds, uniq, inv): ``bounds`` the parts'
    ranges in the entries, ``uniq`` the sorted distinct keys ``col * n + row``, ``inv`` each entry's
    index in ``uniq``."""
    cdef Held held
    held.count = 0
    cdef Py_ssize_t na, nb_, ns, n_parts, total, i, k, lo, hi, pos, group, j
    cdef int64_t nn = n, mu, kj
    cdef const int64_t* ap
    cdef const int64_t* bp
    cdef const int64_t* st
    cdef int64_t* rows_p
    cdef int64_t* cols_p
    cdef int64_t* take_p
    cdef double* sign_p
    cdef int64_t* bounds_p
    cdef int64_t* uniq_p
    cdef int64_t* inv_p
    cdef int64_t* key = NULL
    cdef int64_t* order = NULL
    cdef int64_t* tmp = NULL
    try:
        ap = ivec(&held, "a", a, &na)
        bp = ivec(&held, "b", b, &nb_)
        same_length("b", nb_, "a", na)
        st = ivec(&held, "starts", starts, &ns)
        if ns < 1:
            raise ValueError("starts: need the start of each part and the end of the last")
        n_parts = ns - 1
        for k in range(ns):
            if st[k] < 0 or st[k] > na or (k and st[k] < st[k - 1]):
                raise ValueError(f"starts: need increasing offsets 0 .. {na} into a")
        nodes_below("a", ap, st[n_parts], nn)
        nodes_below("b", bp, st[n_parts], nn)
        total = 0
        for i in range(st[n_parts]):
            if ap[i] >= 0:
                total += 1
            if bp[i] >= 0:
                total += 1
            if ap[i] >= 0 and bp[i] >= 0:
                total += 2
        rows = np.empty(total, np.int64)
        cols = np.empty(total, np.int64)
        take = np.empty(total, np.int64)
        sign = np.empty(total)
        bounds = np.empty(n_parts + 1, np.int64)
        inv = np.empty(total, np.int64)
        uniq = np.empty(total, np.int64)
        rows_p = <int64_t*>hold(&held, rows, True)
        cols_p = <int64_t*>hold(&held, cols, True)
        take_p = <int64_t*>hold(&held, take, True)
        sign_p = <double*>hold(&held, sign, True)
        bounds_p = <int64_t*>hold(&held, bounds, True)
        inv_p = <int64_t*>hold(&held, inv, True)
        uniq_p = <int64_t*>hold(&held, uniq, True)
        key = <int64_t*>PyMem_Malloc(3 * (total + 1) * sizeof(int64_t))
        if key == NULL:
            raise MemoryError()
        order = key + (total + 1)
        tmp = order + (total + 1)
        with nogil:
            pos = 0
            for k in range(n_parts):
                bounds_p[k] = pos
                lo = st[k]
                hi = st[k + 1]
                for group in range(4):
                    for i in range(lo, hi):
                        if group == 0 and ap[i] >= 0:
                            rows_p[pos], cols_p[pos], sign_p[pos] = ap[i], ap[i], 1.0
                        elif group == 1 and bp[i] >= 0:
                            rows_p[pos], cols_p[pos], sign_p[pos] = bp[i], bp[i], 1.0
                        elif group == 2 and ap[i] >= 0 and bp[i] >= 0:
                            rows_p[pos], cols_p[pos], sign_p[pos] = ap[i], bp[i], -1.0
                        elif group == 3 and ap[i] >= 0 and bp[i] >= 0:
                            rows_p[pos], cols_p[pos], sign_p[pos] = bp[i], ap[i], -1.0
                        else:
                            continue
                        take_p[pos] = i - lo
                        pos += 1
            bounds_p[n_parts] = pos
            for j in range(total):
                key[j] = cols_p[j] * nn + rows_p[j]
            merge_sort_int(key, order, tmp, total)
            mu = -1
            for j in range(total):
                kj = key[order[j]]
                if mu < 0 or kj != uniq_p[mu]:
                    mu += 1
                    uniq_p[mu] = kj
                inv_p[order[j]] = mu
    finally:
        PyMem_Free(key)
        release(&held)
    return rows, cols, take, sign, bounds, uniq[: mu + 1].copy(), inv
