"""Compiled kernel of the fastest run: speed envelopes in the distance domain.

State: E = v^2 / 2 [m^2/s^2] over head position s [m], so that dE/ds = a is regular at standstill,
and time t with dt/ds = 1/v. Each grid interval has linear line-resistance laws and a constant
speed ceiling; RK4 steps of at most one interval, with every regime switch root-found inside its
interval (OSRD-style envelopes: braking curves backwards from every ceiling drop and stop, then
maximum traction forwards under them).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from trainsim.model.effort import POWER_CAP_MIN_SPEED_MPS
from trainsim.sim.codes import (  # noqa: F401  (re-exported: kernel.X is how the kernels read them)
    BRAKE,
    COAST,
    CRUISE,
    DWELL,
    FOLLOW,
    N_PARAMS,
    P_BRAKE_FRACTION,
    P_DECEL,
    P_INERTIAL_MASS,
    P_MASS,
    P_R0,
    P_R1,
    P_R2,
    P_TRACTION_SCALE,
    P_WEIGHT,
    POSITION_TOLERANCE,
    REGEN,
    REGIME_NAMES,
    SPEED_TOLERANCE,
    STATUS_OK,
    STATUS_STALLED,
    TRACTION,
)


# inlined (numba IR) into its few callers, as ``_law``: a call passes two arrays with an atomic
# reference count increment and decrement each
@njit(cache=True, inline="always")
def effort(v, starts, coefs, fcap, pcap):
    """Maximum force [N] of a compiled EffortCurve at speed v [m/s]."""
    j = np.searchsorted(starts, v, side="right") - 1
    if j < 0:
        j = 0
    f = coefs[j, 0] + coefs[j, 1] * v + coefs[j, 2] * v * v
    if coefs[j, 3] != 0.0:
        f += coefs[j, 3] / v if v > 0.0 else np.inf
    if f > fcap:
        f = fcap
    vp = v if v > POWER_CAP_MIN_SPEED_MPS else POWER_CAP_MIN_SPEED_MPS
    if f * vp > pcap:
        f = pcap / vp
    return f if f > 0.0 else 0.0


@njit(cache=True, inline="always")
def _law(v, j, coefs):
    """Interval j's law c0 + c1 v + c2 v^2 + ch / v of a compiled EffortCurve [N]."""
    f = coefs[j, 0] + coefs[j, 1] * v + coefs[j, 2] * v * v
    if coefs[j, 3] != 0.0:
        f += coefs[j, 3] / v if v > 0.0 else np.inf
    return f


@njit(cache=True)
def effort_branch(v, vref, starts, coefs, fcap, pcap):
    """Force [N] of a compiled EffortCurve at speed v [m/s] on the smooth branch that holds at the
    reference speed ``vref`` (its interval, and whichever of law, force cap, power cap or zero binds
    there), continued smoothly to v; with ``vref < 0`` the curve itself (``effort``).

    An integration between two kinks evaluates its stages on the branch of the piece it integrates:
    a stage that lands just beyond a kink (a table step such as source 002's braking force jumping
    from 150 to 335 kN between 5 and 6 km/h, or a cap) must not see the next branch, and a piece
    that starts exactly at a kink must see the branch it goes into."""
    if vref < 0.0:
        return effort(v, starts, coefs, fcap, pcap)
    j = np.searchsorted(starts, vref, side="right") - 1
    if j < 0:
        j = 0
    best = _law(vref, j, coefs)
    branch = 0
    if fcap < best:
        best, branch = fcap, 1
    vp = vref if vref > POWER_CAP_MIN_SPEED_MPS else POWER_CAP_MIN_SPEED_MPS
    if pcap / vp < best:
        best, branch = pcap / vp, 2
    if not best > 0.0:
        return 0.0
    if branch == 1:
        return fcap
    if branch == 2:
        return pcap / (v if v > POWER_CAP_MIN_SPEED_MPS else POWER_CAP_MIN_SPEED_MPS)
    f = _law(v, j, coefs)
    return f if f > 0.0 else 0.0


