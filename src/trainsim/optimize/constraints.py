"""Driving constraints that ATO systems and drivers use, applied to any strategy.

* ``max_acceleration_mps2`` / ``max_deceleration_mps2`` (passenger comfort): the traction force is
  capped at rho m a_max and the braking forces (service and regenerative) at rho m d_max, as
  TTOBench's trains do (the acceleration on level track without resistance; on a descent the
  train may accelerate a little more). The reference also bounds the kinematic acceleration
  (v_{k+1}^2 - v_k^2) / (2 h) of every interval, grade included.
* ``max_jerk_mps3``: the reference bounds the change of acceleration between two intervals per
  second; the optimal strategy's regimes switch instantly (a bang-singular-bang control) and
  have no jerk limit.
* ``speed_margin_mps``: holding below every speed limit by a margin (drivers and ATO keep some
  km/h below the overspeed warning): every limit is lowered by the margin.
* ``min_regime_time_s``: every regime arc (traction, holding, coasting, braking) lasts at least this
  long, except where a speed limit, the stop or a gradient (holding impossible) forces a shorter
  one; the optimal strategy meets it by merging short arcs into their neighbours
  (``regime_rules``), the reference reports the arcs that are shorter (not an NLP constraint).
* ``coast_min_speed_mps``: the train coasts only above this speed; below it, it holds the speed
  (powering where the gradient needs it), as ATO's coast-remotor does. The optimal strategy
  replaces coasting below the speed by holding it (``regime_rules``); the reference keeps every
  speed at or above min(this speed, the fastest run's speed) (the train falls below it only on
  the braking curves to the stop and to lower limits).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from trainsim.errors import InputError
from trainsim.model.route import Route
from trainsim.model.train import Train

#: Largest minimum regime time accepted [s]: an hour, beyond any section's running time.
MAX_REGIME_TIME_S = 3600.0
#: Largest lowest coasting speed accepted [m/s] (500 km/h, above every train's design speed).
MAX_COAST_MIN_SPEED_MPS = 500.0 / 3.6


@dataclass(frozen=True)
class DrivingConstraints:
    """Comfort and driving constraints (module doc); None or 0: not constrained.

    Attributes:
        max_acceleration_mps2: largest acceleration [m/s^2].
        max_deceleration_mps2: largest deceleration, positive [m/s^2].
        max_jerk_mps3: largest change of acceleration per second [m/s^3] (reference only).
        speed_margin_mps: how far below every speed limit the train stays [m/s].
        min_regime_time_s: shortest duration of a regime arc [s] (0: any).
        coast_min_speed_mps: lowest speed at which the train coasts [m/s] (0: any).
    """

    max_acceleration_mps2: float | None = None
    max_deceleration_mps2: float | None = None
    max_jerk_mps3: float | None = None
    speed_margin_mps: float = 0.0
    min_regime_time_s: float = 0.0
    coast_min_speed_mps: float = 0.0

    def __post_init__(self) -> None:
        for name in ("max_acceleration_mps2", "max_deceleration_mps2", "max_jerk_mps3"):
            x = getattr(self, name)
            if x is not None and not (isinstance(x, int | float) and np.isfinite(x) and x > 0.0):
                raise InputError("must be a finite number > 0", field=name, value=x, allowed="> 0 or none")
        for name, allowed in (
            ("speed_margin_mps", ">= 0"),
            ("min_regime_time_s", f">= 0 and <= {MAX_REGIME_TIME_S:g} s"),
            ("coast_min_speed_mps", f">= 0 and <= {MAX_COAST_MIN_SPEED_MPS:g} m/s"),
        ):
            m = getattr(self, name)
            top = {"min_regime_time_s": MAX_REGIME_TIME_S, "coast_min_speed_mps": MAX_COAST_MIN_SPEED_MPS}
            if not (
                isinstance(m, int | float)
                and not isinstance(m, bool)
                and np.isfinite(m)
                and 0.0 <= m <= top.get(name, np.inf)
            ):
                raise InputError(f"must be a finite number {allowed}", field=name, value=m, allowed=allowed)

    @property
    def regime_rules(self) -> bool:
        """Whether a minimum regime time or a lowest coasting speed is asked for."""
        return self.min_regime_time_s > 0.0 or self.coast_min_speed_mps > 0.0


def constrained_train(train: Train, dc: DrivingConstraints) -> Train:
    """The train with its traction capped at rho m a_max and its braking at rho m d_max."""
    out = train
    M = train.inertial_mass_kg
    if dc.max_acceleration_mps2 is not None:
        out = dataclasses.replace(out, traction=out.traction.capped(force_cap_n=M * dc.max_acceleration_mps2))
    if dc.max_deceleration_mps2 is not None:
        b = out.braking
        cap = M * dc.max_deceleration_mps2
        if b.service_force is None:
            braking = dataclasses.replace(
                b, deceleration_mps2=min(b.deceleration_mps2, dc.max_deceleration_mps2)
            )
        else:
            braking = dataclasses.replace(b, service_force=b.service_force.capped(force_cap_n=cap))
        if braking.regenerative is not None:
            braking = dataclasses.replace(braking, regenerative=braking.regenerative.capped(force_cap_n=cap))
        out = dataclasses.replace(out, braking=braking)
    return out


def constrained_route(route: Route, dc: DrivingConstraints) -> Route:
    """The route with every speed limit lowered by the margin (never below half the limit)."""
    if dc.speed_margin_mps <= 0.0:
        return route
    limits = []
    for lim in route.speed_limits:
        if dc.speed_margin_mps >= 0.5 * lim.limit_mps:
            raise InputError(
                "the speed margin is not small against a speed limit",
                field="speed_margin_mps",
                value=dc.speed_margin_mps,
                allowed=f"< {0.5 * lim.limit_mps:.2f} m/s (half the limit of {lim.limit_mps:.2f} m/s)",
            )
        limits.append(dataclasses.replace(lim, limit_mps=lim.limit_mps - dc.speed_margin_mps))
    return dataclasses.replace(route, speed_limits=tuple(limits))


def kinematic_limits(s: np.ndarray, v: np.ndarray, dc: DrivingConstraints) -> list[str]:
    """Where a run (positions [m], speeds [m/s]) exceeds the acceleration or deceleration limits:
    the acceleration (v_{k+1}^2 - v_k^2) / (2 h) of each step against them, 1 % tolerance."""
    h = np.diff(s)
    ok = h > 1e-9
    a = (v[1:][ok] ** 2 - v[:-1][ok] ** 2) / (2.0 * h[ok])
    out = []
    if dc.max_acceleration_mps2 is not None and a.size and a.max() > 1.01 * dc.max_acceleration_mps2:
        out.append(f"acceleration {a.max():.3f} m/s^2 above the limit {dc.max_acceleration_mps2:g} m/s^2")
    if dc.max_deceleration_mps2 is not None and a.size and -a.min() > 1.01 * dc.max_deceleration_mps2:
        out.append(f"deceleration {-a.min():.3f} m/s^2 above the limit {dc.max_deceleration_mps2:g} m/s^2")
    return out
