"""Coasting over a crest ahead of a steep descent that ends at the stop, with a regenerative brake
(``SectionSolver._coast_over_crest``): source 002's metro on a 20 per mille hump."""

from __future__ import annotations

import dataclasses
from itertools import pairwise
from pathlib import Path

import numpy as np
import pytest
from test_optimal_structure import net_energy_j, reference_energy_j

import trainsim
from trainsim.constants import KMH
from trainsim.model import GradientSection, Route, SpeedLimit, Station
from trainsim.optimize.optimal import SectionSolver, _within_service, regenerative_holding_speed
from trainsim.sim import codes

ROOT = Path(__file__).resolve().parents[2]
METRO = trainsim.load_scenario(ROOT / "examples" / "metro_b" / "scenario.yaml").train


def hump_solver(regen: bool = True) -> SectionSolver:
    train = METRO
    if regen:
        braking = dataclasses.replace(METRO.braking, regenerative=METRO.traction.scaled(0.8))
        train = dataclasses.replace(METRO, braking=braking)
    route = Route(
        name="hump",
        start_m=0.0,
        end_m=3000.0,
        stations=(Station("A", 0.0), Station("B", 3000.0)),
        speed_limits=(SpeedLimit(0.0, 3000.0, 80 * KMH),),
        gradients=(GradientSection(1000.0, 2000.0, 20.0), GradientSection(2000.0, 3000.0, -20.0)),
    )
    return SectionSolver(train, route, 0.0, 3000.0)


def test_metro_with_regeneration_coasts_over_the_crest_as_the_reference():
    solver = hump_solver()
    T = solver.fastest_time_s * 1.20
    plan = solver.solve(T)
    assert plan.feasible
    assert abs(plan.running_time_s - T) <= max(0.5, 5e-4 * T)
    # the train leaves its holding arc on the climb and coasts over the crest
    climb_end = (plan.s > 1800.0) & (plan.s < 2000.0)
    assert np.all(plan.regime[climb_end] == codes.COAST)
    at_crest = float(np.interp(2000.0, plan.s, plan.v))
    assert at_crest < plan.holding_speed_mps - 10 * KMH
    # on the descent it comes up to the regenerative holding speed W and brakes electrically only
    W = regenerative_holding_speed(solver.train, plan.price_of_time_w, solver.eta_r)
    descent = plan.s > 2000.0
    assert plan.v[descent].max() == pytest.approx(W, rel=1e-3)
    # (the service brake only in the last metres, where its curve to the stop lies below the
    # regenerative one: 150 kN under 5 km/h)
    assert not np.any((plan.regime == codes.BRAKE) & (plan.s < solver.s1 - 10.0))
    assert np.any(plan.regime[descent] == codes.REGEN)
    energy = net_energy_j(solver, plan)
    assert energy == pytest.approx(reference_energy_j(solver, T), rel=5e-3)
    # holding V up to the crest instead (the strategy before the crest coast) costs more
    solver._coast_over_crest = lambda seg, *args: seg
    plain = solver.solve(T)
    assert net_energy_j(solver, plain) > energy * 1.02


def test_without_regeneration_the_hump_run_is_left_as_it_was():
    solver = hump_solver(regen=False)
    T = solver.fastest_time_s * 1.20
    plan = solver.solve(T)
    solver._coast_over_crest = lambda seg, *args: seg
    plain = hump_solver(regen=False).solve(T)
    np.testing.assert_array_equal(plan.s, plain.s)
    np.testing.assert_array_equal(plan.v, plain.v)


@pytest.mark.parametrize("factor", [1.14, 1.30])
def test_hump_with_regeneration_near_the_reference_at_other_supplements(factor):
    solver = hump_solver()
    T = solver.fastest_time_s * factor
    plan = solver.solve(T)
    assert abs(plan.running_time_s - T) <= max(0.5, 5e-4 * T)
    assert net_energy_j(solver, plan) == pytest.approx(reference_energy_j(solver, T), rel=5e-3)


def test_hump_energy_falls_with_running_time():
    solver = hump_solver()
    energies = [
        net_energy_j(solver, solver.solve(solver.fastest_time_s * f)) for f in np.arange(1.10, 1.31, 0.04)
    ]
    assert all(later < earlier for earlier, later in pairwise(energies))


def test_regenerative_curve_kept_within_the_service_curve():
    # the metro's regenerative brake (0.8 x traction, 298 kN at standstill) exceeds its service
    # brake (150 kN below 5 km/h): the solver's electric brake is the lower of the two at every speed
    regen, service = METRO.traction.scaled(0.8), METRO.braking.service_force
    v = np.linspace(0.0, 100 * KMH, 5001)
    assert np.any(regen(v) > service(v))
    np.testing.assert_allclose(
        _within_service(regen, service)(v), np.minimum(regen(v), service(v)), atol=1e-6
    )
    assert np.all(hump_solver().train.braking.regenerative(v) <= service(v) + 1e-6)
    # a regenerative curve below the service curve everywhere is kept as it is
    low = METRO.traction.scaled(0.1)
    assert _within_service(low, service) is low


def test_regenerative_holding_arc_is_labelled_and_counted_as_regeneration():
    """The arc held at W on the hump's descent is reported as holding ("cruising"), driven by the
    electric brake alone, and its energy is regenerated: eta_r x (m g i - R(W)) per metre, the force
    that holds W on a -20 per mille grade, computed here from the train's data."""
    from trainsim.constants import STANDARD_GRAVITY
    from trainsim.optimize.api import _result
    from trainsim.sim.fastest import run_fastest

    solver = hump_solver()
    train, route, settings = solver.train, solver.route, trainsim.RunSettings()
    plan = solver.solve(solver.fastest_time_s * 1.20)
    W = regenerative_holding_speed(train, plan.price_of_time_w, solver.eta_r)
    held = (plan.regime[:-1] == codes.CRUISE) & (plan.s[:-1] > 2000.0) & (np.abs(plan.v[:-1] - W) < 1e-6 * W)
    idx = np.flatnonzero(held)
    assert len(idx) >= 2
    a, b = float(plan.s[idx[0]]), float(plan.s[idx[-1] + 1])
    assert b - a > 50.0
    result = _result(
        "optimal", train, route, settings, run_fastest(train, route, settings), [plan], [plan.running_time_s],
        solvers=[solver],
    )  # fmt: skip
    assert result.summary()["status"] == "ok" and not result.warnings
    trace = result.run.trace
    on = (trace.position_m >= a) & (trace.position_m < b)
    assert on.sum() >= 2
    assert set(np.asarray(trace.regime_names)[on]) == {"cruising"}
    assert np.all(trace.traction_force_n[on] == 0.0)
    assert np.all(trace.friction_braking_force_n[on] == 0.0)
    holding_force = train.mass_kg * STANDARD_GRAVITY * 0.020 - train.resistance_law(W)
    np.testing.assert_allclose(trace.regenerative_braking_force_n[on], holding_force, rtol=1e-6)

    # the energy over the arc: regenerated, none drawn for traction
    def over_arc(cumulative: np.ndarray) -> float:
        return float(np.interp(b, trace.position_m, cumulative) - np.interp(a, trace.position_m, cumulative))

    eta_r = train.electrical.regenerative_efficiency * train.electrical.receptivity
    assert over_arc(trace.traction_work_j) == pytest.approx(0.0, abs=1e-6)
    assert over_arc(trace.regenerated_energy_j) == pytest.approx(eta_r * holding_force * (b - a), rel=1e-6)
    assert over_arc(trace.electrical_energy_j) == pytest.approx(-eta_r * holding_force * (b - a), rel=1e-6)