@njit(cache=True)
def resistance_force(v, u, line, P):
    """Running plus line resistance [N] at speed v and offset u into the interval whose line
    resistance laws are ``line = (a0, a1, b0, b1)``: specific resistance a0 + a1 u [N/kg] and
    v^2 coefficient b0 + b1 u [N s^2/(kg m^2)] (ratios of the weight times the route's g)."""
    a0, a1, b0, b1 = line
    running = P[P_R0] + P[P_R1] * v + P[P_R2] * v * v
    return running + P[P_MASS] * ((a0 + a1 * u) + (b0 + b1 * u) * v * v)


@njit(cache=True)
def acceleration(mode, E, u, line, P, curves, vref=-1.0):
    """dE/ds = acceleration [m/s^2] in a regime with maximum effort. ``curves`` holds the compiled
    traction, service braking and regenerative braking EffortCurves,
    ``(ts, tc, tf, tp, bs, bc, bf, bp, rs, rc, rf, rp)``; ``vref`` >= 0 selects the curves' branch
    (``effort_branch``)."""
    ts, tc, tf, tp, bs, bc, bf, bp, rs, rc, rf, rp = curves
    v = np.sqrt(2.0 * E) if E > 0.0 else 0.0
    res = resistance_force(v, u, line, P)
    M = P[P_INERTIAL_MASS]
    if mode == TRACTION:
        return (P[P_TRACTION_SCALE] * effort_branch(v, vref, ts, tc, tf, tp) - res) / M
    if mode == BRAKE:
        if P[P_DECEL] > 0.0:
            a_res = res / M
            return -a_res if a_res > P[P_DECEL] else -P[P_DECEL]
        return -(P[P_BRAKE_FRACTION] * effort_branch(v, vref, bs, bc, bf, bp) + res) / M
    if mode == REGEN:
        return -(effort_branch(v, vref, rs, rc, rf, rp) + res) / M
    return -res / M


#: Longest RK4 step as a share of the motion's length scale 2E / |a| = v^2 / |a| [-] (within about
#: that distance E(s) meets the square-root singularity of standstill), at most ``MAX_SUBSTEPS``
#: sub-steps per step. Only slow, strongly braked or accelerated steps are divided: at 20 m/s and
#: 1 m/s^2 the scale is 400 m.
LENGTH_SCALE_FRACTION = 0.01
MAX_SUBSTEPS = 64


@njit(cache=True)
def _substeps(E, h, a):
    """Number of RK4 sub-steps for a step h [m] from E with acceleration a [m/s^2] there (see
    ``LENGTH_SCALE_FRACTION``)."""
    a = abs(a)
    if not (a > 0.0 and E > 0.0):
        return 1
    n = int(np.ceil(abs(h) * a / (LENGTH_SCALE_FRACTION * 2.0 * E)))
    return min(max(n, 1), MAX_SUBSTEPS)


@njit(cache=True)
def rk4_energy(E, u, h, mode, line, P, curves, vref=-1.0):
    """E after a step h [m] (negative: backwards) from offset u; not clipped at 0. Slow steps are
    divided into sub-steps (``LENGTH_SCALE_FRACTION``)."""
    k1 = acceleration(mode, E, u, line, P, curves, vref)
    n = _substeps(E, h, k1)
    d = h / n
    for j in range(n):
        if j > 0:
            k1 = acceleration(mode, E, u, line, P, curves, vref)
        E = _rk4_energy_1(E, u, d, mode, line, P, curves, vref, k1)
        u += d
    return E


@njit(cache=True)
def _rk4_energy_1(E, u, h, mode, line, P, curves, vref, k1):
    """One RK4 step of E over h [m] from offset u, with k1 the acceleration there."""
    k2 = acceleration(mode, E + 0.5 * h * k1, u + 0.5 * h, line, P, curves, vref)
    k3 = acceleration(mode, E + 0.5 * h * k2, u + 0.5 * h, line, P, curves, vref)
    k4 = acceleration(mode, E + h * k3, u + h, line, P, curves, vref)
    return E + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


