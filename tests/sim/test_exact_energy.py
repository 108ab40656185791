"""Energies integrated exactly between the events of the motion, whatever the step (issue 13)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from simcases import make_route, make_train

import trainsim
from trainsim.constants import KMH, KWH
from trainsim.model import Braking, EffortCurve
from trainsim.optimize.api import _solvers, optimize
from trainsim.optimize.optimal import SectionPlan
from trainsim.sim.energy import run_works
from trainsim.sim.profile import line_resistance_profile, traction_availability

ROOT = Path(__file__).resolve().parents[2]
FASTEST_EXAMPLES = ["metro_b/scenario.yaml", "loco_001/scenario.yaml", "freight_000/scenario.yaml"]


def _energies(result: trainsim.RunResult) -> np.ndarray:
    e = result.energy_kwh
    return np.array([e.traction, e.braking, e.regenerated, e.net])


@pytest.mark.parametrize("example", FASTEST_EXAMPLES)
def test_fastest_energies_do_not_depend_on_the_step(example):
    """Halving the step changes no energy by more than 1e-6 (it was 3e-4 with trapezoids), and
    the energy balance closes to 1e-6 at every step."""
    sc = trainsim.load_scenario(ROOT / "examples" / example)
    runs = {
        h: trainsim.run_fastest(sc.train, sc.route, dataclasses.replace(sc.settings, max_step_m=h))
        for h in (20.0, 10.0, 5.0)
    }
    for coarse, fine in ((20.0, 10.0), (10.0, 5.0)):
        a, b = _energies(runs[coarse]), _energies(runs[fine])
        assert np.all(np.abs(a - b) <= 1e-6 * np.abs(b) + 1e-9), (coarse, a, b)
        assert runs[coarse].running_time_s == pytest.approx(runs[fine].running_time_s, rel=1e-6)
    for r in runs.values():
        assert r.status == "ok"
        assert abs(r.energy_balance["relative_error"]) < 1e-6
        assert r.energy_balance["off_regime_stretches"] == 0


def test_braking_table_with_a_step_is_integrated_exactly():
    """No resistance, level line: the braking work of a stop is exactly the kinetic energy at the
    start of braking, and the traction work exactly F x distance in traction, although the braking
    force jumps from 150 to 335 kN between 5 and 6 km/h (source 002's table) and every step size
    puts that jump somewhere else inside a step."""
    braking = Braking(
        service_force=EffortCurve.from_table(
            np.array([0, 5, 6, 64.5, 80]) * KMH, np.array([150, 150, 335, 335, 275]) * 1e3
        )
    )
    train = make_train(traction_n=250e3, mass_kg=288.2e3, rho=1.08, braking=braking)
    route = make_route(length_m=1500.0, limit_kmh=70.0)
    M = train.inertial_mass_kg
    for h in (20.0, 7.0, 3.0, 1.1):
        r = trainsim.run_fastest(train, route, trainsim.RunSettings(max_step_m=h))
        tr = r.trace
        v_top = 70 * KMH
        assert r.energy_kwh.braking * KWH == pytest.approx(0.5 * M * v_top**2, rel=2e-9)
        # traction: constant 250 kN from standstill to 70 km/h, then cruising with no resistance
        traction_distance = 0.5 * M * v_top**2 / 250e3
        assert r.energy_kwh.traction * KWH == pytest.approx(250e3 * traction_distance, rel=1e-9)
        assert abs(r.energy_balance["relative_error"]) < 3e-9
        assert tr.speed_mps[-1] == 0.0


def test_regenerative_blending_is_integrated_exactly():
    """Constant service braking B with no resistance decelerates uniformly (v^2 linear in s); the
    regenerative part min(B, P/v) of a power-capped electric brake integrates to
    (B v_c^2 / 2 + P (v0 - v_c)) / a with v_c = P / B, a = B / M (a kink inside a step)."""
    B, P_regen = 200e3, 2.0e6
    regen = EffortCurve.power_limited(P_regen, force_cap_n=1e9)
    braking = Braking(service_force=EffortCurve.constant(B), regenerative=regen)
    train = make_train(traction_n=300e3, braking=braking, mass_kg=300e3, rho=1.0)
    route = make_route(length_m=3000.0, limit_kmh=90.0)
    v0 = 90 * KMH
    a = B / train.inertial_mass_kg
    vc = P_regen / B
    expected = (B * vc**2 / 2 + P_regen * (v0 - vc)) / a
    for h in (20.0, 9.0):
        r = trainsim.run_fastest(train, route, trainsim.RunSettings(max_step_m=h))
        # without electrical data nothing reaches the line: check the work at the wheel itself
        assert np.all(r.trace.regenerative_braking_force_n <= B + 1e-6)
        works, _, off = run_works(
            train=train,
            route=route,
            settings=trainsim.RunSettings(max_step_m=h),
            profile=line_resistance_profile(route, train),
            available=traction_availability(route, train),
            s=r.trace.position_m,
            v=r.trace.speed_mps,
            regime=r.trace.regime,
            level=np.ones(len(r.trace)),
        )
        assert not off.any()
        assert works[:, 2].sum() == pytest.approx(expected, rel=5e-9)
        assert works[:, 1].sum() == pytest.approx(0.5 * train.inertial_mass_kg * v0**2, rel=5e-9)


def test_same_trajectory_same_energy_on_every_path():
    """The optimal strategy's run of the metro with regenerative braking: its sections in the run's
    summary and the optimizer's own per-section energy (``SectionSolver.energy_j``) integrate the same
    trajectory with the same function and agree to rounding."""
    sc = trainsim.load_scenario(ROOT / "examples/metro_b/scenario_eco.yaml")
    t0 = sc.train
    train = dataclasses.replace(
        t0, braking=dataclasses.replace(t0.braking, regenerative=t0.traction.scaled(0.8))
    )
    run = optimize(train, sc.route, sc.timetable, "optimal", sc.settings).run
    assert abs(run.energy_balance["relative_error"]) < 1e-6
    assert run.energy_kwh.regenerated > 1.0
    tr = run.trace
    stops = [s.position_m for s in sc.route.stops]
    starts = [0] + [int(k) for k in np.flatnonzero(np.diff(tr.time_s) > 0) + 1 if tr.regime[k - 1] == 4]
    for k, solver in enumerate(_solvers(train, sc.route, sc.settings)):
        i0 = starts[k]
        i1 = int(np.flatnonzero((tr.regime == 4) & (np.abs(tr.position_m - stops[k + 1]) < 1e-6))[0])
        plan = SectionPlan.__new__(SectionPlan)
        for name, arr in (("s", tr.position_m), ("v", tr.speed_mps), ("t", tr.time_s - tr.time_s[i0])):
            object.__setattr__(plan, name, arr[i0 : i1 + 1])
        object.__setattr__(plan, "regime", tr.regime[i0 : i1 + 1].copy())
        sec = run.sections[k].energy_kwh
        assert solver.energy_j(plan) / KWH == pytest.approx(sec.net - sec.auxiliary, rel=1e-12, abs=1e-12)


@pytest.mark.parametrize("strategy", ["optimal", "lesov"])
def test_energy_balance_of_energy_efficient_runs(strategy):
    """The optimize strategies' runs close their energy balance to 1e-6; stretches whose recorded
    motion is not their regime's maximum effort are integrated as that motion."""
    sc = trainsim.load_scenario(ROOT / "examples/metro_b/scenario_eco.yaml")
    run = optimize(sc.train, sc.route, sc.timetable, strategy, sc.settings).run
    assert abs(run.energy_balance["relative_error"]) < 1e-6
    assert run.energy_balance.get("off_regime_max_speed_difference_mps", 0.0) < 1.0


@pytest.mark.parametrize("example", FASTEST_EXAMPLES)
def test_energy_does_not_depend_on_which_points_a_path_records(example):
    """The same trajectory recorded with far fewer points (every regime change and one point in seven)
    gives the same energies: a path that records its run differently (sections, drivers, exports)
    cannot change the figure, as trapezoids across the points once did (8.708 vs 8.672 kWh)."""
    from trainsim.sim.profile import speed_ceiling
    from trainsim.sim.result import build_result

    sc = trainsim.load_scenario(ROOT / "examples" / example)
    full = trainsim.run_fastest(sc.train, sc.route, sc.settings)
    m = full.trace.regime
    keep = np.ones(len(m), bool)
    keep[1:-1] = (m[1:-1] != m[:-2]) | (m[1:-1] != m[2:]) | (m[1:-1] == 4)
    keep[::7] = True
    thin = build_result(
        train=sc.train,
        route=sc.route,
        settings=sc.settings,
        profile=line_resistance_profile(sc.route, sc.train),
        ceiling=speed_ceiling(sc.route, sc.train),
        s=full.trace.position_m[keep],
        v=full.trace.speed_mps[keep],
        t=full.trace.time_s[keep],
        regime=m[keep],
        status="ok",
    )
    assert keep.sum() < len(m) / 3
    np.testing.assert_allclose(_energies(thin), _energies(full), rtol=1e-7, atol=1e-9)
    assert thin.energy_balance["off_regime_stretches"] == 0
