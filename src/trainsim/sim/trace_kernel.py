"""Compiled point and stretch arrays of a run: forces, powers, line currents and their peaks.

One pass over the points of a run evaluates what ``result._trace_and_peaks_numpy`` evaluates with
numpy (that function is kept as the reference the tests compare against): at every point the forces
of its regime at its speed with the line resistance just right of it, the accelerations, the
mechanical, electrical and paper-convention powers and the line currents (I = P / (U cos phi), source
002 eq. 15); at every stretch the end powers of its regime at both of its ends with the line
resistance at its middle, whose currents enter the running peaks. Every expression is written in the
order numpy evaluates it, so that the arrays are the same bits (IEEE operations without contraction
into fused multiply-adds, which numba does not do without ``fastmath``); with ``with_trace`` false
only the peaks are stored, which is what a summary needs. ``interval_laws`` evaluates the kernel
grid's per-interval line laws the same way (``profile.compile_track``).

A line law is passed as ``(x, left, right, steps)``, the arrays of a ``profile.PiecewiseLinear`` and
whether it is piecewise constant; an effort curve as ``EffortCurve.as_arrays()``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from trainsim.model.effort import POWER_CAP_MIN_SPEED_MPS
from trainsim.sim.codes import BRAKE, CRUISE, DWELL, FOLLOW, REGEN, TRACTION

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


@njit(cache=True, inline="always")
def _nmin(a, b):
    """min(a, b) with NaN propagated (numpy's ``minimum``)."""
    if a != a:
        return a
    if b != b:
        return b
    return a if a <= b else b


@njit(cache=True, inline="always")
def _nmax(a, b):
    """max(a, b) with NaN propagated (numpy's ``maximum``)."""
    if a != a:
        return a
    if b != b:
        return b
    return a if a >= b else b


@njit(cache=True, error_model="numpy")
def piecewise_value(law, s):
    """Value of a ``PiecewiseLinear`` given as ``law = (x, left, right, steps)`` at position s [m],
    as its ``__call__`` computes it (the end values beyond the ends; NaN at NaN)."""
    x, left, right, steps = law
    if s != s:
        return np.nan
    k = np.searchsorted(x, s, side="right") - 1
    if k < 0:
        k = 0
    if k > len(left) - 1:
        k = len(left) - 1
    if steps:
        return left[k] + 0.0
    x0 = x[k]
    frac = _nmin(_nmax((s - x0) / (x[k + 1] - x0), 0.0), 1.0)
    return left[k] + (right[k] - left[k]) * frac


@njit(cache=True, error_model="numpy")
def curve_value(v, curve):
    """Force [N] of an ``EffortCurve`` given as ``as_arrays()`` at speed v [m/s], as its ``__call__``
    computes it (the law, the hyperbolic term c3 / v, the force cap, the power cap P / max(v, 1 mm/s),
    then the clip at 0). ``kernel.effort`` compares F v with the power cap instead: the same force
    but for the last bit, which is why the trace has its own."""
    starts, coefs, fcap, pcap = curve
    j = np.searchsorted(starts, v, side="right") - 1
    if j < 0:
        j = 0
    law = coefs[j, 0] + coefs[j, 1] * v + coefs[j, 2] * v * v
    law = law + (coefs[j, 3] / v if coefs[j, 3] != 0.0 else 0.0)
    power = pcap / _nmax(v, POWER_CAP_MIN_SPEED_MPS)
    return _nmax(_nmin(_nmin(law, fcap), power), 0.0)


@njit(cache=True, error_model="numpy")
def regime_forces(mode, v, running, line, level, avail, inertia, mech, traction, service, regen):
    """(traction, braking) force [N] in regime ``mode`` at speed v [m/s], with running and line
    resistance [N], the driver's level, the available share of tractive effort and the force the
    stretch's acceleration needs (FOLLOW) [N] (``result._regime_forces``). ``mech`` = (inertial mass
    [kg], constant service deceleration [m/s^2], braking fraction, brakes at that constant
    deceleration, has a service braking curve, has a regenerative curve)."""
    m_inertial, decel, fraction, has_decel, has_service, has_regen = mech
    ft = 0.0
    fb = 0.0
    if mode == TRACTION:
        ft = level * avail * curve_value(v, traction)
    elif mode == CRUISE:
        need = running + line
        ft = _nmax(need, 0.0)
        fb = _nmax(-need, 0.0)
    elif mode == BRAKE:
        if has_decel:
            fb = level * _nmax(m_inertial * decel - running - line, 0.0)
        elif has_service:
            fb = level * fraction * curve_value(v, service)
    elif mode == REGEN:
        if has_regen:
            fb = curve_value(v, regen)
    elif mode == FOLLOW:
        need = inertia + running + line
        ft = _nmax(need, 0.0)
        fb = _nmax(-need, 0.0)
    return ft, fb


@njit(cache=True, error_model="numpy")
def run_arrays(
    s, v, regime, level, s_right, laws, resist, weight, mech, electric, traction, service, regen, with_trace
):
    """Point arrays of a run and the line-current peaks.

    ``laws`` = (gradient, curve, tunnel, tunnel_v2, availability, voltage, ceiling) as
    ``(x, left, right, steps)``; ``resist`` = running resistance (c0, c1, c2); ``weight`` = m g [N];
    ``mech`` as in ``regime_forces``; ``electric`` = (has electrics, traction efficiency,
    regenerative efficiency x receptivity, auxiliary power [W], power factor).

    Returns ``(arrays, peak_current, peak_paper_current)``: ``arrays`` of shape (15, n), rows as
    ``TRACE_ROWS``; (15, 0) without ``with_trace``. The peaks [A] hold, at each
    point, the larger of its own current and that of the stretch it starts at either end (NaN
    without electrics)."""
    grad_l, curve_l, tun_l, tun2_l, avail_l, volt_l, ceil_l = laws
    c0, c1, c2 = resist
    m_inertial = mech[0]
    is_elec, eta_t, eta_r, aux_w, pf = electric
    has_regen = mech[5]
    n = len(s)
    out = np.empty((15, n if with_trace else 0))
    peak = np.empty(n)
    peak_paper = np.empty(n)
    for i in range(n):
        vi = v[i]
        sr = s_right[i]
        r = regime[i]
        running = (c0 + c1 * vi + c2 * vi * vi) * (1.0 if vi > 0.0 else 0.0)
        grad = weight * piecewise_value(grad_l, sr)
        curve = weight * piecewise_value(curve_l, sr)
        tunnel = weight * (piecewise_value(tun_l, sr) + piecewise_value(tun2_l, sr) * vi * vi)
        line = grad + curve + tunnel
        inertia = 0.0
        if i < n - 1:
            ds = s[i + 1] - s[i]
            acc_stretch = (v[i + 1] * v[i + 1] - vi * vi) / (2.0 * ds) if ds > 0.0 else 0.0
            inertia = m_inertial * acc_stretch
        avail = piecewise_value(avail_l, sr)
        ft, fb = regime_forces(r, vi, running, line, level[i], avail, inertia, mech, traction, service, regen)
        cap = curve_value(vi, regen) if has_regen else 0.0
        fr = _nmin(fb, cap)
        p_trac = ft * vi / eta_t
        el_power = p_trac + aux_w - fr * vi * eta_r
        paper_power = ft * vi * eta_t
        current = np.nan
        paper_current = np.nan
        if is_elec:
            u = piecewise_value(volt_l, sr)
            safe = u if u > 0.0 else 1.0
            current = el_power / (safe * pf) if u > 0.0 else 0.0
            paper_current = paper_power / (safe * pf) if u > 0.0 else 0.0
            end_current = -np.inf
            end_paper = -np.inf
            if i < n - 1:
                # a point carries the forces of the stretch it starts, so the end of a traction stretch
                # (full effort at its highest speed, often the peak) is only seen from the stretch
                v0 = vi
                v1 = v[i + 1]
                mid = 0.5 * (s[i] + s[i + 1])
                vm = np.sqrt(0.5 * (v0 * v0 + v1 * v1))
                line_mid = (
                    weight * piecewise_value(grad_l, mid)
                    + weight * piecewise_value(curve_l, mid)
                    + weight * (piecewise_value(tun_l, mid) + piecewise_value(tun2_l, mid) * vm * vm)
                )
                avail_mid = piecewise_value(avail_l, mid)
                run0 = c0 + c1 * v0 + c2 * v0 * v0
                run1 = c0 + c1 * v1 + c2 * v1 * v1
                f0t, f0b = regime_forces(
                    r, v0, run0, line_mid, level[i], avail_mid, inertia, mech, traction, service, regen
                )
                f1t, f1b = regime_forces(
                    r, v1, run1, line_mid, level[i], avail_mid, inertia, mech, traction, service, regen
                )
                rg0 = _nmin(f0b, curve_value(v0, regen)) if has_regen else 0.0
                rg1 = _nmin(f1b, curve_value(v1, regen)) if has_regen else 0.0
                u_mid = piecewise_value(volt_l, mid)
                safe_mid = u_mid if u_mid > 0.0 else 1.0
                end_power = _nmax(f0t * v0 / eta_t - rg0 * v0 * eta_r, f1t * v1 / eta_t - rg1 * v1 * eta_r)
                if u_mid > 0.0:
                    end_current = (end_power + aux_w) / (safe_mid * pf)
                    end_paper = eta_t * _nmax(f0t * v0, f1t * v1) / (safe_mid * pf)
                else:
                    end_current = 0.0
                    end_paper = 0.0
            peak[i] = _nmax(current, end_current)
            peak_paper[i] = _nmax(paper_current, end_paper)
        else:
            peak[i] = np.nan
            peak_paper[i] = np.nan
        if with_trace:
            out[0, i] = 0.0 if r == DWELL else (ft - fb - running - line) / m_inertial
            out[1, i] = ft
            out[2, i] = fb
            out[3, i] = fr
            out[4, i] = fb - fr
            out[5, i] = running
            out[6, i] = grad
            out[7, i] = curve
            out[8, i] = tunnel
            out[9, i] = piecewise_value(ceil_l, sr)
            out[10, i] = ft * vi
            out[11, i] = el_power
            out[12, i] = current
            out[13, i] = paper_power
            out[14, i] = paper_current
    return out, peak, peak_paper


@njit(cache=True, error_model="numpy")
def _inside_law(law, lo, hi, span, eps):
    """(value at the interval's start, slope) of the line through a law's values at lo and hi,
    just inside an interval that starts eps before lo and whose inside is ``span`` long."""
    f0 = piecewise_value(law, lo)
    slope = (piecewise_value(law, hi) - f0) / span
    return f0 - slope * eps, slope


@njit(cache=True, error_model="numpy")
def interval_laws(x, gradient, curve, tunnel, tunnel_v2, ceiling, available, g):
    """Per-interval laws of a kernel grid ``x`` [m] (``profile.compile_track``): specific line
    resistance a0 + a1 u [N/kg] and v^2 coefficient b0 + b1 u [N s^2/(kg m^2)] over the offset u into
    each interval, each law read just inside the interval so that a jump at a grid point belongs to
    the interval on its right, and the speed ceiling [m/s] and available share of tractive effort
    at the interval's middle. Laws as ``(x, left, right, steps)`` (``piecewise_value``); g [m/s^2].
    The same operations, in the same order, as the numpy form it replaced."""
    n = len(x) - 1
    a0 = np.empty(n)
    a1 = np.empty(n)
    b0 = np.empty(n)
    b1 = np.empty(n)
    vlim = np.empty(n)
    scale = np.empty(n)
    for i in range(n):
        left = x[i]
        right = x[i + 1]
        eps = 1e-9 * max(1.0, abs(left))
        span = _nmax(right - left - 2.0 * eps, 1e-12)
        lo = left + eps
        hi = right - eps
        g0, g1 = _inside_law(gradient, lo, hi, span, eps)
        c0, c1 = _inside_law(curve, lo, hi, span, eps)
        t0, t1 = _inside_law(tunnel, lo, hi, span, eps)
        k0, k1 = _inside_law(tunnel_v2, lo, hi, span, eps)
        a0[i] = g * (g0 + c0 + t0)
        a1[i] = g * (g1 + c1 + t1)
        b0[i] = g * k0
        b1[i] = g * k1
        mid = 0.5 * (left + right)
        vlim[i] = piecewise_value(ceiling, mid)
        scale[i] = piecewise_value(available, mid)
    return a0, a1, b0, b1, vlim, scale