#: Sub-intervals of a step over which time is summed with the exact constant-acceleration formula.
TIME_SUBSTEPS = 4


@njit(cache=True)
def rk4_energy_time(E, u, h, mode, line, P, curves, vref=-1.0):
    """(E, elapsed time) after a forward step h [m] from offset u; slow steps are divided into
    sub-steps (``LENGTH_SCALE_FRACTION``), each as ``_rk4_energy_time_1``."""
    k1 = acceleration(mode, E, u, line, P, curves, vref)
    n = _substeps(E, h, k1)
    d = h / n
    total = 0.0
    for j in range(n):
        E = E if E > 0.0 else 0.0
        if j > 0:
            k1 = acceleration(mode, E, u, line, P, curves, vref)
        E, dt = _rk4_energy_time_1(E, u, d, mode, line, P, curves, vref, k1)
        total += dt
        u += d
    return E, total


@njit(cache=True)
def _rk4_energy_time_1(E, u, h, mode, line, P, curves, vref, k1):
    """(E, elapsed time) after one forward RK4 step h [m] from offset u.

    Time is the integral of ds / v, singular at standstill. E(s) over the step is taken as the
    cubic Hermite interpolant of its end values and slopes, and on each sub-interval, where E is
    nearly linear, dt = 2 ds / (v_a + v_b), exact for linear E (constant acceleration).
    """
    k2 = acceleration(mode, E + 0.5 * h * k1, u + 0.5 * h, line, P, curves, vref)
    k3 = acceleration(mode, E + 0.5 * h * k2, u + 0.5 * h, line, P, curves, vref)
    k4 = acceleration(mode, E + h * k3, u + h, line, P, curves, vref)
    E1 = E + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    d1 = acceleration(mode, E1 if E1 > 0.0 else 0.0, u + h, line, P, curves, vref)
    dt = 0.0
    v_prev = np.sqrt(2.0 * E) if E > 0.0 else 0.0
    for j in range(1, TIME_SUBSTEPS + 1):
        x = j / TIME_SUBSTEPS
        h00 = 2 * x**3 - 3 * x**2 + 1
        h10 = x**3 - 2 * x**2 + x
        h01 = -2 * x**3 + 3 * x**2
        h11 = x**3 - x**2
        Ej = h00 * E + h10 * h * k1 + h01 * E1 + h11 * h * d1
        vj = np.sqrt(2.0 * Ej) if Ej > 0.0 else 0.0
        dt += 2.0 * (h / TIME_SUBSTEPS) / (v_prev + vj) if v_prev + vj > 0.0 else np.inf
        v_prev = vj
    return E1, dt


#: Speed change covered by one RK4 step of a speed-domain integration [m/s], and the fewest steps.
SPEED_DOMAIN_STEP = 0.05
SPEED_DOMAIN_MIN_STEPS = 3
#: Extra steps per unit of |ln(a_end / a_start)|: a force that changes steeply with speed (source
#: 002's braking force, 150 to 335 kN between 5 and 6 km/h) puts a pole of ds/dv = v / a(v) close to
#: the interval, where a nearly constant one (most tables) needs only the fewest steps.
SPEED_DOMAIN_STEPS_PER_LOG = 12.0


@njit(cache=True)
def speed_domain_steps(v_from, v_to, a_from, a_to):
    """RK4 steps for a speed-domain integration from v_from to v_to [m/s] with accelerations a_from,
    a_to [m/s^2] at its ends (same sign): more where the acceleration changes by a large factor."""
    n = abs(v_to - v_from) / SPEED_DOMAIN_STEP
    if a_from * a_to > 0.0:
        n = min(n, 8.0) + SPEED_DOMAIN_STEPS_PER_LOG * abs(np.log(a_to / a_from))
    return min(max(int(np.ceil(n)), SPEED_DOMAIN_MIN_STEPS), 128)


