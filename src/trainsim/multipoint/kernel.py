"""Compiled kernel of the multi-point model: forces, couplers, implicit midpoint steps, controller.

Equations (source 000's multi-point model; one Newton equation per vehicle, i = 0 at the head)::

    rho_i m_i dv_i/dt = T_(i-1) - T_i + F_i(v_i) - B_i(v_i) - R_i(v_i) - m_i g lambda_i(x_i, v_i)
    dx_i/dt = v_i

with T_k the tension of coupling k (between vehicles k and k+1) as a function of its extension
delta_k = x_k - L_k - x_(k+1) and its rate, F_i the traction of a locomotive, B_i the braking force,
R_i the running resistance and lambda_i the specific gradient, curve and tunnel resistance averaged
over the vehicle's own length.

Integrator: the implicit midpoint rule. With the midpoint velocities w = (v0 + v1) / 2 as unknowns,
x1 = x0 + h w and the residual ``2 M (w - v0) / h - F(x0 + h w / 2, w) = 0`` has a symmetric
tridiagonal Jacobian ``2M/h + D + (h/2) K + C`` (K, C: coupler stiffness and damping, D: derivative of
the vehicles' own forces), solved by Newton iterations with the Thomas algorithm: O(n) per iteration.
The rule is A-stable (any coupler stiffness is stable at any step) and symplectic: it neither adds
nor removes energy from the coupler oscillations, so losses come from the dampers alone, and the
kinetic energy change of a step equals the work of the midpoint forces exactly, which the energy
accounting uses.

Dry friction (running resistance, brakes) is regularised: it opposes motion through tanh(v / v_eps),
so a vehicle at rest is held by a stiff viscous law instead of a switch, which the implicit scheme
integrates without small steps.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from trainsim.sim.codes import BRAKE, COAST, CRUISE, FOLLOW, REGEN, TRACTION

# columns of the vehicle parameter array VP
V_MASS = 0  # static mass m_i [kg]
V_INERTIAL = 1  # rho_i m_i [kg]
V_LENGTH = 2  # length over couplers [m]
V_R0 = 3  # running resistance c0 [N]
V_R1 = 4  # c1 [N s/m]
V_R2 = 5  # c2 [N s^2/m^2]
V_BRAKE = 6  # share of the friction brake [-]
V_REGEN = 7  # share of the electric brake [-]
V_CURVE = 8  # index of the traction curve in the curve bank, -1 for unpowered vehicles
V_PROFILE = 9  # index of the line-resistance profile (by vehicle length)
V_DELAY = 10  # delay of the brake command [s]
N_V = 11

# columns of the coupler parameter array CP
C_KD = 0  # draft stiffness [N/m]
C_KB = 1  # buff stiffness [N/m]
C_CD = 2  # draft damping [N s/m]
C_CB = 3  # buff damping [N s/m]
C_HALF_SLACK = 4  # half the free slack [m]
C_TD = 5  # draft travel [m]
C_TB = 6  # buff travel [m]
C_KS = 7  # solid stiffness [N/m]
C_EPS = 8  # smoothing width [m]
C_MU = 9  # friction ratio of the draft gears: loading (1 + mu) x, unloading (1 - mu) x the spring [-]
C_VF = 10  # regularisation speed of the gears' friction [m/s]
N_C = 11

# scalar parameters SP
S_STEP = 0  # largest time step [s]
S_VEPS = 1  # standstill regularisation speed [m/s]
S_BRAKE_FRACTION = 2  # share of the service braking force used [-]
S_DECEL = 3  # constant service deceleration [m/s^2], 0 for a braking force law
S_BUILD_UP = 4  # brake cylinder time constant [s]
S_TAU = 5  # time constant of the speed controller [s]
S_LOOKAHEAD = 6  # anticipation time of the brake delay [s]
S_REST_SPEED = 7  # every vehicle slower than this: the train is at rest [m/s]
S_STOP_WINDOW = 8  # a stop counts within this distance [m]
S_RECORD_DT = 9  # record interval [s]
S_ETA_T = 10  # traction efficiency [-]
S_ETA_R = 11  # regenerative efficiency x receptivity [-]
S_SERVICE_CURVE = 12  # index of the service braking curve in the bank
S_REGEN_CURVE = 13  # index of the regenerative braking curve, -1 without
S_G = 14  # gravity [m/s^2]
S_STALL_S = 15  # at rest in traction this long: stalled [s]
S_NEWTON_TOL = 16  # Newton tolerance on the midpoint speeds [m/s]
S_TRACK_PROFILE = 17  # 1: in traction follow the reference speed; 0: full traction up to the ceiling
S_RAMP = 18  # time to raise the traction command from 0 to full [s], 0: at once
S_STEP_MIN = 19  # smallest step [s]
S_FORCE_TOL = 20  # tolerance of the coupler-force error estimate per step [N], 0: fixed steps
N_S = 21

# command array CMD: friction brake level, blend flag, signed command for the record, then per vehicle
# traction level (N) and electric brake level (N)
K_FRICTION = 0
K_BLEND = 1
K_COMMAND = 2
K_REGIME = 3
N_K = 4

# accumulators ACC (cumulative works [J], energies [J])
A_TRACTION = 0
A_FRICTION = 1
A_ELECTRIC = 2
A_RUNNING = 3
A_GRADIENT = 4
A_CURVE = 5
A_TUNNEL = 6
A_DAMPER = 7
A_SPRING_WORK = 8  # work of the spring forces (= -change of spring energy, up to the step error)
A_HELD = 9  # kinetic energy removed when the train is declared at rest (counted as braking)
N_WORKS = 10  # A_TRACTION .. A_HELD are recorded
A_PEAK_POWER = 10  # largest line-side power (before auxiliaries) since the last record [W]
A_SUBSTEPS = 11  # steps halved because Newton did not converge
A_NEWTON = 12  # Newton iterations
A_STEPS = 13  # steps
A_REST_SINCE = 14  # time since when the train is at rest in traction [s], -1 when moving
A_H = 15  # size of the next step [s]
A_NMEM = 16  # number of step-end coupler forces remembered (up to 3)
A_REJECTED = 17  # steps repeated shorter for the force tolerance
A_LAST_H = 18  # length of the last step [s]
A_INTEGRATED = 19  # time integrated (excluding dwells) [s]
N_A = 20

# aggregated record columns REC_AGG
R_HEAD = 0
R_SPEED = 1  # inertial-mass-weighted mean speed [m/s]
R_COMMAND = 2
R_REGIME = 3
R_TRACTION = 4  # total traction force [N]
R_ELECTRIC = 5  # total electric braking force [N]
R_FRICTION = 6  # total friction braking force [N]
R_RUNNING = 7
R_GRADIENT = 8
R_CURVE = 9
R_TUNNEL = 10
R_TRACTION_POWER = 11  # sum of F_i v_i [W]
R_ELECTRIC_POWER = 12  # sum of E_i v_i [W]
R_PEAK_POWER = 13  # largest line-side power since the previous record [W] (before auxiliaries)
R_KINETIC = 14  # kinetic energy [J]
R_SPRING = 15  # energy stored in the coupler springs [J]
R_W0 = 16  # first cumulative work column: the accumulators A_TRACTION .. A_HELD follow
N_R = R_W0 + N_WORKS

# extremes EXT: the train's largest draft and buff force, then (when EXT is long enough) per coupling
# k, at N_E + N_EK k: its largest draft force, when, where the head was, its largest buff force, when,
# where the head was
E_DRAFT, E_DRAFT_K, E_DRAFT_T, E_DRAFT_HEAD, E_BUFF, E_BUFF_K, E_BUFF_T, E_BUFF_HEAD = range(8)
N_E = 8
EK_DRAFT, EK_DRAFT_T, EK_DRAFT_HEAD, EK_BUFF, EK_BUFF_T, EK_BUFF_HEAD = range(6)
N_EK = 6

# status codes
ST_TIME = 0  # reached the end time
ST_STOPPED = 1  # at rest at the stop
ST_STALLED = 2
ST_RECORD_FULL = 3
ST_HISTORY_FULL = 4
ST_FAILED = 5  # Newton failed even on the smallest sub-step
ST_END_OF_ROUTE = 6

#: Below this speed the electric (regenerative) brake fades linearly to 0 at standstill and the
#: friction brakes take over its share [m/s]: an electric brake cannot hold a train at rest, and
#: without the fade the locomotives would hold the whole train while the wagons roll away from them.
ELECTRIC_FADE_MPS = 1.0
#: Newton iterations per (sub-)step before halving.
MAX_NEWTON = 12


# Every kernel is compiled with numpy's error model: a division by zero gives inf / nan (which the Newton
# iterations reject as not finite) instead of a Python exception, and the compiled code carries no check
# before each division (-16 % on the coupler forces, issue 14).


# ============================================================================ smoothed piecewise laws
@njit(cache=True, error_model="numpy")
def tanh(z):
    """np.tanh(z), without the library call where tanh(z) rounds to +-1 (|z| >= 22: 1 - tanh(z) < 1e-19,
    below half an ulp of 1): the direction factors of dry friction are +-1 whenever a vehicle moves."""
    if z >= 22.0:
        return 1.0
    if z <= -22.0:
        return -1.0
    return np.tanh(z)


@njit(cache=True, error_model="numpy")
def ramp(z, eps):
    """max(z, 0) with the kink rounded over [-eps, eps] by a quadratic (C1)."""
    if z <= -eps:
        return 0.0
    if z >= eps:
        return z
    return (z + eps) * (z + eps) / (4.0 * eps)


@njit(cache=True, error_model="numpy")
def ramp_slope(z, eps):
    """d ramp / dz: a step from 0 to 1 rounded linearly over [-eps, eps]."""
    if z <= -eps:
        return 0.0
    if z >= eps:
        return 1.0
    return (z + eps) / (2.0 * eps)


@njit(cache=True, error_model="numpy")
def ramp_curvature(z, eps):
    """d^2 ramp / dz^2."""
    if z <= -eps or z >= eps:
        return 0.0
    return 0.5 / eps


@njit(cache=True, error_model="numpy")
def ramp_integral(z, eps):
    """Integral of ramp from -inf to z (potential energy of a unit spring engaged at 0)."""
    if z <= -eps:
        return 0.0
    if z >= eps:
        return 0.5 * z * z + eps * eps / 6.0
    return (z + eps) ** 3 / (12.0 * eps)


@njit(cache=True, error_model="numpy")
def coupler_force(delta, rate, cp):
    """Tension of a coupling [N] (positive in draft) at extension ``delta`` [m] and extension rate
    ``rate`` [m/s]: ``(spring, damper, d tension / d delta, d tension / d rate)``."""
    kd, kb, cd, cb = cp[C_KD], cp[C_KB], cp[C_CD], cp[C_CB]
    hs, td, tb, ks, eps = cp[C_HALF_SLACK], cp[C_TD], cp[C_TB], cp[C_KS], cp[C_EPS]
    zd = delta - hs
    zb = -delta - hs
    spring = (
        kd * ramp(zd, eps)
        + (ks - kd) * ramp(zd - td, eps)
        - kb * ramp(zb, eps)
        - (ks - kb) * ramp(zb - tb, eps)
    )
    hd = ramp_slope(zd, eps)
    hb = ramp_slope(zb, eps)
    c = cd * hd + cb * hb
    damper = c * rate
    k_spring = kd * hd + (ks - kd) * ramp_slope(zd - td, eps) + kb * hb + (ks - kb) * ramp_slope(zb - tb, eps)
    k = k_spring + rate * (cd * ramp_curvature(zd, eps) - cb * ramp_curvature(zb, eps))
    mu = cp[C_MU]
    if mu > 0.0:
        # wedge friction of the draft gears: mu |spring| tanh(rate / v_f), on the loading branch
        # (|delta| growing) the spring force times (1 + mu), on the unloading branch times (1 - mu);
        # its power mu |spring| rate tanh(rate / v_f) is never negative (a loss, as the dampers')
        vf = cp[C_VF]
        th = np.tanh(rate / vf)
        size = np.sqrt(spring * spring + 1.0) - 1.0  # |spring| rounded within 1 N (C1 for Newton)
        damper += mu * size * th
        c += mu * size * (1.0 - th * th) / vf
        k += mu * th * k_spring * spring / (size + 1.0)
    return spring, damper, k, c


@njit(cache=True, error_model="numpy")
def coupler_energy(delta, cp):
    """Potential energy stored in a coupling's springs [J] at extension ``delta`` [m]."""
    kd, kb = cp[C_KD], cp[C_KB]
    hs, td, tb, ks, eps = cp[C_HALF_SLACK], cp[C_TD], cp[C_TB], cp[C_KS], cp[C_EPS]
    zd = delta - hs
    zb = -delta - hs
    return (
        kd * ramp_integral(zd, eps)
        + (ks - kd) * ramp_integral(zd - td, eps)
        + kb * ramp_integral(zb, eps)
        + (ks - kb) * ramp_integral(zb - tb, eps)
    )


