"""The fastest-run simulator against closed-form solutions (errors far below 0.1 %)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from simcases import make_route, make_train

from trainsim.constants import KMH
from trainsim.constants import STANDARD_GRAVITY as G
from trainsim.model import Quadratic
from trainsim.model.scenario import RunSettings
from trainsim.sim.codes import BRAKE, CRUISE, TRACTION
from trainsim.sim.fastest import run_fastest

REL = 1e-6  # closed-form cases are integrated exactly up to round-off and root-finding


def test_constant_force_without_resistance_matches_kinematics():
    F, B, m, rho = 200e3, 300e3, 300e3, 1.1
    train = make_train(traction_n=F, braking_n=B, mass_kg=m, rho=rho)
    route = make_route(length_m=10_000.0, limit_kmh=100.0)
    result = run_fastest(train, route)
    v = 100 * KMH
    a, b = F / (m * rho), B / (m * rho)
    d_acc, d_brk = v**2 / (2 * a), v**2 / (2 * b)
    expected = v / a + (10_000.0 - d_acc - d_brk) / v + v / b
    assert result.status == "ok"
    assert result.running_time_s == pytest.approx(expected, rel=REL)
    tr = result.trace
    ds = np.diff(tr.position_m)
    assert ds[tr.regime[:-1] == TRACTION].sum() == pytest.approx(d_acc, rel=REL)
    assert ds[tr.regime[:-1] == BRAKE].sum() == pytest.approx(d_brk, rel=REL)
    assert ds[tr.regime[:-1] == CRUISE].sum() == pytest.approx(10_000.0 - d_acc - d_brk, rel=REL)
    # traction work = kinetic energy + nothing else in the acceleration phase
    assert result.energy_kwh.traction * 3.6e6 == pytest.approx(F * d_acc, rel=REL)
    assert result.energy_kwh.braking * 3.6e6 == pytest.approx(B * d_brk, rel=REL)


def test_uniform_grade_reduces_acceleration_by_g_times_grade():
    F, m, rho, i = 250e3, 400e3, 1.08, 8.0
    train = make_train(traction_n=F, braking_n=400e3, mass_kg=m, rho=rho)
    route = make_route(length_m=8_000.0, limit_kmh=90.0, gradient_permille=i)
    result = run_fastest(train, route)
    v = 90 * KMH
    a = (F - m * G * i / 1000) / (m * rho)
    b = (400e3 + m * G * i / 1000) / (m * rho)  # the grade helps braking
    expected = v / a + (8_000.0 - v**2 / (2 * a) - v**2 / (2 * b)) / v + v / b
    assert result.running_time_s == pytest.approx(expected, rel=REL)
    # cruising uphill takes exactly the grade force
    tr = result.trace
    cruise = tr.regime == CRUISE
    assert np.allclose(tr.traction_force_n[cruise], m * G * i / 1000)
    # the energy balance includes the potential energy gained
    assert abs(result.energy_balance["relative_error"]) < 1e-6


def test_braking_distance_with_davis_resistance_matches_quadrature():
    from scipy.integrate import quad

    res = Quadratic(3000.0, 40.0, 6.0)
    B, m, rho = 250e3, 350e3, 1.06
    train = make_train(traction_n=300e3, braking_n=B, mass_kg=m, rho=rho, resistance=res)
    route = make_route(length_m=6_000.0, limit_kmh=120.0)
    result = run_fastest(train, route)
    M = m * rho
    v = 120 * KMH
    d_ref = quad(lambda u: M * u / (B + res(u)), 0.0, v, epsabs=1e-12)[0]
    t_ref = quad(lambda u: M / (B + res(u)), 0.0, v, epsabs=1e-12)[0]
    tr = result.trace
    braking = tr.regime[:-1] == BRAKE
    assert np.diff(tr.position_m)[braking].sum() == pytest.approx(d_ref, rel=1e-7)
    assert np.diff(tr.time_s)[braking].sum() == pytest.approx(t_ref, rel=1e-6)


def test_acceleration_against_davis_resistance_matches_quadrature():
    from scipy.integrate import quad

    res = Quadratic(4000.0, 80.0, 9.0)
    F, m, rho = 180e3, 300e3, 1.1
    train = make_train(traction_n=F, braking_n=300e3, mass_kg=m, rho=rho, resistance=res)
    route = make_route(length_m=20_000.0, limit_kmh=140.0)
    result = run_fastest(train, route)
    M = m * rho
    v = 140 * KMH
    d_ref = quad(lambda u: M * u / (F - res(u)), 0.0, v, epsabs=1e-12)[0]
    t_ref = quad(lambda u: M / (F - res(u)), 0.0, v, epsabs=1e-12)[0]
    tr = result.trace
    acc = tr.regime[:-1] == TRACTION
    assert np.diff(tr.position_m)[acc].sum() == pytest.approx(d_ref, rel=1e-7)
    assert np.diff(tr.time_s)[acc].sum() == pytest.approx(t_ref, rel=1e-6)


def test_coasting_against_davis_resistance_matches_closed_form():
    """Coasting from v0 with R = c0 + c2 v^2 stops after s = M/(2 c2) ln(1 + c2 v0^2/c0) and
    t = M / sqrt(c0 c2) atan(v0 sqrt(c2/c0))."""
    from trainsim.sim.driving import DrivingSession

    c0, c2, m, rho = 5000.0, 8.0, 300e3, 1.1
    M = m * rho
    train = make_train(resistance=Quadratic(c0, 0.0, c2), mass_kg=m, rho=rho, traction_n=3e5)
    route = make_route(length_m=30_000.0, limit_kmh=200.0)
    session = DrivingSession(train=train, route=route, stop_window_m=0.0)
    state = session.state()
    while state.speed_mps < 30.0:
        state = session.step(1.0, 0.05)
    # from here on coast: compare with the closed form from the state reached
    v0, s0, t0 = state.speed_mps, state.position_m, state.time_s
    while state.speed_mps > 0.0:
        state = session.step(0.0, 1.0)
    s_ref = M / (2 * c2) * np.log(1 + c2 * v0**2 / c0)
    t_ref = M / np.sqrt(c0 * c2) * np.arctan(v0 * np.sqrt(c2 / c0))
    assert state.position_m - s0 == pytest.approx(s_ref, rel=1e-4)
    # the stop lies inside the last 1 s command; time to rest within that step's resolution
    assert state.time_s - t0 == pytest.approx(t_ref, abs=1.0)


def test_rear_must_clear_a_restriction_before_accelerating():
    L = 200.0
    train = make_train(length_m=L, traction_n=300e3, braking_n=300e3)
    route = make_route(length_m=6_000.0, limits=[(0, 1000, 100), (1000, 1300, 40), (1300, 6000, 100)])
    tr = run_fastest(train, route).trace
    inside = (tr.position_m >= 1000.0) & (tr.position_m < 1300.0 + L)
    assert tr.speed_mps[inside].max() <= 40 * KMH + 1e-9
    # it stays at 40 km/h until the rear clears at 1500 m, and then accelerates
    after = tr.position_m >= 1300.0 + L
    first_after = np.flatnonzero(after)[0]
    assert tr.position_m[first_after] == pytest.approx(1500.0, abs=1e-6)
    assert tr.regime[first_after] == TRACTION
    # it arrives at the restriction exactly at 40 km/h after braking
    at = np.flatnonzero(np.isclose(tr.position_m, 1000.0))[0]
    assert tr.speed_mps[at] == pytest.approx(40 * KMH, rel=1e-9)


def test_stall_on_a_grade_is_reported_with_the_best_feasible_result():
    train = make_train(traction_n=50e3, mass_kg=500e3)  # 10 N/t: cannot climb 20 per mille
    route = make_route(length_m=5_000.0, gradient_permille=20.0)
    result = run_fastest(train, route)
    assert result.status == "stalled"
    assert any("stalls" in w for w in result.warnings)


def test_stall_part_way_ends_the_trace_where_the_train_stops():
    from trainsim.model import GradientSection

    train = make_train(traction_n=120e3, mass_kg=600e3, resistance=Quadratic(3000.0, 0.0, 5.0))
    # the train enters the grade at 100 km/h and runs out of momentum about 7.7 km up it
    route = dataclasses.replace(
        make_route(length_m=16_000.0), gradients=(GradientSection(3000.0, 16_000.0, 25.0),)
    )
    result = run_fastest(train, route)
    assert result.status == "stalled"
    tr = result.trace
    assert tr.speed_mps[-1] == 0.0
    assert 9000.0 < tr.position_m[-1] < 12_000.0
    assert f"{tr.position_m[-1]:.1f}" in result.warnings[0]


@pytest.mark.parametrize("step", [50.0, 10.0, 2.0])
def test_invariants(step):
    res = Quadratic(2000.0, 30.0, 5.0)
    train = make_train(resistance=res)
    route = make_route(
        length_m=9_000.0,
        limits=[(0, 3000, 120), (3000, 3500, 60), (3500, 9000, 140)],
        stations=[("A", 0, 0), ("B", 4200, 30), ("C", 9000, 0)],
    )
    r = run_fastest(train, route, RunSettings(max_step_m=step))
    tr = r.trace
    assert np.all(np.isfinite(tr.speed_mps)) and np.all(np.isfinite(tr.time_s))
    assert np.all(tr.speed_mps >= 0)
    assert np.all(np.diff(tr.position_m) >= 0)
    assert np.all(np.diff(tr.time_s) >= 0)
    assert np.all(tr.speed_mps <= tr.speed_limit_mps + 1e-6)
    assert [s.dwell_s for s in r.sections] == [30.0, 0.0]
    assert abs(r.energy_balance["relative_error"]) < 1e-3


def test_driving_session_from_any_state():
    from trainsim.sim.driving import DrivingSession

    train = make_train(traction_n=200e3, mass_kg=300e3, rho=1.1)
    route = make_route(length_m=5_000.0, limit_kmh=200.0)
    session = DrivingSession(
        train=train, route=route, start_position_m=1000.0, start_speed_mps=20.0, start_time_s=50.0
    )
    state = session.step(1.0, 2.0)
    # constant force, no resistance: v = 20 + a t, s = 1000 + 20 t + a t^2 / 2 with a = F / (rho m)
    a = 200e3 / (1.1 * 300e3)
    assert state.speed_mps == pytest.approx(20.0 + 2.0 * a, rel=1e-9)
    assert state.position_m == pytest.approx(1000.0 + 40.0 + 2.0 * a, rel=1e-9)
    assert state.time_s == pytest.approx(52.0)
    assert state.next_stop_name == "B"
    with pytest.raises(Exception, match="outside the route"):
        DrivingSession(train=train, route=route, start_position_m=9000.0)