@njit(cache=True)
def distance_to_speed(E, u, Et, mode, line, P, curves):
    """Signed distance [m] from (u, E) along ``mode`` until E reaches Et, integrating
    ds/dv = v / a(v, s) in the speed domain (exact event location, no root finding; regular down to
    standstill, and exact for a constant force). The law must be smooth between E and Et (no kink
    inside; it is evaluated on the branch of the speeds in between). Returns inf when the
    acceleration vanishes or changes sign on the way, i.e. Et is never reached."""
    v_from = np.sqrt(2.0 * E) if E > 0.0 else 0.0
    v_to = np.sqrt(2.0 * Et) if Et > 0.0 else 0.0
    vref = 0.5 * (v_from + v_to)  # the law is smooth in between: evaluate it on that branch
    n = speed_domain_steps(
        v_from,
        v_to,
        acceleration(mode, E, u, line, P, curves, vref),
        acceleration(mode, Et, u, line, P, curves, vref),
    )
    dv = (v_to - v_from) / n
    v = v_from
    s = 0.0
    sign = 0.0
    for _ in range(n):
        a1 = acceleration(mode, 0.5 * v * v, u + s, line, P, curves, vref)
        if sign == 0.0:
            sign = 1.0 if a1 > 0.0 else -1.0
        if a1 * sign <= 0.0:
            return np.inf
        r1 = v / a1
        vm = v + 0.5 * dv
        a2 = acceleration(mode, 0.5 * vm * vm, u + s + 0.5 * dv * r1, line, P, curves, vref)
        if a2 * sign <= 0.0:
            return np.inf
        r2 = vm / a2
        a3 = acceleration(mode, 0.5 * vm * vm, u + s + 0.5 * dv * r2, line, P, curves, vref)
        if a3 * sign <= 0.0:
            return np.inf
        r3 = vm / a3
        ve = v + dv
        a4 = acceleration(mode, 0.5 * ve * ve, u + s + dv * r3, line, P, curves, vref)
        if a4 * sign <= 0.0:
            return np.inf
        r4 = ve / a4
        s += dv / 6.0 * (r1 + 2.0 * r2 + 2.0 * r3 + r4)
        v = ve
    return s


@njit(cache=True)
def _next_kink(v0, rising, v_far, kinks):
    """The kink speed closest to v0 in the direction of the speed change, strictly before v_far,
    or -1 (``kinks`` sorted increasing)."""
    if rising:
        j = np.searchsorted(kinks, v0, side="right")
        if j < len(kinks) and kinks[j] < v_far:
            return kinks[j]
    else:
        j = np.searchsorted(kinks, v0, side="left") - 1
        if j >= 0 and kinks[j] > v_far:
            return kinks[j]
    return -1.0


@njit(cache=True)
def _is_kink(v, kinks):
    """Whether speed v [m/s] is one of the kink speeds (sorted), to within SPEED_TOLERANCE."""
    j = np.searchsorted(kinks, v)
    if j < len(kinks) and abs(kinks[j] - v) <= SPEED_TOLERANCE:
        return True
    return j > 0 and abs(kinks[j - 1] - v) <= SPEED_TOLERANCE


