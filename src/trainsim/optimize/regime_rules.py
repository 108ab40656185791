"""Regime rules of ATO and drivers applied to the optimal strategy: a minimum time in every regime and
coasting only above a speed (``DrivingConstraints.min_regime_time_s`` / ``coast_min_speed_mps``).

The optimal run of a holding speed V (``SectionSolver.plan``) is read as a *program*: its regime arcs
as intents (traction, holding a speed, coasting, regenerative braking) that start at positions.
Braking on the braking curves is not an intent: the speed ceiling (the limits and the braking
curves to lower limits and to the stop, ``SectionSolver.Cr_final``) overrides every intent, and
those arcs are *forced* (by a speed limit or by the stop). The program is driven forward with the
solver's own integrator (``sim._kernel_c.step_energy_time``), so the run follows the same train on the same
track:

* traction (up to the speed of a holding arc that follows it);
* holding a speed V_h: traction below it, coasting down to it from above; where the traction (or
  the brake) cannot hold it on a gradient, full traction (brake) until it is held again: those arcs
  are forced *by the gradient*;
* coasting; with ``coast_min_speed_mps`` = v_c the train holds v_c once coasting brings it down to
  v_c (the ATO's coast-remotor), or holds the speed it enters the arc with when that is lower;
* regenerative braking.

With ``min_regime_time_s`` = T_min every arc that is not forced and lasts less than T_min is merged
into a neighbour: its intent is removed and the one before extended over it, or the one after
started at its start, or it absorbs the intent after it (or before it); of these, the run with
fewer short arcs and then the least cost E + mu (T - T_s) is kept (mu: the plan's price of time),
until no arc can be merged. V is then searched (Brent's method on log V) so that the run takes the
scheduled time T_s again; the energy against the optimal run is the cost of the rules. Where an
arc stays shorter than T_min (forced, or no merge makes it longer) or the time cannot be met, the
outcome's notes say which and by how much. A plan that meets both rules is returned unchanged.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import brentq

from trainsim.constants import KMH, KWH
from trainsim.optimize.constraints import DrivingConstraints
from trainsim.optimize.optimal import SectionPlan, SectionSolver
from trainsim.sim import _kernel_c, codes

#: Speeds closer than this are the same speed [m/s] (holding, ceiling contact).
SPEED_TOLERANCE_MPS = 1e-6
#: Runs whose arcs differ by less than this are the same [s].
ARC_TIME_TOLERANCE_S = 1e-6
#: Arcs of the optimal run shorter than this are labels it switches through, not arcs [s].
LABEL_TIME_S = 0.05
#: An arc lengthened to the minimum regime time is lengthened by this factor of what it lacks [-]
#: (the motion after the switch changes with it: a little more keeps it above the minimum).
EXTEND_FACTOR = 1.02
#: Iterations of Brent's method on the holding speed.
SPEED_SEARCH_ITERATIONS = 30
#: The bracket on V grows by this factor per step, at most ``BRACKET_STEPS`` times.
BRACKET_FACTOR = 1.25
BRACKET_STEPS = 12
#: Forced arcs, by what forces them.
FORCED_LIMIT, FORCED_STOP, FORCED_GRADIENT = "speed limit", "stop", "gradient"
#: Arcs where the coast-remotor holds the speed (not forced: they count for the minimum time).
REMOTOR = "remotor"

_NO_KINKS = np.zeros(0)


@dataclass
class _Arc:
    """One intent of a program: regime code, start position [m], speed to hold [m/s] (holding)."""

    regime: int
    start_m: float
    hold_mps: float = np.nan


@dataclass(frozen=True)
class RuleOutcome:
    """A section's run under the regime rules.

    Attributes:
        plan: the run (the optimal plan itself where it meets the rules).
        energy_cost_j: its net energy without auxiliaries minus the optimal plan's [J].
        notes: arcs that stay shorter than the minimum and why; the running time where it is missed.
        time_met: whether the scheduled running time is met (within max(0.5 s, 0.05 %)).
        changed: whether the rules changed the optimal run.
    """

    plan: SectionPlan
    energy_cost_j: float
    notes: tuple[str, ...] = field(default=())
    time_met: bool = True
    changed: bool = False


class _Driver:
    """Drives a program forward over the solver's grid (module doc)."""

    def __init__(self, sv: SectionSolver, rules: DrivingConstraints) -> None:
        self.sv, self.rules = sv, rules
        tr = sv.track
        self.x, self.i0, self.i1 = tr.x, sv.i0, sv.i1
        self.Cr, self.US, self.modes = sv.Cr_final, sv.US_final, sv.final_curve_modes
        self.P = []
        for i in range(len(tr.a0)):
            p = sv.P.copy()
            p[codes.P_TRACTION_SCALE] = tr.traction_scale[i]
            self.P.append(p)
        self.lines = [
            (float(tr.a0[i]), float(tr.a1[i]), float(tr.b0[i]), float(tr.b1[i])) for i in range(len(tr.a0))
        ]

    def kinks(self, mode: int) -> np.ndarray:
        sv = self.sv
        return {codes.TRACTION: sv.tk, codes.BRAKE: sv.bk, codes.REGEN: sv.rk}.get(mode, _NO_KINKS)

    def ceiling_e(self, i: int, u: float) -> float:
        """Kinetic energy per unit mass of the speed ceiling at offset u of interval i [m^2/s^2]."""
        k = i - self.i0
        w = self.x[i + 1] - self.x[i]
        if u < self.US[k] or self.US[k] >= w:
            return 0.5 * float(self.sv.track.vlim[i]) ** 2
        mode = int(self.modes[k])
        Er = 0.5 * float(self.Cr[k]) ** 2
        return float(
            _kernel_c.step_energy(
                Er, w, u - w, mode, self.lines[i], self.P[i], self.sv.curves, self.kinks(mode)
            )
        )

    def step(self, E: float, i: int, u: float, h: float, mode: int) -> tuple[float, float]:
        if h <= 0.0:
            return E, 0.0
        E1, dt = _kernel_c.step_energy_time(
            E, u, h, mode, self.lines[i], self.P[i], self.sv.curves, self.kinks(mode)
        )
        return max(float(E1), 0.0), float(dt)

    def crossing(self, E: float, i: int, u: float, h: float, target_e: float, mode: int) -> float:
        d = _kernel_c.find_speed_crossing_split(
            E, u, h, target_e, mode, self.lines[i], self.P[i], self.sv.curves, self.kinks(mode)
        )
        return float(min(max(d, 0.0), h))

    def accel(self, mode: int, E: float, i: int, u: float) -> float:
        return float(_kernel_c.acceleration_of(mode, E, u, self.lines[i], self.P[i], self.sv.curves))

    def drive(self, program: list[_Arc]):
        """(s, v, t, regime, kind, arc index) of the run, or None where it stalls."""
        sv = self.sv
        starts = [a.start_m for a in program]
        s_out, e_out, t_out, m_out, k_out, j_out = [self.x[self.i0]], [0.0], [0.0], [], [], []
        E, t = 0.0, 0.0
        remotor: dict[int, float] = {}

        def record(s1: float, E1: float, dt: float, mode: int, kind: str, j: int) -> None:
            nonlocal E, t
            if s1 - s_out[-1] <= 1e-12:
                return
            m_out.append(mode)
            k_out.append(kind)
            j_out.append(j)
            t += dt
            E = E1
            s_out.append(s1)
            e_out.append(E1)
            t_out.append(t)

        def follow(i: int, u: float, ue: float, j: int) -> bool:
            """Along the ceiling from offset u to ue: the limit held, or its braking curve."""
            xi, k = float(self.x[i]), i - self.i0
            on_limit = u < self.US[k] - 1e-9
            kind = FORCED_STOP if self._to_stop(i) and not on_limit else FORCED_LIMIT
            if on_limit:
                end = min(ue, float(self.US[k]))
                Ec = self.ceiling_e(i, u)
                record(xi + end, Ec, (end - u) / max(np.sqrt(2.0 * Ec), 1e-12), codes.CRUISE, kind, j)
                return True
            mode = int(self.modes[k])
            E1, dt = self.step(self.ceiling_e(i, u), i, u, ue - u, mode)
            if E1 <= 0.0 and xi + ue < sv.s1 - 1e-6:
                return False
            # on the curve itself (the integration's rounding would leave it by 1e-12 and start an
            # arc of no duration below it)
            record(xi + ue, self.ceiling_e(i, ue), dt, mode, kind, j)
            return True

        for i in range(self.i0, self.i1):
            xi, w = float(self.x[i]), float(self.x[i + 1] - self.x[i])
            guard = 0
            while s_out[-1] < xi + w - 1e-9:
                guard += 1
                if guard > 2000:
                    return None
                u = s_out[-1] - xi
                j = int(np.searchsorted(starts, s_out[-1] + 1e-9, side="right")) - 1
                j = max(j, 0)
                nxt = starts[j + 1] - xi if j + 1 < len(starts) else np.inf
                ue = min(w, nxt) if nxt > u + 1e-9 else w
                arc = program[j]
                # the ceiling first: on it, an intent that would rise above it follows it instead
                Ec = self.ceiling_e(i, u)
                if Ec - 1e-9 <= E and self._wants_above(
                    arc, remotor.get(j), E, i, u, u < self.US[i - self.i0] - 1e-9
                ):
                    if not follow(i, u, ue, j):
                        return None
                    continue
                mode, target, kind = self._intent(arc, j, remotor, E, i, u)
                if mode == codes.CRUISE:
                    v = np.sqrt(2.0 * E)
                    end = self._holdable_until(E, i, u, ue)
                    if end <= u + 1e-9:  # the gradient: full effort until the speed is back
                        mode = codes.TRACTION if self.accel(codes.TRACTION, E, i, u) < 0.0 else codes.BRAKE
                        kind = FORCED_GRADIENT
                        target = None
                    else:
                        # never above the ceiling while holding (a braking curve starts inside)
                        end = self._below_ceiling(i, u, end, lambda x, E=E: E)
                        if end <= u + 1e-9:
                            if not follow(i, u, ue, j):
                                return None
                        else:
                            record(xi + end, E, (end - u) / max(v, 1e-12), codes.CRUISE, kind, j)
                        continue
                elif (
                    mode == codes.TRACTION
                    and arc.regime == codes.CRUISE
                    and k_out
                    and k_out[-1] == FORCED_GRADIENT
                ):
                    kind = FORCED_GRADIENT  # still regaining the speed the gradient took
                h = ue - u
                E1, dt = self.step(E, i, u, h, mode)
                if target is not None:
                    rising = self.accel(mode, E, i, u) > 0.0
                    if (rising and target + 1e-12 < E1) or (not rising and target - 1e-12 > E1):
                        d = self.crossing(E, i, u, h, target, mode)
                        if d < h:
                            h = d
                            E1, dt = self.step(E, i, u, h, mode)
                            E1 = target
                Ec1 = self.ceiling_e(i, u + h)
                if Ec1 + 1e-9 < E1:
                    # meets the ceiling inside the step: go to the meeting point, the ceiling takes over
                    def gap(x: float, E=E, i=i, u=u, mode=mode) -> float:
                        return self.step(E, i, u, x - u, mode)[0] - self.ceiling_e(i, x)

                    lo = u
                    hi = u + h
                    if gap(lo) < 0.0:
                        hi = float(brentq(gap, lo, hi, xtol=1e-9))
                    if hi - u <= 1e-9:  # on the ceiling already
                        if not follow(i, u, ue, j):
                            return None
                        continue
                    E1, dt = self.step(E, i, u, hi - u, mode)
                    E1 = min(E1, self.ceiling_e(i, hi))
                    h = hi - u
                if E1 <= 0.0 and xi + u + h < sv.s1 - 1e-6:
                    return None
                record(xi + u + h, E1, dt, mode, kind, j)
        v = np.sqrt(2.0 * np.maximum(np.asarray(e_out), 0.0))
        v[-1] = 0.0
        return (
            np.asarray(s_out, dtype=float),
            v,
            np.asarray(t_out, dtype=float),
            np.asarray([*m_out, codes.DWELL], dtype=np.int8),
            [*k_out, ""],
            [*j_out, -1],
        )

    def _to_stop(self, i: int) -> bool:
        """Whether the braking curve through interval i is the one into the stop (no limit part after)."""
        k = i - self.i0
        return bool(np.all(self.US[k + 1 :] <= 1e-12)) if k + 1 < len(self.US) else True

    def _wants_above(
        self, arc: _Arc, remotor: float | None, E: float, i: int, u: float, on_limit: bool
    ) -> bool:
        """Whether the intent at a point on the ceiling would leave it upwards (or slower than its curve)."""
        if on_limit:
            if arc.regime == codes.TRACTION:
                return True
            if arc.regime == codes.CRUISE:
                return arc.hold_mps >= np.sqrt(2.0 * E) - SPEED_TOLERANCE_MPS
            if arc.regime == codes.COAST and remotor is not None:
                return remotor >= np.sqrt(2.0 * E) - SPEED_TOLERANCE_MPS
            return self.accel(arc.regime if arc.regime != codes.CRUISE else codes.COAST, E, i, u) >= 0.0
        # on a braking curve: only braking at least as hard as the curve stays below it
        return arc.regime != codes.REGEN or int(self.modes[i - self.i0]) != codes.REGEN

    def _intent(self, arc: _Arc, j: int, remotor: dict[int, float], E: float, i: int, u: float):
        """(mode, target kinetic energy or None, kind) of an arc's intent at a point below the ceiling."""
        v = np.sqrt(2.0 * E)
        vc = self.rules.coast_min_speed_mps
        if arc.regime == codes.TRACTION:
            cap = arc.hold_mps
            if np.isfinite(cap) and v >= cap - SPEED_TOLERANCE_MPS:
                return codes.CRUISE, None, ""
            return codes.TRACTION, (0.5 * cap * cap if np.isfinite(cap) else None), ""
        if arc.regime == codes.REGEN:
            return codes.REGEN, None, ""
        hold, kind = arc.hold_mps, ""
        if arc.regime == codes.COAST:
            if j in remotor:
                hold, kind = remotor[j], REMOTOR
            elif vc > 0.0 and v <= vc + SPEED_TOLERANCE_MPS:
                remotor[j] = hold = min(vc, v) if v < vc - SPEED_TOLERANCE_MPS else vc
                kind = REMOTOR
            else:
                return codes.COAST, (0.5 * vc * vc if vc > 0.0 else None), ""
        if v < hold - SPEED_TOLERANCE_MPS:
            return codes.TRACTION, 0.5 * hold * hold, kind
        if v > hold + SPEED_TOLERANCE_MPS:
            return codes.COAST, 0.5 * hold * hold, kind
        return codes.CRUISE, None, kind

    def _holdable_until(self, E: float, i: int, u: float, ue: float) -> float:
        """Up to where in [u, ue] the speed can be held (the resistance is linear in the offset)."""

        def ok(x: float) -> bool:
            return self.accel(codes.TRACTION, E, i, x) >= -1e-12 and self.accel(codes.BRAKE, E, i, x) <= 1e-12

        if not ok(u):
            return u
        if ok(ue):
            return ue
        lo, hi = u, ue
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if ok(mid) else (lo, mid)
        return lo

    def _below_ceiling(self, i: int, u: float, end: float, e_of) -> float:
        """The first offset in [u, end] where the ceiling comes down to the run's energy, else end."""
        if self.ceiling_e(i, end) >= e_of(end) - 1e-9:
            return end
        lo, hi = u, end
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if self.ceiling_e(i, mid) >= e_of(mid) - 1e-9 else (lo, mid)
        return lo