# ============================================================================ effort curves, profiles
@njit(cache=True, error_model="numpy")
def effort_slope(v, c, cs, cc, coff, cfc, cpc, vsel=-1.0):
    """Force [N] and its slope d F / d v [N s/m] of curve ``c`` of the bank at speed v >= 0 [m/s]
    (the law of ``trainsim.sim.kernel.effort``). The law's interval is the one of speed ``vsel`` if
    given (>= 0): within a step the integrator keeps the interval of the step's start, since a law
    may jump where two intervals meet (e.g. a quadratic starting range followed by a hyperbola) and
    Newton's method finds no root on a jump."""
    lo = coff[c]
    hi = coff[c + 1]
    j = lo
    sel = v if vsel < 0.0 else vsel
    while j + 1 < hi and cs[j + 1] <= sel:
        j += 1
    c0 = cc[j, 0]
    c1 = cc[j, 1]
    c2 = cc[j, 2]
    ch = cc[j, 3]
    f = c0 + c1 * v + c2 * v * v
    df = c1 + 2.0 * c2 * v
    if ch != 0.0:
        if v > 0.0:
            f += ch / v
            df -= ch / (v * v)
        else:
            f = np.inf
            df = 0.0
    if f > cfc[c]:
        f = cfc[c]
        df = 0.0
    if v > 0.0 and f * v > cpc[c]:
        f = cpc[c] / v
        df = -cpc[c] / (v * v)
    if f <= 0.0:
        return 0.0, 0.0
    return f, df