@njit(cache=True)
def step_energy_time(E, u, h, mode, line, P, curves, kinks):
    """(E, elapsed time) after a step h [m] from offset u, restarted at every kink of the
    effort curve on the way: one RK4 step across a kink (e.g. source 002's braking force jumping
    from 150 to 335 kN between 5 and 6 km/h) loses its accuracy, so the kink is located in the
    speed domain and the step split there."""
    remaining = h
    total_dt = 0.0
    split = _is_kink(np.sqrt(2.0 * E) if E > 0.0 else 0.0, kinks)
    for _ in range(64):
        E1, dt = rk4_energy_time(E, u, remaining, mode, line, P, curves)
        v0 = np.sqrt(2.0 * E) if E > 0.0 else 0.0
        v1 = np.sqrt(2.0 * E1) if E1 > 0.0 else 0.0
        rising = v1 > v0
        # a kink just beyond v1 may still lie inside the step: RK4 across it can land on either side
        v_far = v1 + 0.5 * (v1 - v0) + 1e-6 if rising else v1 - 0.5 * (v0 - v1) - 1e-6
        vk = _next_kink(v0, rising, v_far, kinks)
        hk = np.inf
        if vk >= 0.0:
            hk = distance_to_speed(E, u, 0.5 * vk * vk, mode, line, P, curves)
        if not (hk * remaining > 0.0 and abs(hk) < abs(remaining) - POSITION_TOLERANCE):
            if split or vk >= 0.0:
                # again on this piece's branch: it starts at a kink, or one lies at its very end
                E1, dt = rk4_energy_time(E, u, remaining, mode, line, P, curves, 0.5 * (v0 + v1))
            return E1, total_dt + dt
        split = True
        _, dtk = rk4_energy_time(E, u, hk, mode, line, P, curves, 0.5 * (v0 + vk))
        total_dt += dtk
        E = 0.5 * vk * vk
        u += hk
        remaining -= hk
    return E1, total_dt + dt


@njit(cache=True)
def step_energy(E, u, h, mode, line, P, curves, kinks):
    """E after a kink-aware step h [m] (negative: backwards) from offset u; like
    ``step_energy_time`` without the time, for the backward braking curves."""
    remaining = h
    E1 = E
    split = _is_kink(np.sqrt(2.0 * E) if E > 0.0 else 0.0, kinks)
    for _ in range(64):
        E1 = rk4_energy(E, u, remaining, mode, line, P, curves)
        v0 = np.sqrt(2.0 * E) if E > 0.0 else 0.0
        v1 = np.sqrt(2.0 * E1) if E1 > 0.0 else 0.0
        rising = v1 > v0
        v_far = v1 + 0.5 * (v1 - v0) + 1e-6 if rising else v1 - 0.5 * (v0 - v1) - 1e-6
        vk = _next_kink(v0, rising, v_far, kinks)
        hk = np.inf
        if vk >= 0.0:
            hk = distance_to_speed(E, u, 0.5 * vk * vk, mode, line, P, curves)
        if not (hk * remaining > 0.0 and abs(hk) < abs(remaining) - POSITION_TOLERANCE):
            if split or vk >= 0.0:
                E1 = rk4_energy(E, u, remaining, mode, line, P, curves, 0.5 * (v0 + v1))
            return E1
        split = True
        E = 0.5 * vk * vk
        u += hk
        remaining -= hk
    return E1


@njit(cache=True)
def find_speed_crossing_split(E, u, H, target_E, mode, line, P, curves, kinks):
    """Signed distance in (0, H] (H may be negative) where E reaches target_E along ``mode``,
    chaining speed-domain integrations across the kinks in between; H if it is not reached."""
    v_t = np.sqrt(2.0 * target_E) if target_E > 0.0 else 0.0
    v = np.sqrt(2.0 * E) if E > 0.0 else 0.0
    rising = v_t > v
    total = 0.0
    for _ in range(64):
        vk = _next_kink(v, rising, v_t, kinks)
        Ek = 0.5 * vk * vk if vk >= 0.0 else target_E
        hk = distance_to_speed(E, u + total, Ek, mode, line, P, curves)
        if not np.isfinite(hk):
            return H
        total += hk
        if vk < 0.0:
            break
        E, v = Ek, vk
    if total * H <= 0.0 or abs(total) > abs(H):
        return H
    return total


