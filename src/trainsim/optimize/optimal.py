"""The energy-optimal driving strategy of a section between two stops for a given running time.

Structure from the theory of optimal train control (Albrecht, Howlett, Pudney, Vu, Zhou 2016,
"The key principles of optimal train control", Parts 1 and 2, Transportation Research Part B 94):
maximum traction, holding a speed V, coasting, regenerative braking, maximum braking. The holding
speed V sets the price of time mu = V^2 R'(V) / eta_t (``price_of_time_w``); the final coasting
and braking phase is driven by the adjoint (``pmp_kernel``) from the point where the train stops
holding, found so that the train stops exactly at the next station; V is solved so that the
section takes its scheduled time. Sections of a line that share mu share the marginal energy per
second of running time, which makes a split of a line's supplement optimal.

Scope of this implementation (see docs/OPTIMIZATION.md): holding arcs follow V or the speed
limit where it is lower, with maximum traction where the train cannot hold V uphill and
regenerative-then-friction braking where holding needs braking downhill; the coasting phases that
the exact theory also places before steep downhill and before lower speed limits are not
constructed, so on hilly lines the result is an upper bound close to the optimum.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from trainsim.constants import KWH
from trainsim.errors import InputError
from trainsim.model.route import Route
from trainsim.model.scenario import RunSettings
from trainsim.model.train import Train
from trainsim.optimize import pmp_kernel as pk
from trainsim.sim import kernel
from trainsim.sim.fastest import kernel_parameters, kink_speeds, regenerative_arrays
from trainsim.sim.profile import compile_track

#: Shooting on the coasting point stops when its bracket is shorter than this [m].
COAST_POINT_TOLERANCE_M = 1e-2
#: The section time is met to this [s] (far inside the max(0.5 s, 0.05 %) the schedule needs).
TIME_TOLERANCE_S = 1e-3
#: Largest step of the adjoint-driven phase [m].
ADJOINT_STEP_M = 20.0


def price_of_time_w(train: Train, holding_speed_mps: float) -> float:
    """mu = V^2 R'(V) / eta_t [W]: the energy per second of running time saved at the margin when
    the train holds speed V (Albrecht et al. 2016, Part 1, eq. for the singular arc; psi(V) / eta)."""
    law = train.resistance_law
    slope = law.c1 + 2.0 * law.c2 * holding_speed_mps
    eta_t = train.electrical.traction_efficiency if train.electrical else 1.0
    return holding_speed_mps**2 * slope / eta_t


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
    return float(brentq(lambda w: w * w * (law.c1 + 2.0 * law.c2 * w) - target, 0.0, 1e4))


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


class SectionSolver:
    """Energy-optimal runs of one section [s0, s1] for any running time."""

    def __init__(self, train: Train, route: Route, s0: float, s1: float, settings: RunSettings | None = None):
        settings = settings or RunSettings()
        self.train, self.route, self.s0, self.s1 = train, route, s0, s1
        self.track, _, _ = compile_track(route, train, [s0, s1], settings.max_step_m)
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
        self.Cr, _, self.US = kernel.braking_ceiling(
            tr.x, tr.a0, tr.a1, tr.b0, tr.b1, tr.vlim, self.i0, self.i1, P, self.curves, self.bk
        )
        self.n_max = 8 * len(tr.x) + int((s1 - s0) / pk.MIN_SWITCH_STEP_M) + 64
        self._last_coast_point: float | None = None
        #: whether holding arcs are left early ahead of steep descents (coasting excursions)
        self.excursions = True
        fastest = self._fastest_points()
        self.fastest = fastest
        self.fastest_time_s = float(fastest[2][-1])
        if not np.isfinite(self.fastest_time_s) or fastest[1][-1] > 1e-6:
            raise InputError(
                f"the train cannot run from {s0:.0f} m to {s1:.0f} m (it stalls on the way)",
                field="route",
            )

    # ------------------------------------------------------------------ phases
    def _phase_a(self, holding_speed: float):
        """Maximum traction to min(V, limit), hold it; coast down steep descents up to min(limit, W)
        and hold there with braking; brake to lower limits and the stop."""
        tr = self.track
        if not np.isfinite(holding_speed) or holding_speed >= 10.0 * float(tr.vlim.max()):
            return self.fastest
        vhold = np.minimum(tr.vlim, holding_speed)
        W = regenerative_holding_speed(self.train, price_of_time_w(self.train, holding_speed), self.eta_r)
        vtop = np.maximum(np.minimum(tr.vlim, W), vhold)
        Cr, US, modes = self._ceiling(vtop)
        mu = price_of_time_w(self.train, holding_speed)
        steep_down = self._steep_descents(holding_speed, vhold, vtop)
        if not self.excursions:
            steep_down[:] = False
        pieces: list[tuple[np.ndarray, ...]] = []
        start = (-1, 0.0, 0.0, 0.0)
        last_pos = self.s0
        for _ in range(10_000):
            seg = self._holding(vhold, vtop, Cr, US, modes, start)
            if seg is None:
                return self._stalled()
            if steep_down.any():
                self._has_descents = True
            a = self._next_descent(seg, steep_down, vhold, last_pos, holding_speed)
            if a is None:
                pieces.append(seg)
                break
            p_lo = self._first_at_speed(seg, holding_speed, last_pos)
            p, excursion, q = self._shoot_departure(seg, p_lo, a, vtop, holding_speed, mu)
            keep = seg[0] < p
            pieces.append(tuple(arr[keep] for arr in seg))
            pieces.append(excursion)
            start = q
            last_pos = tr.x[q[0]] + q[1]
        return tuple(np.concatenate([pc[k] for pc in pieces]) for k in range(4))

    def _ceiling(self, vtop: np.ndarray):
        """Braking ceiling for the holding phases: service braking on the final approach to the stop
        (as the fastest run), regenerative braking only before lower limits where the train has it
        (the friction brakes would waste what the electric brake returns)."""
        tr = self.track
        modes = np.full(len(tr.a0), kernel.BRAKE, dtype=np.int64)
        if self.has_regen:
            _, _, US_s = kernel.braking_ceiling(
                tr.x, tr.a0, tr.a1, tr.b0, tr.b1, vtop, self.i0, self.i1, self.P, self.curves, self.bk
            )
            # the final approach: the intervals after the last one that reaches the limit plateau
            plateau = np.flatnonzero(US_s > 0.0)
            last = self.i0 + (int(plateau[-1]) if len(plateau) else -1)
            modes[self.i0 : last + 1] = kernel.REGEN
        Cr, _, US = kernel.braking_ceiling_mixed(
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
        return s, np.array([0.0, 1.0]), np.array([0.0, np.inf]), np.array([0, kernel.DWELL], dtype=np.int8)

    def _steep_descents(self, V: float, vhold: np.ndarray, vtop: np.ndarray) -> np.ndarray:
        """Intervals where coasting at V speeds the train up (holding V would need braking) and the
        train may go faster than V there."""
        tr = self.track
        law = self.train.resistance_law
        weight = self.P[kernel.P_WEIGHT]
        res_left = law(V) + weight * (tr.a0 + tr.b0 * V * V)
        res_right = law(V) + weight * (
            tr.a0 + tr.a1 * np.diff(tr.x) + (tr.b0 + tr.b1 * np.diff(tr.x)) * V * V
        )
        return (np.minimum(res_left, res_right) < 0.0) & (vhold >= V - 1e-9) & (vtop > V + 1e-6)

    def _next_descent(self, seg, steep_down, vhold, after: float, V: float) -> float | None:
        """Start of the next steep descent beyond ``after`` that the holding run meets at speed V."""
        tr = self.track
        idx = np.flatnonzero(steep_down[self.i0 : self.i1]) + self.i0
        starts = idx[np.concatenate([[True], np.diff(idx) > 1])] if len(idx) else idx
        for i in starts:
            a = tr.x[i]
            if a <= after + 1.0:
                continue
            v_at = np.interp(a, seg[0], seg[1])
            if abs(v_at - V) <= 1e-6 * max(V, 1.0):
                return float(a)
        return None

    def _first_at_speed(self, seg, V: float, after: float) -> float:
        s, v = seg[0], seg[1]
        ok = np.flatnonzero((s >= after) & (np.abs(v - V) <= 1e-6 * max(V, 1.0)))
        return float(s[ok[0]]) if len(ok) else float(after)

    def _shoot_departure(self, seg, p_lo: float, a: float, vtop, V: float, mu: float):
        """The departure point p in [p_lo, a] from which coasting rejoins the holding arc with the
        adjoint back at 1/eta_t (bisection on the sign of the residual)."""
        tr = self.track

        def excursion(p: float):
            i, u, v, t, _ = self._state_at(seg, p)
            out = [np.empty(self.n_max) for _ in range(3)] + [np.empty(self.n_max, dtype=np.int8)]
            n, status, res, iq, uq, tq = pk.coast_excursion(
                tr.x, tr.a0, tr.a1, tr.b0, tr.b1, vtop, tr.traction_scale, i, u, v, t, self.i1,
                self.P, self.curves, self.bk, V, mu, self.inv_eta_t, ADJOINT_STEP_M, *out,
            )  # fmt: skip
            return (res if status == 0 else -np.inf), tuple(x[:n] for x in out), (iq, uq, V, tq)

        res_a, ex_a, q_a = excursion(a)
        if res_a <= 0.0 or not np.isfinite(res_a):
            return a, ex_a, q_a
        lo, hi = p_lo, a
        res_lo, ex_lo, q_lo = excursion(lo)
        if res_lo >= 0.0:
            return lo, ex_lo, q_lo
        best = (a, ex_a, q_a)
        while hi - lo > 0.5:
            mid = 0.5 * (lo + hi)
            res, ex, q = excursion(mid)
            if res >= 0.0:
                hi, best = mid, (mid, ex, q)
            else:
                lo = mid
        return best

    def _fastest_points(self):
        tr = self.track
        out_s = np.empty(self.n_max)
        out_v = np.empty(self.n_max)
        out_t = np.empty(self.n_max)
        out_m = np.empty(self.n_max, dtype=np.int8)
        n, status, _ = kernel.fastest_segment(
            tr.x, tr.a0, tr.a1, tr.b0, tr.b1, tr.vlim, tr.traction_scale, self.i0, self.i1, 0.0,
            self.P, self.curves, self.tk, self.bk, out_s, out_v, out_t, out_m, 0,
        )  # fmt: skip
        if status != kernel.STATUS_OK:
            return out_s[:n], np.append(out_v[: n - 1], 1.0), np.append(out_t[: n - 1], np.inf), out_m[:n]
        return out_s[:n], out_v[:n], out_t[:n], out_m[:n]

    def _state_at(self, phase_a, s_c: float) -> tuple[int, float, float, float, int]:
        """(interval, offset, speed, time, index of the last phase-A point before) at s_c."""
        s, v, t, m = phase_a
        j = int(np.searchsorted(s, s_c, side="right")) - 1
        j = min(max(j, 0), len(s) - 2)
        tr = self.track
        i = min(int(np.searchsorted(tr.x, s[j], side="right")) - 1, self.i1 - 1)
        u0 = s[j] - tr.x[i]
        h = s_c - s[j]
        mode = int(m[j])
        self.P[kernel.P_TRACTION_SCALE] = tr.traction_scale[i]
        if h <= 0.0:
            return i, u0, float(v[j]), float(t[j]), j
        if mode in (kernel.CRUISE, kernel.DWELL):
            return i, u0 + h, float(v[j]), float(t[j] + h / v[j]) if v[j] > 0 else float(t[j]), j
        line = (tr.a0[i], tr.a1[i], tr.b0[i], tr.b1[i])
        kinks = self.tk if mode == kernel.TRACTION else self.bk  # coasting has no kinks: any list works
        E1, dt = kernel.step_energy_time(0.5 * v[j] ** 2, u0, h, mode, line, self.P, self.curves, kinks)
        return i, u0 + h, float(np.sqrt(max(2.0 * E1, 0.0))), float(t[j] + dt), j

    def _phase_b_forced(self, phase_a, s_c: float):
        """From s_c on phase A, maximum regenerative braking until the service braking curve to the
        stop (source 004's recuperative braking)."""
        points, status, _ = self._phase_b(phase_a, s_c, 0.0, force_mode=kernel.REGEN)
        return points, status

    def _phase_b(self, phase_a, s_c: float, mu: float, force_mode: int = -1, v_hold: float = np.inf):
        tr = self.track
        i, u, v, t, j = self._state_at(phase_a, s_c)
        if u >= tr.x[i + 1] - tr.x[i] - 1e-12 and i + 1 < self.i1:
            i, u = i + 1, 0.0
        out_s = np.empty(self.n_max)
        out_v = np.empty(self.n_max)
        out_t = np.empty(self.n_max)
        out_m = np.empty(self.n_max, dtype=np.int8)
        n, status, s_event = pk.final_phase(
            tr.x, tr.a0, tr.a1, tr.b0, tr.b1, tr.vlim, tr.traction_scale, i, u, v, t, self.i1,
            self.P, self.curves, self.tk, self.bk, self.Cr, self.US, mu, self.inv_eta_t, self.eta_r,
            self.has_regen, ADJOINT_STEP_M, out_s, out_v, out_t, out_m, 0, force_mode, v_hold,
        )  # fmt: skip
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

    def plan(self, holding_speed_mps: float) -> SectionPlan:
        """The optimal run for holding speed V: the coasting point found by bisection so that the
        train stops exactly at the next station."""
        mu = price_of_time_w(self.train, holding_speed_mps)
        phase_a = self._phase_a(holding_speed_mps)

        # The last coasting point from which the train still reaches the stop: on a hilly line the
        # outcome is not monotone in the coasting point, and the optimum leaves the holding arc as
        # late as possible, so search backwards from the stop for a bracket first.
        def residual(s_c: float):
            points, status, s_event = self._phase_b(phase_a, s_c, mu, v_hold=holding_speed_mps)
            # < 0: stops short of the station by that much; >= 0: meets the braking curve to it
            return (self.s1 - s_event if status == pk.HIT_CEILING else s_event - self.s1), points

        hi = self.s1
        _, best = residual(hi)
        step = max(50.0, (self.s1 - self.s0) / 200.0)
        lo = hi - step
        guess = self._last_coast_point
        step_guess = 20.0
        if guess is not None and self.s0 < guess - step_guess < guess + step_guess < self.s1:
            # warm start from the previous holding speed's coasting point (the outer solve moves V
            # a little at a time)
            r_g, points = residual(guess + step_guess)
            if r_g >= 0.0:
                hi, best = guess + step_guess, points
                lo = guess - step_guess
        while True:
            lo = max(lo, self.s0)
            r_lo, points = residual(lo)
            if r_lo < 0.0 or lo <= self.s0:
                break
            hi, best = lo, points
            step *= 1.5
            lo = hi - step
        # bisection: the outcome is discontinuous at the boundary (the train meets the service braking
        # curve some metres before the stop), so a secant on a residual does not converge faster
        while hi - lo > COAST_POINT_TOLERANCE_M and r_lo < 0.0:
            mid = 0.5 * (lo + hi)
            r_mid, points = residual(mid)
            if r_mid >= 0.0:
                hi, best = mid, points
            else:
                lo = mid
        self._last_coast_point = hi
        s, v, t, m = best
        # the stop point closes the section
        m = m.copy()
        m[-1] = kernel.DWELL
        return SectionPlan(s, v, t, m, float(t[-1]), holding_speed_mps, hi, mu, self.fastest_time_s, True)

    def solve(self, running_time_s: float) -> SectionPlan:
        """The least-energy run that takes ``running_time_s``; the fastest run (``feasible`` False)
        when that is shorter than the fastest possible.

        Where the section has descents too steep to hold the speed on, the run is built both with
        and without coasting excursions ahead of them and the one that needs less energy is kept:
        the excursions follow the optimality conditions locally, but on lines where descents,
        lower limits and the final approach interact they can lose to plain holding."""
        self.excursions = True
        self._has_descents = False
        with_excursions = self._solve_once(running_time_s)
        if not self._has_descents:
            return with_excursions
        self.excursions = False
        self._last_coast_point = None
        plain = self._solve_once(running_time_s)
        self.excursions = True
        return min((with_excursions, plain), key=self.energy_j)

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
        if running_time_s <= self.fastest_time_s + TIME_TOLERANCE_S:
            s, v, t, m = self.fastest
            m = m.copy()
            m[-1] = kernel.DWELL
            return SectionPlan(
                s, v, t, m, self.fastest_time_s, np.inf, self.s1, np.inf, self.fastest_time_s,
                running_time_s >= self.fastest_time_s - TIME_TOLERANCE_S,
            )  # fmt: skip
        vmax = float(self.track.vlim.max())

        def excess(log_v: float) -> float:
            return self.plan(float(np.exp(log_v))).running_time_s - running_time_s

        lo, hi = np.log(0.5), np.log(vmax * 20.0)
        if excess(lo) < 0:
            raise InputError(
                "the scheduled time is longer than a run at walking pace; split the section or add a stop",
                field="timetable",
                value=running_time_s,
            )
        if excess(hi) > 0:
            hi = np.log(vmax * 1000.0)
        log_v = brentq(excess, lo, hi, xtol=1e-10, rtol=1e-10, maxiter=200)
        plan = self.plan(float(np.exp(log_v)))
        return plan
