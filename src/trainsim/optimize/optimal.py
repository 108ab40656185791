"""The energy-optimal driving strategy of a section between two stops for a given running time.

Structure from the theory of optimal train control (Albrecht, Howlett, Pudney, Vu, Zhou 2016,
"The key principles of optimal train control", Parts 1 and 2, Transportation Research Part B 94):
maximum traction, holding a speed V, coasting, regenerative braking, maximum braking. The holding
speed V sets the price of time mu = V^2 R'(V) / eta_t (``price_of_time_w``); the final coasting
and braking phase is driven by the adjoint (``_pmp_c``) from the point where the train stops
holding, found so that the train stops exactly at the next station; V is solved so that the
section takes its scheduled time. Sections of a line that share mu share the marginal energy per
second of running time, which makes a split of a line's supplement optimal.

For a fixed mu the optimal run minimises energy + mu x time; the local choices of the
construction (where to stop driving ahead of steep descents and lower limits, where to start the
final coast) are made by comparing that cost on the stretch they change. docs/OPTIMIZATION.md
describes the construction step by step and where it still falls short of the reference optimum.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from itertools import pairwise

import numpy as np
from scipy.optimize import brentq

from trainsim.constants import KWH
from trainsim.errors import InputError
from trainsim.model.effort import EffortCurve
from trainsim.model.route import Route
from trainsim.model.scenario import RunSettings
from trainsim.model.train import Train
from trainsim.optimize import _pmp_c as pk
from trainsim.sim import _kernel_c, codes
from trainsim.sim.parameters import kernel_parameters, kink_speeds, regenerative_arrays
from trainsim.sim.profile import compile_track

#: Shooting on the coasting point stops when its bracket is shorter than this [m]: the switching
#: point is located exactly (to rounding at 50 km), so the run does not move with the step (issue 13).
COAST_POINT_TOLERANCE_M = 1e-9
#: Departures tried back from the latest one where a scan found none that saves, spaced
#: geometrically from 1 m (``SectionSolver._near_end``).
NEAR_END_POINTS = 24
#: A run that comes to rest no farther than this before the stop stops there [m]: far below what
#: moves an energy or a time by 1e-9, and within the energy integration's own tolerance.
STOP_TOLERANCE_M = 1e-7
#: The section time is met to this [s] (far inside the max(0.5 s, 0.05 %) the schedule needs, and
#: tight enough that energies and times do not move by 1e-9 relative with the step, issue 13, nor
#: with the path the holding speed search takes to it, issue 16).
TIME_TOLERANCE_S = 1e-8
#: Where the running time cannot be met to TIME_TOLERANCE_S (it jumps or is ragged in the holding
#: speed), the closest run of the search is kept if within this [s] (the tolerance before issue 16)
#: rather than bridged: the bridges and samples below are for schedules missed by more.
JUMP_TIME_TOLERANCE_S = 1e-4
#: ... and the variants built to compare with the first run of a solve, to this [s].
VARIANT_TIME_TOLERANCE_S = 0.1
#: Iterations of the holding speed search before the fallbacks take over.
HOLDING_SPEED_ITERATIONS = 16
#: Steps that grow the holding speed's bracket follow the secant of the last two runs this many
#: times as far (0: geometric steps only, as before issue 16) ...
BRACKET_OVERSHOOT = 1.5
#: ... and are no shorter than this nor longer than that (in log V).
BRACKET_MIN_STEP = 1e-3
BRACKET_MAX_STEP = float(np.log(2.0))
#: Holding speeds closer than this (in log) with running times on either side of the schedule...
JUMP_LOG_SPEED = 1e-2
#: ... whose running times differ by more than this many times the slope over the whole bracket
#: predicts mark a jump of the running time [-].
JUMP_FACTOR = 5.0
#: Bisection steps of the homotopy between departure choices where the running time jumps.
BRIDGE_ITERATIONS = 16
#: Runs that keep the schedule collected around a ragged crossing before the least-energy one is kept.
RAGGED_SAMPLES = 3
#: The final coasting point's search aims at the jump of the outcome predicted from the last short
#: runs this fraction of the way short of it (grown tenfold after each prediction that overshot) ...
JUMP_MARGIN = 1e-3
#: ... and closes the bracket with two runs this fraction of COAST_POINT_TOLERANCE_M either side of it [-].
JUMP_AIM_FRACTION = 0.25
#: Within this distance of the predicted jump [m] (as long as no prediction overshot), the runs go
#: right beside it at once (the interpolation is then accurate to far below the tolerance).
JUMP_CLOSE_M = 1e-4
#: First half-width of the bracket around the previous holding speed's final coasting point [m].
WARM_COAST_STEP_M = 20.0
#: Largest step of the adjoint-driven phase [m].
ADJOINT_STEP_M = 20.0
#: Half-width of the window around the previous holding speed's coasting point ahead of a lower
#: limit that is searched first [m].
DEPARTURE_WINDOW_M = 150.0
#: ... when the holding speed differs from the previous one by less than this (in log) [-].
WARM_START_LOG_SPEED = 0.005
#: Departure points ahead of descents and lower limits are located to this [m] (at 0.5 m the
#: running time moved with the step by 1e-5 through them).
DEPARTURE_TOLERANCE_M = 1e-2
#: Departure points ahead of descents are then refined to the root of their switching condition
#: to this [m] (``_departure_root``; issue 13: step-independent to about 1e-6 m) ...
DEPARTURE_ROOT_TOLERANCE_M = 1e-9
#: ... bracketed from the cost's minimum by half-widths from this [m] ...
DEPARTURE_ROOT_START_M = 2.0
#: ... up to this [m] (the minimum is within a metre or so of the root) ...
DEPARTURE_ROOT_WINDOW_M = 64.0
#: ... and kept where its cost exceeds the minimum's by no more than this fraction of the run's
#: cost (the minimum's own discretisation error, which the root does not share: 53 J of 3e9 J on
#: the freight example's second section, where the minimum moved 1.3 m with the step) [-].
DEPARTURE_ROOT_COST_SLACK = 1e-7


def price_of_time_w(train: Train, holding_speed_mps: float) -> float:
    """mu = V^2 R'(V) / eta_t [W]: the energy per second of running time saved at the margin when
    the train holds speed V (Albrecht et al. 2016, Part 1, eq. for the singular arc; psi(V) / eta)."""
    law = train.resistance_law
    slope = law.c1 + 2.0 * law.c2 * holding_speed_mps
    eta_t = train.electrical.traction_efficiency if train.electrical else 1.0
    return holding_speed_mps**2 * slope / eta_t


def _within_service(regen: EffortCurve, service: EffortCurve) -> EffortCurve:
    """The regenerative curve no higher than the service curve at any speed (the electric brake is
    part of the service brake): min(regen, service) for curves of polynomial laws without caps,
    with the crossings inside intervals solved exactly; ``regen`` itself where it never exceeds
    the service curve or where either has a cap or a hyperbolic term (source 002's metro with a
    regenerative brake of 0.8 x traction: 298 kN against the service brake's 150 kN below 5 km/h)."""
    rs, rc, rcap, rpow = regen.as_arrays()
    ss, sc, scap, spow = service.as_arrays()
    if not (np.isinf(rcap) and np.isinf(rpow) and np.isinf(scap) and np.isinf(spow)):
        return regen
    if np.any(rc[:, 3] != 0.0) or np.any(sc[:, 3] != 0.0):
        return regen
    starts = np.union1d(rs, ss)
    cuts = [0.0]
    rows = []
    for k, v0 in enumerate(starts):
        v1 = starts[k + 1] if k + 1 < len(starts) else v0 + 1e3
        cr = rc[max(int(np.searchsorted(rs, v0, side="right")) - 1, 0)]
        cs = sc[max(int(np.searchsorted(ss, v0, side="right")) - 1, 0)]
        d = cr[:3] - cs[:3]  # regen - service = d0 + d1 v + d2 v^2 on [v0, v1)
        roots = np.roots(d[::-1]) if np.any(d != 0.0) else np.array([])
        inner = sorted(float(r.real) for r in roots if abs(r.imag) < 1e-12 and v0 < r.real < v1)
        for a, z in zip([v0, *inner], [*inner, v1], strict=True):
            mid = 0.5 * (a + z)
            lower = cr if d[0] + d[1] * mid + d[2] * mid * mid <= 0.0 else cs
            if a > v0 or k > 0:
                cuts.append(a)
            rows.append(lower)
    if len(rows) == len(starts) and all(
        np.array_equal(row, rc[max(int(np.searchsorted(rs, v, side="right")) - 1, 0)])
        for row, v in zip(rows, starts, strict=True)
    ):
        return regen
    return EffortCurve(
        np.array(cuts), np.array(rows), label=regen.label, adhesion_limit_kg=regen.adhesion_limit_kg
    )


def regenerative_holding_speed(train: Train, mu: float, eta_r: float) -> float:
    """W with mu = eta_r W^2 R'(W): the speed at which the optimal strategy holds with
    regenerative braking on a steep descent (phi = eta_r on a singular arc); inf without
    regeneration."""
    if eta_r <= 0.0 or not np.isfinite(mu):
        return float("inf")
    law = train.resistance_law
    if law.c2 <= 0.0 and law.c1 <= 0.0:
        return float("inf")
    # psi(W) = W^2 (c1 + 2 c2 W) = mu / eta_r, increasing in W
    target = mu / eta_r

    def excess(w: float) -> float:
        return w * w * (law.c1 + 2.0 * law.c2 * w) - target

    if excess(1e4) < 0.0:
        return float("inf")  # the price of time of a run far above every limit: it never holds W
    return float(brentq(excess, 0.0, 1e4))


def key_equation_braking_speed(train: Train, holding_speed_mps: float) -> float:
    """W = psi(V) / (R(V) + V R'(V)): on level track without regeneration the speed at which
    coasting ends and braking begins (Albrecht et al. 2016; MARECO, SNCF 1981)."""
    law = train.resistance_law
    V = holding_speed_mps
    slope = law.c1 + 2.0 * law.c2 * V
    return V * V * slope / (law(V) + V * slope)


@dataclass(frozen=True)
class SectionPlan:
    """The optimal run of one section: points (position [m], speed [m/s], time from departure
    [s], regime code) and the parameters that define it."""

    s: np.ndarray
    v: np.ndarray
    t: np.ndarray
    regime: np.ndarray
    running_time_s: float
    holding_speed_mps: float
    coast_start_m: float
    price_of_time_w: float
    fastest_time_s: float
    feasible: bool


class _ConvergedError(Exception):
    """Ends the holding speed search as soon as a plan meets the time (not an error)."""

    def __init__(self, plan: SectionPlan) -> None:
        super().__init__()
        self.plan = plan


class _JumpError(RuntimeError):
    """Ends the holding speed search where the running time jumps in V (not an error)."""


class SectionSolver:
    """Energy-optimal runs of one section [s0, s1] for any running time."""

    def __init__(
        self,
        train: Train,
        route: Route,
        s0: float,
        s1: float,
        settings: RunSettings | None = None,
        breaks_m: tuple[float, ...] = (),
    ):
        """``breaks_m``: positions inside the section that must be grid points (binding timing
        points, where the holding speed may change, ``stretches``)."""
        settings = settings or RunSettings()
        b = train.braking
        if (
            b.regenerative is not None
            and b.service_force is not None
            and np.isfinite(b.service_force.force_cap_n)
        ):
            # the electric brake is part of the service brake: never more than its cap (TTOBench's
            # comfort deceleration caps the service brake below the regenerative force of the FLIRT
            # and the KISS)
            regen = b.regenerative.capped(force_cap_n=b.service_force.force_cap_n)
            train = dataclasses.replace(train, braking=dataclasses.replace(b, regenerative=regen))
        b = train.braking
        if b.regenerative is not None and b.service_force is not None:
            regen = _within_service(b.regenerative, b.service_force)
            if regen is not b.regenerative:
                train = dataclasses.replace(train, braking=dataclasses.replace(b, regenerative=regen))
        self.train, self.route, self.s0, self.s1 = train, route, s0, s1
        inner = sorted(float(b) for b in breaks_m if s0 < b < s1)
        self.track, _, _ = compile_track(route, train, [s0, *inner, s1], settings.max_step_m)
        #: fixed holding speeds of the stretches before binding timing points: ((end [m], V [m/s]), ...)
        #: in order; the holding speed a plan is built for holds after the last end (see
        #: ``trainsim.optimize.windows``). Empty: one holding speed for the whole section.
        self.stretches: tuple[tuple[float, float], ...] = ()
        P, trac, brk = kernel_parameters(train, settings)
        self.P = P
        self.curves = (*trac, *brk, *regenerative_arrays(train))
        self.tk = kink_speeds(*trac)
        self.bk = kink_speeds(*brk)
        self.rk = kink_speeds(*regenerative_arrays(train))
        elec = train.electrical
        self.inv_eta_t = 1.0 / (elec.traction_efficiency if elec else 1.0)
        has_regen = train.braking.regenerative is not None and elec is not None
        self.eta_r = elec.regenerative_efficiency * elec.receptivity if has_regen else 0.0
        self.has_regen = has_regen and self.eta_r > 0.0
        tr = self.track
        self.i0, self.i1 = int(tr.stop_index[0]), int(tr.stop_index[-1])
        self._last_interval = len(tr.a0) - 1
        #: buffers of ``_energy_to``'s two-point stretch (s, v, regime, cumulative energy)
        self._two_points = (np.empty(2), np.empty(2), np.empty(2, dtype=np.int8), np.empty(2))
        self.Cr, _, self.US = _kernel_c.braking_ceiling(
            tr.x, tr.a0, tr.a1, tr.b0, tr.b1, tr.vlim, self.i0, self.i1, P, self.curves, self.bk
        )
        self.n_max = 8 * len(tr.x) + int((s1 - s0) / pk.MIN_SWITCH_STEP_M) + 64
        #: (variant, holding speed, final coasting point) of the plans built in this solve
        self._coast_points: list[tuple[tuple[bool, ...], float, float]] = []
        #: d(running time)/d(log V) [s] over the first variant's bracket in this solve
        self._time_slope: float | None = None
        #: whether holding arcs are left early ahead of steep descents (coasting excursions)
        self.excursions = True
        #: whether the train coasts ahead of lower limits (not only brakes to them)
        self.limit_coasting = True
        #: whether excursions must be back on the holding arc before the next steep descent
        self.short_excursions = False
        #: whether a final phase that starts on an arc held by braking starts braking (adjoint
        #: just below eta_r) rather than coasting (just below 1/eta_t)
        self.braking_arc_exits = False
        #: whether the stop is approached on the regenerative braking curve (where the train's
        #: regenerative brake alone can stop it) rather than the service braking curve
        regen, service = train.braking.regenerative, train.braking.service_force
        grid_v = np.linspace(0.0, float(self.track.vlim.max()), 200)
        self.regen_final_approach = bool(
            self.has_regen
            and regen is not None
            and service is not None
            and float(np.min(regen(grid_v))) > 0.0
            and bool(np.all(regen(grid_v) <= service(grid_v) + 1.0))
        )
        if self.regen_final_approach:
            tr = self.track
            modes = np.full(len(tr.a0), codes.REGEN, dtype=np.int64)
            self.Cr_regen, _, self.US_regen = _kernel_c.braking_ceiling_mixed(
                tr.x, tr.a0, tr.a1, tr.b0, tr.b1, tr.vlim, self.i0, self.i1, self.P, self.curves, self.bk,
                self.rk, modes,
            )  # fmt: skip
        #: the final phase's braking curves and the braking mode of each (indexed as ``Cr``): with
        #: regeneration those to lower limits are regenerative-only (the adjoint lies in (0, eta_r]
        #: along them, where friction braking is not optimal), the one to the stop is service braking
        self.Cr_final, self.US_final, self.final_curve_modes = self._final_phase_curves()
        self._final_phase_on_braking_arc = False
        self._has_long_excursions = False
        #: the last departure point ahead of each lower limit, to search near first
        self._departure_points: dict[tuple[str, int], float] = {}
        self._has_descents = self._has_limit_braking = False
        self._last_departure_speed: float | None = None
        self._near_last_speed = False
        #: the departure points chosen by the last phase A, (p, lowest, highest) per descent or
        #: lower limit, and departure points imposed on the next (see _bridge)
        self._decisions: dict[tuple[str, int], tuple[float, float, float]] = {}
        self._forced: dict[tuple[str, int], float] = {}
        self._last_holding_speed: float | None = None
        #: whether the variant being built is only compared with the first one of its solve
        self._secondary = False
        #: W [m/s] by price of time mu [W]: a root search that every final phase repeated
        self._w_by_mu: dict[float, float] = {}
        #: the departures ahead of descents already searched in this solve, by everything they
        #: depend on, with what the search recorded (``_best_departure``)
        self._departure_memo: dict[tuple, tuple] = {}
        fastest = self._fastest_points()
        self.fastest = fastest
        self.fastest_time_s = float(fastest[2][-1])
        if not np.isfinite(self.fastest_time_s) or fastest[1][-1] > 1e-6:
            raise InputError(
                f"the train cannot run from {s0:.0f} m to {s1:.0f} m (it stalls on the way)",
                field="route",
            )

    def _final_phase_curves(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(Cr, US, mode per interval) of the braking curves the final phase meets: the service
        braking curve to the stop (the intervals from the one where it leaves the limit on) and,
        for trains with regeneration, regenerative-only curves to the lower limits before it."""
        tr = self.track
        modes = np.full(len(tr.a0), codes.BRAKE, dtype=np.int64)
        if not self.has_regen:
            return self.Cr, self.US, modes[self.i0 : self.i1].copy()
        # the stop's service curve leaves the limit in the last interval with part of it at the limit
        plateau = np.flatnonzero(self.US > 0.0)
        first_stop = self.i0 + (int(plateau[-1]) if len(plateau) else 0)
        modes[self.i0 : first_stop] = codes.REGEN
        Cr, _, US = _kernel_c.braking_ceiling_mixed(
            tr.x, tr.a0, tr.a1, tr.b0, tr.b1, tr.vlim, self.i0, self.i1, self.P, self.curves, self.bk,
            self.rk, modes,
        )  # fmt: skip
        return Cr, US, modes[self.i0 : self.i1].copy()

    # ------------------------------------------------------------------ phases
    def _phase_a(self, holding_speed: float):
        """The run for holding speed V up to the stop, before the final coast: maximum traction to
        min(V, limit), hold it; coast down steep descents up to min(limit, W) and hold there with
        braking; brake to lower limits and the stop; with the departures ahead of steep descents
        (``excursions``) and lower limits (``limit_coasting``) that lower energy + mu x time.

        With ``stretches`` (binding timing points) each stretch is driven so with its own holding
        speed, from the state in which the previous one ends: the price of time jumps at a binding
        point, the speed does not (Albrecht et al. 2016, Part 1, interior time constraints)."""
        tr = self.track
        self._decisions = {}
        self._has_long_excursions = False
        if not self.stretches:
            if not np.isfinite(holding_speed) or holding_speed >= 10.0 * float(tr.vlim.max()):
                return self.fastest
            return self._phase_a_from(holding_speed, (-1, 0.0, 0.0, 0.0), self.s0)
        pieces = []
        start, s_from = (-1, 0.0, 0.0, 0.0), self.s0
        for end, V in (*self.stretches, (self.s1, holding_speed)):
            points = self._phase_a_from(V, start, s_from)
            if end >= self.s1 or not np.isfinite(points[2][-1]):
                pieces.append(points)
                break
            i, u, v, t, _ = self._state_at(points, end)
            if v <= 0.0:
                return self._stalled()
            keep = points[0] < end - 1e-9
            pieces.append(tuple(arr[keep] for arr in points))
            start, s_from = (i, u, v, t), end
        return tuple(np.concatenate([pc[k] for pc in pieces]) for k in range(4))

    def _phase_a_from(self, holding_speed: float, start: tuple[int, float, float, float], s_from: float):
        """Phase A for holding speed V [m/s] from ``start`` (interval, offset [m], speed [m/s], time
        [s]; interval -1: at rest at the section's start, which is ``s_from`` [m])."""
        tr = self.track
        # close to the last holding speed the best departures ahead of lower limits move little:
        # searched near the last ones first (not between stretches, whose speeds alternate)
        last = self._last_departure_speed
        self._near_last_speed = (
            not self.stretches
            and last is not None
            and abs(np.log(holding_speed / last)) < WARM_START_LOG_SPEED
        )
        self._last_departure_speed = holding_speed
        V_int, mu_int, W_int = self._interval_speeds(holding_speed)
        vhold = np.minimum(tr.vlim, V_int)
        vtop = np.maximum(np.minimum(tr.vlim, W_int), vhold)
        Cr, US, modes = self._ceiling(vtop)
        steep_down = self._steep_descents(V_int, vhold, vtop)
        # a stretch driven fastest (no price of time) never leaves its arc early
        steep_down &= np.isfinite(mu_int)
        if not self.excursions:
            steep_down[:] = False
        pieces: list[tuple[np.ndarray, ...]] = []
        last_pos = s_from
        for _ in range(10_000):
            seg = self._holding(vhold, vtop, Cr, US, modes, start)
            if seg is None:
                return self._stalled()
            if steep_down.any():
                self._has_descents = True
            found = None
            after = last_pos
            while found is None:
                descent = self._next_descent(seg, steep_down, after, vhold)
                if descent is None:
                    break
                a, after, v_rejoin = descent
                k = self._interval_of(a)
                found = self._best_departure(
                    seg, last_pos, a, float(W_int[k]), float(V_int[k]), float(mu_int[k]), ("descent", round(after)),
                    v_rejoin,
                    self._next_steep_start(steep_down, after),
                )  # fmt: skip
            if found is None:
                pieces.append(
                    self._coast_over_crest(seg, vhold, vtop, Cr, US, modes, mu_int, steep_down, last_pos)
                )
                break
            p, excursion, q = found
            keep = seg[0] < p
            pieces.append(tuple(arr[keep] for arr in seg))
            pieces.append(excursion)
            start = q
            last_pos = tr.x[q[0]] + q[1]
        points = tuple(np.concatenate([pc[k] for pc in pieces]) for k in range(4))
        if self.limit_coasting:
            points = self._coast_before_limits(points, vtop, Cr, US, modes, mu_int)
        return points

    def _coast_over_crest(self, seg, vhold, vtop, Cr, US, modes, mu_int, steep_down, p_lo: float):
        """``seg`` (phase A to the stop) with a coast over the crest ahead of a steep descent that
        ends at the stop, where that lowers energy + mu x time: from a departure p before the
        descent the train coasts (up the hill to the crest and down) until it reaches the
        regenerative holding speed W on the descent and holds W with braking, then brakes to the
        stop. No excursion can rejoin the holding arc after such a descent (``coast_excursion``
        fails there), so without this the train held V up to the crest: source 002's metro with a
        regenerative brake on a 20 per mille hump at +20 % was 2.5 % above the reference, which
        coasts from 500 m before the crest.

        Only for trains with regeneration (W finite): the run's regenerative holding arc on the
        descent then pays back what coasting over the crest saves."""
        tr = self.track
        if not self.has_regen or not self.excursions:
            return seg
        if self.stretches and p_lo < self.stretches[-1][0] - 1e-9:
            return seg  # a stretch before a binding point: the final descent is another stretch's
        steep = steep_down[self.i0 : self.i1]
        if not steep[-1]:
            return seg
        # the steep descent that ends at the stop: its first interval
        flat = np.flatnonzero(~steep)
        k0 = self.i0 + (int(flat[-1]) + 1 if len(flat) else 0)
        mu = float(mu_int[k0])
        a = self._steep_from(k0, float(vhold[k0]))
        if not np.isfinite(mu) or a - p_lo <= 1.0:
            return seg
        regen = self.train.braking.regenerative
        if regen is None or float(np.min(regen(np.linspace(0.0, float(tr.vlim.max()), 200)))) <= 0.0:
            return seg
        cum = np.empty(len(seg[0]))
        pk.path_energy(
            seg[0], seg[1], seg[3], tr.x, tr.a0, tr.a1, tr.b0, tr.b1, tr.traction_scale, self.P, self.curves,
            self.inv_eta_t, self.eta_r, cum, self.tk, self.bk, self.rk,
        )  # fmt: skip
        # the runs are compared braking to the stop with the electric brake alone, as the final
        # phase will: on the service curve the friction brake's share would favour the runs that
        # come slower to the stop
        # (only to compare them: where the regenerative force exceeds the service force, as the
        # metro's 298 kN against 150 kN below 5 km/h, that curve brakes harder than the train may;
        # the run returned brakes to the stop as phase A does, the final phase then replaces that)
        curves = (Cr, US, modes)
        modes = modes.copy()
        modes[k0 : self.i1] = codes.REGEN
        Cr, _, US = _kernel_c.braking_ceiling_mixed(
            tr.x, tr.a0, tr.a1, tr.b0, tr.b1, vtop, self.i0, self.i1, self.P, self.curves, self.bk, self.rk,
            modes,
        )  # fmt: skip
        # a holding speed far below any speed: the train coasts (and holds the top speed W with
        # braking on the descent) from p to the stop
        crawl = 1e-3

        def cost(p: float, keep: bool = False):
            state = self._state_at(seg, p)
            i, u, vp, tp, _ = state
            vh = vhold.copy()
            vh[i:] = np.minimum(vh[i:], crawl)
            out = self._holding(vh, vtop, Cr, US, modes, (i, u, vp, tp))
            if keep and out is not None:
                out = self._holding(vh, vtop, *curves, (i, u, vp, tp))
            if out is None or not np.isfinite(out[2][-1]):
                return np.inf, None
            e = np.empty(len(out[0]))
            pk.path_energy(
                out[0], out[1], out[3], tr.x, tr.a0, tr.a1, tr.b0, tr.b1, tr.traction_scale, self.P,
                self.curves, self.inv_eta_t, self.eta_r, e, self.tk, self.bk, self.rk,
            )  # fmt: skip
            total = self._energy_to(seg, cum, p, state) + float(e[-1]) + mu * float(out[2][-1])
            return total - base, (out if keep else None)

        # coasting from the descent's start is what phase A does without a crest coast
        base = 0.0
        base = cost(a)[0]
        if not np.isfinite(base):
            return seg
        key = ("crest", round(a))
        lo = min(p_lo + 1.0, a)
        forced = self._forced.get(key)
        if forced is not None:
            p = min(max(forced, lo), a)
            dj = -1.0 if p < a - 1e-6 else np.inf
        else:
            p, dj = self._minimise(cost, lo, a)
        self._decisions[key] = (a, lo, a)
        if not np.isfinite(dj) or dj >= 0.0:
            return seg
        dj, out = cost(p, keep=True)
        if out is None or (forced is None and dj >= 0.0):
            return seg
        self._decisions[key] = (p, lo, a)
        keep = seg[0] < p
        return tuple(np.concatenate([arr[keep], o]) for arr, o in zip(seg, out, strict=True))

    def _regenerative_holding_speed(self, mu: float) -> float:
        """``regenerative_holding_speed`` of this train for price of time mu [W], remembered."""
        W = self._w_by_mu.get(mu)
        if W is None:
            W = self._w_by_mu[mu] = regenerative_holding_speed(self.train, mu, self.eta_r)
        return W

    def _path_cost(self, points, mu: float) -> float:
        """Electrical energy [J] + mu [W] x running time [s] of a run to the stop."""
        tr = self.track
        cum = np.empty(len(points[0]))
        pk.path_energy(
            points[0], points[1], points[3], tr.x, tr.a0, tr.a1, tr.b0, tr.b1, tr.traction_scale, self.P,
            self.curves, self.inv_eta_t, self.eta_r, cum, self.tk, self.bk, self.rk,
        )  # fmt: skip
        return float(cum[-1]) + mu * float(points[2][-1])

    def _energy_to(self, points, cum: np.ndarray, s_m: float, state=None) -> float:
        """Electrical energy [J] of the run ``points`` from its start to ``s_m`` [m], ``cum`` its
        cumulative energy at its points (``pk.path_energy``): the last stretch integrated in its
        regime up to s_m as the whole run is. (Interpolated linearly between the points, the costs
        of the departures had kinks at the run's points, which lie on the grid: the heavy-haul
        example's departure ahead of its last descent sat on such a kink and moved by 0.9 m with
        the step.)"""
        tr = self.track
        # (``state``: ``_state_at(points, s_m)`` if the caller has it already)
        _, _, v, _, j = self._state_at(points, s_m) if state is None else state
        s0 = float(points[0][j])
        if s_m <= s0:
            return float(np.interp(s_m, points[0], cum))
        s2, v2, m2, out = self._two_points
        s2[0], s2[1] = s0, s_m
        v2[0], v2[1] = float(points[1][j]), v
        m2[0] = m2[1] = points[3][j]
        pk.path_energy(
            s2, v2, m2, tr.x, tr.a0, tr.a1, tr.b0, tr.b1, tr.traction_scale, self.P, self.curves,
            self.inv_eta_t, self.eta_r, out, self.tk, self.bk, self.rk,
        )  # fmt: skip
        return float(cum[j]) + float(out[1])

    def _interval_of(self, s_m: float) -> int:
        """The grid interval that holds position ``s_m`` [m] (the last one at the section's end)."""
        # (Python's min and max: np.clip on a scalar cost more than the search, issue 16)
        k = int(self.track.x.searchsorted(s_m, side="right")) - 1
        return min(max(k, 0), self._last_interval)

    def _interval_speeds(self, holding_speed: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(V, mu, W) on every grid interval [m/s, W, m/s] for holding speed V; far above every
        limit (a stretch before a binding point driven fastest) no price of time holds it back."""
        tr = self.track
        fastest = not np.isfinite(holding_speed) or holding_speed >= 10.0 * float(tr.vlim.max())
        mu = np.inf if fastest else price_of_time_w(self.train, holding_speed)
        W = self._regenerative_holding_speed(mu)
        n = len(tr.a0)
        return np.full(n, float(holding_speed)), np.full(n, mu), np.full(n, W)

    def _coast_before_limits(self, points, vtop, Cr, US, modes, mu_int: np.ndarray):
        """Coast ahead of every lower limit instead of holding up to its braking curve.

        For each braking run down to a lower limit (not the stop), the train leaves its holding or
        traction arc at a point p and coasts until it meets the same braking curve. p minimises the
        local cost: energy + mu x time of the changed stretch, the quantity the optimal control
        minimises for the section's price of time mu (Albrecht et al. 2016, Part 2: the approach to
        a speed limit from above is hold, coast, brake). Coasting that reaches the limit before the
        braking curve would be slower for no saving, so only points that meet the curve count."""
        tr = self.track
        out = [np.empty(self.n_max) for _ in range(3)] + [np.empty(self.n_max, dtype=np.int8)]
        p_floor = after = self.s0
        while True:
            s, v, _, m = points
            episode = self._next_limit_braking(m, s, after)
            if episode is None:
                return points
            self._has_limit_braking = True
            q, b = episode
            mu = float(mu_int[self._interval_of(q)])
            if not np.isfinite(mu):
                # a stretch driven fastest brakes to the limit at the last moment
                self._decisions[("limit", round(b))] = (q, p_floor, q)
                p_floor = after = b
                continue
            i_last = int(np.searchsorted(tr.x, b - 1e-9, side="right")) - 1
            cum = np.empty(len(s))
            pk.path_energy(
                s, v, m, tr.x, tr.a0, tr.a1, tr.b0, tr.b1, tr.traction_scale, self.P, self.curves,
                self.inv_eta_t, self.eta_r, cum, self.tk, self.bk, self.rk,
            )  # fmt: skip

            def cost(p: float, keep: bool = False, points=points, cum=cum, q=q, b=b, i_last=i_last, mu=mu):
                state_p = self._state_at(points, p)
                i, u, vp, tp, _ = state_p
                n, status, i_r, u_r, v_r, t_r, e_coast = pk.coast_to_curve(
                    tr.x, tr.a0, tr.a1, tr.b0, tr.b1, vtop, tr.traction_scale, i, u, vp, tp, i_last,
                    self.i0, self.P, self.curves, self.bk, self.rk, Cr, US, modes, ADJOINT_STEP_M,
                    self.eta_r, *out,
                )  # fmt: skip
                r = tr.x[i_r] + u_r
                if status != 0 or n >= self.n_max - 8 or not q - 1e-6 <= r <= b + 1e-6:
                    return np.inf, None  # came to rest, or met another limit's braking curve first
                state_r = self._state_at(points, r)
                t_a = state_r[3]
                dj = (
                    e_coast
                    - (self._energy_to(points, cum, r, state_r) - self._energy_to(points, cum, p, state_p))
                    + mu * (t_r - t_a)
                )
                if not keep:
                    return dj, None
                return dj, (tuple(arr[:n].copy() for arr in out), (r, v_r, t_r), t_r - t_a)

            key = ("limit", round(b))
            best_p, dj = np.nan, np.inf
            warm = self._departure_points.get(key) if self._near_last_speed else None
            forced = self._forced.get(key)
            if forced is not None:
                best_p = min(max(forced, p_floor), q)
                dj = cost(best_p)[0] if best_p < q - 1e-6 else 0.0
                warm = None
            elif warm is not None:
                # the outer search moves V a little at a time: look near the last optimum first
                lo, hi = max(p_floor, warm - DEPARTURE_WINDOW_M), min(q, warm + DEPARTURE_WINDOW_M)
                if hi - lo > 1.0:
                    best_p, dj = self._golden(cost, lo, hi)
                    at_edge = min(best_p - lo, hi - best_p) < 1.0 and not (
                        best_p - lo < 1.0 and lo <= p_floor
                    )
                    if at_edge:
                        dj = np.inf
            if not np.isfinite(dj) and forced is None:
                best_p, dj = self._minimise(cost, p_floor, q)
                # on an ascent coasting slows the train almost as fast as braking: the coasts that
                # meet the curve start within tens of metres of q (CH_Fribourg_Bern, FLIRT, the
                # 100 km/h limit at 19852 m: the scan's 250 m step missed them and the train braked)
                best_p, dj = self._near_end(cost, p_floor, q, best_p, dj)
            if np.isfinite(dj):
                self._departure_points[key] = best_p
            accepted = False
            if np.isfinite(dj) and (dj < 0.0 or forced is not None):
                dj, splice = cost(best_p, keep=True)
                if splice is not None and (dj < 0.0 or forced is not None):
                    points = self._splice(points, best_p, *splice)
                    accepted = True
            self._decisions[key] = (best_p if accepted else q, p_floor, q)
            # a later approach may coast through this limit too (from the same holding arc) only
            # if the train coasted here: it then passes under the limit
            if not accepted:
                p_floor = b
            after = b

    @staticmethod
    def _next_limit_braking(m, s, after: float):
        """(start, end) [m] of the first braking run after ``after`` that ends at a lower limit
        (not at the stop), or None."""
        braking = (m == codes.REGEN) | (m == codes.BRAKE)
        idx = np.flatnonzero(braking[:-1] & (s[:-1] > after + 1e-6))
        if not len(idx):
            return None
        j0 = int(idx[0])
        j1 = j0
        while j1 + 1 < len(s) - 1 and braking[j1 + 1]:
            j1 += 1
        if j1 + 1 >= len(s) - 1:
            return None  # the approach to the stop
        return float(s[j0]), float(s[j1 + 1])

    @staticmethod
    def _minimise(cost, lo: float, hi: float, tol_m: float | None = None):
        """(p, cost) of a scan of [lo, hi] refined by golden section around the best point."""
        count = int(min(64, max(16, (hi - lo) / 250.0)))
        grid = np.linspace(lo, hi, count + 1)[1:]
        values = np.array([cost(p)[0] for p in grid])
        k = int(np.argmin(values))
        if not np.isfinite(values[k]):
            return float(grid[k]), np.inf
        a = grid[k - 1] if k > 0 else lo
        z = grid[min(k + 1, len(grid) - 1)]
        p, value = SectionSolver._golden(cost, a, z, tol_m)
        return (p, value) if value <= values[k] else (float(grid[k]), values[k])

    @staticmethod
    def _near_end(cost, lo: float, hi: float, p: float, value: float):
        """(p, cost): where a scan of [lo, hi] found no point that saves (cost >= 0), points spaced
        geometrically back from hi, refined by golden section around the best; the departures that
        save may all lie closer to hi than the scan's step. ``p``, ``value`` otherwise."""
        if value < 0.0 or not hi - lo > 2.0:
            return p, value
        near = hi - np.geomspace(1.0, hi - lo, NEAR_END_POINTS)
        values = np.array([cost(x)[0] for x in near])
        j = int(np.argmin(values))
        if not values[j] < min(value, 0.0):
            return p, value
        a = float(near[j + 1]) if j + 1 < len(near) else lo
        z = float(near[j - 1]) if j > 0 else hi
        best, best_value = SectionSolver._golden(cost, a, z)
        return (best, best_value) if best_value <= values[j] else (float(near[j]), float(values[j]))

    @staticmethod
    def _golden(cost, a: float, z: float, tol_m: float | None = None):
        """(p, cost) of a golden-section search of [a, z]."""
        tol_m = DEPARTURE_TOLERANCE_M if tol_m is None else tol_m
        g = 0.5 * (np.sqrt(5.0) - 1.0)
        c, d = z - g * (z - a), a + g * (z - a)
        fc, fd = cost(c)[0], cost(d)[0]
        while z - a > tol_m:
            if fc <= fd:
                z, d, fd = d, c, fc
                c = z - g * (z - a)
                fc = cost(c)[0]
            else:
                a, c, fc = c, d, fd
                d = a + g * (z - a)
                fd = cost(d)[0]
        return min((c, fc), (d, fd), key=lambda pv: pv[1])

    @staticmethod
    def _splice(points, p: float, coast, rejoin, dt: float):
        """Points of ``points`` before p, the coasting path, the rejoin point on the braking curve
        and the points after it (their times moved by dt)."""
        s, v, t, m = points
        r, v_r, t_r = rejoin
        head = s < p - 1e-9
        j_r = int(np.searchsorted(s, r, side="right"))
        mode_r = m[max(j_r - 1, 0)]
        return (
            np.concatenate([s[head], coast[0], [r], s[j_r:]]),
            np.concatenate([v[head], coast[1], [v_r], v[j_r:]]),
            np.concatenate([t[head], coast[2], [t_r], t[j_r:] + dt]),
            np.concatenate([m[head], coast[3], np.array([mode_r], dtype=np.int8), m[j_r:]]),
        )

    def _ceiling(self, vtop: np.ndarray):
        """Braking ceiling for the holding phases: service braking on the final approach to the stop
        (as the fastest run), regenerative braking only before lower limits where the train has it
        (the friction brakes would waste what the electric brake returns)."""
        tr = self.track
        modes = np.full(len(tr.a0), codes.BRAKE, dtype=np.int64)
        if self.has_regen:
            _, _, US_s = _kernel_c.braking_ceiling(
                tr.x, tr.a0, tr.a1, tr.b0, tr.b1, vtop, self.i0, self.i1, self.P, self.curves, self.bk
            )
            # the final approach: the intervals after the last one that reaches the limit plateau
            plateau = np.flatnonzero(US_s > 0.0)
            last = self.i0 + (int(plateau[-1]) if len(plateau) else -1)
            modes[self.i0 : last + 1] = codes.REGEN
            if self.regen_final_approach:
                modes[self.i0 : self.i1] = codes.REGEN
        Cr, _, US = _kernel_c.braking_ceiling_mixed(
            tr.x,
            tr.a0,
            tr.a1,
            tr.b0,
            tr.b1,
            vtop,
            self.i0,
            self.i1,
            self.P,
            self.curves,
            self.bk,
            self.rk,
            modes,
        )
        return Cr, US, modes

    def _holding(self, vhold, vtop, Cr, US, modes, start):
        tr = self.track
        out = [np.empty(self.n_max) for _ in range(3)] + [np.empty(self.n_max, dtype=np.int8)]
        n, status = pk.holding_segment(
            tr.x, tr.a0, tr.a1, tr.b0, tr.b1, vhold, vtop, tr.traction_scale, self.i0, self.i1,
            self.P, self.curves, self.tk, self.bk, self.rk, Cr, US, modes, *out, *start,
        )  # fmt: skip
        if status != 0:
            return None
        return tuple(a[:n] for a in out)

    def _stalled(self):
        """A run that cannot be driven (the train stalls): infinite time, so the holding speed
        search moves away from it."""
        s = np.array([self.s0, self.s1])
        return s, np.array([0.0, 1.0]), np.array([0.0, np.inf]), np.array([0, codes.DWELL], dtype=np.int8)

    def _steep_descents(self, V: float, vhold: np.ndarray, vtop: np.ndarray) -> np.ndarray:
        """Intervals where holding the local holding speed (V, or the limit where lower) would need
        braking: coasting speeds the train up there. On holding arcs at V the train must also be
        allowed faster than V; on a speed limit it holds the limit with braking on the descent, and
        coasting ahead of it saves that braking."""
        tr = self.track
        law = self.train.resistance_law
        weight = self.P[codes.P_WEIGHT]
        w = np.diff(tr.x)
        res_left = law(vhold) + weight * (tr.a0 + tr.b0 * vhold * vhold)
        res_right = law(vhold) + weight * (tr.a0 + tr.a1 * w + (tr.b0 + tr.b1 * w) * vhold * vhold)
        on_v = (vhold >= V - 1e-9) & (vtop > V + 1e-6)
        on_limit = vhold < V - 1e-9
        return (np.minimum(res_left, res_right) < 0.0) & (on_v | on_limit)

    def _next_descent(self, seg, steep_down, after: float, vhold: np.ndarray):
        """(a, end, hold speed) of the next steep descent ending beyond ``after``: a [m] is where
        the run without excursion is at its holding speed [m/s] on it (its start, or where the train
        reaches that speed on it); None if there is none."""
        tr = self.track
        idx = np.flatnonzero(steep_down[self.i0 : self.i1]) + self.i0
        if not len(idx):
            return None
        # a descent is split where its holding speed changes (a speed limit rises or falls on it):
        # each part has one speed to leave and to rejoin (a departure under a lower limit that
        # coasts on past the limit's end would rejoin that limit's speed, not the holding speed)
        breaks = np.flatnonzero((np.diff(idx) > 1) | (np.diff(vhold[idx]) != 0.0))
        starts = idx[np.concatenate([[0], breaks + 1])]
        ends = idx[np.concatenate([breaks, [len(idx) - 1]])] + 1
        s, v = seg[0], seg[1]
        for i, j in zip(starts, ends, strict=True):
            lo, hi = max(self._steep_from(i, float(vhold[i])), after), tr.x[j]
            if hi <= after + 1.0:
                continue
            k = min(int(np.searchsorted(tr.x, lo, side="right")) - 1, j - 1)
            v_hold = float(vhold[k])
            if np.interp(lo, s, v) >= v_hold * (1.0 - 1e-6):
                return float(lo), float(hi), v_hold
            at_v = np.flatnonzero((s > lo) & (s < hi) & (v >= v_hold * (1.0 - 1e-6)))
            if len(at_v):
                return float(s[at_v[0]]), float(hi), v_hold
        return None

    def _steep_from(self, i: int, v_hold: float) -> float:
        """Where holding v_hold [m/s] starts to need braking in interval i [m]: the grade varies
        linearly along an interval, so the descent begins where the resistance crosses zero, not at
        the interval's start (a start snapped to the grid moved the departure with the step)."""
        tr = self.track
        law = self.train.resistance_law
        weight = self.P[codes.P_WEIGHT]
        r0 = law(v_hold) + weight * (tr.a0[i] + tr.b0[i] * v_hold * v_hold)
        slope = weight * (tr.a1[i] + tr.b1[i] * v_hold * v_hold)
        if r0 < 0.0 or slope >= 0.0:
            return float(tr.x[i])
        return float(tr.x[i] + min(-r0 / slope, tr.x[i + 1] - tr.x[i]))

    @staticmethod
    def _back_at(seg, after: float, V: float) -> float:
        """First position [m] from ``after`` where ``seg`` holds V (or ``after`` if it never does)."""
        s, v, _, m = seg
        tol = 1e-6 * max(V, 1.0)
        # (positions along a run never decrease: only the points from ``after`` on are looked at,
        # not the whole run for each departure tried, issue 16)
        j0 = int(s.searchsorted(after - 1e-9, side="left"))
        holding: np.ndarray = np.empty(0, dtype=np.intp)
        for a, z in ((j0, j0 + 64), (j0 + 64, len(s))):  # (the hold starts near ``after`` mostly)
            s_, v_, m_ = s[a:z], v[a:z], m[a:z]
            holding = np.flatnonzero((s_ >= after - 1e-9) & (m_ == codes.CRUISE) & (np.abs(v_ - V) <= tol))
            if len(holding):
                holding = holding + a
                break
        if not len(holding):
            return after
        j = int(holding[0])
        # the hold may have started before this point: it then holds already at ``after``
        if j > 0 and m[j - 1] == codes.CRUISE and abs(v[j - 1] - V) <= tol and s[j - 1] <= after:
            return after
        return float(s[j])

    def _holding_cost(self, a: float, b: float, V: float) -> tuple[float, float]:
        """(electrical energy [J], time [s]) of holding V from a to b (traction for the resistance
        where it pulls back, regenerative braking where the line pushes)."""
        if b <= a + 1e-9:
            return 0.0, 0.0
        tr = self.track
        # (the grid points strictly between a and b, found by bisection on the sorted grid)
        inner = tr.x[int(tr.x.searchsorted(a, side="right")) : int(tr.x.searchsorted(b, side="left"))]
        s = np.concatenate([[a], inner, [b]])
        v = np.full(len(s), V)
        m = np.full(len(s), codes.CRUISE, dtype=np.int8)
        cum = np.empty(len(s))
        pk.path_energy(
            s, v, m, tr.x, tr.a0, tr.a1, tr.b0, tr.b1, tr.traction_scale, self.P, self.curves,
            self.inv_eta_t, self.eta_r, cum, self.tk, self.bk, self.rk,
        )  # fmt: skip
        return float(cum[-1]), (b - a) / V

    def _next_steep_start(self, steep_down: np.ndarray, after: float) -> float:
        """Start [m] of the first steep descent that begins after ``after`` (the section's end if none)."""
        tr = self.track
        idx = np.flatnonzero(steep_down[self.i0 : self.i1] & (tr.x[self.i0 : self.i1] >= after + 1.0))
        return float(tr.x[self.i0 + idx[0]]) if len(idx) else self.s1

    def _best_departure(
        self, seg, p_lo: float, a: float, W: float, V: float, mu: float, key, v_rejoin: float,
        horizon: float = np.inf,
    ):  # fmt: skip
        """``_search_departure``, remembered within a solve: a pure function of the run ``seg`` and
        of its parameters, so the same search repeated (the homotopy of ``_bridge`` rebuilds the
        departures ahead of the ones it moves: on CH_Fribourg_Bern with the FLIRT one search in
        eight) is looked up, with what it recorded in ``_decisions`` and ``_has_long_excursions``."""
        memo_key = (
            b"".join(np.ascontiguousarray(arr).tobytes() for arr in seg),
            p_lo, a, W, V, mu, key, v_rejoin, horizon, self.short_excursions, self._forced.get(key),
        )  # fmt: skip
        hit = self._departure_memo.get(memo_key)
        if hit is None:
            long_before = self._has_long_excursions
            self._has_long_excursions = False
            found = self._search_departure(seg, p_lo, a, W, V, mu, key, v_rejoin, horizon)
            hit = (found, self._decisions.get(key), self._has_long_excursions)
            self._has_long_excursions |= long_before
            self._departure_memo[memo_key] = hit
        else:
            found, decision, long_excursion = hit
            if decision is not None:
                self._decisions[key] = decision
            self._has_long_excursions |= long_excursion
        return found

    def _search_departure(
        self, seg, p_lo: float, a: float, W: float, V: float, mu: float, key, v_rejoin: float,
        horizon: float = np.inf,
    ):  # fmt: skip
        """The coasting excursion ahead of a steep descent that starts at a: (p, points, rejoin
        state) with the departure point p in [p_lo, a] that minimises energy + mu x time against
        the run without it, or None when no excursion is cheaper.

        Cost minimisation rather than shooting on the adjoint's residual: on hilly lines the
        residual has several roots and the excursion may start in the traction phase, before the
        train has reached V."""
        tr = self.track
        cum = np.empty(len(seg[0]))
        pk.path_energy(
            seg[0], seg[1], seg[3], tr.x, tr.a0, tr.a1, tr.b0, tr.b1, tr.traction_scale, self.P, self.curves,
            self.inv_eta_t, self.eta_r, cum, self.tk, self.bk, self.rk,
        )  # fmt: skip
        out = [np.empty(self.n_max) for _ in range(3)] + [np.empty(self.n_max, dtype=np.int8)]
        # the switching condition of each departure tried, and where its rejoin point q lies against
        # the point where the run without it holds again (``_departure_root``)
        residuals: dict[float, float] = {}
        corners: dict[float, float] = {}

        def cost(p: float, keep: bool = False):
            state_p = self._state_at(seg, p)
            i, u, vp, tp, _ = state_p
            n, status, residual, iq, uq, tq, e_path = pk.coast_excursion(
                tr.x, tr.a0, tr.a1, tr.b0, tr.b1, tr.vlim, W, tr.traction_scale, i, u, vp, tp, self.i1,
                self.P, self.curves, self.bk, V, v_rejoin, mu, self.inv_eta_t, self.eta_r, ADJOINT_STEP_M,
                *out, self.Cr, self.US,
            )  # fmt: skip
            if status != 0 or n >= self.n_max - 8:
                return np.inf, None
            residuals[p] = residual
            q = tr.x[iq] + uq
            # compare where both runs hold again: the run without the excursion may still be
            # coasting down from above V at q; the excursion then holds V up to where it is back
            back = self._back_at(seg, q, v_rejoin)
            k_q, k_b = self._interval_of(q), self._interval_of(max(q, back))
            if np.any(np.abs(np.minimum(tr.vlim[k_q : k_b + 1], V) - v_rejoin) > 1e-9 * v_rejoin):
                # the excursion would rejoin (and hold up to where both runs hold again) a speed
                # that is not the holding speed there: back up to a lower limit only after the
                # limit has risen, or holding it up to a later limit of the same speed; the costs
                # compared would not be those of the run spliced (issue 16, CH_Fribourg_Bern)
                return np.inf, None
            corners[p] = back - q
            q_both = max(q, back)
            if q_both > horizon and self.short_excursions:
                return np.inf, None
            state_q = self._state_at(seg, q_both)
            t_a = state_q[3]
            e_hold, t_hold = self._holding_cost(q, q_both, v_rejoin)
            dj = (
                e_path + e_hold
                - (self._energy_to(seg, cum, q_both, state_q) - self._energy_to(seg, cum, p, state_p))
                + mu * (tq + t_hold - t_a)
            )  # fmt: skip
            if not keep:
                return dj, None
            self._has_long_excursions |= q_both > horizon
            return dj, (tuple(arr[:n].copy() for arr in out), (iq, uq, v_rejoin, tq))

        lo = min(p_lo + 1.0, a)
        forced = self._forced.get(key)
        if forced is not None:
            p = min(max(forced, lo), a)
            self._decisions[key] = (p, lo, a)
            dj, found = cost(p, keep=True) if p < a - 1e-6 else (np.inf, None)
            return None if found is None else (p, found[0], found[1])
        # no warm start here: on hilly lines the best departure ahead of a descent jumps between
        # distant local optima as V moves, and a window around the last one would miss them
        p, dj = self._minimise(cost, lo, a) if a - lo > 1.0 else (a, cost(a)[0])
        # from a speed-limit arc the excursion must be back up to the limit before the descent
        # ends: only departures within a few hundred metres of a do (CH_Fribourg_Bern, KISS at +5 %,
        # 9680-9926 m, between two points of the scan: the train held 110 km/h braking downhill)
        p, dj = self._near_end(cost, lo, a, p, dj)
        if np.isfinite(dj) and lo < p < a:
            # (the cost's scale: the energy of the run without the excursion and mu x its time)
            scale = abs(float(cum[-1])) + mu * float(seg[2][-1])
            p, dj = self._departure_root(cost, (residuals, corners), p, dj, lo, a, scale)
        self._decisions[key] = (a, lo, a)
        if not np.isfinite(dj) or dj >= 0.0:
            return None
        dj, found = cost(p, keep=True)
        if found is None or dj >= 0.0:
            return None
        self._decisions[key] = (p, lo, a)
        return p, found[0], found[1]

    @staticmethod
    def _departure_root(
        cost,
        conditions: tuple[dict[float, float], ...],
        p: float,
        dj: float,
        lo: float,
        hi: float,
        scale: float,
    ) -> tuple[float, float]:
        """(p, cost) of the departure point refined from the cost's minimum ``p`` to the root of
        the first of ``conditions`` that changes sign near p, rising through zero, located by brentq
        to DEPARTURE_ROOT_TOLERANCE_M in a bracket grown from p within [lo, hi]. Each condition is
        filled by ``cost`` (position [m] -> value): the switching condition (``pk.coast_excursion``'s
        residual, zero where d(cost)/dp = 0), then the corner where the excursion's rejoin point
        passes the point where the run without it holds again (the cost has a kink there, and its
        minimum may be that kink: the heavy-haul example's second section).

        The cost is flat at a smooth minimum, so its golden-section minimum moved by up to 1 m with
        the step (its discretisation error tilts it); the conditions cross zero with a finite slope
        and their roots do not move. Golden section's point is kept (the fallback) where no
        condition has a sign change near it, or where the root costs more than it by over
        DEPARTURE_ROOT_COST_SLACK x ``scale`` [J] (the magnitude of the whole run's cost): the
        condition then belongs to another arc structure than the minimum's."""
        for values in conditions:
            found = SectionSolver._root_of(cost, values, p, lo, hi)
            if found is None:
                continue
            value = cost(found)[0]
            if np.isfinite(value) and value <= dj + DEPARTURE_ROOT_COST_SLACK * scale:
                return found, value
        return p, dj

    @staticmethod
    def _root_of(cost, values: dict[float, float], p: float, lo: float, hi: float) -> float | None:
        """The root [m] near p of a condition that ``cost`` records in ``values``, rising through
        zero; None without a sign change within DEPARTURE_ROOT_WINDOW_M of p."""

        def residual(x: float) -> float:
            if x not in values:
                cost(x)
            return values.get(x, np.nan)

        if not np.isfinite(residual(p)):
            return None
        width = DEPARTURE_ROOT_START_M
        while width <= DEPARTURE_ROOT_WINDOW_M:
            a, z = max(p - width, lo), min(p + width, hi)
            r_a, r_z = residual(a), residual(z)
            if not (np.isfinite(r_a) and np.isfinite(r_z)):
                return None
            if r_a < 0.0 < r_z:
                return float(
                    brentq(residual, a, z, xtol=DEPARTURE_ROOT_TOLERANCE_M, rtol=4 * np.finfo(float).eps)
                )
            if r_a * r_z <= 0.0:
                return None  # falling through zero (a maximum of the cost), or zero on a stretch
            width *= 2.0
        return None

    def _fastest_points(self):
        tr = self.track
        out_s = np.empty(self.n_max)
        out_v = np.empty(self.n_max)
        out_t = np.empty(self.n_max)
        out_m = np.empty(self.n_max, dtype=np.int8)
        n, status, _ = _kernel_c.fastest_segment(
            tr.x, tr.a0, tr.a1, tr.b0, tr.b1, tr.vlim, tr.traction_scale, self.i0, self.i1, 0.0,
            self.P, self.curves, self.tk, self.bk, out_s, out_v, out_t, out_m, 0,
        )  # fmt: skip
        if status != codes.STATUS_OK:
            return out_s[:n], np.append(out_v[: n - 1], 1.0), np.append(out_t[: n - 1], np.inf), out_m[:n]
        return out_s[:n], out_v[:n], out_t[:n], out_m[:n]

    def _state_at(self, phase_a, s_c: float) -> tuple[int, float, float, float, int]:
        """(interval, offset, speed, time, index of the last phase-A point before) at s_c."""
        s, v, t, m = phase_a
        tr = self.track
        i, u, vc, tc, j = pk.state_at(
            s, v, t, m, tr.x, tr.a0, tr.a1, tr.b0, tr.b1, tr.traction_scale, self.i1, self.P,
            self.curves, self.tk, self.bk, float(s_c), self.rk,
        )  # fmt: skip
        return int(i), float(u), float(vc), float(tc), int(j)

    def _phase_b_forced(self, phase_a, s_c: float):
        """From s_c on phase A, maximum regenerative braking until the service braking curve to the
        stop (source 004's recuperative braking)."""
        points, status, _ = self._phase_b(phase_a, s_c, 0.0, force_mode=codes.REGEN)
        return points, status

    def _braking_arc_start(self, phase_a, j: int, s_c: float, v: float, v_hold: float) -> bool:
        """Whether a final phase from s_c starts on an arc of phase A held above the holding speed
        by braking, and starts there from the braking side (the variant ``braking_arc_exits``)."""
        if not self.braking_arc_exits:
            return False
        s, _, _, m = phase_a
        return bool(m[j] == codes.CRUISE and v > v_hold * (1.0 + 1e-6) and s[min(j + 1, len(s) - 1)] > s_c)

    def _phase_b(
        self,
        phase_a,
        s_c: float,
        mu: float,
        force_mode: int = -1,
        v_hold: float = np.inf,
        phi_start: float | None = None,
    ):
        tr = self.track
        i, u, v, t, j = self._state_at(phase_a, s_c)
        if u >= tr.x[i + 1] - tr.x[i] - 1e-12 and i + 1 < self.i1:
            i, u = i + 1, 0.0
        out_s = np.empty(self.n_max)
        out_v = np.empty(self.n_max)
        out_t = np.empty(self.n_max)
        out_m = np.empty(self.n_max, dtype=np.int8)
        given_phi = phi_start
        phi_start = -1.0 if given_phi is None else given_phi
        # the final phase meets the service braking curve to the stop (following the regenerative
        # one instead, ``self.Cr_regen``, cost 1.6 % on test_coasts_ahead_of_a_lower_limit) and,
        # with regeneration, the regenerative curves to lower limits (KISS on CN_Songjiazhuang_Yizhuang
        # 3906-6272 m at +5 %: 0.92 kWh, the difference the service brake's blend spent in friction)
        Cr, US, curve_modes = self.Cr_final, self.US_final, self.final_curve_modes
        if given_phi is None and self._braking_arc_start(phase_a, j, s_c, v, v_hold):
            # on an arc held above V by braking (a steep descent) the adjoint sits at eta_r (a
            # regenerative holding arc; at 0 without regeneration), not at 1/eta_t: the train
            # leaves it braking
            phi_start = self.eta_r * (1.0 - 1e-9) if self.has_regen else -1e-9
        W = -1.0
        if self.has_regen and force_mode < 0 and mu > 0.0:
            W = self._regenerative_holding_speed(mu)

        def run(w_end: float):
            return pk.final_phase_modes(
                tr.x, tr.a0, tr.a1, tr.b0, tr.b1, tr.vlim, tr.traction_scale, i, u, v, t, self.i1,
                self.P, self.curves, self.tk, self.bk, Cr, US, mu, self.inv_eta_t, self.eta_r,
                self.has_regen, ADJOINT_STEP_M, out_s, out_v, out_t, out_m, 0, force_mode, v_hold, phi_start,
                curve_modes, self.rk, W, w_end,
            )  # fmt: skip

        n, status, s_event, arc_start, arc_end = run(np.inf)
        if status == pk.STOPPED_SHORT and 0.0 <= arc_start < arc_end and n < self.n_max:
            # held at W with regenerative braking to the descent's end the train stops short: it
            # leaves the arc where it then stops exactly at the stop
            w_end = self._regen_arc_end(run, arc_start, arc_end)
            if w_end is not None:
                n, status, s_event, _, _ = run(w_end)
        if n >= self.n_max:
            status = pk.STOPPED_SHORT  # the buffers filled up: an unusable attempt
        s, vv, tt, m = phase_a
        keep = slice(0, j + 1)
        return (
            (
                np.concatenate([s[keep], out_s[:n]]),
                np.concatenate([vv[keep], out_v[:n]]),
                np.concatenate([tt[keep], out_t[:n]]),
                np.concatenate([m[keep], out_m[:n]]),
            ),
            status,
            s_event,
        )

    @staticmethod
    def _jump_of(shorts: list[tuple[float, float]]) -> float | None:
        """Where the shortfall of runs that stop short falls to pk.REST_AT_STOP_M [m], from the last
        (coasting point, residual) pairs of such runs: inverse quadratic interpolation through three
        (the shortfall curves a little: a secant line overshot the jump on every step, issue 16),
        the secant line through two; None from one, or from residuals not distinct."""
        target = -pk.REST_AT_STOP_M
        if len(shorts) >= 3:
            (s0, r0), (s1, r1), (s2, r2) = shorts[-3:]
            if r0 != r1 and r1 != r2 and r0 != r2:
                return (
                    s0 * (target - r1) * (target - r2) / ((r0 - r1) * (r0 - r2))
                    + s1 * (target - r0) * (target - r2) / ((r1 - r0) * (r1 - r2))
                    + s2 * (target - r0) * (target - r1) / ((r2 - r0) * (r2 - r1))
                )
        if len(shorts) >= 2:
            (s0, r0), (s1, r1) = shorts[-2:]
            if r0 != r1:
                return s1 + (target - r1) * (s1 - s0) / (r1 - r0)
        return None

    def _regen_arc_end(self, run, lo: float, hi: float) -> float | None:
        """Where the final phase's regenerative holding arc (from ``lo``; held to ``hi``, the
        descent's end, the run stops short) ends so that the run stops at the stop: left at once it
        meets the braking curve to the stop, left later it stops sooner. Located as the final
        coasting point is (bisection to COAST_POINT_TOLERANCE_M, or a run that comes to rest within
        STOP_TOLERANCE_M of the stop); None if leaving at once stops short as well."""
        n, status, s_event, _, _ = run(lo)
        if status != pk.HIT_CEILING or n >= self.n_max:
            return None
        short: list[tuple[float, float]] = []  # (arc end, where the run came to rest) of short runs
        bisect = True
        while hi - lo > COAST_POINT_TOLERANCE_M:
            mid = 0.5 * (lo + hi)
            if not bisect and len(short) >= 2 and short[-1][1] != short[-2][1]:
                # where a short run comes to rest moves continuously with the arc's end: a secant
                # step on those runs every other step (aimed just inside the stop tolerance)
                (w0, e0), (w1, e1) = short[-2], short[-1]
                guess = w1 + (self.s1 - 0.25 * STOP_TOLERANCE_M - e1) * (w1 - w0) / (e1 - e0)
                if lo < guess < hi:
                    mid = guess
            bisect = not bisect
            n, status, s_event, _, _ = run(mid)
            if status == pk.HIT_CEILING and n < self.n_max:
                lo = mid
            else:
                if self.s1 - s_event <= STOP_TOLERANCE_M:
                    return mid
                hi = mid
                short.append((mid, s_event))
        return lo

    def _leave_at_floor(self, residual, floor: float, coasting):
        """The final phase from the last binding timing point (``floor``) when coasting from there
        still meets the braking curve ahead of the stop: the adjoint there is not 1/eta_t (the
        train was not holding under the new price of time) but lies between the braking threshold
        (eta_r, or 0 without regeneration) and 1/eta_t; the value with which the run stops exactly
        at the stop, by bisection (the run brakes sooner the lower it starts)."""
        lo = self.eta_r * (1.0 - 1e-9) if self.has_regen else 0.0
        hi = self.inv_eta_t * (1.0 - 1e-9)
        r_lo, points = residual(floor, lo)
        if r_lo >= 0.0:
            return points  # braking from the point on, the train still meets the braking curve
        best = coasting
        for _ in range(80):
            if hi - lo <= 1e-13 * hi:
                break
            mid = 0.5 * (lo + hi)
            r_mid, points = residual(floor, mid)
            if r_mid >= 0.0:
                hi, best = mid, points
            else:
                if self.s1 - (self.s1 + r_mid) <= STOP_TOLERANCE_M:
                    return points
                lo = mid
        return best

    def _coast_point_guess(self, holding_speed_mps: float) -> float | None:
        """Where the final coast of holding speed V probably starts: from the plans of this solve
        with the closest holding speeds (this variant's if it has any), interpolated between the
        two closest or extrapolated no farther than they are apart, else the closest one's."""
        variant = (self.excursions, self.limit_coasting, self.short_excursions, self.braking_arc_exits)
        points = [(v, c) for k, v, c in self._coast_points if k == variant]
        if not points and not self.braking_arc_exits:
            # (that variant searches from the stop: its coast may start on a braking arc that the
            # others' coasts passed over)
            points = [(v, c) for _, v, c in self._coast_points]
        if not points:
            return None
        points.sort(key=lambda vc: abs(vc[0] - holding_speed_mps))
        v0, c0 = points[0]
        if len(points) == 1 or abs(points[1][0] - v0) < 1e-9:
            return c0
        v1, c1 = points[1]
        if abs(holding_speed_mps - v0) > abs(v1 - v0):
            return c0
        guess = c0 + (c1 - c0) * (holding_speed_mps - v0) / (v1 - v0)
        return float(guess) if self.s0 < guess < self.s1 else c0

    def plan(self, holding_speed_mps: float) -> SectionPlan:
        """The optimal run for holding speed V: the coasting point found by bisection so that the
        train stops exactly at the next station."""
        mu = price_of_time_w(self.train, holding_speed_mps)
        phase_a = self._phase_a(holding_speed_mps)

        # The last coasting point from which the train still reaches the stop: on a hilly line the
        # outcome is not monotone in the coasting point, and the optimum leaves the holding arc as
        # late as possible, so search backwards from the stop for a bracket first.
        def residual(s_c: float, phi: float | None = None):
            points, status, s_event = self._phase_b(phase_a, s_c, mu, v_hold=holding_speed_mps, phi_start=phi)
            # < 0: stops short of the station by that much; >= 0: meets the braking curve to it
            return (self.s1 - s_event if status == pk.HIT_CEILING else s_event - self.s1), points

        step = max(50.0, (self.s1 - self.s0) / 200.0)
        # the final coast starts after the last binding timing point: before it the stretches hold
        # their own speeds (the final phase is driven by one price of time)
        floor = self.stretches[-1][0] if self.stretches else self.s0
        guess = self._coast_point_guess(holding_speed_mps)
        below = None  # a coasting point after which the run stops short, with its residual
        if guess is not None and floor < guess < self.s1:
            # warm start: the outer solve moves V a little at a time and the coasting point with
            # it, so the bracket grows outwards from the previous one (on hilly lines the outcome
            # jumps at several coasting points: a bracket grown from the guess alone, issue 16, found
            # others than this one and moved a line's split of its supplement by 6 s)
            width = WARM_COAST_STEP_M
            while True:
                hi = min(guess + width, self.s1)
                r_hi, best = residual(hi)
                if r_hi >= 0.0 or hi >= self.s1:
                    break
                below = (hi, r_hi)
                width *= 2.0
            step = 2.0 * WARM_COAST_STEP_M
        else:
            hi = self.s1
            _, best = residual(hi)
        if below is not None:
            lo, r_lo = below
        else:
            while True:
                lo = max(hi - step, floor)
                r_lo, points = residual(lo)
                if r_lo < 0.0:
                    break
                if lo <= floor:
                    # even coasting from the floor the train meets the braking curve: leave there
                    hi, best = lo, points
                    if self.stretches:
                        best = self._leave_at_floor(residual, floor, points)
                    break
                hi, best = lo, points
                step *= 1.5
        # the outcome jumps at the boundary (beyond it the train meets the service braking curve
        # some metres before the stop), so the bracket is kept by bisection
        lo_points = None
        shorts = [(lo, r_lo)]  # the short runs of the bracket's lower end, latest last (residual < 0)
        margin = JUMP_MARGIN  # the prediction is aimed this fraction of the way short of the jump
        queued: list[float] = []  # the run just beyond the predicted jump, tried next
        # on until the train comes to rest at the stop itself, or the bracket closes on the point
        # where the outcome jumps (the run then meets the braking curve there): a coasting point
        # left a metre early (a tolerance) moved with the step and its energy with it
        while r_lo < -STOP_TOLERANCE_M and hi - lo > COAST_POINT_TOLERANCE_M:
            mid = 0.5 * (lo + hi)
            queued = [q for q in queued if lo < q < hi]
            aimed = False
            jump = self._jump_of(shorts)
            if queued:
                mid = queued.pop(0)
            elif jump is not None and lo < jump < hi + COAST_POINT_TOLERANCE_M:
                # where a run stops short moves on smoothly with the coasting point (the residual
                # of a run that arrives does not): interpolating the last short runs predicts the
                # jump, where the shortfall falls to the kernel's REST_AT_STOP_M (the run then
                # counts as arriving; no run stops closer, so the search ends on that jump). Aimed
                # a little short of it, the next run stays short and the next prediction is
                # closer; within COAST_POINT_TOLERANCE_M two runs either side close the bracket.
                eps = JUMP_AIM_FRACTION * COAST_POINT_TOLERANCE_M
                close = jump - lo < JUMP_CLOSE_M and margin <= JUMP_MARGIN
                aim = jump - (eps if close else max(margin * (jump - lo), eps))
                if aim - lo < eps:
                    aim = jump + eps  # (the jump lies within eps of lo)
                else:
                    queued = [jump + eps] if close or jump - lo < 1e3 * COAST_POINT_TOLERANCE_M else []
                if lo < aim < hi:
                    mid, aimed = aim, True
            r_mid, points = residual(mid)
            if r_mid >= 0.0:
                hi, best = mid, points
                if aimed and not queued:
                    # the prediction overshot: aim farther short of it from now on
                    margin = min(0.5, 10.0 * margin)
            else:
                lo, r_lo, lo_points = mid, r_mid, points
                shorts = [*shorts[-2:], (lo, r_lo)]
        coast_point = hi
        # whether the final phase replaces an arc phase A holds above V by braking
        s_a, v_a, _, m_a = phase_a
        self._final_phase_on_braking_arc = bool(
            np.any(
                (m_a[:-1] == codes.CRUISE) & (v_a[:-1] > holding_speed_mps * (1.0 + 1e-6)) & (s_a[:-1] > lo)
            )
        )
        if -STOP_TOLERANCE_M <= r_lo < 0.0:
            coast_point = lo
            best = lo_points if lo_points is not None else residual(lo)[1]
        if not self._forced:  # runs with imposed departures are no guide to the next V's
            variant = (self.excursions, self.limit_coasting, self.short_excursions, self.braking_arc_exits)
            self._coast_points = [*self._coast_points[-11:], (variant, holding_speed_mps, coast_point)]
        crest = [d[0] for k, d in self._decisions.items() if k[0] == "crest" and d[0] < d[2]]
        if crest and self._path_cost(phase_a, mu) < self._path_cost(best, mu):
            # phase A coasts over the crest and brakes electrically to the stop: a final phase
            # started on its holding arc just before the departure coasts over the crest as well,
            # misses the regenerative holding arc and meets the service curve (metro hump at +14 %:
            # 13.10 kWh against phase A's 7.535, reference 7.537), so the run without a final phase is kept then
            best, coast_point = phase_a, float(crest[0])
        s, v, t, m = best
        # the stop point closes the section
        s, m = s.copy(), m.copy()
        s[-1] = self.s1
        m[-1] = codes.DWELL
        return SectionPlan(
            s, v, t, m, float(t[-1]), holding_speed_mps, coast_point, mu, self.fastest_time_s, True
        )

    def solve(self, running_time_s: float) -> SectionPlan:
        """The least-energy run that takes ``running_time_s``; the fastest run (``feasible`` False)
        when that is shorter than the fastest possible.

        Runs are built with the departures ahead of steep descents and lower limits, and, where the
        section has any, also without them; where the run coasts through several descents, also
        with excursions that end before the next descent; where its final coast replaces an arc
        held by regenerative braking, also with a final phase that leaves such arcs at eta_r. The
        one that needs least energy at the
        scheduled time among those that keep the schedule is kept. Each departure minimises the
        cost locally, and on lines where descents, lower limits and the final approach interact the
        local choices can lose to plain holding. The two mixed variants are tried only when none
        keeps the schedule."""
        self._has_descents = False
        self._has_limit_braking = False
        self._coast_points = []
        self._time_slope = None
        self._departure_memo = {}
        built: list[tuple[tuple[bool, ...], SectionPlan]] = []

        def build(
            excursions: bool,
            limit_coasting: bool,
            short: bool = False,
            first: bool = False,
            arcs: bool = False,
        ) -> None:
            guess = None if first else built[0][1].holding_speed_mps
            plan = self._solve_variant(
                running_time_s, excursions, limit_coasting, guess, short=short, braking_arc_exits=arcs
            )
            built.append(((excursions, limit_coasting, short, arcs), plan))

        build(True, True, first=True)
        first = built[0][1]

        # whether the last run built (in most cases the one returned) left any arc early: if not,
        # the run without departures is the same run
        def departed() -> bool:
            return any(p < latest - 1e-9 for p, _, latest in self._decisions.values())

        plain_differs = departed()
        long_excursions = self._has_long_excursions
        if first.feasible and self.has_regen and self._final_phase_on_braking_arc:
            # the final coast replaces an arc held by regenerative braking: leaving it the adjoint
            # starts at eta_r, and from 1/eta_t a heavy train's adjoint may not come down to eta_r
            # before the stop at all (it then coasts far too fast into the braking curve)
            build(True, True, arcs=True)
        if first.feasible and long_excursions:
            # the last run built coasts through several descents; it was compared with a run that
            # has none of their own departures, which favours it: also build the runs whose
            # excursions end before the next descent (without any, they are the plain runs)
            build(True, True, short=True)
            plain_differs = departed()
        if (
            first.feasible
            and (self._has_descents or self._has_limit_braking)
            and (plain_differs or not self._meets(first, running_time_s))
        ):
            build(False, False)
            if not any(self._meets(p, running_time_s) for _, p in built):
                if self._has_limit_braking:
                    build(False, True)
                if self._has_descents and self._has_limit_braking:
                    build(True, False)
        meeting = [(k, p) for k, p in built if self._meets(p, running_time_s)]
        if len(meeting) == 1:
            best = meeting[0][1]  # (nothing to compare: its energy is not computed, issue 16)
        elif meeting:
            # compared at the scheduled time (dE/dT = -mu): the variants after the first stop within
            # VARIANT_TIME_TOLERANCE_S of it
            _, best = min(
                meeting,
                key=lambda kp: (
                    self.energy_j(kp[1]) + kp[1].price_of_time_w * (kp[1].running_time_s - running_time_s)
                ),
            )
        else:
            best = min((p for _, p in built), key=lambda p: abs(p.running_time_s - running_time_s))
        if meeting and best.feasible and abs(best.running_time_s - running_time_s) > TIME_TOLERANCE_S:
            # a variant compared within VARIANT_TIME_TOLERANCE_S won: meet the time with it exactly
            key = next(k for k, p in meeting if p is best)
            exact = self._solve_variant(
                running_time_s, key[0], key[1], best.holding_speed_mps, short=key[2], braking_arc_exits=key[3],
                exact=True,
            )  # fmt: skip
            if abs(exact.running_time_s - running_time_s) < abs(best.running_time_s - running_time_s):
                best = exact
        self.excursions = self.limit_coasting = True
        self.short_excursions = self.braking_arc_exits = False
        return best

    def _solve_variant(
        self,
        running_time_s: float,
        excursions: bool,
        limit_coasting: bool,
        guess_mps: float | None = None,
        short: bool = False,
        braking_arc_exits: bool = False,
        exact: bool = False,
    ) -> SectionPlan:
        """The run with or without departures ahead of descents and lower limits (with ``short``,
        excursions that end before the next descent only), starting from the holding speed
        ``guess_mps`` and the coasting points of the variants built before in this solve, never
        from an earlier solve (results do not depend on history). A variant started from another's
        holding speed is built to compare with it and meets the time to VARIANT_TIME_TOLERANCE_S."""
        self.excursions, self.limit_coasting, self.short_excursions = excursions, limit_coasting, short
        self.braking_arc_exits = braking_arc_exits
        self._departure_points = {}
        self._last_departure_speed = None
        self._last_holding_speed = guess_mps if guess_mps is not None and np.isfinite(guess_mps) else None
        self._secondary = self._last_holding_speed is not None and not exact
        try:
            return self._solve_once(running_time_s)
        finally:
            self._secondary = False

    @staticmethod
    def _meets(plan: SectionPlan, running_time_s: float) -> bool:
        """Whether a plan keeps the schedule: within max(0.5 s, 0.05 %), or is the fastest run of an
        infeasible schedule."""
        if not plan.feasible:
            return True
        return abs(plan.running_time_s - running_time_s) <= max(0.5, 5e-4 * running_time_s)

    def energy_j(self, plan: SectionPlan) -> float:
        """Net electrical energy of a plan without auxiliaries [J] (what the strategy minimises)."""
        import dataclasses

        from trainsim.model.route import Station
        from trainsim.sim.profile import line_resistance_profile, speed_ceiling
        from trainsim.sim.result import build_result

        route = dataclasses.replace(self.route, stations=(Station("a", self.s0), Station("b", self.s1)))
        res = build_result(
            train=self.train, route=route, settings=RunSettings(), profile=line_resistance_profile(route, self.train),
            ceiling=speed_ceiling(route, self.train), s=plan.s, v=plan.v, t=plan.t, regime=plan.regime, status="ok",
        )  # fmt: skip
        return (res.energy_kwh.net - res.energy_kwh.auxiliary) * KWH

    def _solve_once(self, running_time_s: float) -> SectionPlan:
        # (with fixed stretches the fastest run is not a plan of this solver: the search below
        # ends at the fastest plan that keeps them)
        if running_time_s <= self.fastest_time_s + TIME_TOLERANCE_S and not self.stretches:
            s, v, t, m = self.fastest
            m = m.copy()
            m[-1] = codes.DWELL
            return SectionPlan(
                s, v, t, m, self.fastest_time_s, np.inf, self.s1, np.inf, self.fastest_time_s,
                running_time_s >= self.fastest_time_s - TIME_TOLERANCE_S,
            )  # fmt: skip
        vmax = float(self.track.vlim.max())

        on_time: list[SectionPlan] = []  # plans that keep the schedule, if not to TIME_TOLERANCE_S

        secondary = self._secondary
        seen: dict[float, float] = {}
        seen_decisions: dict[float, dict] = {}
        seen_plans: dict[float, SectionPlan] = {}

        def excess(log_v: float) -> float:
            # the same holding speed twice gives the same answer (plans warm-start from the last
            # one, so a second evaluation could land on the other side of a jump)
            if log_v in seen:
                return seen[log_v]
            plan = self.plan(float(np.exp(log_v)))
            error = plan.running_time_s - running_time_s
            if abs(error) <= (VARIANT_TIME_TOLERANCE_S if secondary else TIME_TOLERANCE_S):
                raise _ConvergedError(plan)
            if self._meets(plan, running_time_s):
                on_time.append(plan)
            seen[log_v] = error
            seen_decisions[log_v] = dict(self._decisions)
            seen_plans[log_v] = plan
            slow = [k for k in seen if seen[k] > 0.0]
            fast = [k for k in seen if seen[k] < 0.0]
            if slow and fast:
                # a step of the running time far above what the slope over the whole bracket
                # predicts over a very narrow bracket is a jump: bridged below
                width = min(fast) - max(slow)
                step = seen[max(slow)] - seen[min(fast)]
                slope = (seen[min(slow)] - seen[max(fast)]) / (max(fast) - min(slow))
                if width < JUMP_LOG_SPEED and step > JUMP_FACTOR * slope * width + 2.0 * TIME_TOLERANCE_S:
                    raise _JumpError
            return error

        try:
            lo, hi = self._bracket(excess, running_time_s, vmax)
            if self._time_slope is None and hi > lo:
                self._time_slope = (seen[hi] - seen[lo]) / (hi - lo)
            # smooth cases converge in well under HOLDING_SPEED_ITERATIONS; more means the running
            # time is ragged or jumps in V, which the fallbacks below handle better than more steps
            # (xtol far below what moves the time by TIME_TOLERANCE_S: the time is what ends the search)
            log_v = brentq(
                excess, lo, hi, xtol=1e-14, rtol=4 * np.finfo(float).eps, maxiter=HOLDING_SPEED_ITERATIONS
            )
        except _ConvergedError as done:
            self._last_holding_speed = done.plan.holding_speed_mps
            return done.plan
        except RuntimeError:  # a jump, or not converged in HOLDING_SPEED_ITERATIONS
            log_v = min(seen, key=lambda k: abs(seen[k]))
            if abs(seen[log_v]) <= JUMP_TIME_TOLERANCE_S:
                self._last_holding_speed = seen_plans[log_v].holding_speed_mps
                return seen_plans[log_v]
        # the running time jumps between the two closest holding speeds on either side of the
        # schedule when the departures chosen there differ: move them together at the faster speed
        speeds = sorted(seen)
        pairs = [(a, b) for a, b in pairwise(speeds) if seen[a] > 0.0 > seen[b]]
        if pairs:
            slow_v, fast_v = min(pairs, key=lambda ab: ab[1] - ab[0])
            bridged = self._bridge(
                float(np.exp(fast_v)), seen_decisions[slow_v], seen_decisions[fast_v], running_time_s
            )
            if bridged is not None:
                return bridged
            candidates = [seen_plans[slow_v], seen_plans[fast_v]]
        else:
            # the closest plan on either side
            candidates = []
            decisions = []
            for f in (1.0 - 1e-9, 1.0, 1.0 + 1e-9):
                candidates.append(self.plan(float(np.exp(log_v * f))))
                decisions.append(dict(self._decisions))
            slow = [k for k, p in enumerate(candidates) if p.running_time_s > running_time_s]
            fast = [k for k, p in enumerate(candidates) if p.running_time_s < running_time_s]
            if slow and fast:
                bridged = self._bridge(
                    float(np.exp(log_v)), decisions[slow[-1]], decisions[fast[0]], running_time_s
                )
                if bridged is not None:
                    return bridged
        slow = [p for p in candidates if p.running_time_s > running_time_s]
        if slow:
            bridged = self._hold_longer(min(slow, key=lambda p: p.running_time_s), running_time_s)
            if bridged is not None:
                candidates.append(bridged)
        on_time += [p for p in candidates if self._meets(p, running_time_s)]
        if not on_time:
            # the running time is ragged in V here (long adjoint-driven phases on hilly lines are
            # sensitive to it): look around the crossing for holding speeds that keep the schedule
            for tried, f in enumerate(sorted(np.linspace(-0.01, 0.01, 21), key=abs), start=1):
                plan = self.plan(float(np.exp(log_v + f)))
                if self._meets(plan, running_time_s):
                    on_time.append(plan)
                if len(on_time) >= RAGGED_SAMPLES or (on_time and tried >= 3 * RAGGED_SAMPLES):
                    break
        if on_time:
            return min(on_time, key=self.energy_j)
        return min(candidates, key=lambda p: abs(p.running_time_s - running_time_s))

    def _bracket(self, excess, running_time_s: float, vmax: float) -> tuple[float, float]:
        """(log V) bracket of the holding speed that meets the time, grown geometrically from a
        guess: the average speed the schedule needs, a little higher (the train also accelerates
        and brakes), or the holding speed another variant of this solve found."""
        length = self.s1 - self.s0
        guess = self._last_holding_speed or 1.1 * length / running_time_s
        log_lo = log_hi = float(np.log(guess))
        e_lo = e_hi = excess(log_lo)
        # from another variant's holding speed the answer is near: a first step from the slope of
        # the running time in log V that variant saw, a little long so that it brackets
        factor = np.log(1.25)
        if self._last_holding_speed is not None:
            factor = np.log(1.03)
            if self._time_slope is not None and self._time_slope < 0.0:
                factor = float(np.clip(-1.2 * abs(e_lo) / self._time_slope, np.log(1.01), np.log(1.25)))
        while e_hi > 0.0:  # too slow: a higher holding speed
            log_lo, e_lo = log_hi, e_hi
            log_hi += factor
            if log_hi > np.log(vmax * 1000.0):
                # holding speeds far above every limit are the fastest run with its coasting
                raise _ConvergedError(self.plan(float(np.exp(log_lo))))
            e_hi = excess(log_hi)
            factor = self._bracket_step(log_lo, e_lo, log_hi, e_hi, 1.5 * factor)
        while e_lo < 0.0:  # too fast: a lower one
            log_hi, e_hi = log_lo, e_lo
            log_lo -= factor
            if log_lo < np.log(0.5):
                raise InputError(
                    "the scheduled time is longer than a run at walking pace; split the section or add a stop",
                    field="timetable",
                    value=running_time_s,
                )
            e_lo = excess(log_lo)
            factor = self._bracket_step(log_lo, e_lo, log_hi, e_hi, 1.5 * factor)
        return log_lo, log_hi

    @staticmethod
    def _bracket_step(a: float, e_a: float, b: float, e_b: float, grown: float) -> float:
        """The next step in log V while both runs a < b miss the time on the same side: the secant
        through them, BRACKET_OVERSHOOT times as long, within BRACKET_MIN_STEP and BRACKET_MAX_STEP
        (issue 16: a bracket close to the root saves Brent's first steps); ``grown``, the geometric
        step used before, where there is no falling secant. The running time is convex and
        falling in log V, so from the slow side the secant's root falls short of the root (hence
        the overshoot), from the fast side it lies beyond it."""
        if BRACKET_OVERSHOOT <= 0.0 or e_a * e_b <= 0.0:
            return grown
        slope = (e_b - e_a) / (b - a)
        if not slope < 0.0:  # not falling here (ragged): no line to follow
            return grown
        toward = abs(e_b if e_b > 0.0 else e_a) / -slope
        return float(min(BRACKET_MAX_STEP, max(BRACKET_OVERSHOOT * toward, BRACKET_MIN_STEP)))

    def _bridge(self, V: float, slow: dict, fast: dict, running_time_s: float) -> SectionPlan | None:
        """Where the running time jumps at holding speed V because departure points ahead of
        descents or limits jump between two nearly equally good choices: move them together from
        the slower run's to the faster run's (a homotopy in lambda) until the run takes
        ``running_time_s``; None if the time cannot be met that way."""

        def departure(decisions: dict, other: dict, k) -> float:
            # a departure the other run did not consider is the run without it: its latest point
            return decisions[k][0] if k in decisions else other[k][2]

        keys = [
            k
            for k in set(slow) | set(fast)
            if abs(departure(slow, fast, k) - departure(fast, slow, k)) > 1e-3
        ]
        if not keys:
            return None

        def plan_at(lam: float) -> SectionPlan:
            self._forced = {}
            for k in keys:
                self._forced[k] = (1.0 - lam) * departure(slow, fast, k) + lam * departure(fast, slow, k)
            try:
                return self.plan(V)
            finally:
                self._forced = {}

        lo, hi = 0.0, 1.0
        e_lo = e_hi = None  # the errors at lo and hi once runs there were built
        side = 0
        best = None
        errors = []
        for _ in range(BRIDGE_ITERATIONS):
            lam = 0.5 * (lo + hi)
            if e_lo is not None and e_hi is not None:
                # regula falsi (Illinois) once both sides are known: the time moves smoothly with
                # lambda between them
                lam = lo + (hi - lo) * e_lo / (e_lo - e_hi)
            plan = plan_at(lam)
            error = plan.running_time_s - running_time_s
            errors.append(error)
            if best is None or abs(error) < abs(best.running_time_s - running_time_s):
                best = plan
            if abs(error) <= TIME_TOLERANCE_S:
                break
            if len(errors) >= 3 and np.ptp(errors) < 2.0 * TIME_TOLERANCE_S:
                break  # the time does not move with these departures: no bridge here
            if error > 0.0:
                lo, e_lo = lam, error
                if side > 0 and e_hi is not None:
                    e_hi *= 0.5
                side = 1
            else:
                hi, e_hi = lam, error
                if side < 0 and e_lo is not None:
                    e_lo *= 0.5
                side = -1
        if best is None or abs(best.running_time_s - running_time_s) > max(0.5, 5e-4 * running_time_s):
            return None
        return best

    def _hold_longer(self, slow: SectionPlan, running_time_s: float) -> SectionPlan | None:
        """A plan that keeps the time where the running time jumps with the holding speed: the
        slower plan's holding speed, with its final coasting point moved later (a little faster,
        at a little more energy) until the run takes ``running_time_s``; None if it cannot."""
        V, mu = slow.holding_speed_mps, slow.price_of_time_w
        phase_a = self._phase_a(V)

        def run(s_c: float):
            points, status, _ = self._phase_b(phase_a, s_c, mu, v_hold=V)
            return (points if status == pk.HIT_CEILING else None), s_c

        lo, hi = slow.coast_start_m, self.s1
        fast, _ = run(hi)
        if fast is None or fast[2][-1] > running_time_s:
            return None
        best = fast
        for _ in range(60):
            if hi - lo <= COAST_POINT_TOLERANCE_M:
                break
            mid = 0.5 * (lo + hi)
            points, _ = run(mid)
            if points is not None and points[2][-1] <= running_time_s:
                hi, best = mid, points
            else:
                lo = mid
        s, v, t, m = best
        m = m.copy()
        m[-1] = codes.DWELL
        return SectionPlan(s, v, t, m, float(t[-1]), V, hi, mu, self.fastest_time_s, True)