@njit(cache=True, error_model="numpy")
def profile_at(p, s, poff, px, pval, cache, i):
    """Values of line-resistance profile ``p`` at position s: (gradient ratio, curve ratio, tunnel
    ratio, tunnel v^2 coefficient [s^2/m^2]); ``cache[i]`` keeps vehicle i's last piece."""
    lo = poff[p]
    hi = poff[p + 1]
    j = cache[i]
    if j < lo or j > hi - 2:
        j = lo
    while j < hi - 2 and px[j + 1] <= s:
        j += 1
    while j > lo and px[j] > s:
        j -= 1
    cache[i] = j
    x0 = px[j]
    x1 = px[j + 1]
    if s <= x0:
        f = 0.0
    elif s >= x1:
        f = 1.0
    else:
        f = (s - x0) / (x1 - x0)
    g = pval[j, 0] + (pval[j + 1, 0] - pval[j, 0]) * f
    c = pval[j, 1] + (pval[j + 1, 1] - pval[j, 1]) * f
    tu = pval[j, 2] + (pval[j + 1, 2] - pval[j, 2]) * f
    b = pval[j, 3] + (pval[j + 1, 3] - pval[j, 3]) * f
    return g, c, tu, b


@njit(cache=True, error_model="numpy")
def step_value(s, sx, sval):
    """Value of a piecewise constant function (value ``sval[k]`` on ``[sx[k], sx[k+1])``)."""
    k = np.searchsorted(sx, s, side="right") - 1
    if k < 0:
        k = 0
    if k > len(sval) - 1:
        k = len(sval) - 1
    return sval[k]


@njit(cache=True, error_model="numpy")
def linear_value(s, x, left, right):
    """A ``PiecewiseLinear`` at s (the value from the right at a breakpoint)."""
    k = np.searchsorted(x, s, side="right") - 1
    if k < 0:
        k = 0
    if k > len(left) - 1:
        k = len(left) - 1
    x0 = x[k]
    f = (s - x0) / (x[k + 1] - x0)
    if f < 0.0:
        f = 0.0
    if f > 1.0:
        f = 1.0
    return left[k] + (right[k] - left[k]) * f