def _program(plan: SectionPlan) -> list[_Arc]:
    """The intents of an optimal plan: its arcs, braking read as coasting under the ceiling."""
    out: list[_Arc] = []
    r, s, v, t = plan.regime, plan.s, plan.v, plan.t
    labels = [codes.COAST if int(m) in (codes.BRAKE, codes.FOLLOW) else int(m) for m in r[:-1]]
    k = 0
    while k < len(labels):
        q = k
        while q + 1 < len(labels) and labels[q + 1] == labels[k]:
            q += 1
        # labels held for no time are no arc (the optimal run switches through them)
        if t[q + 1] - t[k] > LABEL_TIME_S and not (out and out[-1].regime == labels[k]):
            out.append(_Arc(labels[k], float(s[k]), float(v[k]) if labels[k] == codes.CRUISE else np.nan))
        k = q + 1
    out[0].start_m = float(s[0])
    return _capped(out)


def _capped(program: list[_Arc]) -> list[_Arc]:
    """Traction intents end at the speed of a holding intent right after them."""
    for a, b in zip(program, [*program[1:], None], strict=True):
        if a.regime == codes.TRACTION:
            a.hold_mps = b.hold_mps if b is not None and b.regime == codes.CRUISE else np.nan
    return program


@dataclass
class _Run:
    program: list[_Arc]
    plan: SectionPlan
    arcs: list[tuple[int, str, float, float, float, int]]  # regime, kind, start m, end m, duration s, intent
    short: list[tuple[int, str, float, float, float, int]]
    energy_j: float