@njit(cache=True)
def find_curve_meeting(E, u, Er, w, line, P, curves, tk, bk):
    """Offset in (u, w] where the traction curve from (u, E) meets the braking curve ending at
    (w, Er) (Illinois method on their difference)."""
    lo, hi = u, w
    f_lo = E - step_energy(Er, w, u - w, BRAKE, line, P, curves, bk)
    f_hi = step_energy(E, u, w - u, TRACTION, line, P, curves, tk) - Er
    side = 0
    x = hi
    for _ in range(100):
        if f_hi == f_lo:
            break
        x = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
        f = step_energy(E, u, x - u, TRACTION, line, P, curves, tk) - step_energy(
            Er, w, x - w, BRAKE, line, P, curves, bk
        )
        if (f > 0.0) == (f_hi > 0.0):
            hi, f_hi = x, f
            if side == 1:
                f_lo *= 0.5
            side = 1
        else:
            lo, f_lo = x, f
            if side == -1:
                f_hi *= 0.5
            side = -1
        if abs(hi - lo) < POSITION_TOLERANCE or f == 0.0:
            break
    return x


@njit(cache=True)
def braking_ceiling(x, a0, a1, b0, b1, vlim, i0, i1, P, curves, bk, mode=BRAKE):
    """Backward pass from standstill at x[i1] to x[i0]: the speed ceiling made of the limits and
    the braking curves of ``mode`` (BRAKE: service braking; REGEN: regenerative braking only) to
    every lower limit and to the stop, ``bk`` being that curve's kinks. See
    ``braking_ceiling_mixed`` for the result."""
    modes = np.full(len(a0), mode, dtype=np.int64)
    return braking_ceiling_mixed(x, a0, a1, b0, b1, vlim, i0, i1, P, curves, bk, bk, modes)


@njit(cache=True)
def braking_ceiling_mixed(x, a0, a1, b0, b1, vlim, i0, i1, P, curves, bk, rk, modes):
    """Backward pass from standstill at x[i1] to x[i0]: the speed ceiling made of the limits and
    the service braking curves to every lower limit and to the stop. For interval k = i - i0 it
    is the limit vlim[i] on offsets below US[k] and the braking curve ending at (width, Cr[k])
    above; Cl[k] is its value at the interval's start. ``mode`` is BRAKE (service braking) or
    REGEN (regenerative braking only, for energy-efficient approaches to lower limits). Here the
    mode is per interval (``modes[i]``), with ``bk`` / ``rk`` the kinks of each braking curve."""
    m_int = i1 - i0
    Cr = np.empty(m_int)
    Cl = np.empty(m_int)
    US = np.empty(m_int)
    c_next = 0.0
    for k in range(m_int - 1, -1, -1):
        i = i0 + k
        w = x[i + 1] - x[i]
        cr = min(vlim[i], c_next)
        Er = 0.5 * cr * cr
        line = (a0[i], a1[i], b0[i], b1[i])
        mode = modes[i]
        kinks = bk if mode == BRAKE else rk
        if cr >= vlim[i] and (
            acceleration(mode, Er, 0.0, line, P, curves) < 0.0
            and acceleration(mode, Er, w, line, P, curves) < 0.0
        ):
            # braking backwards from the limit only rises above it: the whole interval is at the limit
            US[k] = w
            Cl[k] = vlim[i]
            Cr[k] = cr
            c_next = vlim[i]
            continue
        El = step_energy(Er, w, -w, mode, line, P, curves, kinks)
        vl = np.sqrt(2.0 * El) if El > 0.0 else 0.0
        if vl <= vlim[i]:
            US[k] = 0.0
            Cl[k] = vl
        else:
            if cr >= vlim[i] - SPEED_TOLERANCE:
                US[k] = w
            else:
                h = find_speed_crossing_split(
                    Er,
                    w,
                    -w,
                    0.5 * vlim[i] * vlim[i],
                    mode,
                    line,
                    P,
                    curves,
                    kinks,
                )
                US[k] = w + h
            Cl[k] = vlim[i]
        Cr[k] = cr
        c_next = Cl[k]

    return Cr, Cl, US