# ============================================================================ forces
@njit(cache=True, error_model="numpy")
def vehicle_forces(xm, w, v0, VP, SP, CMD, trac, elec, bm, bank, prof, avail, pcache, out, D, detail, parts):
    """External force on every vehicle [N] at midpoint positions ``xm`` and speeds ``w`` into ``out``,
    minus its derivative with respect to the vehicle's own speed into ``D``; with ``detail`` the
    parts (traction, electric brake, friction brake, running, gradient, curve, tunnel) into
    ``parts`` (n x 7), signed so that part x displacement is the work done by (traction) or against
    (the others) the train.

    ``v0`` are the speeds at the start of the step: the effort laws keep the interval of ``v0``, and
    the direction factor tanh(v / v_eps) of the dry-friction forces (running, curve and tunnel
    resistance, brakes) is taken at the end-of-step speed ``2 w - v0``. That part of the scheme is
    backward Euler, which damps the stiff friction law near standstill (the midpoint rule alone would
    let a held vehicle's speed flip sign from step to step); the kinetic-energy change of a step is
    still exactly the work of the applied forces over the step's displacement ``h w``.

    Braking with the blend flag: the command's full level is the service braking force (share
    ``S_BRAKE_FRACTION`` of the service curve) met by the electric brake first and by the friction
    brakes for the rest; in the regenerative-braking regime (``CMD[K_REGIME] == REGEN``) it is the
    larger of that and the electric brake's curve, as the single-point model's REGEN regime brakes."""
    cs, cc, coff, cfc, cpc = bank
    poff, px, pval = prof
    ax, aval = avail
    n = len(w)
    veps = SP[S_VEPS]
    frac = SP[S_BRAKE_FRACTION]
    decel = SP[S_DECEL]
    g = SP[S_G]
    sc = int(SP[S_SERVICE_CURVE])
    rc = int(SP[S_REGEN_CURVE])
    blend = CMD[K_BLEND] > 0.5
    electric_regime = blend and int(CMD[K_REGIME]) == REGEN and rc >= 0
    for i in range(n):
        v = w[i]
        av = abs(v)
        sgn = tanh((2.0 * v - v0[i]) / veps)
        dsgn = 2.0 * (1.0 - sgn * sgn) / veps  # d sgn / d w
        m = VP[i, V_MASS]
        L = VP[i, V_LENGTH]
        # running resistance, opposing motion
        r = VP[i, V_R0] + VP[i, V_R1] * av + VP[i, V_R2] * av * av
        dr = VP[i, V_R1] + 2.0 * VP[i, V_R2] * av
        running = r * sgn
        drun = dr * abs(sgn) + r * dsgn
        # line resistance over the vehicle's length
        gr, cu, tu, b2 = profile_at(int(VP[i, V_PROFILE]), xm[i], poff, px, pval, pcache, i)
        weight = m * g
        grad = weight * gr
        curve = weight * cu * sgn
        tun = weight * (tu + b2 * v * v)
        tunnel = tun * sgn
        curve_tunnel = curve + tunnel
        dct = weight * cu * dsgn + weight * 2.0 * b2 * av * abs(sgn) + tun * dsgn
        # traction
        traction = 0.0
        dtr = 0.0
        c = int(VP[i, V_CURVE])
        if c >= 0 and trac[i] > 0.0:
            f, df = effort_slope(av, c, cs, cc, coff, cfc, cpc, abs(v0[i]))
            a = trac[i] * step_value(xm[i] - 0.5 * L, ax, aval)
            traction = a * f
            dtr = a * df * (1.0 if v >= 0.0 else -1.0)
        # braking: electric at the vehicles with a regenerative share, friction on all
        electric = 0.0
        friction = 0.0
        dbr = 0.0
        if decel > 0.0:
            if bm[i] > 0.0:
                need = VP[i, V_INERTIAL] * decel * frac - running - grad - curve_tunnel
                if need > 0.0:
                    friction = bm[i] * need
        elif bm[i] > 0.0 or (elec[i] > 0.0 and VP[i, V_REGEN] > 0.0):
            s_f, s_df = effort_slope(av, sc, cs, cc, coff, cfc, cpc, abs(v0[i]))
            demand = frac * s_f
            d_demand = frac * s_df
            regen = 0.0
            d_regen = 0.0
            if rc >= 0:
                regen, d_regen = effort_slope(av, rc, cs, cc, coff, cfc, cpc, abs(v0[i]))
                if av < ELECTRIC_FADE_MPS:
                    # electric braking fades out towards standstill; the friction brakes take over
                    d_regen = d_regen * av / ELECTRIC_FADE_MPS + regen / ELECTRIC_FADE_MPS
                    regen *= av / ELECTRIC_FADE_MPS
            if electric_regime and regen > demand:
                # the single-point model's regenerative braking (REGEN) brakes with the electric brake's
                # own curve, stronger than the service brake at low speeds (source 004: 0.8 x traction):
                # full command is then the electric brake alone, the friction brakes adding nothing
                demand = regen
                d_demand = d_regen
            share_r = VP[i, V_REGEN]
            if share_r > 0.0 and elec[i] > 0.0 and rc >= 0:
                if blend:
                    want = elec[i] * demand
                    if want < regen:
                        electric = share_r * want
                        dbr += share_r * elec[i] * d_demand
                    else:
                        electric = share_r * regen
                        dbr += share_r * d_regen
                else:
                    electric = share_r * elec[i] * regen
                    dbr += share_r * elec[i] * d_regen
            if bm[i] > 0.0:
                sub = regen if blend else 0.0
                rest = bm[i] * demand - sub
                if rest > 0.0:
                    friction = VP[i, V_BRAKE] * rest
                    dbr += VP[i, V_BRAKE] * (bm[i] * d_demand - (d_regen if blend else 0.0))
        braking = electric + friction
        out[i] = traction - braking * sgn - running - grad - curve_tunnel
        # d(-force)/dv; the slopes of falling effort curves make it larger, keep it >= 0 for the solver
        d = drun + dct + braking * dsgn + dbr * abs(sgn) - dtr
        D[i] = d if d > 0.0 else 0.0
        if detail:
            parts[i, 0] = traction
            parts[i, 1] = electric * sgn
            parts[i, 2] = friction * sgn
            parts[i, 3] = running
            parts[i, 4] = grad
            parts[i, 5] = curve
            parts[i, 6] = tunnel


@njit(cache=True, error_model="numpy")
def coupler_forces(xm, w, VP, CP, Ts, Td, K, C):
    """Spring and damper tension of every coupling, and their derivatives, at positions ``xm`` and
    speeds ``w``."""
    for k in range(len(Ts)):
        delta = xm[k] - VP[k, V_LENGTH] - xm[k + 1]
        rate = w[k] - w[k + 1]
        s, d, kk, c = coupler_force(delta, rate, CP[k])
        Ts[k] = s
        Td[k] = d
        K[k] = kk if kk > 0.0 else 0.0
        C[k] = c


@njit(cache=True, error_model="numpy")
def thomas(diag, off, rhs, out, cprime):
    """Solve the symmetric tridiagonal system (diagonal ``diag``, off-diagonal ``off``) for ``rhs``."""
    n = len(diag)
    if n == 1:
        out[0] = rhs[0] / diag[0]
        return
    cprime[0] = off[0] / diag[0]
    out[0] = rhs[0] / diag[0]
    for i in range(1, n):
        den = diag[i] - off[i - 1] * cprime[i - 1]
        if i < n - 1:
            cprime[i] = off[i] / den
        out[i] = (rhs[i] - off[i - 1] * out[i - 1]) / den
    for i in range(n - 2, -1, -1):
        out[i] -= cprime[i] * out[i + 1]