class RegimeRules:
    """Applies the regime rules to one section's optimal runs (module doc)."""

    def __init__(self, sv: SectionSolver, rules: DrivingConstraints) -> None:
        self.sv, self.rules = sv, rules
        self.driver = _Driver(sv, rules)
        self.fixed: set[float] = set()

    def run(self, program: list[_Arc], template: SectionPlan) -> _Run | None:
        # intents that repeat the one before are no switch (a merge leaves coasting after coasting)
        program = [
            _Arc(a.regime, a.start_m, a.hold_mps)
            for k, a in enumerate(program)
            if k == 0
            or a.regime != program[k - 1].regime
            or (a.regime == codes.CRUISE and abs(a.hold_mps - program[k - 1].hold_mps) > SPEED_TOLERANCE_MPS)
        ]
        out = self.driver.drive(_capped(program))
        if out is None:
            return None
        s, v, t, m, kinds, js = out
        plan = SectionPlan(
            s, v, t, m, float(t[-1]), template.holding_speed_mps, template.coast_start_m,
            template.price_of_time_w, template.fastest_time_s, template.feasible,
        )  # fmt: skip
        arcs = []
        k = 0
        while k < len(s) - 1:
            q = k
            # one regime is one arc, whatever holds it (a hold the intent asks for that runs on
            # into a hold at the limit is one hold): forced where any part of it is forced
            while q + 1 < len(s) - 1 and m[q + 1] == m[k]:
                q += 1
            parts = set(kinds[k : q + 1])
            forced = [x for x in (FORCED_STOP, FORCED_LIMIT, FORCED_GRADIENT) if x in parts]
            kind = forced[0] if forced else (REMOTOR if REMOTOR in parts else "")
            arcs.append((int(m[k]), kind, float(s[k]), float(s[q + 1]), float(t[q + 1] - t[k]), js[k]))
            k = q + 1
        tmin = self.rules.min_regime_time_s
        short = [
            a
            for a in arcs
            if tmin > 0.0
            and ARC_TIME_TOLERANCE_S < a[4] < tmin - ARC_TIME_TOLERANCE_S
            and a[1] in ("", REMOTOR)
        ]
        return _Run(program, plan, arcs, short, self.sv.energy_j(plan))

    def _cost(self, r: _Run, running_time_s: float) -> float:
        return r.energy_j + r.plan.price_of_time_w * (r.plan.running_time_s - running_time_s)

    def merged(self, plan: SectionPlan, running_time_s: float) -> _Run | None:
        """The plan's program driven with the rules, its short arcs merged (module doc)."""
        best = self.run(_program(plan), plan)
        if best is None:
            return None
        fixed: set[int] = set()
        tmin = self.rules.min_regime_time_s
        for _ in range(4 * len(best.program) + 4):
            todo = [a for a in best.short if a[5] not in fixed and a[5] >= 0]
            if not todo:
                break
            worst = min(todo, key=lambda a: a[4])
            j = worst[5]
            p = best.program
            t_run, s_run = best.plan.t, best.plan.s
            end_m = self.sv.s1
            options = []
            if j > 0:  # the one before extends over it
                options.append(p[:j] + p[j + 1 :])
            if j + 1 < len(p):  # the one after starts at its start
                options.append([*p[:j], _Arc(p[j + 1].regime, p[j].start_m, p[j + 1].hold_mps), *p[j + 2 :]])
            if j > 0:  # it absorbs the one before
                options.append([*p[: j - 1], _Arc(p[j].regime, p[j - 1].start_m, p[j].hold_mps), *p[j + 1 :]])
            if j > 0:  # it starts earlier, by a little more than it lacks
                t_j = float(np.interp(p[j].start_m, s_run, t_run))
                x = float(np.interp(t_j - EXTEND_FACTOR * (tmin - worst[4]), t_run, s_run))
                if x > p[j - 1].start_m + 1e-6:
                    options.append([*p[:j], _Arc(p[j].regime, x, p[j].hold_mps), *p[j + 1 :]])
            runs = [r for r in (self.run(o, plan) for o in options) if r is not None]
            if j + 1 < len(p):
                # it absorbs the one after, or lasts the minimum (the one after starts later): the
                # same motion up to the switch, read off the run without the one after
                absorbed = self.run(p[: j + 1] + p[j + 2 :], plan)
                if absorbed is not None:
                    runs.append(absorbed)
                    t_a = float(np.interp(worst[2], s_run, t_run))
                    x = float(np.interp(t_a + EXTEND_FACTOR * tmin, absorbed.plan.t, absorbed.plan.s))
                    limit = p[j + 2].start_m if j + 2 < len(p) else end_m
                    if p[j + 1].start_m < x < limit - 1e-6:
                        r = self.run(
                            [*p[: j + 1], _Arc(p[j + 1].regime, x, p[j + 1].hold_mps), *p[j + 2 :]], plan
                        )
                        if r is not None:
                            runs.append(r)
            runs = [r for r in runs if len(r.short) < len(best.short)]
            if not runs:
                fixed.add(j)
                continue
            best = min(runs, key=lambda r: (len(r.short), self._cost(r, running_time_s)))
            fixed = set()
        return best


