# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True
"""Compiled (Cython) stray-current sum of ``power/rail.py``: :func:`segment_leakage_total_a`.

The operations of the numba function it replaced (issue 14), in the same order and association
(Python's ``max(acc, v)`` is ``v if v > acc else acc``, ``min`` ``v if v < acc else acc``), with the C
library's hyperbolic functions, which numba called too: the same bits. The numba function divided
under Python's error model; none of its divisions can be by zero for finite segments (a
non-linear segment has alpha L >= 1e-4, the sign change needs V_a != V_b), and for the degenerate
ones (an infinite length without leakage) a division by zero still raises ZeroDivisionError.
"""

from libc.math cimport atanh, cosh, sinh, sqrt, tanh
from cpython.buffer cimport PyBUF_C_CONTIGUOUS, PyBUF_FORMAT, PyBuffer_Release, PyObject_GetBuffer

import numpy as np

_NAMES = ("va_v", "vb_v", "length_m", "r_ohm_per_m", "g_s_per_m")


cdef int leakage_loop(const double** cols, Py_ssize_t n, double* total_out) noexcept nogil:
    """The sum into ``total_out``; 1 on a division by zero (Python's error model raised), else 0."""
    cdef double total_a = 0.0, va, vb, length, r, g, alpha, al, a_safe, total, positive, sh, ch
    cdef double x0, first, q, half, den
    cdef bint lin
    cdef Py_ssize_t k
    for k in range(n):
        va = cols[0][k]
        vb = cols[1][k]
        length = cols[2][k]
        r = cols[3][k]
        g = cols[4][k]
        alpha = sqrt(r * g)
        al = alpha * length
        lin = al < 1e-4
        a_safe = 1.0 if lin else alpha
        if lin:
            total = (va + vb) * length / 2
        else:
            if a_safe == 0.0:
                return 1
            total = (va + vb) * tanh(al / 2) / a_safe
        positive = total if va + vb > 0 else 0.0
        if va * vb < 0:
            sh = sinh(al)
            ch = cosh(al)
            if lin:
                x0 = length * va / (va - vb)
                first = va * x0 / 2
            else:
                den = va * ch - vb
                if den == 0.0:
                    return 1
                q = va * sh / den
                q = -1 + 1e-16 if -1 + 1e-16 > q else q
                q = 1 - 1e-16 if 1 - 1e-16 < q else q
                x0 = atanh(q) / a_safe
                half = sinh(alpha * x0 / 2)
                den = a_safe * sh
                if den == 0.0:
                    return 1
                first = (va * 2 * sinh(alpha * (2 * length - x0) / 2) * half + vb * 2 * half * half) / den
            positive = first if va > 0 else total - first
        total_a += g * (0.0 if 0.0 > positive else positive)
    total_out[0] = total_a
    return 0


def segment_leakage_total_a(va_v, vb_v, length_m, r_ohm_per_m, g_s_per_m) -> float:
    """The sum over rail segments of ``rail.segment_leakage_a`` [A]: the current leaving each segment
    into the earth, g times the integral of max(V, 0) along it, from its end potentials V_a, V_b [V],
    length [m], rail resistance r [ohm/m] and rail-to-earth conductance g [S/m] (1-D arrays of one
    length), segment by segment with the same formulas and branches."""
    cdef Py_buffer views[5]
    cdef const double* cols[5]
    cdef int held = 0, k, bad = 0
    cdef Py_ssize_t n = -1
    cdef double total = 0.0
    arrays = []
    for k in range(5):
        arr = np.asarray((va_v, vb_v, length_m, r_ohm_per_m, g_s_per_m)[k])
        if arr.ndim != 1 or arr.dtype.kind not in "biuf":
            raise ValueError(f"{_NAMES[k]}: need a 1-D array of real numbers, got shape {arr.shape} of {arr.dtype}")
        if n >= 0 and arr.shape[0] != n:
            raise ValueError(f"{_NAMES[k]}: length {arr.shape[0]}, need the length of va_v ({n})")
        n = arr.shape[0]
        arrays.append(np.ascontiguousarray(arr, dtype=np.float64))
    try:
        for k in range(5):
            PyObject_GetBuffer(arrays[k], &views[k], PyBUF_C_CONTIGUOUS | PyBUF_FORMAT)
            held += 1
            cols[k] = <const double*>views[k].buf
        with nogil:
            bad = leakage_loop(cols, n, &total)
    finally:
        for k in range(held):
            PyBuffer_Release(&views[k])
    if bad:
        raise ZeroDivisionError("float division by zero: a degenerate rail segment (length_m, r_ohm_per_m, g_s_per_m)")
    return total