# ============================================================================ one implicit step
@njit(cache=True, error_model="numpy")
def implicit_step(x0, v0, h, w, VP, CP, SP, CMD, trac, elec, bm, bank, prof, avail, pcache, ws):
    """Solve the implicit midpoint step of length h from (x0, v0) for the midpoint speeds ``w``
    (given as the initial guess). Returns the number of Newton iterations, -1 without convergence.
    On return the work arrays hold the forces of the last iteration, whose speeds differ from the
    solution by less than the tolerance (the energy accounting uses them: its error is of the order of
    the Newton residual)."""
    n = len(x0)
    xm, F, D, Ts, Td, K, C, G, diag, off, dw, cprime, parts = ws
    tol = SP[S_NEWTON_TOL]
    veps = SP[S_VEPS]
    for it in range(MAX_NEWTON):
        for i in range(n):
            xm[i] = x0[i] + 0.5 * h * w[i]
        vehicle_forces(xm, w, v0, VP, SP, CMD, trac, elec, bm, bank, prof, avail, pcache, F, D, True, parts)
        coupler_forces(xm, w, VP, CP, Ts, Td, K, C)
        for i in range(n):
            T_front = Ts[i - 1] + Td[i - 1] if i > 0 else 0.0
            T_back = Ts[i] + Td[i] if i < n - 1 else 0.0
            mi = VP[i, V_INERTIAL]
            G[i] = 2.0 * mi * (w[i] - v0[i]) / h - (F[i] + T_front - T_back)
            dg = 2.0 * mi / h + D[i]
            if i > 0:
                dg += 0.5 * h * K[i - 1] + C[i - 1]
            if i < n - 1:
                dg += 0.5 * h * K[i] + C[i]
                off[i] = -(0.5 * h * K[i] + C[i])
            diag[i] = dg
        thomas(diag, off, G, dw, cprime)
        # Newton can cycle next to a kink of a force law (a power cap, the blending of electric and
        # friction braking); after a few full steps, half steps break such cycles
        damping = 1.0 if it < 6 else 0.5
        big = 0.0
        for i in range(n):
            w_new = w[i] - damping * dw[i]
            # the dry-friction law turns over within a few v_eps of standstill: an update that would
            # carry a vehicle's end speed across 0 from outside that zone stops it at 0 first
            ve_old = 2.0 * w[i] - v0[i]
            ve_new = 2.0 * w_new - v0[i]
            if ve_old * ve_new < 0.0 and abs(ve_old) > 2.0 * veps:
                w_new = 0.5 * v0[i]
            if abs(w_new - w[i]) > big:
                big = abs(w_new - w[i])
            w[i] = w_new
        if not np.isfinite(big):
            return -1
        if big < tol:
            return it + 1
    return -1


# ============================================================================ brake command history
@njit(cache=True, error_model="numpy")
def history_value(t, hist, nh):
    """Friction brake command at time t from the history (times in column 0, values in column 1)."""
    if nh <= 1 or t >= hist[nh - 1, 0]:
        return hist[nh - 1, 1]
    lo = 0
    hi = nh - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if hist[mid, 0] <= t:
            lo = mid
        else:
            hi = mid
    return hist[lo, 1]


# ============================================================================ controller
@njit(cache=True, error_model="numpy")
def reference_speed(s, ref_s, ref_v2):
    """Reference speed at head position s [m/s]: v^2 linear in position between the points."""
    n = len(ref_s)
    if s <= ref_s[0]:
        return np.sqrt(max(ref_v2[0], 0.0))
    if s >= ref_s[n - 1]:
        return np.sqrt(max(ref_v2[n - 1], 0.0))
    k = np.searchsorted(ref_s, s, side="right") - 1
    ds = ref_s[k + 1] - ref_s[k]
    if ds <= 0.0:
        return np.sqrt(max(ref_v2[k + 1], 0.0))
    f = (s - ref_s[k]) / ds
    return np.sqrt(max(ref_v2[k] + (ref_v2[k + 1] - ref_v2[k]) * f, 0.0))


@njit(cache=True, error_model="numpy")
def reference_acceleration(s, ref_s, ref_v2):
    """Acceleration of the reference at head position s: d(v^2/2)/ds of its stretch [m/s^2]."""
    n = len(ref_s)
    if s < ref_s[0] or s >= ref_s[n - 1]:
        return 0.0
    k = np.searchsorted(ref_s, s, side="right") - 1
    ds = ref_s[k + 1] - ref_s[k]
    if ds <= 0.0:
        return 0.0
    return 0.5 * (ref_v2[k + 1] - ref_v2[k]) / ds


@njit(cache=True, error_model="numpy")
def reference_regime(s, ref_s, ref_m):
    """Regime of the reference stretch containing head position s."""
    n = len(ref_s)
    if s >= ref_s[n - 1]:
        return ref_m[n - 2] if n > 1 else ref_m[0]
    k = np.searchsorted(ref_s, s, side="right") - 1
    if k < 0:
        k = 0
    # skip stretches of no length (regime switches)
    while k + 1 < n - 1 and ref_s[k + 1] <= s:
        k += 1
    return ref_m[k]