def _tolerance(running_time_s: float) -> float:
    return max(0.5, 5e-4 * running_time_s)


def apply_regime_rules(
    sv: SectionSolver, running_time_s: float, plan: SectionPlan, rules: DrivingConstraints
) -> RuleOutcome:
    """The run of section ``sv`` that keeps the regime rules and takes ``running_time_s`` [s] (module doc).

    Args:
        sv: the section's solver (its train, track and braking curves).
        running_time_s: the scheduled running time [s].
        plan: the section's optimal run for that time.
        rules: the driving constraints (``min_regime_time_s``, ``coast_min_speed_mps``).
    """
    if not rules.regime_rules:
        return RuleOutcome(plan, 0.0)
    e_opt = sv.energy_j(plan)
    rr = RegimeRules(sv, rules)
    first = rr.merged(plan, running_time_s)
    if first is not None and _same(first, plan) and not first.short:
        return RuleOutcome(plan, 0.0)
    seen: dict[float, _Run | None] = {}

    def at(log_v: float) -> _Run | None:
        if log_v not in seen:
            seen[log_v] = rr.merged(sv.plan(float(np.exp(log_v))), running_time_s)
        return seen[log_v]

    def excess(log_v: float) -> float:
        r = at(log_v)
        return np.inf if r is None else r.plan.running_time_s - running_time_s

    notes: list[str] = []
    if not plan.feasible:
        chosen = first
    else:
        lv = float(np.log(plan.holding_speed_mps))
        lo = hi = lv
        f0 = excess(lv)
        chosen = at(lv)
        if np.isfinite(f0) and abs(f0) > 1e-3:
            step = np.log(BRACKET_FACTOR) * (1.0 if f0 > 0.0 else -1.0)
            other = lv
            for _ in range(BRACKET_STEPS):
                other += step
                f1 = excess(other)
                if np.isfinite(f1) and np.sign(f1) != np.sign(f0):
                    break
            lo, hi = sorted((lv, other))
            if np.isfinite(excess(lo)) and np.isfinite(excess(hi)) and excess(lo) * excess(hi) < 0.0:
                root = brentq(
                    excess, lo, hi, xtol=1e-7, rtol=1e-10, maxiter=SPEED_SEARCH_ITERATIONS, disp=False
                )
                at(root)
            candidates = [r for r in seen.values() if r is not None]
            chosen = _pick(candidates, running_time_s)
            if chosen is not None and abs(chosen.plan.running_time_s - running_time_s) > _tolerance(
                running_time_s
            ):
                # the running time jumps with V here (arcs merged one way or the other): move the start
                # of the last coasting arc of the nearest runs instead
                for r in sorted(candidates, key=lambda r: abs(r.plan.running_time_s - running_time_s))[:3]:
                    for regime in (codes.COAST, codes.TRACTION):
                        candidates += _shift_last(rr, r, running_time_s, plan, regime)
                chosen = _pick(candidates, running_time_s)
    if chosen is None:
        notes.append("regime rules: no run keeps them (the train stalls); the optimal run is returned")
        return RuleOutcome(plan, 0.0, tuple(notes), True, False)
    miss = chosen.plan.running_time_s - running_time_s
    time_met = (not plan.feasible) or abs(miss) <= _tolerance(running_time_s)
    if not time_met:
        notes.append(
            f"regime rules: no run that keeps them takes the scheduled {running_time_s:.1f} s; the nearest "
            f"takes {chosen.plan.running_time_s:.1f} s ({miss:+.1f} s)"
        )
    for regime, kind, a, b, dur, _ in chosen.arcs:
        if 0.0 < dur < rules.min_regime_time_s - ARC_TIME_TOLERANCE_S:
            why = (
                f"forced by the {kind}"
                if kind in (FORCED_LIMIT, FORCED_STOP, FORCED_GRADIENT)
                else "no merge lengthens it"
            )
            notes.append(
                f"regime rules: {codes.REGIME_NAMES[regime]} {a:.0f}-{b:.0f} m lasts {dur:.1f} s, shorter than "
                f"{rules.min_regime_time_s:g} s ({why})"
            )
    cost = chosen.energy_j - e_opt
    notes.append(
        f"regime rules cost {cost / KWH:.4f} kWh ({100.0 * cost / max(abs(e_opt), 1.0):+.2f} %) between "
        f"{sv.s0:.0f} and {sv.s1:.0f} m"
        + (
            f" (coasting only above {rules.coast_min_speed_mps / KMH:.1f} km/h)"
            if rules.coast_min_speed_mps
            else ""
        )
    )
    return RuleOutcome(chosen.plan, cost, tuple(notes), time_met, True)


