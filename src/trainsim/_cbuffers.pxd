# cython: language_level=3
"""Shared inline helpers of the compiled (Cython) modules (issue 14): reading numpy arrays through the
buffer protocol, searching sorted arrays (the kink speeds of the effort curves among them) and
Python's ``min``/``max`` of two floats. Each module cimports what it uses, so that each helper exists
once.

Two ways of reading an array are used:

- ``Held`` / ``release``: the buffers a call takes are held until the call returns (``sim._energy_c``,
  ``sim._trace_c``, ``multipoint._mp_c``, ``power._solver_c``; each module's ``hold`` checks the
  buffer its own way and names the argument). The counts held at most: ``_energy_c.stretch_works``
  5 point arrays + 7 laws + P + 3 kink arrays + 3 outputs = 19; ``_trace_c.run_arrays`` 5 run arrays
  + 7 laws x 3 + 3 outputs = 29; ``_mp_c.run`` 41; ``_solver_c.newton_dc_dense`` 19 inputs and 8
  relabelled or output arrays.
- ``_array``: pointer and shape checked and the buffer released at once (``sim._kernel_c``,
  ``optimize._pmp_c``); the pointers stay valid for the call because the caller holds the arrays
  and numpy frees an array's data only with the array.
"""

from cpython.buffer cimport (
    PyBUF_C_CONTIGUOUS,
    PyBUF_FORMAT,
    PyBUF_WRITABLE,
    PyBuffer_Release,
    PyObject_GetBuffer,
)


# ---- buffers held for the call

cdef enum:
    MAX_HELD = 48


cdef struct Held:
    Py_buffer views[MAX_HELD]
    int count


cdef inline void release(Held* held) noexcept:
    cdef int k
    for k in range(held.count):
        PyBuffer_Release(&held.views[k])
    held.count = 0


cdef inline bint is_format(const char* f, char kind) noexcept:
    """A native buffer format of ``kind``: ``d`` float64, ``q`` int64 (``l`` or ``q``), ``b`` int8;
    False without a format."""
    if f == NULL:
        return False
    if f[0] == c'@' or f[0] == c'=':
        f += 1
    if f[0] == 0 or f[1] != 0:
        return False
    if kind == c'q':
        return f[0] == c'l' or f[0] == c'q'
    return f[0] == kind


# ---- buffers read and released at once

cdef struct Arr:
    void* data
    Py_ssize_t n  # length (rows of a 2-D array)
    Py_ssize_t cols  # columns of a 2-D array, 1 for a 1-D one


cdef inline Arr _array(object a, str what, char kind, int ndim=1, bint writable=False) except *:
    """Data pointer and shape of a C-contiguous array of float64 (``kind`` 'd'), int8 ('b') or int64
    ('q'), or a ValueError naming ``what`` and what is allowed."""
    cdef Py_buffer view
    cdef int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT
    if writable:
        flags |= PyBUF_WRITABLE
    cdef Py_ssize_t size = 1 if kind == c'b' else 8
    cdef str need = (
        f"a C-contiguous {'writable ' if writable else ''}{ndim}-D array of "
        + ("float64" if kind == c'd' else "int8" if kind == c'b' else "int64")
    )
    try:
        PyObject_GetBuffer(a, &view, flags)
    except Exception as e:
        raise ValueError(f"{what}: need {need}, got {type(a).__name__} ({e})") from None
    cdef char f
    cdef bint ok
    cdef Arr out
    try:
        f = view.format[0] if view.format != NULL else c'B'
        if f == c'@' or f == c'=' or f == c'<':
            f = view.format[1]
        ok = (
            view.ndim == ndim
            and view.itemsize == size
            and (f == kind or (kind == c'q' and f == c'l'))
            and (ndim == 1 or view.shape[1] > 0)
        )
        if not ok:
            raise ValueError(
                f"{what}: need {need}, got {view.ndim}-D of format "
                f"{view.format.decode() if view.format else '?'} and item size {view.itemsize}"
            )
        out.data = view.buf
        out.n = view.shape[0]
        out.cols = view.shape[1] if ndim == 2 else 1
    finally:
        PyBuffer_Release(&view)
    return out


# ---- sorted-array searches

cdef inline Py_ssize_t search_right(const double* a, Py_ssize_t n, double v) noexcept nogil:
    """``np.searchsorted(a, v, side="right")`` on a sorted array without NaN (NaN v sorts last)."""
    cdef Py_ssize_t lo = 0, hi = n, mid
    if v != v:
        return n
    while lo < hi:
        mid = (lo + hi) >> 1
        if a[mid] <= v:
            lo = mid + 1
        else:
            hi = mid
    return lo


cdef inline Py_ssize_t search_left(const double* a, Py_ssize_t n, double v) noexcept nogil:
    """``np.searchsorted(a, v, side="left")`` on a sorted array without NaN (NaN v sorts last)."""
    cdef Py_ssize_t lo = 0, hi = n, mid
    if v != v:
        return n
    while lo < hi:
        mid = (lo + hi) >> 1
        if a[mid] < v:
            lo = mid + 1
        else:
            hi = mid
    return lo


# ---- kink speeds: a sorted array searched

cdef struct Kinks:
    const double* v  # kink speeds [m/s], increasing
    Py_ssize_t n


cdef inline double next_kink(double v0, bint rising, double v_far, const Kinks* kinks) noexcept nogil:
    """The kink speed [m/s] closest to v0 in the direction of the speed change, strictly before
    v_far, or -1 (kinks sorted increasing)."""
    cdef Py_ssize_t j
    if rising:
        j = search_right(kinks.v, kinks.n, v0)
        if j < kinks.n and kinks.v[j] < v_far:
            return kinks.v[j]
    else:
        j = search_left(kinks.v, kinks.n, v0) - 1
        if j >= 0 and kinks.v[j] > v_far:
            return kinks.v[j]
    return -1.0


# ---- Python's min and max of two floats

cdef inline double pmin(double a, double b) noexcept nogil:
    """Python's (and numba's) min(a, b): b if b < a else a."""
    return b if b < a else a


cdef inline double pmax(double a, double b) noexcept nogil:
    """Python's (and numba's) max(a, b): b if b > a else a."""
    return b if b > a else a