@njit(cache=True, error_model="numpy")
def control(x, v, VP, SP, bank, prof, avail, pcache, ref, ceiling):
    """Command in [-1, 1], regime and mean speed that follow the reference profile.

    The regime is the reference's at the head (braking when the reference brakes one mean brake delay
    ahead). The controller asks for the force that holds the present mean speed (from the vehicles'
    own resistances) plus the force that closes the speed error in ``S_TAU`` seconds, as a command:
    traction (up to full) towards the speed ceiling (or the reference speed), cruising at the
    reference speed, coasting unless above the ceiling, full service braking eased when below the
    braking curve."""
    ref_s, ref_v2, ref_m, stop_at = ref
    cx, cl, cr = ceiling
    cs, cc, coff, cfc, cpc = bank
    poff, px, pval = prof
    ax, aval = avail
    n = len(v)
    mtot = 0.0
    mom = 0.0
    resist = 0.0
    fmax = 0.0
    veps = SP[S_VEPS]
    g = SP[S_G]
    for i in range(n):
        mi = VP[i, V_INERTIAL]
        mtot += mi
        mom += mi * v[i]
        av = abs(v[i])
        sgn = tanh(v[i] / veps)
        r = VP[i, V_R0] + VP[i, V_R1] * av + VP[i, V_R2] * av * av
        gr, cu, tu, b2 = profile_at(int(VP[i, V_PROFILE]), x[i], poff, px, pval, pcache, i)
        resist += r * sgn + VP[i, V_MASS] * g * (gr + (cu + tu + b2 * v[i] * v[i]) * sgn)
        c = int(VP[i, V_CURVE])
        if c >= 0:
            f, _ = effort_slope(av, c, cs, cc, coff, cfc, cpc)
            fmax += f * step_value(x[i] - 0.5 * VP[i, V_LENGTH], ax, aval)
    vc = mom / mtot
    s = x[0]
    if SP[S_DECEL] > 0.0:
        bmax = mtot * SP[S_DECEL] * SP[S_BRAKE_FRACTION]
    else:
        f, _ = effort_slope(abs(vc), int(SP[S_SERVICE_CURVE]), cs, cc, coff, cfc, cpc)
        bmax = SP[S_BRAKE_FRACTION] * f
    regime = reference_regime(s, ref_s, ref_m)
    v_ref = reference_speed(s, ref_s, ref_v2)
    ceil = linear_value(s, cx, cl, cr)
    ahead = s + max(vc, 0.0) * SP[S_LOOKAHEAD]
    if SP[S_LOOKAHEAD] > 0.0 and ahead > s:
        regime_ahead = reference_regime(ahead, ref_s, ref_m)
        if regime_ahead in (BRAKE, REGEN):
            if regime_ahead == BRAKE or regime != BRAKE:
                regime = regime_ahead
            v_ref = min(v_ref, reference_speed(ahead, ref_s, ref_v2))
    rate = mtot / SP[S_TAU]  # force per m/s of speed error [N s/m]
    if regime in (BRAKE, REGEN):
        # full service braking (or, in the regenerative-braking regime of energy-efficient runs, the
        # full electric brake alone), eased in proportion to how far below the braking curve the train is
        base = -1.0
        rc = int(SP[S_REGEN_CURVE])
        if regime == REGEN and rc >= 0 and bmax > 0.0:
            regen, _ = effort_slope(abs(vc), rc, cs, cc, coff, cfc, cpc)
            if SP[S_DECEL] <= 0.0:
                # the command's full level in this regime (vehicle_forces): an electric brake stronger
                # than the service brake brakes with its own curve, as the reference did
                bmax = max(bmax, regen)
            base = -min(1.0, regen / bmax)
        ease = rate * (min(v_ref, ceil) - max(vc, 0.0))
        u = base + (ease / bmax if bmax > 0.0 else 0.0)
        if s >= stop_at - SP[S_STOP_WINDOW] and vc < 0.5:
            u = -1.0  # at the stop: hold the train
        elif u > 0.0:
            # no traction while braking, except to draw up to a stop the train came to rest short of
            short = stop_at - s > SP[S_STOP_WINDOW] and vc < 0.5 * v_ref
            if short:
                want = resist + ease
                u = want / fmax if fmax > 0.0 else 0.0
            else:
                u = 0.0
    else:
        if regime == TRACTION:
            if SP[S_TRACK_PROFILE] > 0.5:
                # the reference speed a controller time constant ahead: a profile that starts from
                # standstill asks for speed where the train is going to be, not 0 where it stands
                preview = s + max(vc, 1.0) * SP[S_TAU]
                target = min(max(v_ref, reference_speed(preview, ref_s, ref_v2)), ceil)
            else:
                target = ceil
            want = resist + rate * (target - vc)
        elif regime in (CRUISE, FOLLOW):
            # hold the reference speed; a profile prescribed point by point (FOLLOW) also gives the
            # force its acceleration needs
            target = min(v_ref, ceil)
            want = resist + rate * (target - vc)
            if regime == FOLLOW:
                want += mtot * reference_acceleration(s, ref_s, ref_v2)
        else:
            target = ceil
            want = resist + rate * (target - vc)
        if want >= 0.0:  # noqa: SIM108 (a nested conditional expression would be harder to read)
            u = want / fmax if fmax > 0.0 else 0.0
        else:
            u = want / bmax if bmax > 0.0 else -1.0
        if regime == COAST and u > 0.0:
            u = 0.0
    if u > 1.0:
        u = 1.0
    if u < -1.0:
        u = -1.0
    return u, regime, vc


# ============================================================================ the main loop
@njit(cache=True, error_model="numpy")
def force_error(Tend, tmem, tmem_t, nmem, t1):
    """Largest deviation of the coupler forces at the end of a step (time t1) from their quadratic
    extrapolation through the ends of the three previous steps [N]: a third difference (about
    h^3 d3T/dt3), small while the forces vary smoothly, large at impacts and sudden force changes."""
    if nmem < 3:
        return 0.0
    ta, tb, tc = tmem_t[0], tmem_t[1], tmem_t[2]
    la = (t1 - tb) * (t1 - tc) / ((ta - tb) * (ta - tc))
    lb = (t1 - ta) * (t1 - tc) / ((tb - ta) * (tb - tc))
    lc = (t1 - ta) * (t1 - tb) / ((tc - ta) * (tc - tb))
    err = 0.0
    for k in range(len(Tend)):
        e = abs(Tend[k] - (la * tmem[0, k] + lb * tmem[1, k] + lc * tmem[2, k]))
        if e > err:
            err = e
    return err


