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

from trainsim.model.route import Route
from trainsim.model.scenario import RunSettings
from trainsim.model.train import Train
from trainsim.sim._energy_c import stretch_works
from trainsim.sim.profile import LineResistanceProfile, PiecewiseLinear

__all__ = [
    "N_WORKS",
    "WORK_NAMES",
    "LineLaws",
    "blending_speeds",
    "line_laws",
    "run_works",
    "stretch_works",
]

# The integration itself is compiled (sim/_energy_c.pyx, Cython): ``stretch_works`` and the pieces it
# integrates. The settings below are compiled into it; tests/sim/test_energy_compiled.py checks that
# the two agree.

#: Longest RK4 sub-step of the work integration [m] (the motion's length scale v^2/a is hundreds of
#: metres at speed; near standstill ``LENGTH_SCALE_FRACTION`` takes over). Against scipy's DOP853 at
#: rtol 1e-13, the works of stretches 20 m long agree to 5e-9 of their largest work, whole motions
#: to 2e-9 (tests/sim/test_energy_compiled.py). The number of sub-steps is set at a piece's start:
#: a piece much longer than the length scale at its end (a long braking stretch recorded as one)
#: integrates 1/v-like forces less accurately (5e-7 of the regenerative work over 380 m, 24 -> 6 m/s).
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

#: A stretch whose regime, integrated from its first point, ends further than this from its last
#: point's speed [m/s] (plus ``OFF_REGIME_RELATIVE`` of it; compared as kinetic energy per mass
#: at the stretch's higher speed, so that a stretch ending at standstill is judged by energy, not
#: by the square root) does not follow its regime: it is integrated as the motion it records
#: (v^2 linear, the forces that motion needs) instead. Traces of the fastest run agree to 1e-8 m/s.
OFF_REGIME_SPEED_MPS = 1e-5
OFF_REGIME_RELATIVE = 1e-6

#: Number of work quantities integrated per stretch (see ``WORK_NAMES``).
N_WORKS = 6
#: Traction, braking (regenerative + friction), regenerative braking at the wheel, running
#: resistance, gradient, curve + tunnel resistance [J].
WORK_NAMES = ("traction", "braking", "regenerative", "running", "gradient", "curve_tunnel")


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
    inner = np.concatenate(
        [
            np.asarray(f.x, dtype=float)
            for f in (profile.gradient, profile.curve, profile.tunnel, profile.tunnel_v2, available)
        ]
    )
    # the set of breakpoints, sorted (np.unique: the same values as a set of floats, in one call)
    x = np.unique(np.concatenate([[lo, hi], inner[(inner > lo) & (inner < hi)]]))
    x = x[np.concatenate([[True], np.diff(x) > 1e-9])]
    if len(x) < 2:
        x = np.array([lo, max(hi, lo + 1.0)])
    left, right = x[:-1], x[1:]
    width = right - left
    eps = np.minimum(1e-9 * np.maximum(1.0, np.abs(left)), 0.25 * width)

    # just inside each piece, so that a jump at a breakpoint belongs to the piece on its right; both
    # ends in one evaluation per law (elementwise: the same values as two)
    inside = np.concatenate([left + eps, right - eps])
    n = len(left)

    def law(f: PiecewiseLinear) -> tuple[np.ndarray, np.ndarray]:
        ab = f(inside)
        a, b = ab[:n], ab[n:]
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
    # compiled (sim/_energy_c.pyx): converts and checks the point arrays itself
    return stretch_works(
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