@njit(cache=True)
def fastest_segment(
    x,
    a0,
    a1,
    b0,
    b1,
    vlim,
    tscale,
    i0,
    i1,
    t0,
    P,
    curves,
    tk,
    bk,
    out_s,
    out_v,
    out_t,
    out_m,
    n,
):
    """Fastest run from standstill at x[i0] to standstill at x[i1]; appends points to the out
    arrays from index n. Returns (new n, status, position of a stall)."""
    m_int = i1 - i0
    Cr, _, US = braking_ceiling(x, a0, a1, b0, b1, vlim, i0, i1, P, curves, bk)

    # forward pass: maximum traction under the ceiling
    v = 0.0
    t = t0
    for k in range(m_int):
        i = i0 + k
        w = x[i + 1] - x[i]
        line = (a0[i], a1[i], b0[i], b1[i])
        vl_i = vlim[i]
        P[P_TRACTION_SCALE] = tscale[i]
        u = 0.0
        while u < w:
            E = 0.5 * v * v
            if u < US[k]:
                end = US[k]
                if v >= vl_i - SPEED_TOLERANCE:
                    v = vl_i
                    # cruise as long as the traction can hold the speed
                    need_u = resistance_force(v, u, line, P)
                    need_end = resistance_force(v, end, line, P)
                    fmax = P[P_TRACTION_SCALE] * effort(v, curves[0], curves[1], curves[2], curves[3])
                    if need_u > fmax * (1.0 + 1e-12):
                        stop_at = u
                    elif need_end > fmax:
                        stop_at = u + (end - u) * (fmax - need_u) / (need_end - need_u)
                    else:
                        stop_at = end
                    if stop_at > u:
                        out_s[n] = x[i] + u
                        out_v[n] = v
                        out_t[n] = t
                        out_m[n] = CRUISE
                        n += 1
                        t += (stop_at - u) / v
                        u = stop_at
                        continue
                # traction towards the end of this part
                E1, dt = step_energy_time(E, u, end - u, TRACTION, line, P, curves, tk)
                if E1 <= 0.0:
                    h = find_speed_crossing_split(E, u, end - u, 0.0, TRACTION, line, P, curves, tk)
                    out_s[n] = x[i] + u
                    out_v[n] = v
                    out_t[n] = t
                    out_m[n] = TRACTION
                    n += 1
                    out_s[n] = x[i] + u + h
                    out_v[n] = 0.0
                    out_t[n] = t + (2.0 * h / v if v > 0 else 0.0)
                    out_m[n] = TRACTION
                    n += 1
                    return n, STATUS_STALLED, x[i] + u + h
                v1 = np.sqrt(2.0 * E1)
                out_s[n] = x[i] + u
                out_v[n] = v
                out_t[n] = t
                out_m[n] = TRACTION
                n += 1
                if v1 > vl_i and v < vl_i:
                    h = find_speed_crossing_split(
                        E,
                        u,
                        end - u,
                        0.5 * vl_i * vl_i,
                        TRACTION,
                        line,
                        P,
                        curves,
                        tk,
                    )
                    _, dt = step_energy_time(E, u, h, TRACTION, line, P, curves, tk)
                    t += dt
                    u += h
                    v = vl_i
                else:
                    t += dt
                    u = end
                    v = min(v1, vl_i)
            else:
                # under the braking curve that ends at (w, Cr[k])
                Er = 0.5 * Cr[k] * Cr[k]
                Eb = step_energy(Er, w, u - w, BRAKE, line, P, curves, bk)
                if Eb * (1.0 - 1e-9) - 1e-12 > E:
                    E1, dt = step_energy_time(E, u, w - u, TRACTION, line, P, curves, tk)
                    out_s[n] = x[i] + u
                    out_v[n] = v
                    out_t[n] = t
                    out_m[n] = TRACTION
                    n += 1
                    if Er < E1:
                        xm = find_curve_meeting(E, u, Er, w, line, P, curves, tk, bk)
                        Em, dt = step_energy_time(E, u, xm - u, TRACTION, line, P, curves, tk)
                        t += dt
                        u = xm
                        v = np.sqrt(2.0 * Em) if Em > 0 else 0.0
                        continue
                    if E1 <= 0.0:
                        return n, STATUS_STALLED, x[i] + u
                    t += dt
                    u = w
                    v = np.sqrt(2.0 * E1)
                else:
                    out_s[n] = x[i] + u
                    out_v[n] = v
                    out_t[n] = t
                    out_m[n] = BRAKE
                    n += 1
                    _, dt = step_energy_time(0.5 * v * v, u, w - u, BRAKE, line, P, curves, bk)
                    t += dt
                    u = w
                    v = Cr[k]
    out_s[n] = x[i1]
    out_v[n] = 0.0
    out_t[n] = t
    out_m[n] = DWELL
    n += 1
    return n, STATUS_OK, 0.0


