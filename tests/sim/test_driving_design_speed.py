"""DrivingSession: effort beyond the last table point follows the train file, and traction never
takes the train past its design speed (issue 19: a metro with a design speed of 80 km/h reached
147 km/h at full power because the table's last value was extrapolated)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from simcases import make_route, make_train

from trainsim.constants import KMH
from trainsim.model.effort import EffortCurve
from trainsim.model.laws import Quadratic
from trainsim.sim.driving import DrivingSession, _Scalar, _ScalarEffort
from trainsim.sim.profile import PiecewiseLinear


def _full_power(session: DrivingSession, seconds: float, dt_s: float = 0.5) -> list:
    states = []
    for _ in range(int(seconds / dt_s)):
        states.append(session.step(1.0, dt_s))
    return states


def test_full_power_holds_the_design_speed_on_level_track() -> None:
    # 200 kN constant to any speed, Davis resistance; the line allows 200 km/h, the train 80 km/h
    res = Quadratic(3000.0, 0.0, 6.0)
    train = make_train(traction_n=200e3, resistance=res, vmax_kmh=80.0)
    session = DrivingSession(train=train, route=make_route(length_m=20_000.0, limit_kmh=200.0))
    states = _full_power(session, 200.0)
    top = max(s.speed_mps for s in states)
    # one 0.1 s substep can cross the design speed by at most a * h (a <= F / (rho m) = 0.61 m/s2)
    assert 80.0 * KMH <= top <= 80.0 * KMH + 0.1 * 200e3 / (1.1 * 300e3)
    last = states[-1]
    # held: the tractive effort is the running resistance at that speed (the governor's effort)
    v = last.speed_mps
    assert last.traction_force_n == pytest.approx(res.c0 + res.c2 * v * v, rel=1e-12)
    assert abs(last.acceleration_mps2) < 1e-9
    assert last.speed_mps == pytest.approx(top, abs=1e-9)


def test_gravity_may_carry_the_train_over_but_traction_never_does() -> None:
    train = make_train(traction_n=200e3, vmax_kmh=60.0)  # no running resistance
    session = DrivingSession(
        train=train, route=make_route(length_m=30_000.0, limit_kmh=200.0, gradient_permille=-10.0)
    )
    states = _full_power(session, 120.0)
    over = [s for s in states if s.speed_mps > 60.0 * KMH + 1e-6]
    assert over, "a 10 per mille fall accelerates the train past 60 km/h"
    assert all(s.traction_force_n == 0.0 for s in over)
    # coasting on the fall: a = g i / rho exactly
    assert over[-1].acceleration_mps2 == pytest.approx(9.80665 * 0.010 / 1.1, rel=1e-9)


def test_beyond_the_table_power_limited_when_the_file_gives_max_power() -> None:
    # table to 40 km/h (200 kN flat), 2 MW cap, design speed 120 km/h: above 36 km/h F = P / v
    table = EffortCurve.from_table([0.0, 40 * KMH], [200e3, 200e3]).capped(power_cap_w=2e6)
    train = make_train(traction=table, vmax_kmh=120.0)
    session = DrivingSession(train=train, route=make_route(length_m=40_000.0, limit_kmh=200.0))
    states = _full_power(session, 150.0)
    beyond = [s for s in states if 40 * KMH < s.speed_mps < 120 * KMH]
    assert beyond
    for s in beyond:
        assert s.traction_force_n == pytest.approx(2e6 / s.speed_mps, rel=1e-12)
    # with no resistance, constant power: v^2 = v0^2 + 2 P t / (rho m) between two states
    a, b = beyond[0], beyond[-1]
    lhs = b.speed_mps**2 - a.speed_mps**2
    assert lhs == pytest.approx(2 * 2e6 * (b.time_s - a.time_s) / (1.1 * 300e3), rel=1e-6)


def test_beyond_the_table_zero_when_the_table_ends_at_zero() -> None:
    # the effort falls linearly to 0 kN at 50 km/h and stays 0 beyond: the train stops accelerating
    table = EffortCurve.from_table([0.0, 20 * KMH, 50 * KMH], [200e3, 200e3, 0.0])
    train = make_train(traction=table, vmax_kmh=100.0, resistance=Quadratic(2000.0))
    session = DrivingSession(train=train, route=make_route(length_m=40_000.0, limit_kmh=200.0))
    states = _full_power(session, 400.0)
    top = max(s.speed_mps for s in states)
    # balance F(v) = R: 200e3 (50 - V) / 30 = 2000 at V = 49.7 km/h
    assert top == pytest.approx((50.0 - 30.0 * 2000.0 / 200e3) * KMH, rel=1e-6)
    assert top < 50 * KMH


def test_metro_example_never_passes_its_design_speed_at_full_power() -> None:
    from trainsim.web.examples import route_spec, train_spec

    train = train_spec("metro_b").to_train("metro")
    route = route_spec("metro_b").to_route("metro")
    session = DrivingSession(train=train, route=route)
    states = _full_power(session, 120.0)
    top = max(s.speed_mps for s in states)
    assert top <= train.max_speed_mps + 0.1 * 1.2  # one substep at under 1.2 m/s2
    assert top > train.max_speed_mps - 1.0 * KMH  # and it does reach it


def test_scalar_evaluators_give_the_numpy_values() -> None:
    rng = np.random.default_rng(19)
    x = np.cumsum(rng.uniform(1.0, 50.0, 40))
    f = PiecewiseLinear(x, rng.normal(size=39), rng.normal(size=39))
    fast = _Scalar(f)
    for s in np.concatenate([x, x + 1e-7, rng.uniform(x[0] - 100, x[-1] + 100, 500)]):
        assert fast(float(s)) == float(f(s))
    curve = EffortCurve.piecewise(
        [0.0, 10.0, 20.0],
        [[3e5, -100.0, 0.0, 0.0], [2e5, 0.0, -50.0, 0.0], [0.0, 0.0, 0.0, 4e6]],
        force_cap_n=2.5e5,
        power_cap_w=3.5e6,
    )
    fast_curve = _ScalarEffort(curve)
    for v in np.concatenate([[0.0, 1e-4, 10.0, 20.0], rng.uniform(0.0, 60.0, 500)]):
        assert fast_curve(float(v)) == float(curve(v))
    hyperbolic = EffortCurve.piecewise([0.0], [[0.0, 0.0, 0.0, 1e6]], force_cap_n=3e5)
    assert _ScalarEffort(hyperbolic)(0.0) == float(hyperbolic(0.0)) == 3e5
    assert math.isfinite(_ScalarEffort(hyperbolic)(1e-9))