@njit(cache=True, error_model="numpy")
def run(
    mode,
    t_end,
    state,
    VP,
    CP,
    SP,
    CMD,
    trac,
    elec,
    bank,
    prof,
    avail,
    ref,
    ceiling,
    hist,
    nh,
    acc,
    rec_t,
    rec_x,
    rec_v,
    rec_a,
    rec_T,
    rec_agg,
    nrec,
    ext,
    route_end,
):
    """Integrate until ``t_end`` (mode 0: fixed commands in CMD / trac / elec; mode 1: follow the
    reference ``ref`` and stop at its end). ``state`` = (x, v, b, t, a, next_record_time, pcache,
    tmem, tmem_t): positions, speeds, brake levels, time (array of 1), last accelerations, next record
    time (array of 1), profile cache, coupler forces at the ends of the last three steps and their
    times. Returns ``(status, nh, nrec)``.

    Step size: at most ``S_STEP``; with a force tolerance ``S_FORCE_TOL`` > 0 a step whose coupler
    forces leave their extrapolation (``force_error``) by more than the tolerance is repeated shorter,
    and the next step is sized for the tolerance (third-order law), down to ``S_STEP_MIN``. A step
    whose Newton iterations do not converge is halved."""
    x, v, b, tt, a_last, next_rec, pcache, tmem, tmem_t = state
    n = len(x)
    nc = max(n - 1, 1)
    h_max = SP[S_STEP]
    h_min = SP[S_STEP_MIN]
    tol = SP[S_FORCE_TOL]
    # work arrays
    xm = np.empty(n)
    F = np.empty(n)
    D = np.empty(n)
    Ts = np.empty(nc)
    Td = np.empty(nc)
    K = np.empty(nc)
    C = np.empty(nc)
    G = np.empty(n)
    diag = np.empty(n)
    off = np.empty(nc)
    dw = np.empty(n)
    cprime = np.empty(n)
    parts = np.zeros((n, 7))
    ws = (xm, F, D, Ts, Td, K, C, G, diag, off, dw, cprime, parts)
    w = np.empty(n)
    bm = np.empty(n)
    tgt = np.empty(n)
    x1 = np.empty(n)
    v1 = np.empty(n)
    Tend = np.zeros(nc)
    build = SP[S_BUILD_UP]
    eta_t = SP[S_ETA_T]
    eta_r = SP[S_ETA_R]
    rest_speed = SP[S_REST_SPEED]
    t = tt[0]
    status = ST_TIME
    if acc[A_H] <= 0.0:
        acc[A_H] = h_max if tol <= 0.0 else max(h_min, 0.25 * h_max)
    while t < t_end - 1e-12:
        h = min(acc[A_H], t_end - t)
        if tol > 0.0 and acc[A_NMEM] < 3:
            # no error estimate yet (start, or after a dwell): small steps until there is one
            h = min(h, 4.0 * h_min)
        # ---- command for this step
        if mode == 1:
            u, regime, _ = control(x, v, VP, SP, bank, prof, avail, pcache, ref, ceiling)
            if SP[S_RAMP] > 0.0 and u > 0.0:
                # the driver (or the traction control) raises the effort gradually: by the time
                # since the previous command at most
                u_max = max(CMD[K_COMMAND], 0.0) + acc[A_LAST_H] / SP[S_RAMP]
                if u > u_max:
                    u = u_max
            CMD[K_COMMAND] = u
            CMD[K_REGIME] = regime
            CMD[K_BLEND] = 1.0
            CMD[K_FRICTION] = -u if u < 0.0 else 0.0
            for i in range(n):
                trac[i] = u if (u > 0.0 and VP[i, V_CURVE] >= 0) else 0.0
                elec[i] = -u if u < 0.0 else 0.0
        # ---- brake command history (only changes are stored)
        if abs(hist[nh - 1, 1] - CMD[K_FRICTION]) > 1e-12:
            if nh >= hist.shape[0]:
                status = ST_HISTORY_FULL
                break
            hist[nh, 0] = t
            hist[nh, 1] = CMD[K_FRICTION]
            nh += 1
        # ---- one step, shortened until Newton converges and the force error is within tolerance
        err = 0.0
        tm = t
        while True:
            tm = t + 0.5 * h
            decay = np.exp(-0.5 * h / build) if build > 0.0 else 0.0
            for i in range(n):
                target = history_value(tm - VP[i, V_DELAY], hist, nh)
                tgt[i] = target
                if build > 0.0:
                    bm[i] = target + (b[i] - target) * decay
                else:
                    bm[i] = target
                w[i] = v[i] + 0.5 * h * a_last[i]
            its = implicit_step(x, v, h, w, VP, CP, SP, CMD, trac, elec, bm, bank, prof, avail, pcache, ws)
            if its < 0:
                if h <= h_min * 1.000001:
                    break
                h = max(0.5 * h, h_min)
                acc[A_SUBSTEPS] += 1
                continue
            acc[A_NEWTON] += its
            for i in range(n):
                x1[i] = x[i] + h * w[i]
                v1[i] = 2.0 * w[i] - v[i]
            for k in range(n - 1):
                s_, d_, _, _ = coupler_force(x1[k] - VP[k, V_LENGTH] - x1[k + 1], v1[k] - v1[k + 1], CP[k])
                Tend[k] = s_ + d_
            if tol > 0.0:
                err = force_error(Tend, tmem, tmem_t, int(acc[A_NMEM]), t + h)
                if err > tol and h > h_min * 1.000001:
                    h = max(h_min, h * max(0.2, 0.9 * (tol / err) ** (1.0 / 3.0)))
                    acc[A_REJECTED] += 1
                    continue
            break
        if its < 0:
            status = ST_FAILED
            break
        acc[A_STEPS] += 1
        # ---- accept: energy accounting with the midpoint forces (exact for the midpoint rule)
        p_tr = 0.0
        p_el = 0.0
        for i in range(n):
            dx = h * w[i]
            acc[A_TRACTION] += parts[i, 0] * dx
            acc[A_ELECTRIC] += parts[i, 1] * dx
            acc[A_FRICTION] += parts[i, 2] * dx
            acc[A_RUNNING] += parts[i, 3] * dx
            acc[A_GRADIENT] += parts[i, 4] * dx
            acc[A_CURVE] += parts[i, 5] * dx
            acc[A_TUNNEL] += parts[i, 6] * dx
            p_tr += parts[i, 0] * w[i]
            p_el += parts[i, 1] * w[i]
        for k in range(n - 1):
            ddelta = h * (w[k] - w[k + 1])
            acc[A_DAMPER] += Td[k] * ddelta
            acc[A_SPRING_WORK] -= Ts[k] * ddelta
        line_power = p_tr / eta_t - p_el * eta_r
        if line_power > acc[A_PEAK_POWER]:
            acc[A_PEAK_POWER] = line_power
        decay = np.exp(-h / build) if build > 0.0 else 0.0
        for i in range(n):
            a_last[i] = (v1[i] - v[i]) / h
            x[i] = x1[i]
            v[i] = v1[i]
            target = tgt[i]
            if build > 0.0:
                b[i] = target + (b[i] - target) * decay
            else:
                b[i] = target
        t += h
        tt[0] = t
        acc[A_LAST_H] = h
        acc[A_INTEGRATED] += h
        # ---- size of the next step
        if tol > 0.0:
            grow = 2.0 if err <= 0.0 else min(2.0, 0.9 * (tol / err) ** (1.0 / 3.0))
            acc[A_H] = min(h_max, max(h_min, h * max(grow, 0.2)))
        else:
            acc[A_H] = h_max
        for j in range(2):
            tmem_t[j] = tmem_t[j + 1]
            for k in range(n - 1):
                tmem[j, k] = tmem[j + 1, k]
        tmem_t[2] = t
        for k in range(n - 1):
            tmem[2, k] = Tend[k]
        if acc[A_NMEM] < 3:
            acc[A_NMEM] += 1
        # ---- extremes of the coupler forces at the end of the step
        for k in range(n - 1):
            tension = Tend[k]
            if tension > ext[E_DRAFT]:
                ext[E_DRAFT] = tension
                ext[E_DRAFT_K] = k
                ext[E_DRAFT_T] = t
                ext[E_DRAFT_HEAD] = x[0]
            if tension < ext[E_BUFF]:
                ext[E_BUFF] = tension
                ext[E_BUFF_K] = k
                ext[E_BUFF_T] = t
                ext[E_BUFF_HEAD] = x[0]
            if len(ext) >= N_E + N_EK * (n - 1):
                j = N_E + N_EK * k
                if tension > ext[j + EK_DRAFT]:
                    ext[j + EK_DRAFT] = tension
                    ext[j + EK_DRAFT_T] = t
                    ext[j + EK_DRAFT_HEAD] = x[0]
                if tension < ext[j + EK_BUFF]:
                    ext[j + EK_BUFF] = tension
                    ext[j + EK_BUFF_T] = t
                    ext[j + EK_BUFF_HEAD] = x[0]
        # ---- events
        # at rest: the mean speed below the rest speed and no vehicle faster than 10 x that (vehicles
        # still creep while compressed couplers relax against the regularised brakes)
        at_rest = True
        mom = 0.0
        mtot = 0.0
        for i in range(n):
            mom += VP[i, V_INERTIAL] * v[i]
            mtot += VP[i, V_INERTIAL]
            if abs(v[i]) > 10.0 * rest_speed:
                at_rest = False
        if abs(mom / mtot) > rest_speed:
            at_rest = False
        if mode == 1:
            stop_at = ref[3]
            if at_rest and x[0] >= stop_at - SP[S_STOP_WINDOW]:
                status = ST_STOPPED
            if at_rest and CMD[K_COMMAND] >= 1.0:
                if acc[A_REST_SINCE] < 0.0:
                    acc[A_REST_SINCE] = t
                elif t - acc[A_REST_SINCE] > SP[S_STALL_S]:
                    status = ST_STALLED
            else:
                acc[A_REST_SINCE] = -1.0
        if x[0] >= route_end:
            status = ST_END_OF_ROUTE
        # ---- record
        if t >= next_rec[0] - 1e-9 or status != ST_TIME:
            if nrec >= len(rec_t):
                status = ST_RECORD_FULL
                break
            nrec = record(
                nrec, t, x, v, a_last, VP, CP, CMD, parts, acc, rec_t, rec_x, rec_v, rec_a, rec_T, rec_agg
            )
            next_rec[0] = max(next_rec[0] + SP[S_RECORD_DT], t)
        if status != ST_TIME:
            break
    return status, nh, nrec


