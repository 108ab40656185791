# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True
"""Reading effort curves into the structs of ``_forces.pxd`` (see there)."""

import numpy as np


cdef int curve_from(object arrays, Curve* out) except -1:
    """Fill ``out`` from ``(starts, coefs, fcap, pcap)``; the arrays must stay alive (they are the
    caller's) and are C-contiguous float64 as ``EffortCurve.as_arrays()`` makes them."""
    starts, coefs, fcap, pcap = arrays
    cdef const double[::1] s = starts
    cdef const double[:, ::1] c = coefs
    if s.shape[0] == 0 or c.shape[0] != s.shape[0] or c.shape[1] != 4:
        raise ValueError(f"effort curve arrays of shapes {np.shape(starts)} and {np.shape(coefs)}: need (n,) and (n, 4), n >= 1")
    out.starts = &s[0]
    out.coefs = &c[0, 0]
    out.n = s.shape[0]
    out.fcap = fcap
    out.pcap = pcap
    return 0


cdef int curves_from(object curves, Curves* out) except -1:
    """Fill ``out`` from the 12-tuple ``(ts, tc, tf, tp, bs, bc, bf, bp, rs, rc, rf, rp)`` of the
    traction, service braking and regenerative braking curves' ``as_arrays()``."""
    curve_from(curves[0:4], &out.traction)
    curve_from(curves[4:8], &out.brake)
    curve_from(curves[8:12], &out.regen)
    return 0


def power_cap_min_speed():
    """The floor of the power cap's speed compiled into the extension [m/s] (checked by a test
    against ``trainsim.model.effort.POWER_CAP_MIN_SPEED_MPS``)."""
    return POWER_CAP_MIN_SPEED


def effort_at(double v, object arrays):
    """``effort`` [N] at speed v [m/s] through the compiled structs (for tests)."""
    cdef Curve k
    curve_from(arrays, &k)
    return effort(v, &k)


def effort_branch_at(double v, double vref, object arrays):
    """``effort_branch`` [N] at speed v on the branch of ``vref`` through the compiled structs (for tests)."""
    cdef Curve k
    curve_from(arrays, &k)
    return effort_branch(v, vref, &k)


def effort_on_at(speeds, double vref, object arrays):
    """``effort_on`` at each of the speeds [m/s] with the branch ``branch_at(vref)`` chose once, as the
    energy integration evaluates a piece (for tests: it must equal ``effort_branch`` at each)."""
    cdef Curve k
    cdef Branch b
    curve_from(arrays, &k)
    branch_at(vref, &k, &b)
    return [effort_on(v, &b, &k) for v in speeds]


def compiled_codes():
    """The regime codes and parameter indices compiled into the extension (checked by a test
    against ``trainsim.sim.codes``)."""
    return {
        "TRACTION": TRACTION, "CRUISE": CRUISE, "COAST": COAST, "BRAKE": BRAKE, "DWELL": DWELL,
        "REGEN": REGEN, "FOLLOW": FOLLOW, "P_INERTIAL_MASS": P_INERTIAL_MASS, "P_MASS": P_MASS,
        "P_R0": P_R0, "P_R1": P_R1, "P_R2": P_R2, "P_DECEL": P_DECEL, "P_BRAKE_FRACTION": P_BRAKE_FRACTION,
        "P_TRACTION_SCALE": P_TRACTION_SCALE, "N_PARAMS": N_PARAMS,
    }


def speed_domain_steps_of(double v_from, double v_to, double a_from, double a_to):
    """``speed_domain_steps`` through the compiled function (for tests)."""
    return speed_domain_steps(v_from, v_to, a_from, a_to)


def speed_domain_settings():
    """The speed-domain step settings compiled into the extension (checked against
    ``trainsim.sim.codes``)."""
    return SPEED_DOMAIN_STEP, SPEED_DOMAIN_MIN_STEPS, SPEED_DOMAIN_STEPS_PER_LOG
