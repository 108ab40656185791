"""Driving by command, step by step in the time domain (source 002's accelerator and brake).

The session holds the train's state; each ``step(command, dt_s)`` applies a command in [-1, 1]
(positive: that share of the maximum tractive effort; negative: that share of the service braking
force; 0: coasting) for ``dt_s`` seconds. Stops are served when the train comes to rest with its
head within ``stop_window_m`` of a stop it has not served yet; it then dwells (commands are
ignored) for the station's dwell time. The recorded drive converts to the same ``RunResult`` as a
fastest run, so both can be compared.

Traction follows the train's effort curve as its file defines it, also beyond the last point of a
table (constant, or lower where ``max_power_kw`` caps it: power-limited; zero where the table ends
at 0 kN), but never drives the train past its design speed ``max_speed_mps``: at or above it the
tractive effort is at most what holds the speed (the running and line resistance, never
negative), as a speed governor does. Gravity on a falling grade can still carry the train over
it; braking is then the driver's (or ATP's) job.

A live drive evaluates the forces hundreds of thousands of times per simulated hour, so the
route's profiles and the train's laws are evaluated here as plain floats (:class:`_Scalar`,
:class:`_ScalarEffort`): the same formulas and the same numbers as their numpy ``__call__``,
without numpy's per-call overhead on scalars.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from dataclasses import dataclass

import numpy as np

from trainsim.errors import InputError
from trainsim.model.effort import POWER_CAP_MIN_SPEED_MPS, EffortCurve
from trainsim.model.route import Route
from trainsim.model.scenario import RunSettings, Scenario
from trainsim.model.train import Train
from trainsim.sim.codes import BRAKE, COAST, DWELL, TRACTION
from trainsim.sim.profile import (
    PiecewiseLinear,
    line_resistance_profile,
    line_voltage,
    speed_ceiling,
    traction_availability,
)
from trainsim.sim.result import RunResult, build_result

#: Largest internal time step [s]; a command may span many of them.
MAX_SUBSTEP_S = 0.1
#: A stop counts when the head is this close to the stopping point [m].
DEFAULT_STOP_WINDOW_M = 5.0
#: Longest drive a session records [s], to bound memory.
MAX_DRIVE_S = 6 * 3600.0


class _Scalar:
    """A :class:`~trainsim.sim.profile.PiecewiseLinear` evaluated at one position [m] with floats:
    the same lookup (first piece whose start is <= s, clamped to the ends) and interpolation."""

    __slots__ = ("last", "left", "right", "x")

    def __init__(self, f: PiecewiseLinear) -> None:
        self.x: list[float] = f.x.tolist()
        self.left: list[float] = f.left.tolist()
        self.right: list[float] = f.right.tolist()
        self.last = len(self.left) - 1

    def __call__(self, s: float) -> float:
        x = self.x
        k = bisect_right(x, s) - 1
        k = 0 if k < 0 else self.last if k > self.last else k
        x0 = x[k]
        frac = (s - x0) / (x[k + 1] - x0)
        frac = 0.0 if frac < 0.0 else 1.0 if frac > 1.0 else frac
        left = self.left[k]
        return left + (self.right[k] - left) * frac


class _ScalarEffort:
    """An :class:`~trainsim.model.effort.EffortCurve` evaluated at one speed [m/s] with floats
    (the formula of ``EffortCurve.__call__``)."""

    __slots__ = ("force_cap", "power_cap", "rows", "starts")

    def __init__(self, curve: EffortCurve) -> None:
        starts, coefficients, self.force_cap, self.power_cap = curve.as_arrays()
        self.starts: list[float] = starts.tolist()
        self.rows: list[tuple[float, ...]] = [tuple(r) for r in coefficients.tolist()]

    def __call__(self, v: float) -> float:
        j = bisect_right(self.starts, v) - 1
        c0, c1, c2, ch = self.rows[j if j > 0 else 0]
        law = c0 + c1 * v + c2 * v * v
        if ch != 0.0:
            law = law + (ch / v if v != 0.0 else math.copysign(math.inf, ch))
        power = self.power_cap / (v if v > POWER_CAP_MIN_SPEED_MPS else POWER_CAP_MIN_SPEED_MPS)
        out = min(law, self.force_cap, power)
        return out if out > 0.0 else 0.0


@dataclass(frozen=True)
class DrivingState:
    """What the driver sees after a step (SI units)."""

    time_s: float
    position_m: float
    speed_mps: float
    acceleration_mps2: float
    command: float
    regime: str
    traction_force_n: float
    braking_force_n: float
    speed_limit_mps: float
    next_limit_position_m: float | None
    next_limit_mps: float | None
    next_stop_name: str | None
    next_stop_distance_m: float | None
    dwell_remaining_s: float
    line_current_a: float | None
    electrical_energy_j: float
    overspeed: bool
    finished: bool
    message: str


class DrivingSession:
    """A train driven by command along a route, from standstill at its first stop."""

    def __init__(
        self,
        scenario: Scenario | None = None,
        *,
        train: Train | None = None,
        route: Route | None = None,
        settings: RunSettings | None = None,
        stop_window_m: float = DEFAULT_STOP_WINDOW_M,
        start_position_m: float | None = None,
        start_speed_mps: float = 0.0,
        start_time_s: float = 0.0,
    ) -> None:
        """A session from standstill at the route's first stop, or from any state: head position
        ``start_position_m`` [m] at speed ``start_speed_mps`` [m/s] and time ``start_time_s`` [s]
        (the next stop is then the first one ahead)."""
        if scenario is not None:
            train, route, settings = scenario.train, scenario.route, scenario.settings
        if train is None or route is None:
            raise InputError("a driving session needs a scenario or a train and a route", field="session")
        self.train = train.at_gravity(route.gravity_mps2)
        train = self.train
        self.route = route
        self.settings = settings or RunSettings()
        self.stop_window_m = stop_window_m
        self._profile = line_resistance_profile(route, train)
        self._ceiling = speed_ceiling(route, train)
        self._available = traction_availability(route, train)
        self._voltage = line_voltage(route, train)
        p = self._profile
        self._gradient, self._curve = _Scalar(p.gradient), _Scalar(p.curve)
        self._tunnel, self._tunnel_v2 = _Scalar(p.tunnel), _Scalar(p.tunnel_v2)
        self._available_at = _Scalar(self._available)
        self._ceiling_at = _Scalar(self._ceiling)
        self._voltage_at = _Scalar(self._voltage)
        # the limit in force just after each breakpoint of the ceiling, for "next limit" lookups
        self._limit_after = [self._ceiling_at(x + 1e-7) for x in self._ceiling_at.x]
        self._next_limit_cache: tuple[int, float, int | None] = (-1, math.nan, None)
        self._traction = _ScalarEffort(train.traction)
        b = train.braking
        self._service = _ScalarEffort(b.service_force) if b.service_force is not None else None
        self._regen = _ScalarEffort(b.regenerative) if b.regenerative is not None else None
        law = train.resistance_law
        self._resistance = (law.c0, law.c1, law.c2)
        self._weight_n = train.mass_kg * route.gravity_mps2
        stops = route.stops
        if not stops:
            raise InputError("the route has no stop to start from", field="stations")
        self._stops = list(stops)
        self._next_stop = 1
        self.time_s = float(start_time_s)
        self.position_m = stops[0].position_m
        self.speed_mps = 0.0
        if start_position_m is not None:
            if not route.start_m <= start_position_m < route.end_m:
                raise InputError(
                    "the start position lies outside the route",
                    field="start_position_m",
                    value=start_position_m,
                    allowed=f"{route.start_m:g} .. {route.end_m:g} m",
                )
            if not 0.0 <= start_speed_mps < 200.0:
                raise InputError("invalid start speed", field="start_speed_mps", value=start_speed_mps)
            self.position_m = float(start_position_m)
            self.speed_mps = float(start_speed_mps)
            ahead = [k for k, st in enumerate(stops) if st.position_m > self.position_m + stop_window_m]
            self._next_stop = ahead[0] if ahead else len(stops)
        self.dwell_remaining_s = 0.0
        self.finished = self._next_stop >= len(stops)
        self._energy_j = 0.0
        self._message = f"at {stops[0].name}" if start_position_m is None else f"at {self.position_m:.0f} m"
        self._record: list[tuple[float, float, float, int, float]] = [
            (self.time_s, self.position_m, self.speed_mps, COAST, 0.0)
        ]
        self._passed: list[str] = []

    # ------------------------------------------------------------------ physics
    def _forces(self, command: float, v: float, s: float) -> tuple[float, float, float]:
        """(traction, braking, resistance) [N] for a command at speed v and head position s."""
        c0, c1, c2 = self._resistance
        running = c0 + c1 * v + c2 * v * v if v > 0 else 0.0
        ratio = self._gradient(s) + self._curve(s) + self._tunnel(s) + self._tunnel_v2(s) * v * v
        resistance = running + self._weight_n * ratio
        traction = 0.0
        if command > 0:
            traction = command * self._available_at(s + 1e-7) * self._traction(v)
            if v >= self.train.max_speed_mps:
                # the design speed: at most the effort that holds the speed (a governor)
                traction = min(traction, resistance if resistance > 0.0 else 0.0)
        braking = 0.0
        if command < 0:
            deceleration = self.train.braking.deceleration_mps2
            if deceleration is not None or self._service is None:
                decel = float(deceleration or 0.0) * self.settings.braking_fraction
                braking = -command * max(self.train.inertial_mass_kg * decel - resistance, 0.0)
            else:
                braking = -command * self.settings.braking_fraction * self._service(v)
        return traction, braking, resistance

    def _line_power_w(self, command: float) -> float:
        """Power drawn from the line now [W] (for the live display; the record is integrated
        properly by ``result``)."""
        elec = self.train.electrical
        if elec is None:
            return 0.0
        v = self.speed_mps
        traction, braking, _ = self._forces(command, v, self.position_m)
        regen = min(braking, self._regen(v)) if self._regen is not None else 0.0
        return (
            traction * v / elec.traction_efficiency
            + elec.auxiliary_power_w
            - regen * v * elec.regenerative_efficiency * elec.receptivity
        )

    def _acceleration(self, command: float, v: float, s: float) -> float:
        traction, braking, resistance = self._forces(command, v, s)
        net = traction - braking - resistance
        if v <= 0.0 and net <= 0.0:
            return 0.0  # at rest, resistance and brakes hold the train; they never push it back
        return net / self.train.inertial_mass_kg

    def _substep(self, command: float, h: float) -> None:
        s, v = self.position_m, self.speed_mps
        a1 = self._acceleration(command, v, s)
        a2 = self._acceleration(command, max(v + 0.5 * h * a1, 0.0), s + 0.5 * h * v)
        a3 = self._acceleration(command, max(v + 0.5 * h * a2, 0.0), s + 0.5 * h * (v + 0.5 * h * a1))
        a4 = self._acceleration(command, max(v + h * a3, 0.0), s + h * (v + 0.5 * h * a2))
        v_new = v + h / 6.0 * (a1 + 2 * a2 + 2 * a3 + a4)
        if v_new < 0.0:
            # stops within the step: constant-deceleration estimate of when and where
            h_stop = h * v / (v - v_new) if v > 0 else 0.0
            s += 0.5 * v * h_stop
            v_new = 0.0
        else:
            s += h / 6.0 * (v + 2 * (v + 0.5 * h * a1) + 2 * (v + 0.5 * h * a2) + (v + h * a3))
        self.position_m = min(s, self.route.end_m)
        self.speed_mps = v_new
        self.time_s += h

    # ------------------------------------------------------------------ API
    def step(self, command: float, dt_s: float) -> DrivingState:
        """Apply ``command`` in [-1, 1] for ``dt_s`` seconds (0 < dt_s <= 60) and return the state."""
        if not math.isfinite(command) or not -1.0 <= command <= 1.0:
            raise InputError("the driving command must be in [-1, 1]", field="command", value=command)
        if not 0.0 < dt_s <= 60.0:
            raise InputError("the time step must be in (0, 60] s", field="dt_s", value=dt_s)
        if self.finished:
            return self.state(command)
        if self.time_s + dt_s > MAX_DRIVE_S:
            self.finished = True
            self._message = "drive too long: stopped recording"
            return self.state(command)
        remaining = dt_s
        while remaining > 1e-12 and not self.finished:
            h = min(MAX_SUBSTEP_S, remaining)
            if self.dwell_remaining_s > 0.0:
                h = min(h, self.dwell_remaining_s)
                self.time_s += h
                self._energy_j += self._line_power_w(0.0) * h
                self.dwell_remaining_s -= h
                self._log(DWELL, 0.0)
                if self.dwell_remaining_s <= 1e-9:
                    self.dwell_remaining_s = 0.0
                    self._message = f"departing {self._stops[self._next_stop - 1].name}"
            else:
                self._log(
                    TRACTION if command > 0 else BRAKE if command < 0 else COAST, abs(command), replace=True
                )
                self._energy_j += self._line_power_w(command) * h
                self._substep(command, h)
                self._after_move()
                self._log(TRACTION if command > 0 else BRAKE if command < 0 else COAST, abs(command))
            remaining -= h
        return self.state(command)

    def _after_move(self) -> None:
        stop = self._stops[self._next_stop]
        ahead = stop.position_m - self.position_m
        if self.speed_mps == 0.0 and abs(ahead) <= self.stop_window_m:
            self._next_stop += 1
            if self._next_stop >= len(self._stops):
                self.finished = True
                self._message = f"arrived at {stop.name}: end of the route"
            else:
                self.dwell_remaining_s = stop.dwell_s
                self._message = f"stopped at {stop.name}: dwell {stop.dwell_s:.0f} s"
        elif ahead < -self.stop_window_m:
            self._passed.append(stop.name)
            self._message = f"passed {stop.name} without stopping"
            self._next_stop += 1
            if self._next_stop >= len(self._stops):
                self.finished = True
        if self.position_m >= self.route.end_m:
            self.finished = True
            self._message = "reached the end of the route"

    def _log(self, regime: int, level: float, replace: bool = False) -> None:
        entry = (self.time_s, self.position_m, self.speed_mps, regime, level)
        if replace:
            # the point that starts a stretch carries that stretch's regime
            self._record[-1] = (*self._record[-1][:3], regime, level)
        else:
            self._record.append(entry)

    def speed_limit_mps(self) -> float:
        """The speed ceiling at the head now (line limits, the rear's clearance and the train's
        design speed) [m/s]."""
        return self._ceiling_at(self.position_m + 1e-7)

    def _next_limit_index(self, s: float, limit: float) -> int | None:
        """Index of the first breakpoint of the ceiling beyond s + 1 um after which the limit
        differs from ``limit`` (None: none ahead); remembered while s stays between breakpoints."""
        first = bisect_right(self._ceiling_at.x, s + 1e-6)
        k, known, found = self._next_limit_cache
        if k == first and known == limit:
            return found
        after = self._limit_after
        found = next((j for j in range(first, len(after)) if abs(after[j] - limit) > 1e-9), None)
        self._next_limit_cache = (first, limit, found)
        return found

    def state(self, command: float = 0.0) -> DrivingState:
        """The current state without moving."""
        s, v = self.position_m, self.speed_mps
        traction, braking, resistance = self._forces(command if self.dwell_remaining_s == 0 else 0.0, v, s)
        limit = self._ceiling_at(s + 1e-7)
        later = self._next_limit_index(s, limit)
        next_pos = self._ceiling_at.x[later] if later is not None else None
        next_lim = self._limit_after[later] if later is not None else None
        nxt = self._stops[self._next_stop] if self._next_stop < len(self._stops) else None
        elec = self.train.electrical
        current = None
        u_line = self._voltage_at(s + 1e-7)
        if elec and u_line > 0:
            current = self._line_power_w(command if self.dwell_remaining_s == 0 else 0.0) / (
                u_line * elec.power_factor
            )
        regime = (
            "dwell"
            if self.dwell_remaining_s > 0
            else "traction"
            if command > 0
            else "braking"
            if command < 0
            else "coasting"
        )
        return DrivingState(
            time_s=self.time_s,
            position_m=s,
            speed_mps=v,
            acceleration_mps2=(traction - braking - resistance) / self.train.inertial_mass_kg
            if v > 0
            else 0.0,
            command=command,
            regime=regime,
            traction_force_n=traction,
            braking_force_n=braking,
            speed_limit_mps=limit,
            next_limit_position_m=next_pos,
            next_limit_mps=next_lim,
            next_stop_name=nxt.name if nxt else None,
            next_stop_distance_m=(nxt.position_m - s) if nxt else None,
            dwell_remaining_s=self.dwell_remaining_s,
            line_current_a=current,
            electrical_energy_j=self._energy_j,
            overspeed=v > limit + 1e-6,
            finished=self.finished,
            message=self._message,
        )

    def result(self) -> RunResult:
        """The drive so far as a RunResult (same trace and summary as a fastest run)."""
        rec = np.array(self._record, dtype=float)
        t, s, v, regime, level = rec[:, 0], rec[:, 1], rec[:, 2], rec[:, 3].astype(np.int8), rec[:, 4]
        warnings = [f"passed {name} without stopping" for name in self._passed]
        if not self.finished:
            warnings.append("the drive has not reached its destination yet")
        served = [st.name for st in self._stops if st.name not in self._passed]
        return build_result(
            train=self.train,
            route=self.route,
            settings=self.settings,
            profile=self._profile,
            ceiling=self._ceiling,
            s=s,
            v=v,
            t=t,
            regime=regime,
            status="ok" if self.finished else "in progress",
            kind="driven",
            warnings=warnings,
            level=level,
            stop_names=served,
        )