@njit(cache=True, error_model="numpy")
def record(nrec, t, x, v, a_last, VP, CP, CMD, parts, acc, rec_t, rec_x, rec_v, rec_a, rec_T, rec_agg):
    """Store the state at time t as record ``nrec``; the forces (``parts``) are those of the last
    step's midpoint."""
    n = len(x)
    rec_t[nrec] = t
    mtot = 0.0
    mom = 0.0
    kinetic = 0.0
    for i in range(n):
        rec_x[nrec, i] = x[i]
        rec_v[nrec, i] = v[i]
        rec_a[nrec, i] = a_last[i]
        mi = VP[i, V_INERTIAL]
        mtot += mi
        mom += mi * v[i]
        kinetic += 0.5 * mi * v[i] * v[i]
    spring = 0.0
    for k in range(n - 1):
        delta = x[k] - VP[k, V_LENGTH] - x[k + 1]
        s_, d_, _, _ = coupler_force(delta, v[k] - v[k + 1], CP[k])
        rec_T[nrec, k] = s_ + d_
        spring += coupler_energy(delta, CP[k])
    agg = rec_agg[nrec]
    agg[R_HEAD] = x[0]
    agg[R_SPEED] = mom / mtot
    agg[R_COMMAND] = CMD[K_COMMAND]
    agg[R_REGIME] = CMD[K_REGIME]
    tr = 0.0
    el = 0.0
    fr = 0.0
    ru = 0.0
    gr = 0.0
    cu = 0.0
    tu = 0.0
    ptr = 0.0
    pel = 0.0
    for i in range(n):
        tr += parts[i, 0]
        el += abs(parts[i, 1])
        fr += abs(parts[i, 2])
        ru += parts[i, 3]
        gr += parts[i, 4]
        cu += parts[i, 5]
        tu += parts[i, 6]
        ptr += parts[i, 0] * v[i]
        pel += parts[i, 1] * v[i]
    agg[R_TRACTION] = tr
    agg[R_ELECTRIC] = el
    agg[R_FRICTION] = fr
    agg[R_RUNNING] = ru
    agg[R_GRADIENT] = gr
    agg[R_CURVE] = cu
    agg[R_TUNNEL] = tu
    agg[R_TRACTION_POWER] = ptr
    agg[R_ELECTRIC_POWER] = pel
    agg[R_PEAK_POWER] = acc[A_PEAK_POWER]
    acc[A_PEAK_POWER] = -np.inf
    agg[R_KINETIC] = kinetic
    agg[R_SPRING] = spring
    for j in range(N_WORKS):
        agg[R_W0 + j] = acc[A_TRACTION + j]
    return nrec + 1