@njit(cache=True)
def _kinks_between(v0, v1, kinks):
    """Number of kink speeds strictly between v0 and v1 (0, not -1, when v0 == v1 is a kink: that
    miscount once sized the output of ``insert_kink_points`` too small, and the trace lost its
    last points)."""
    lo, hi = min(v0, v1), max(v0, v1)
    n = np.searchsorted(kinks, hi, side="left") - np.searchsorted(kinks, lo, side="right")
    return n if n > 0 else 0


@njit(cache=True)
def insert_kink_points(x, a0, a1, b0, b1, tscale, P, curves, tk, bk, s, v, t, m):
    """The trace with a point added wherever a traction or braking stretch crosses a kink of its
    effort curve, so that trapezoidal work integrals over the trace are exact at kinks."""
    n = len(s)
    extra = 0
    for k in range(n - 1):
        if m[k] == TRACTION:
            extra += _kinks_between(v[k], v[k + 1], tk)
        elif m[k] == BRAKE:
            extra += _kinks_between(v[k], v[k + 1], bk)
    out_s = np.empty(n + extra)
    out_v = np.empty(n + extra)
    out_t = np.empty(n + extra)
    out_m = np.empty(n + extra, dtype=m.dtype)
    j = 0
    n_int = len(a0)
    for k in range(n):
        out_s[j] = s[k]
        out_v[j] = v[k]
        out_t[j] = t[k]
        out_m[j] = m[k]
        j += 1
        if k == n - 1 or (m[k] != TRACTION and m[k] != BRAKE):
            continue
        kinks = tk if m[k] == TRACTION else bk
        if _kinks_between(v[k], v[k + 1], kinks) == 0:
            continue
        i = np.searchsorted(x, s[k], side="right") - 1
        if i > n_int - 1:
            i = n_int - 1
        P[P_TRACTION_SCALE] = tscale[i]
        line = (a0[i], a1[i], b0[i], b1[i])
        u = s[k] - x[i]
        E = 0.5 * v[k] * v[k]
        time = t[k]
        remaining = s[k + 1] - s[k]
        rising = v[k + 1] > v[k]
        vc = v[k]
        # never more points than counted above (the output arrays are sized by that count)
        for _ in range(_kinks_between(v[k], v[k + 1], kinks)):
            vk = _next_kink(vc, rising, v[k + 1], kinks)
            if vk < 0.0:
                break
            hk = distance_to_speed(E, u, 0.5 * vk * vk, m[k], line, P, curves)
            if not (0.0 < hk < remaining):
                break
            _, dt = rk4_energy_time(E, u, hk, m[k], line, P, curves, 0.5 * (vc + vk))
            E = 0.5 * vk * vk
            u += hk
            remaining -= hk
            time += dt
            vc = vk
            out_s[j] = x[i] + u
            out_v[j] = vk
            out_t[j] = time
            out_m[j] = m[k]
            j += 1
    return out_s[:j], out_v[:j], out_t[:j], out_m[:j]
