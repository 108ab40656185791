"""The optimal strategy's structure where lines are not flat: coasting ahead of lower limits, leaving
the holding or traction arc ahead of steep descents, keeping the schedule where the running time
jumps with the holding speed, and results that do not depend on earlier solves. Energies are checked
against the reference optimum (CasADi/IPOPT) where it is installed."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

import trainsim
from trainsim.constants import KMH
from trainsim.io.ttobench import read_ttobench_track, read_ttobench_train
from trainsim.model import (
    Braking,
    EffortCurve,
    Electrical,
    GradientSection,
    Quadratic,
    ResistanceTerm,
    Route,
    SpeedLimit,
    Station,
    Train,
)
from trainsim.optimize.optimal import SectionSolver
from trainsim.sim import codes
from trainsim.sim.profile import line_resistance_profile, speed_ceiling
from trainsim.sim.result import build_result

ROOT = Path(__file__).resolve().parents[2]
TTOBENCH = ROOT.parent / "shared" / "data" / "ttobench"


def regen_train() -> Train:
    traction = EffortCurve.power_limited(3.0e6, force_cap_n=250e3)
    return Train(
        name="regenerating test train",
        mass_kg=300e3,
        rotating_mass_factor=1.08,
        length_m=100.0,
        max_speed_mps=160 * KMH,
        traction=traction,
        braking=Braking(service_force=EffortCurve.constant(300e3), regenerative=traction.scaled(0.8)),
        resistance=(ResistanceTerm("Davis", Quadratic(4000.0, 60.0, 8.0)),),
        electrical=Electrical(line_voltage_v=3000.0, traction_efficiency=0.9, regenerative_efficiency=0.8),
    )


def net_energy_j(solver: SectionSolver, plan) -> float:
    route = dataclasses.replace(solver.route, stations=(Station("a", solver.s0), Station("b", solver.s1)))
    res = build_result(
        train=solver.train, route=route, settings=trainsim.RunSettings(),
        profile=line_resistance_profile(route, solver.train), ceiling=speed_ceiling(route, solver.train),
        s=plan.s, v=plan.v, t=plan.t, regime=plan.regime, status="ok",
    )  # fmt: skip
    return res.energy_kwh.net * 3.6e6


def reference_energy_j(solver: SectionSolver, running_time_s: float, intervals: int = 1000) -> float:
    pytest.importorskip("casadi")
    from trainsim.optimize.reference import solve_reference

    ref = solve_reference(
        solver.train, solver.route, solver.s0, solver.s1, running_time_s, intervals=intervals
    )
    assert ref.status == "ok"
    return ref.energy_j


def tolerance(T: float) -> float:
    return max(0.5, 5e-4 * T)


def ttobench_solver(train: str, track: str, s0: float, s1: float) -> SectionSolver:
    tt = read_ttobench_train(TTOBENCH / "trains" / f"{train}.json")
    route = read_ttobench_track(TTOBENCH / "tracks" / f"{track}.json", tt)
    return SectionSolver(tt.train, route, s0, s1)


def lower_limit_route() -> Route:
    return Route(
        name="lower limit",
        start_m=0.0,
        end_m=10_000.0,
        stations=(Station("A", 0.0), Station("B", 10_000.0)),
        speed_limits=(
            SpeedLimit(0.0, 5_000.0, 160 * KMH),
            SpeedLimit(5_000.0, 6_000.0, 80 * KMH),
            SpeedLimit(6_000.0, 10_000.0, 160 * KMH),
        ),
    )


def descent_route() -> Route:
    return Route(
        name="descent",
        start_m=0.0,
        end_m=30_000.0,
        stations=(Station("A", 0.0), Station("B", 30_000.0)),
        speed_limits=(SpeedLimit(0.0, 30_000.0, 160 * KMH),),
        gradients=(GradientSection(10_000.0, 12_000.0, -20.0),),
    )


def test_coasts_ahead_of_a_lower_limit():
    solver = SectionSolver(regen_train(), lower_limit_route(), 0.0, 10_000.0)
    T = solver.fastest_time_s * 1.15
    plan = solver.solve(T)
    assert abs(plan.running_time_s - T) <= tolerance(T)
    # the stretch just before the 80 km/h limit: coasting, then (regenerative) braking onto it
    before = (plan.s > 4_000.0) & (plan.s < 5_000.0)
    assert (plan.regime[before] == codes.COAST).any()
    assert not (plan.regime[before] == codes.BRAKE).any()
    assert np.all(
        plan.v[plan.s >= 5_000.0 - 1e-6][plan.s[plan.s >= 5_000.0 - 1e-6] < 6_000.0] <= 80 * KMH + 1e-6
    )
    # holding up to the braking curve instead costs energy
    energy = net_energy_j(solver, plan)
    solver.limit_coasting = False
    plain = solver._solve_once(T)
    solver.limit_coasting = True
    assert net_energy_j(solver, plain) > energy * 1.001
    assert energy == pytest.approx(reference_energy_j(solver, T), rel=5e-3)


def test_leaves_the_holding_arc_ahead_of_a_steep_descent():
    solver = SectionSolver(regen_train(), descent_route(), 0.0, 30_000.0)
    T = solver.fastest_time_s * 1.10
    plan = solver.solve(T)
    assert abs(plan.running_time_s - T) <= tolerance(T)
    # the train coasts well before the descent, runs faster than its holding speed on it and is
    # back on the holding arc after it
    before = (plan.s > 8_000.0) & (plan.s < 10_000.0)
    assert (plan.regime[before] == codes.COAST).all()
    on_descent = (plan.s > 10_000.0) & (plan.s < 12_000.0)
    assert plan.v[on_descent].max() > plan.holding_speed_mps
    after = (plan.s > 14_000.0) & (plan.s < 20_000.0)
    assert (plan.regime[after] == codes.CRUISE).all()
    energy = net_energy_j(solver, plan)
    # holding V up to the descent and letting the descent speed the train up costs 2 % more here
    solver.excursions = False
    plain = solver._solve_once(T)
    solver.excursions = True
    assert net_energy_j(solver, plain) > energy * 1.01
    assert energy == pytest.approx(reference_energy_j(solver, T, intervals=3000), rel=2e-3)


@pytest.mark.skipif(not TTOBENCH.exists(), reason="TTOBench data not found beside the checkout")
def test_ttobench_section_with_lower_limits_is_near_the_reference():
    # the 2.6 km section of Beijing's Yizhuang line: 50, 80, 65, 80 and 60 km/h; coasting ahead of
    # the lower limits was worth 15 % here
    solver = ttobench_solver("CN_Beijing_Subway", "CN_Songjiazhuang_Yizhuang", 0.0, 2631.0)
    T = solver.fastest_time_s * 1.10
    plan = solver.solve(T)
    assert abs(plan.running_time_s - T) <= tolerance(T)
    assert net_energy_j(solver, plan) == pytest.approx(reference_energy_j(solver, T), rel=5e-3)


@pytest.mark.skipif(not TTOBENCH.exists(), reason="TTOBench data not found beside the checkout")
def test_schedule_kept_where_the_running_time_jumps_with_the_holding_speed():
    # here the final coasting phase starts meeting a lower limit's braking curve as the holding
    # speed grows, and the running time jumps by 6 s at about 119 km/h
    solver = ttobench_solver("NL_Intercity_VIRM6", "CN_Songjiazhuang_Yizhuang", 13419.0, 15757.0)
    T = solver.fastest_time_s * 1.05
    plan = solver.solve(T)
    assert plan.feasible
    assert abs(plan.running_time_s - T) <= tolerance(T)


@pytest.mark.skipif(not TTOBENCH.exists(), reason="TTOBench data not found beside the checkout")
def test_net_regenerating_descent_ends_on_regenerative_braking():
    # Zurich Stadelhofen - Altstetten, first 1.7 km: downhill all the way, the train returns more
    # than it draws. The final coast must end on the regenerative braking curve to the stop, not on
    # the friction brakes a few metres too late (that cost 7 % of the energy returned)
    solver = ttobench_solver("NL_Intercity_VIRM6", "CH_Stadelhofen_Altstetten", 0.0, 1690.0)
    T = solver.fastest_time_s * 1.30
    plan = solver.solve(T)
    assert abs(plan.running_time_s - T) <= tolerance(T)
    energy, reference = net_energy_j(solver, plan), reference_energy_j(solver, T)
    assert reference < 0.0
    assert abs(energy - reference) <= 5e-3 * abs(reference)


def test_solves_do_not_depend_on_earlier_solves():
    route = lower_limit_route()
    solver = SectionSolver(regen_train(), route, 0.0, 10_000.0)
    T = solver.fastest_time_s * 1.2
    solver.solve(solver.fastest_time_s * 1.05)
    after_other = solver.solve(T)
    fresh = SectionSolver(regen_train(), route, 0.0, 10_000.0).solve(T)
    np.testing.assert_array_equal(after_other.s, fresh.s)
    np.testing.assert_array_equal(after_other.v, fresh.v)


@pytest.mark.skipif(not TTOBENCH.exists(), reason="TTOBench data not found beside the checkout")
def test_line_supplement_on_a_hilly_line_with_lower_limits_is_met():
    from trainsim.optimize.api import optimize
    from trainsim.optimize.timetable import line_supplement

    tt = read_ttobench_train(TTOBENCH / "trains" / "NL_Intercity_VIRM6.json")
    route = read_ttobench_track(TTOBENCH / "tracks" / "CN_Songjiazhuang_Yizhuang.json", tt)
    res = optimize(tt.train, route, line_supplement("5%"))
    total = res.fastest.running_time_s * 1.05
    assert res.run.running_time_s == pytest.approx(total, abs=max(0.5, 5e-4 * total))
    assert res.energy_saved_kwh > 0.0
    assert all(
        abs(d) <= tolerance(T)
        for d, T in zip(res.schedule_deviation_s, res.scheduled_running_time_s, strict=True)
    )


@pytest.mark.skipif(not TTOBENCH.exists(), reason="TTOBench data not found beside the checkout")
@pytest.mark.parametrize(
    ("track", "train", "end_m", "supplement"),
    [
        # a coast from 5.6 km swallowed the departures of four later descents: 50 s slow at the
        # holding speed the reference keeps, and 3.5 % above it once the time was met another way
        ("CH_StGallen_Wil", "CN_Beijing_Subway", 29556.1, 0.05),
        # the departure ahead of the first descent in the traction phase: 70 km/h against 98
        ("CH_Fribourg_Bern", "NL_Intercity_VIRM6", 31240.7, 0.10),
    ],
)
def test_excursions_that_swallow_later_descents_are_weighed_against_short_ones(
    track, train, end_m, supplement
):
    solver = ttobench_solver(train, track, 0.0, end_m)
    T = solver.fastest_time_s * (1.0 + supplement)
    plan = solver.solve(T)
    assert abs(plan.running_time_s - T) <= tolerance(T)
    reference = reference_energy_j(solver, T, intervals=int(end_m / 20.0))
    assert net_energy_j(solver, plan) <= reference + 0.01 * abs(reference)


@pytest.mark.skipif(not TTOBENCH.exists(), reason="TTOBench data not found beside the checkout")
def test_running_time_jump_between_departure_choices_is_bridged():
    # Yizhuang line 3906-6272 m, Beijing metro: with its departures the run's time jumps by 8 s
    # between holding speeds 0.03 % apart (the departure ahead of the first descent moves 70 m);
    # the departures are moved together between the two sides until the time is met
    solver = ttobench_solver("CN_Beijing_Subway", "CN_Songjiazhuang_Yizhuang", 3906.0, 6272.0)
    T = solver.fastest_time_s * 1.20
    with_departures = solver._solve_variant(T, True, True)
    assert abs(with_departures.running_time_s - T) <= tolerance(T)
    plan = solver.solve(T)
    assert abs(plan.running_time_s - T) <= tolerance(T)
    assert plan.s[-1] == 6272.0 and plan.v[-1] == 0.0
    assert np.all(np.diff(plan.s) >= 0.0) and np.all(np.isfinite(plan.v))


def test_heavy_train_leaves_a_regenerative_holding_arc_braking():
    # the 10 700 t heavy-haul train, Mine - Junction at 2891.5 s: it holds its regenerative speed W
    # down the 6 per mille descent; from 1/eta_t its adjoint does not come down to eta_r before
    # the stop, and the final coast then started 13 km out and ran into the friction brakes at
    # 65 km/h (25 % above the reference). Leaving the arc at eta_r it is within 5 % of it.
    heavy = trainsim.load_scenario(ROOT / "examples" / "heavy_haul" / "scenario_head.yaml")
    solver = SectionSolver(heavy.train, heavy.route, 0.0, 26_000.0)
    T = 2891.5
    plan = solver.solve(T)
    assert abs(plan.running_time_s - T) <= tolerance(T)
    assert plan.coast_start_m > 20_000.0
    reference = reference_energy_j(solver, T, intervals=1300)
    energy = net_energy_j(solver, plan) - heavy.train.electrical.auxiliary_power_w * plan.running_time_s
    assert reference <= energy <= 1.05 * reference
