"""Compiled part of the energy-optimal strategy: the final phase of a section driven by the
adjoint of Pontryagin's principle.

With distance s as the independent variable, speed v as state and the price of time mu [W] (the
multiplier of the running-time constraint, equal to -dE/dT), write phi = -lambda / (M v) for the
scaled adjoint of v. Minimising the Hamiltonian
    H = u_t / eta_t - eta_r u_r + mu / v + lambda (u_t - u_r - u_f - R(v) - G(s)) / (M v)
gives the optimal control from phi alone:
    phi > 1 / eta_t: maximum traction;     phi = 1 / eta_t: hold the speed (partial traction);
    eta_r < phi < 1 / eta_t: coast;        0 < phi <= eta_r: maximum regenerative braking;
    phi <= 0: maximum service braking (regenerative and friction),
and the adjoint equation becomes, whatever the control and the grade,
    dphi/ds = (phi R'(v) - mu / v^2) / (M v).
On a speed-holding arc phi stays 1 / eta_t, hence mu = V^2 R'(V) / eta_t: the holding speed V
fixes mu (Albrecht, Howlett, Pudney, Vu, Zhou 2016, "The key principles of optimal train control",
Transportation Research Part B 94, Part 1 section 3; our eta factors follow from the cost).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from trainsim.sim.kernel import (
    BRAKE,
    COAST,
    CRUISE,
    P_INERTIAL_MASS,
    P_R1,
    P_R2,
    P_TRACTION_SCALE,
    P_WEIGHT,
    REGEN,
    TRACTION,
    distance_to_speed,
    rk4_energy_time,
    step_energy,
    step_energy_time,
)

HIT_CEILING = 1  # met the braking curve to the stop: coasting started too late
STOPPED_SHORT = 2  # came to rest before the stop: coasting started too early

#: Below this speed [m/s] the adjoint is not integrated further (mu / v^2 is singular at rest and
#: the control is maximum braking there anyway).
PHI_MIN_SPEED = 0.05


@njit(cache=True)
def mode_of(phi, inv_eta_t, eta_r, has_regen):
    if phi >= inv_eta_t:
        return TRACTION
    if phi > eta_r or (not has_regen and phi > 0.0):
        return COAST
    if phi > 0.0:
        return REGEN
    return BRAKE


@njit(cache=True)
def phi_slope(phi, E, u, b0, b1, P, mu):
    """dphi/ds [1/m] at kinetic energy per mass E and offset u."""
    v = np.sqrt(2.0 * E) if E > 0.0 else 0.0
    if v < PHI_MIN_SPEED:
        v = PHI_MIN_SPEED
    # slope of the running plus tunnel resistance over speed [N s/m]
    dR = P[P_R1] + 2.0 * P[P_R2] * v + 2.0 * P[P_WEIGHT] * (b0 + b1 * u) * v
    return (phi * dR - mu / (v * v)) / (P[P_INERTIAL_MASS] * v)


@njit(cache=True)
def phi_step(phi, E0, E1, u, h, b0, b1, P, mu):
    """RK4 for phi over a step h, with E varying linearly along it (the switching points are
    stationary for the cost, so this accuracy is ample)."""
    Em = 0.5 * (E0 + E1)
    k1 = phi_slope(phi, E0, u, b0, b1, P, mu)
    k2 = phi_slope(phi + 0.5 * h * k1, Em, u + 0.5 * h, b0, b1, P, mu)
    k3 = phi_slope(phi + 0.5 * h * k2, Em, u + 0.5 * h, b0, b1, P, mu)
    k4 = phi_slope(phi + h * k3, E1, u + h, b0, b1, P, mu)
    return phi + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


@njit(cache=True)
def ceiling_at(u, w, k, Cr, US, vcap, line, P, curves, bk):
    """The speed ceiling [m/s] at offset u of interval k (limit, or braking curve to the stop)."""
    if u < US[k]:
        return vcap
    Eb = step_energy(0.5 * Cr[k] * Cr[k], w, u - w, BRAKE, line, P, curves, bk)
    return np.sqrt(2.0 * Eb) if Eb > 0.0 else 0.0


@njit(cache=True)
def final_phase(
    x, a0, a1, b0, b1, vcap, tscale, i_start, u_start, v_start, t_start, i_end,
    P, curves, tk, bk, Cr, US, mu, inv_eta_t, eta_r, has_regen, h_max,
    out_s, out_v, out_t, out_m, n,
):  # fmt: skip
    """From (x[i_start] + u_start, v_start) with phi = 1/eta_t, drive by the adjoint to the stop at
    x[i_end]. Appends points; returns (n, status): HIT_CEILING when the train meets the braking
    curve to the stop (it then follows it and stops exactly at x[i_end]), STOPPED_SHORT when it
    comes to rest before (the last point is where it stopped)."""
    # just below the traction threshold: the train leaves the holding arc into coasting
    phi = inv_eta_t * (1.0 - 1e-9)
    E = 0.5 * v_start * v_start
    t = t_start
    u = u_start
    for i in range(i_start, i_end):
        kk = i - (i_end - len(Cr))  # Cr and US are indexed from the section's first interval
        w = x[i + 1] - x[i]
        line = (a0[i], a1[i], b0[i], b1[i])
        P[P_TRACTION_SCALE] = tscale[i]
        while u < w - 1e-12:
            v = np.sqrt(2.0 * E) if E > 0.0 else 0.0
            mode = mode_of(phi, inv_eta_t, eta_r, has_regen)
            if mode == TRACTION and v >= vcap[i] - 1e-9:
                mode = CRUISE
            out_s[n] = x[i] + u
            out_v[n] = v
            out_t[n] = t
            out_m[n] = mode
            n += 1
            h = min(h_max, w - u)
            if mode == CRUISE:
                E1, dt = E, h / v
            else:
                E1, dt = step_energy_time(E, u, h, mode, line, P, curves, tk if mode == TRACTION else bk)
            if E1 <= 0.0:
                # comes to rest inside the step
                hs = distance_to_speed(E, u, 0.0, mode, line, P, curves)
                if not np.isfinite(hs) or hs > h:
                    hs = h
                _, dts = rk4_energy_time(E, u, hs, mode, line, P, curves)
                out_s[n] = x[i] + u + hs
                out_v[n] = 0.0
                out_t[n] = t + dts
                out_m[n] = mode
                n += 1
                if x[i] + u + hs >= x[i_end] - 1e-6:
                    return n, HIT_CEILING
                return n, STOPPED_SHORT
            phi1 = phi_step(phi, E, E1, u, h, b0[i], b1[i], P, mu) if v > PHI_MIN_SPEED else phi
            new_mode = mode_of(phi1, inv_eta_t, eta_r, has_regen)
            if new_mode != mode and not (mode == CRUISE and new_mode == TRACTION):
                # switch inside the step: cut it where phi crosses the threshold
                thr = inv_eta_t if max(phi, phi1) >= inv_eta_t and min(phi, phi1) < inv_eta_t else (
                    eta_r if max(phi, phi1) > eta_r and min(phi, phi1) <= eta_r else 0.0
                )
                frac = (thr - phi) / (phi1 - phi) if phi1 != phi else 1.0
                frac = min(max(frac, 1e-6), 1.0)
                h = frac * h
                if mode == CRUISE:
                    E1, dt = E, h / v
                else:
                    E1, dt = step_energy_time(E, u, h, mode, line, P, curves, tk if mode == TRACTION else bk)
                phi1 = thr - 1e-12 if phi1 < phi else thr + 1e-12
            # the braking curve to the stop must not be crossed
            v1 = np.sqrt(2.0 * E1) if E1 > 0.0 else 0.0
            c1 = ceiling_at(u + h, w, kk, Cr, US, vcap[i], line, P, curves, bk)
            if v1 > c1 + 1e-9 and mode != BRAKE:
                lo, hi = 0.0, h
                for _ in range(40):
                    mid = 0.5 * (lo + hi)
                    Em, _ = step_energy_time(E, u, mid, mode, line, P, curves, bk)
                    vm = np.sqrt(2.0 * Em) if Em > 0.0 else 0.0
                    if vm > ceiling_at(u + mid, w, kk, Cr, US, vcap[i], line, P, curves, bk):
                        hi = mid
                    else:
                        lo = mid
                Em, dtm = step_energy_time(E, u, lo, mode, line, P, curves, bk)
                t += dtm
                u += lo
                E = Em
                return _follow_ceiling(
                    x, a0, a1, b0, b1, tscale, i, u, E, t, i_end, P, curves, bk, Cr, kk, out_s, out_v, out_t, out_m, n
                ), HIT_CEILING
            E, t, u, phi = E1, t + dt, u + h, phi1
        u = 0.0
    out_s[n] = x[i_end]
    out_v[n] = np.sqrt(2.0 * E) if E > 0.0 else 0.0
    out_t[n] = t
    out_m[n] = BRAKE
    n += 1
    return n, HIT_CEILING


@njit(cache=True)
def _follow_ceiling(x, a0, a1, b0, b1, tscale, i, u, E, t, i_end, P, curves, bk, Cr, kk, out_s, out_v, out_t, out_m, n):
    """Maximum service braking along the braking curve from (x[i] + u) to the stop at x[i_end]."""
    k = kk
    for j in range(i, i_end):
        w = x[j + 1] - x[j]
        line = (a0[j], a1[j], b0[j], b1[j])
        out_s[n] = x[j] + u
        out_v[n] = np.sqrt(2.0 * E) if E > 0.0 else 0.0
        out_t[n] = t
        out_m[n] = BRAKE
        n += 1
        _, dt = step_energy_time(E, u, w - u, BRAKE, line, P, curves, bk)
        t += dt
        E = 0.5 * Cr[k] * Cr[k]
        u = 0.0
        k += 1
    out_s[n] = x[i_end]
    out_v[n] = 0.0
    out_t[n] = t
    out_m[n] = BRAKE
    n += 1
    return n
