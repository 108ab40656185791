"""Energy-efficient driving: schedules met, the key equation, the energy-time curve, infeasible
schedules, source 004's method, the reference optimum, timetable files and the CLI."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import trainsim
from trainsim.cli import app
from trainsim.constants import KMH
from trainsim.errors import InputError
from trainsim.io.timetable_file import read_timetable_yaml
from trainsim.io.ttobench import read_ttobench_track, read_ttobench_train
from trainsim.model import (
    Braking,
    EffortCurve,
    Electrical,
    Quadratic,
    ResistanceTerm,
    Route,
    SpeedLimit,
    Station,
    Train,
)
from trainsim.optimize.api import energy_time_curve, optimize
from trainsim.optimize.optimal import SectionSolver, key_equation_braking_speed
from trainsim.optimize.timetable import SectionSchedule, Timetable, line_supplement
from trainsim.sim import codes

ROOT = Path(__file__).resolve().parents[2]
TTOBENCH = ROOT.parent / "shared" / "data" / "ttobench"
METRO = ROOT / "examples" / "metro_b" / "scenario.yaml"


def tolerance(T: float) -> float:
    return max(0.5, 5e-4 * T)


@pytest.fixture(scope="module")
def metro():
    return trainsim.load_scenario(METRO)


def level_train(regen: bool = False) -> Train:
    traction = EffortCurve.power_limited(3.0e6, force_cap_n=250e3)
    return Train(
        name="level test train",
        mass_kg=300e3,
        rotating_mass_factor=1.08,
        length_m=100.0,
        max_speed_mps=160 * KMH,
        traction=traction,
        braking=Braking(
            service_force=EffortCurve.constant(300e3),
            regenerative=traction.scaled(0.8) if regen else None,
        ),
        resistance=(ResistanceTerm("Davis", Quadratic(4000.0, 60.0, 8.0)),),
        electrical=Electrical(line_voltage_v=3000.0, traction_efficiency=0.9, regenerative_efficiency=0.8),
    )


def level_route(length: float = 12_000.0) -> Route:
    return Route(
        name="level",
        start_m=0.0,
        end_m=length,
        stations=(Station("A", 0.0), Station("B", length)),
        speed_limits=(SpeedLimit(0.0, length, 160 * KMH),),
    )


@pytest.mark.parametrize("supplement", [0.05, 0.1, 0.2, 0.3])
def test_schedule_met_per_section(metro, supplement):
    tt = Timetable(sections=tuple(SectionSchedule(supplement_fraction=supplement) for _ in range(3)))
    res = optimize(metro.train, metro.route, tt)
    for dev, T in zip(res.schedule_deviation_s, res.scheduled_running_time_s, strict=True):
        assert abs(dev) <= tolerance(T)
    assert not res.warnings
    assert res.run.energy_kwh.net < res.fastest.energy_kwh.net


def test_line_supplement_is_split_at_equal_price_of_time(metro):
    res = optimize(metro.train, metro.route, line_supplement("12.8%"))
    assert res.run.running_time_s == pytest.approx(res.fastest.running_time_s * 1.128, abs=0.5)
    mu = np.array(res.price_of_time_w)
    assert np.allclose(mu, mu[0], rtol=1e-9)  # equal marginal energy per second in every section
    # a different split of the same total costs more energy
    other = optimize(
        metro.train,
        metro.route,
        Timetable(sections=tuple(SectionSchedule(running_time_s=t) for t in [res.scheduled_running_time_s[0] + 6,
                                                                                res.scheduled_running_time_s[1] - 3,
                                                                                res.scheduled_running_time_s[2] - 3])),
    )  # fmt: skip
    assert other.run.energy_kwh.net > res.run.energy_kwh.net


def test_key_equation_on_level_track_without_regeneration():
    """W = psi(V) / (R(V) + V R'(V)): where coasting ends and braking starts (Albrecht et al. 2016)."""
    train, route = level_train(regen=False), level_route(30_000.0)
    solver = SectionSolver(train, route, 0.0, route.end_m)
    for supplement in (0.15, 0.25, 0.4):
        plan = solver.solve(solver.fastest_time_s * (1 + supplement))
        # the equation holds for a run that holds V (below the line limit) before coasting
        cruising = plan.v[plan.regime == codes.CRUISE]
        assert len(cruising) and np.allclose(cruising, plan.holding_speed_mps)
        assert plan.holding_speed_mps < 160 * KMH
        k = np.flatnonzero((plan.regime[:-1] == codes.COAST) & (plan.regime[1:] == codes.BRAKE))[0] + 1
        W = key_equation_braking_speed(train, plan.holding_speed_mps)
        assert plan.v[k] == pytest.approx(W, abs=0.05)


def test_energy_time_curve_decreases(metro):
    table = energy_time_curve(metro.train, metro.route, [0.0, 0.05, 0.1, 0.2, 0.3])
    assert np.all(np.diff(table["running_time_s"]) > 0)
    assert np.all(np.diff(table["energy_kwh"]) < 0)


def test_infeasible_schedule_returns_the_fastest_run_with_the_shortfall(metro):
    tt = Timetable(sections=(SectionSchedule(running_time_s=60.0), SectionSchedule(supplement_fraction=0.1),
                             SectionSchedule(supplement_fraction=0.1)))  # fmt: skip
    res = optimize(metro.train, metro.route, tt)
    assert res.summary()["status"] == "infeasible schedule"
    fastest_first = res.fastest.sections[0].running_time_s
    assert res.run.sections[0].running_time_s == pytest.approx(fastest_first, abs=1e-6)
    assert f"{fastest_first - 60.0:.1f} s late" in res.warnings[0]


def test_lesov_method_meets_the_schedule_and_saves_less_than_optimal(metro):
    tt = line_supplement("12.8%")
    opt = optimize(metro.train, metro.route, tt)
    les = optimize(metro.train, metro.route, tt, strategy="lesov")
    for dev, T in zip(les.schedule_deviation_s, les.scheduled_running_time_s, strict=True):
        assert abs(dev) <= tolerance(T)
    assert opt.run.energy_kwh.net <= les.run.energy_kwh.net < les.fastest.energy_kwh.net
    regimes = {p.regime for p in les.switching_points}
    assert {"traction", "cruising", "regenerative braking", "braking"} <= regimes
    assert abs(les.run.energy_balance["relative_error"]) < 1e-3


def test_lesov_method_on_a_train_braking_at_a_constant_deceleration():
    # source 001's locomotive brakes at a constant net deceleration (no braking force law): the
    # mechanical braking below 10 km/h then gives that deceleration
    loco = trainsim.load_scenario(ROOT / "examples" / "loco_001" / "scenario.yaml")
    les = optimize(loco.train, loco.route, line_supplement("10%"), strategy="lesov")
    for dev, T in zip(les.schedule_deviation_s, les.scheduled_running_time_s, strict=True):
        assert abs(dev) <= tolerance(T)
    assert les.run.energy_kwh.net < les.fastest.energy_kwh.net
    opt = optimize(loco.train, loco.route, line_supplement("10%"))
    assert opt.run.energy_kwh.net <= les.run.energy_kwh.net


def test_lesov_equations():
    from trainsim.optimize import lesov

    # dt = dV / (zeta f_t); zeta is 2.0 km/h per minute per N/kN for rho = 1.06 (the paper's 2)
    assert pytest.approx(2.0, rel=1e-3) == 3.6 * 60 * 9.81 / (1000 * 1.06)
    assert lesov.time_step_min(10.0, 5.0, 2.0) == pytest.approx(1.0)
    assert lesov.path_step_m(40.0, 10.0, 1.0) == pytest.approx(16.7 * 45.0)
    # the corrected increment covers dS in dt_tr: dS = 16.7 (V + dV/2) dt_tr
    dv = lesov.corrected_speed_increment_kmh(1000.0, 50.0, 1.0)
    assert lesov.path_step_m(50.0, dv, 1.0) == pytest.approx(1000.0)
    assert lesov.speed_step_kmh(20.0, 80.0) == 10.0
    assert lesov.speed_step_kmh(60.0, 80.0) == 5.0
    assert lesov.speed_step_kmh(77.0, 80.0) == 1.0


def test_reference_optimum_agrees_with_the_optimal_strategy():
    pytest.importorskip("casadi")
    from trainsim.optimize.reference import solve_reference
    from trainsim.sim.profile import line_resistance_profile, speed_ceiling
    from trainsim.sim.result import build_result

    train, route = level_train(regen=True), level_route(6_000.0)
    solver = SectionSolver(train, route, 0.0, route.end_m)
    T = solver.fastest_time_s * 1.15
    plan = solver.solve(T)
    res = build_result(train=train, route=route, settings=trainsim.RunSettings(), profile=line_resistance_profile(route, train),
                       ceiling=speed_ceiling(route, train), s=plan.s, v=plan.v, t=plan.t, regime=plan.regime, status="ok")  # fmt: skip
    ref = solve_reference(train, route, 0.0, route.end_m, T, intervals=800)
    assert ref.status == "ok"
    assert ref.running_time_s == pytest.approx(T, abs=0.01)
    assert res.energy_kwh.net * 3.6e6 == pytest.approx(ref.energy_j, rel=2e-3)


def test_every_ttobench_track_and_train_loads_and_runs():
    if not TTOBENCH.exists():
        pytest.skip("TTOBench data not found beside the checkout")
    trains = [read_ttobench_train(p) for p in sorted((TTOBENCH / "trains").glob("*.json"))]
    assert len(trains) == 4
    for track in sorted((TTOBENCH / "tracks").glob("*.json")):
        for tt in trains:
            route = read_ttobench_track(track, tt)
            res = trainsim.run_fastest(tt.train, route)
            assert res.status == "ok", (track.name, tt.train.name, res.warnings)
            assert abs(res.energy_balance["relative_error"]) < 1e-3


def test_ttobench_optimal_on_a_flat_track_meets_the_schedule():
    if not TTOBENCH.exists():
        pytest.skip("TTOBench data not found beside the checkout")
    tt = read_ttobench_train(TTOBENCH / "trains" / "NL_Intercity_VIRM6.json")
    route = read_ttobench_track(TTOBENCH / "tracks" / "00_reference.json", tt)
    res = optimize(tt.train, route, line_supplement("10%"))
    assert res.run.running_time_s == pytest.approx(res.fastest.running_time_s * 1.1, abs=1.0)
    assert res.energy_saved_kwh > 0


def test_timetable_file(tmp_path):
    f = tmp_path / "tt.yaml"
    f.write_text("schema: trainsim/timetable\nversion: 1\nsections:\n  - {running_time_s: 110}\n"
                 "  - {supplement: '8%'}\n  - {departure_s: 100, arrival_s: 205}\n")  # fmt: skip
    tt = read_timetable_yaml(f, n_sections=3)
    assert tt.sections[0].running_time_s == 110
    assert tt.sections[1].supplement_fraction == pytest.approx(0.08)
    assert tt.sections[2].running_time_s == 105
    bad = tmp_path / "bad.yaml"
    bad.write_text("schema: trainsim/timetable\nversion: 1\nsections:\n  - {running_time: 110}\n")
    with pytest.raises(InputError, match=r"sections\[0\]"):
        read_timetable_yaml(bad)
    with pytest.raises(InputError, match="one schedule per section"):
        read_timetable_yaml(f, n_sections=2)
    with pytest.raises(InputError, match="cannot read the supplement"):
        line_supplement("10")


def test_cli_optimize_json():
    result = CliRunner().invoke(app, ["optimize", str(METRO), "--supplement", "12.8%", "--json"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    for key in ("status", "warnings", "distance_m", "running_time_s", "total_time_s", "peak_current_a",
                "energy_kwh", "sections", "switching_points", "schedule_deviation_s"):  # fmt: skip
        assert key in data
    assert set(data["energy_kwh"]) >= {"traction", "regenerated", "net"}
    assert all(abs(d) <= 0.5 for d in data["schedule_deviation_s"])
    assert data["switching_points"][0]["regime"] == "traction"


def test_cli_optimize_errors():
    runner = CliRunner()
    r = runner.invoke(app, ["optimize", str(METRO)])
    assert r.exit_code == 2 and "exactly one of --supplement, --timetable and --allowance" in r.output
    r = runner.invoke(app, ["optimize", str(METRO), "--supplement", "5%", "--strategy", "magic"])
    assert r.exit_code == 2 and "unknown strategy" in r.output
    assert "Traceback" not in r.output


def test_lesov_slope_budgets():
    """t_b = k_cor (S_i/S) t_norm: a climb gets more of the schedule than its length share."""
    import dataclasses as dc

    from trainsim.model import GradientSection
    from trainsim.optimize.lesov import slope_budgets

    train = level_train()
    route = dc.replace(level_route(10_000.0), gradients=(GradientSection(4000.0, 6000.0, 30.0),))
    ((a, b, budget),) = slope_budgets(train, route, 0.0, 10_000.0, 500.0)
    assert (a, b) == (4000.0, 6000.0)
    flat = dc.replace(level_route(10_000.0), gradients=(GradientSection(4000.0, 6000.0, 1e-9),))
    ((_, _, budget_flat),) = slope_budgets(train, flat, 0.0, 10_000.0, 500.0)
    assert budget > budget_flat  # the climb takes a larger share of the time
    assert slope_budgets(train, level_route(), 0.0, 12_000.0, 500.0) == []


def test_strategy_from_the_scenario_file():
    eco = trainsim.load_scenario(ROOT / "examples" / "metro_b" / "scenario_eco.yaml")
    assert eco.strategy == "optimal"
    run = trainsim.run(eco)
    assert run.kind == "optimal"
    fastest = trainsim.run(trainsim.load_scenario(METRO))
    assert run.running_time_s == pytest.approx(fastest.running_time_s * 1.128, abs=0.5)
    result = CliRunner().invoke(
        app, ["optimize", str(ROOT / "examples" / "metro_b" / "scenario_eco.yaml"), "--json"]
    )
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout)["strategy"] == "optimal"


def test_scenario_driving_block_needs_a_schedule(tmp_path):
    f = tmp_path / "s.yaml"
    f.write_text(
        f"schema: trainsim/scenario\nversion: 1\nname: x\ntrain: {ROOT}/examples/metro_b/train.yaml\n"
        f"route: {ROOT}/examples/metro_b/route.yaml\ndriving: {{strategy: lesov}}\n"
    )
    with pytest.raises(InputError, match="needs a supplement or a timetable"):
        trainsim.load_scenario(f)
