"""Work integrals of a run, exact between the events of the motion.

A run is a sequence of stretches (point k to point k + 1), each in one regime. Along a stretch the
train obeys the regime's equation of motion in the distance domain,

    dE/ds = (F_t(v) - F_b(v) - R(v) - m (g_l(s) + k(s) v^2)) / (rho m),   E = v^2 / 2,

and every work integral is one more state of the same system (W_x' = F_x). The stretch is
integrated again from its first point with RK4 sub-steps of at most ``MAX_SUBSTEP_M``, restarted at
every event where a force is not smooth: the kinks and steps of the traction, braking and
regenerative effort curves (table points, caps, e.g. source 002's braking force jumping from 150
to 335 kN between 5 and 6 km/h), the speeds where the service braking demand crosses the
regenerative capacity (blending), breakpoints of the line-resistance laws, and where a cruising
force changes sign. Between these events the integrands are smooth, so the integrals converge at
fourth order in the sub-step and do not depend on the simulation's step. Because RK4 is linear in
the stage derivatives, the accumulated works satisfy the work-energy identity of each sub-step to
rounding: the energy balance of a run measures only how well its points lie on one trajectory.

Cruising (constant speed) and prescribed profiles (``FOLLOW``: v^2 linear over the stretch) are
integrated in closed form or with Gauss-Legendre rules between their sign changes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from trainsim.model.route import Route
from trainsim.model.scenario import RunSettings
from trainsim.model.train import Train
from trainsim.sim import _energy_c, kernel
from trainsim.sim.kernel import BRAKE, COAST, CRUISE, DWELL, FOLLOW, REGEN, TRACTION, effort, effort_branch
from trainsim.sim.profile import LineResistanceProfile, PiecewiseLinear

#: Longest RK4 sub-step of the work integration [m]. 2 m keeps the quadrature error of every
#: example below 1e-10 relative (the motion's length scale v^2/a is hundreds of metres at speed;
#: near standstill the simulation's points are graded down to 5 mm anyway).
MAX_SUBSTEP_M = 10.0

#: Longest sub-step as a share of the motion's length scale v^2 / |a| [-], shortest sub-step [m] and
#: most sub-steps per piece: near standstill E(s) = v^2/2 has a square-root singularity just ahead
#: (at v = 0), so the steps shrink with the speed.
LENGTH_SCALE_FRACTION = 0.02
MIN_SUBSTEP_M = 1e-4
MAX_SUBSTEPS = 20_000

#: A kink speed this close to a stretch's recorded end speed (relative to 1 + v [m/s]) is taken as
#: its end: traces place points at kinks, and their speeds are exact to about 1e-8 m/s.
KINK_MARGIN_MPS = 1e-6

#: Number of work quantities integrated per stretch (see ``WORK_NAMES``).
N_WORKS = 6
#: Traction, braking (regenerative + friction), regenerative braking at the wheel, running
#: resistance, gradient, curve + tunnel resistance [J].
WORK_NAMES = ("traction", "braking", "regenerative", "running", "gradient", "curve_tunnel")

_W_T, _W_B, _W_R, _W_RUN, _W_GRAD, _W_CT = range(N_WORKS)

#: Gauss-Legendre nodes and weights on [0, 1] (5 points, exact for polynomials of degree 9).
_GL_X = (
    np.array([-0.9061798459386640, -0.5384693101056831, 0.0, 0.5384693101056831, 0.9061798459386640]) * 0.5
    + 0.5
)
_GL_W = (
    np.array(
        [0.2369268850561891, 0.4786286704993665, 0.5688888888888889, 0.4786286704993665, 0.2369268850561891]
    )
    * 0.5
)


@dataclass(frozen=True)
class LineLaws:
    """Line resistance per unit mass over head position, linear on each ``[x[i], x[i+1])``
    [N/kg = ratio of the weight x g]: gradient ``g0 + g1 u``, curve and tunnel ``c0 + c1 u``, tunnel
    v^2 coefficient ``k0 + k1 u`` [1/m], u the offset into the piece; ``available`` the share of the
    tractive effort the line allows on each piece."""

    x: np.ndarray
    g0: np.ndarray
    g1: np.ndarray
    c0: np.ndarray
    c1: np.ndarray
    k0: np.ndarray
    k1: np.ndarray
    available: np.ndarray


def line_laws(profile: LineResistanceProfile, available: PiecewiseLinear, lo: float, hi: float) -> LineLaws:
    """The line-resistance laws of ``profile`` on [lo, hi] as per-piece linear laws per unit mass,
    with the breakpoints of every law (and of the traction availability)."""
    pts = {lo, hi}
    for f in (profile.gradient, profile.curve, profile.tunnel, profile.tunnel_v2, available):
        pts.update(float(p) for p in f.x if lo < p < hi)
    x = np.array(sorted(pts))
    x = x[np.concatenate([[True], np.diff(x) > 1e-9])]
    if len(x) < 2:
        x = np.array([lo, max(hi, lo + 1.0)])
    left, right = x[:-1], x[1:]
    width = right - left
    eps = np.minimum(1e-9 * np.maximum(1.0, np.abs(left)), 0.25 * width)

    def law(f: PiecewiseLinear) -> tuple[np.ndarray, np.ndarray]:
        # just inside each piece, so that a jump at a breakpoint belongs to the piece on its right
        a = f(left + eps)
        b = f(right - eps)
        slope = (b - a) / (width - 2 * eps)
        return a - slope * eps, slope

    g = profile.gravity_mps2
    g0, g1 = law(profile.gradient)
    c0, c1 = law(profile.curve)
    t0, t1 = law(profile.tunnel)
    k0, k1 = law(profile.tunnel_v2)
    return LineLaws(
        x, g * g0, g * g1, g * (c0 + t0), g * (c1 + t1), g * k0, g * k1, available(0.5 * (left + right))
    )


# inlined into its callers: passing the 12 curve arrays to a separate function costs an atomic
# reference count increment and decrement per array and call, more than the evaluation itself
@njit(cache=True, inline="always")
def _forces(mode, E, u, lw, level, P, curves, vref=-1.0):
    """(acceleration [m/s^2], traction, braking, regenerative, running, gradient, curve+tunnel [N])
    in ``mode`` at E = v^2/2 and offset u into a piece with laws ``lw`` = (g0, g1, c0, c1, k0, k1,
    available); ``level`` scales the traction or braking effort (the driver's command); ``vref``
    selects the smooth branch of every effort curve and of the blending (see ``effort_branch``)."""
    ts, tc, tf, tp, bs, bc, bf, bp, rs, rc, rf, rp = curves
    g0, g1, c0, c1, k0, k1, avail = lw
    v = np.sqrt(2.0 * E) if E > 0.0 else 0.0
    m = P[kernel.P_MASS]
    running = P[kernel.P_R0] + P[kernel.P_R1] * v + P[kernel.P_R2] * v * v
    grad = m * (g0 + g1 * u)
    ct = m * ((c0 + c1 * u) + (k0 + k1 * u) * v * v)
    res = running + grad + ct
    ft = 0.0
    fb = 0.0
    if mode == TRACTION:
        ft = level * avail * effort_branch(v, vref, ts, tc, tf, tp)
    elif mode == BRAKE:
        if P[kernel.P_DECEL] > 0.0:
            need = P[kernel.P_INERTIAL_MASS] * P[kernel.P_DECEL] - res
            fb = level * need if need > 0.0 else 0.0
        else:
            fb = level * P[kernel.P_BRAKE_FRACTION] * effort_branch(v, vref, bs, bc, bf, bp)
    elif mode == REGEN:
        fb = effort_branch(v, vref, rs, rc, rf, rp)
    fr = 0.0
    if fb > 0.0:
        cap = effort_branch(v, vref, rs, rc, rf, rp)
        if vref >= 0.0 and mode == BRAKE and P[kernel.P_DECEL] == 0.0:
            # the blend's branch at the reference speed: regenerative force limited by the demand or not
            demand_ref = level * P[kernel.P_BRAKE_FRACTION] * effort_branch(vref, vref, bs, bc, bf, bp)
            fr = fb if demand_ref < effort_branch(vref, vref, rs, rc, rf, rp) else cap
        else:
            fr = fb if fb < cap else cap
    acc = (ft - fb - res) / P[kernel.P_INERTIAL_MASS]
    return acc, ft, fb, fr, running, grad, ct


@njit(cache=True, inline="always")
def _rk4_works(E, u, h, n, mode, lw, level, P, curves, W, vref):
    """Integrate E and the works over [u, u + h] with n RK4 sub-steps, adding the works to W;
    returns E at the end (not clipped at 0)."""
    d = h / n
    # the four stages as scalars (a stage array allocated per call cost more than a short piece)
    for _ in range(n):
        f1 = _forces(mode, E if E > 0.0 else 0.0, u, lw, level, P, curves, vref)
        E2 = E + 0.5 * d * f1[0]
        f2 = _forces(mode, E2 if E2 > 0.0 else 0.0, u + 0.5 * d, lw, level, P, curves, vref)
        E3 = E + 0.5 * d * f2[0]
        f3 = _forces(mode, E3 if E3 > 0.0 else 0.0, u + 0.5 * d, lw, level, P, curves, vref)
        E4 = E + d * f3[0]
        f4 = _forces(mode, E4 if E4 > 0.0 else 0.0, u + d, lw, level, P, curves, vref)
        for q in range(N_WORKS):
            W[q] += d / 6.0 * (f1[q + 1] + 2.0 * f2[q + 1] + 2.0 * f3[q + 1] + f4[q + 1])
        E = E + d / 6.0 * (f1[0] + 2.0 * f2[0] + 2.0 * f3[0] + f4[0])
        u += d
    return E


@njit(cache=True)
def _distance_to_speed(E, u, Et, mode, lw, level, P, curves):
    """Distance [m] from (u, E) along ``mode`` until E reaches Et, integrating ds/dv = v / a in the
    speed domain (as ``kernel.distance_to_speed``, with the driver's level); inf when the
    acceleration vanishes or changes sign on the way."""
    v_from = np.sqrt(2.0 * E) if E > 0.0 else 0.0
    v_to = np.sqrt(2.0 * Et) if Et > 0.0 else 0.0
    vref = 0.5 * (v_from + v_to)
    n = kernel.speed_domain_steps(
        v_from,
        v_to,
        _forces(mode, E, u, lw, level, P, curves, vref)[0],
        _forces(mode, Et, u, lw, level, P, curves, vref)[0],
    )
    dv = (v_to - v_from) / n
    v = v_from
    s = 0.0
    sign = 0.0
    r = np.empty(4)
    for _ in range(n):
        for j in range(4):
            if j == 0:
                vj, sj = v, s
            elif j == 3:
                vj, sj = v + dv, s + dv * r[2]
            else:
                vj, sj = v + 0.5 * dv, s + 0.5 * dv * r[j - 1]
            a = _forces(mode, 0.5 * vj * vj, u + sj, lw, level, P, curves, vref)[0]
            if sign == 0.0:
                sign = 1.0 if a > 0.0 else -1.0
            if a * sign <= 0.0:
                return np.inf
            r[j] = vj / a
        s += dv / 6.0 * (r[0] + 2.0 * r[1] + 2.0 * r[2] + r[3])
        v += dv
    return s


@njit(cache=True, inline="always")
def _substeps(E, u, h, mode, lw, level, P, curves):
    """Number of RK4 sub-steps over a length h [m] from (u, E): steps of at most ``MAX_SUBSTEP_M``
    and at most ``LENGTH_SCALE_FRACTION`` of the motion's length scale v^2 / |a| (E(s) is analytic
    only within about that distance of standstill), at least ``MIN_SUBSTEP_M``."""
    a = abs(_forces(mode, E, u, lw, level, P, curves)[0])
    d = MAX_SUBSTEP_M
    if a > 0.0:
        scale = LENGTH_SCALE_FRACTION * 2.0 * E / a
        if scale < d:
            d = scale if scale > MIN_SUBSTEP_M else MIN_SUBSTEP_M
    n = int(np.ceil(h / d))
    return min(max(n, 1), MAX_SUBSTEPS)


@njit(cache=True, inline="always")
def _dynamic_piece(E, u, h, mode, lw, level, P, curves, kinks, W, v_hint):
    """Works over [u, u + h] along ``mode`` from E, restarted at every kink speed between the
    start speed and ``v_hint`` (the speed the trace records at the stretch's end; a kink just beyond
    it is looked for too); each piece is integrated on its own branch of the effort curves."""
    remaining = h
    v0 = np.sqrt(2.0 * E) if E > 0.0 else 0.0
    rising = v_hint > v0
    # the trace's end speed is exact to about 1e-8 m/s: a kink within KINK_MARGIN_MPS of it is the end
    margin = KINK_MARGIN_MPS * (1.0 + v_hint)
    v_far = v_hint + margin if rising else v_hint - margin
    # one call site of the (inlined) sub-step count and integration: every piece goes through it
    n_tries = len(kinks) + 2
    for attempt in range(n_tries + 1):
        vk = -1.0
        hk = np.inf
        if attempt == n_tries:
            # kinks left after every try: the rest in one piece, on no particular branch
            final, h_piece, vref = True, remaining, -1.0
        else:
            vk = kernel._next_kink(v0, rising, v_far, kinks)
            if vk >= 0.0 and abs(vk - v_hint) > margin:
                hk = _distance_to_speed(E, u, 0.5 * vk * vk, mode, lw, level, P, curves)
            # no kink inside: one smooth piece to the end (a kink at its very end is not crossed)
            final = not (0.0 < hk < remaining - kernel.POSITION_TOLERANCE)
            if final:
                v_end = v_hint
                if vk >= 0.0 and (v_hint > vk if rising else v_hint < vk):
                    v_end = vk
                h_piece, vref = remaining, 0.5 * (v0 + v_end)
            else:
                h_piece, vref = hk, 0.5 * (v0 + vk)
        n = _substeps(E, u, h_piece, mode, lw, level, P, curves)
        E_piece = _rk4_works(E, u, h_piece, n, mode, lw, level, P, curves, W, vref)
        if final:
            return E_piece
        E = 0.5 * vk * vk
        v0 = vk
        u += hk
        remaining -= hk
    return E


@njit(cache=True)
def _integral_min_linear(b_a, b_b, cap, h):
    """Integral over a length h [m] of min(b, cap) for b linear from b_a to b_b (both >= 0) [N m]."""
    if b_a <= cap and b_b <= cap:
        return 0.5 * (b_a + b_b) * h
    if b_a >= cap and b_b >= cap:
        return cap * h
    z = h * (cap - b_a) / (b_b - b_a)
    if b_a < cap:
        return 0.5 * (b_a + cap) * z + cap * (h - z)
    return cap * z + 0.5 * (cap + b_b) * (h - z)


@njit(cache=True, inline="always")
def _cruise_piece(E, u, h, lw, P, curves, W):
    """Works over [u, u + h] at constant speed: the force that holds it, R(v) + m (g_l(u) + k(u) v^2),
    is linear in u; its positive part is traction, its negative part braking (split at its zero),
    of which the regenerative part is min(braking, capacity) (split where they cross)."""
    fa = _forces(COAST, E, u, lw, 1.0, P, curves)
    fb = _forces(COAST, E, u + h, lw, 1.0, P, curves)
    need_a = -fa[0] * P[kernel.P_INERTIAL_MASS]
    need_b = -fb[0] * P[kernel.P_INERTIAL_MASS]
    cap = effort(np.sqrt(2.0 * E) if E > 0.0 else 0.0, curves[8], curves[9], curves[10], curves[11])
    W[_W_RUN] += 0.5 * (fa[4] + fb[4]) * h
    W[_W_GRAD] += 0.5 * (fa[5] + fb[5]) * h
    W[_W_CT] += 0.5 * (fa[6] + fb[6]) * h
    if need_a >= 0.0 and need_b >= 0.0:
        W[_W_T] += 0.5 * (need_a + need_b) * h
    elif need_a <= 0.0 and need_b <= 0.0:
        W[_W_B] -= 0.5 * (need_a + need_b) * h
        W[_W_R] += _integral_min_linear(-need_a, -need_b, cap, h)
    else:
        z = h * need_a / (need_a - need_b)  # where the holding force changes sign
        if need_a > 0.0:
            W[_W_T] += 0.5 * need_a * z
            W[_W_B] -= 0.5 * need_b * (h - z)
            W[_W_R] += _integral_min_linear(0.0, -need_b, cap, h - z)
        else:
            W[_W_T] += 0.5 * need_b * (h - z)
            W[_W_B] -= 0.5 * need_a * z
            W[_W_R] += _integral_min_linear(-need_a, 0.0, cap, z)
    return E


@njit(cache=True)
def _follow_need(E0, a, u0, u, lw, P, curves):
    """Force a prescribed profile needs at offset u (v^2/2 = E0 + a (u - u0)): traction > 0,
    braking < 0; its running, gradient and curve+tunnel parts, and the regenerative capacity [N]."""
    E = E0 + a * (u - u0)
    f = _forces(COAST, E if E > 0.0 else 0.0, u, lw, 1.0, P, curves)
    need = P[kernel.P_INERTIAL_MASS] * (a - f[0])
    v = np.sqrt(2.0 * E) if E > 0.0 else 0.0
    cap = effort(v, curves[8], curves[9], curves[10], curves[11])
    return need, f[4], f[5], f[6], cap


@njit(cache=True)
def _follow_piece(E0, a, u, h, lw, P, curves, W):
    """Works of a prescribed profile (v^2 linear: E = E0 + a (x - u), a [m/s^2]) over [u, u + h]:
    5-point Gauss-Legendre on sub-pieces of at most ``MAX_SUBSTEP_M``, split where the needed force
    changes sign (bisection). Returns E at u + h."""
    n = max(1, int(np.ceil(h / MAX_SUBSTEP_M)))
    d = h / n
    for j in range(n):
        lo = u + j * d
        hi = lo + d
        # split at one sign change of the need inside (a smooth need changes sign at most once here)
        na = _follow_need(E0, a, u, lo, lw, P, curves)[0]
        nb = _follow_need(E0, a, u, hi, lw, P, curves)[0]
        cuts = np.array([lo, hi, hi])
        m = 2
        if na * nb < 0.0:
            x0, x1 = lo, hi
            f0 = na
            for _ in range(100):
                xm = 0.5 * (x0 + x1)
                fm = _follow_need(E0, a, u, xm, lw, P, curves)[0]
                if (fm < 0.0) == (f0 < 0.0):
                    x0, f0 = xm, fm
                else:
                    x1 = xm
                if x1 - x0 < 1e-12:
                    break
            cuts = np.array([lo, 0.5 * (x0 + x1), hi])
            m = 3
        for p in range(m - 1):
            a0, b0 = cuts[p], cuts[p + 1]
            for q in range(5):
                x = a0 + (b0 - a0) * _GL_X[q]
                w = (b0 - a0) * _GL_W[q]
                need, run, grad, ct, cap = _follow_need(E0, a, u, x, lw, P, curves)
                W[_W_RUN] += w * run
                W[_W_GRAD] += w * grad
                W[_W_CT] += w * ct
                if need > 0.0:
                    W[_W_T] += w * need
                else:
                    W[_W_B] -= w * need
                    W[_W_R] += w * min(-need, cap)
    return E0 + a * h


#: A stretch whose regime, integrated from its first point, ends further than this from its last
#: point's speed [m/s] (plus ``OFF_REGIME_RELATIVE`` of it; compared as kinetic energy per mass
#: at the stretch's higher speed, so that a stretch ending at standstill is judged by energy, not
#: by the square root) does not follow its regime: it is integrated as the motion it records
#: (v^2 linear, the forces that motion needs) instead. Traces of the fastest run agree to 1e-8 m/s.
OFF_REGIME_SPEED_MPS = 1e-5
OFF_REGIME_RELATIVE = 1e-6


@njit(cache=True, inline="always")
def _piece_loop(k, s, v, mode, level, lx, laws, P, curves, tk, bk, rk, row, acc_follow):
    """Integrate stretch k piece by piece of the line laws; returns E at its end."""
    g0, g1, c0, c1, k0, k1, avail = laws
    n_pieces = len(g0)
    E = 0.5 * v[k] * v[k]
    pos = s[k]
    for _ in range(n_pieces + 2):
        i = np.searchsorted(lx, pos, side="right") - 1
        if i < 0:
            i = 0
        if i > n_pieces - 1:
            i = n_pieces - 1
        end = s[k + 1]
        if i + 1 < len(lx) - 1 and lx[i + 1] < end - kernel.POSITION_TOLERANCE:
            end = lx[i + 1]
        u = pos - lx[i]
        h = end - pos
        lw = (g0[i], g1[i], c0[i], c1[i], k0[i], k1[i], avail[i])
        if mode == CRUISE:
            E = _cruise_piece(E, u, h, lw, P, curves, row)
        elif mode == FOLLOW:
            E = _follow_piece(E, acc_follow, u, h, lw, P, curves, row)
        else:
            kinks = tk if mode == TRACTION else bk if mode == BRAKE else rk if mode == REGEN else tk[:0]
            E = _dynamic_piece(E, u, h, mode, lw, level, P, curves, kinks, row, v[k + 1])
        pos = end
        if pos >= s[k + 1] - kernel.POSITION_TOLERANCE:
            break
    return E


@njit(cache=True)
def stretch_works(s, v, regime, level, lx, laws, P, curves, tk, bk, rk):
    """Works [J] of every stretch of a run (one row per stretch, columns as ``WORK_NAMES``), the
    speed at each stretch's end reached by integrating its regime from its start [m/s] (0 where
    the regime stops the train earlier), and whether the stretch was integrated as its recorded
    motion because its regime does not lead to its end (``OFF_REGIME_SPEED_MPS``).

    ``lx`` are the breakpoints of the per-piece line laws ``laws`` = (g0, g1, c0, c1, k0, k1,
    available) (see ``LineLaws``); ``tk``, ``bk``, ``rk`` the kink speeds in traction, service
    braking (with the blending crossings and the regenerative curve's kinks) and regenerative
    braking."""
    n = len(s) - 1
    W = np.zeros((n, N_WORKS))
    v_end = np.empty(n)
    off = np.zeros(n, dtype=np.bool_)
    for k in range(n):
        mode = regime[k]
        h_total = s[k + 1] - s[k]
        if mode == DWELL or not h_total > 0.0:
            v_end[k] = v[k + 1] if mode == DWELL else v[k]
            continue
        acc_follow = (0.5 * v[k + 1] * v[k + 1] - 0.5 * v[k] * v[k]) / h_total
        ve = 0.0
        # one call site of the (inlined) piece loop: the regime's motion, then, if it does not lead
        # to the stretch's end, the recorded motion
        for attempt in range(2):
            E = _piece_loop(
                k, s, v, mode if attempt == 0 else FOLLOW, level[k] if attempt == 0 else 1.0,
                lx, laws, P, curves, tk, bk, rk, W[k], acc_follow,
            )  # fmt: skip
            if attempt == 1:
                break
            ve = np.sqrt(2.0 * E) if E > 0.0 else 0.0
            # compared as kinetic energy per mass (E < 0: the regime stops the train before the end),
            # with a tolerance of OFF_REGIME_SPEED_MPS in speed at the stretch's speed (dE = v dv)
            v_max = max(v[k], v[k + 1])
            tol = (OFF_REGIME_SPEED_MPS + OFF_REGIME_RELATIVE * v_max) * v_max + 1e-12
            if not (mode != FOLLOW and abs(E - 0.5 * v[k + 1] * v[k + 1]) > tol):
                break
            # the recorded motion is not this regime's (e.g. a stop reached later than full braking
            # would reach it): the forces are those the recorded motion needs
            off[k] = True
            for q in range(N_WORKS):
                W[k, q] = 0.0
        v_end[k] = ve
    return W, v_end, off


def blending_speeds(train: Train, settings: RunSettings) -> np.ndarray:
    """Speeds [m/s] where the service braking force equals the regenerative capacity (the blend of
    regenerative and friction braking has a kink there), found by sampling and bisection."""
    regen = train.braking.regenerative
    service = train.braking.service_force
    if regen is None or service is None:
        return np.empty(0)
    vmax = 1.5 * train.max_speed_mps
    grid = np.unique(
        np.concatenate([np.linspace(0.0, vmax, 4001), regen.interval_start_mps, service.interval_start_mps])
    )
    grid = grid[grid <= vmax]

    def diff(x):
        return settings.braking_fraction * np.asarray(service(x)) - np.asarray(regen(x))

    d = diff(grid)
    out = []
    for j in np.flatnonzero(np.sign(d[:-1]) * np.sign(d[1:]) < 0):
        lo, hi = grid[j], grid[j + 1]
        flo = d[j]
        for _ in range(80):
            mid = 0.5 * (lo + hi)
            fm = diff(mid)
            if (fm < 0) == (flo < 0):
                lo, flo = mid, fm
            else:
                hi = mid
        out.append(0.5 * (lo + hi))
    return np.array(out, dtype=float)


def run_works(
    *,
    train: Train,
    route: Route,
    settings: RunSettings,
    profile: LineResistanceProfile,
    available: PiecewiseLinear,
    s: np.ndarray,
    v: np.ndarray,
    regime: np.ndarray,
    level: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Works [J] of every stretch of a run given as points (rows of ``WORK_NAMES``), the end speed
    of each stretch by integration [m/s] and which stretches do not follow their regime (see
    ``stretch_works``). This is the one place where
    trainsim integrates energies; every path (fastest run, driving, optimisation) goes through it."""
    from trainsim.sim.parameters import kernel_parameters, kink_speeds, regenerative_arrays

    if len(s) < 2:
        return np.zeros((0, N_WORKS)), np.zeros(0), np.zeros(0, dtype=bool)
    P, trac, brk = kernel_parameters(train, settings)
    rg = regenerative_arrays(train)
    curves = (*trac, *brk, *rg)
    tk = kink_speeds(*trac)
    rk = kink_speeds(*rg)
    bk = np.unique(np.concatenate([kink_speeds(*brk), rk, blending_speeds(train, settings)]))
    lo = min(float(s[0]), route.start_m)
    hi = max(float(s[-1]), route.end_m)
    laws = line_laws(profile, available, lo, hi)
    # the compiled integration (sim/_energy_c.pyx) converts and checks the point arrays itself
    return _energy_c.stretch_works(
        s,
        v,
        regime,
        level,
        laws.x,
        (laws.g0, laws.g1, laws.c0, laws.c1, laws.k0, laws.k1, laws.available),
        P,
        curves,
        tk,
        bk,
        rk,
    )