def _pick(runs: list[_Run], running_time_s: float) -> _Run | None:
    """The run that meets the time, then has fewest short arcs, then least energy; else the nearest."""
    if not runs:
        return None
    tol = _tolerance(running_time_s)

    def key(r: _Run) -> tuple:
        miss = abs(r.plan.running_time_s - running_time_s)
        return (miss > tol, len(r.short), miss if miss > tol else r.energy_j)

    return min(runs, key=key)


def _shift_last(
    rr: RegimeRules, run: _Run, running_time_s: float, template: SectionPlan, regime: int
) -> list[_Run]:
    """Runs of ``run``'s program with the start of its last arc of ``regime`` (coasting: the later
    the shorter the run; traction after a hold: the later the longer) moved to where the running
    time is met, by Brent's method between its neighbours' starts."""
    p = run.program
    coast = [c for c in range(1, len(p)) if p[c].regime == regime]
    if not coast:
        return []
    c = coast[-1]
    # a traction arc moves with the coasting arc after it (it keeps its length, about the minimum)
    n = 2 if regime == codes.TRACTION and c + 1 < len(p) and p[c + 1].regime == codes.COAST else 1
    width = p[c + n - 1].start_m - p[c].start_m
    lo = p[c - 1].start_m + 1e-3
    hi = (p[c + n].start_m if c + n < len(p) else rr.sv.s1) - 1e-3 - width
    out: dict[float, _Run] = {}

    def excess(x: float) -> float:
        moved = [_Arc(a.regime, a.start_m + x - p[c].start_m, a.hold_mps) for a in p[c : c + n]]
        r = rr.run([*p[:c], *moved, *p[c + n :]], template)
        if r is None:
            return np.nan
        out[x] = r
        return r.plan.running_time_s - running_time_s

    if not hi > lo:
        return []
    # from where it starts now, towards the side that moves the running time the right way
    here = min(max(p[c].start_m, lo), hi)
    f_here = run.plan.running_time_s - running_time_s
    for a, b in ((here, hi), (lo, here)):
        f_a = f_here if a == here else excess(a)
        f_b = f_here if b == here else excess(b)
        if np.isfinite(f_a) and np.isfinite(f_b) and f_a * f_b < 0.0:
            with contextlib.suppress(ValueError):  # a stall inside the bracket: keep what was found
                brentq(excess, a, b, xtol=1e-6, maxiter=SPEED_SEARCH_ITERATIONS, disp=False)
            break
    return list(out.values())


def _same(run: _Run, plan: SectionPlan) -> bool:
    """Whether a driven run is the optimal plan itself (the rules do not bind): same time and energy."""
    return (
        abs(run.plan.running_time_s - plan.running_time_s) <= 1e-3
        and not any(kind == REMOTOR for _, kind, *_ in run.arcs)
        and len(run.program) == len(_program(plan))
    )
