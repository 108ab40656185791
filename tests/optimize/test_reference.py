"""The reference optimum (CasADi/IPOPT): speeds never below 0, warm starts, time limits, mesh
refinement, the convex relaxation's lower bound, and timing-point windows."""

from __future__ import annotations

import numpy as np
import pytest

from trainsim.constants import KMH
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
from trainsim.model.timetable import TimingPoint
from trainsim.optimize.optimal import SectionSolver
from trainsim.optimize.reference import concave_hull_in_slowness

casadi = pytest.importorskip("casadi")

from trainsim.optimize.reference import (  # noqa: E402
    certified_reference,
    lower_bound,
    solve_reference,
)


def small_train(regen: bool = True) -> Train:
    traction = EffortCurve.power_limited(1.5e6, force_cap_n=150e3)
    return Train(
        name="reference test train",
        mass_kg=150e3,
        rotating_mass_factor=1.08,
        length_m=1.0,
        max_speed_mps=100 * KMH,
        traction=traction,
        braking=Braking(
            service_force=EffortCurve.constant(150e3), regenerative=traction.scaled(1.0) if regen else None
        ),
        resistance=(ResistanceTerm("Davis", Quadratic(2000.0, 30.0, 4.0)),),
        electrical=Electrical(line_voltage_v=1500.0, traction_efficiency=0.9, regenerative_efficiency=0.8),
    )


def line(length: float, gradients: tuple = ()) -> Route:
    return Route(
        name="test line",
        start_m=0.0,
        end_m=length,
        stations=(Station("A", 0.0), Station("B", length)),
        speed_limits=(SpeedLimit(0.0, length, 80 * KMH),),
        gradients=tuple(GradientSection(*g) for g in gradients),
    )


def test_concave_hull_bounds_a_curve_from_above_and_is_exact_for_force_and_power_caps():
    curve = EffortCurve.power_limited(1.5e6, force_cap_n=150e3)
    lines = concave_hull_in_slowness(curve, 30.0)
    v = np.linspace(1e-3, 30.0, 50_001)
    hull = np.min([a + b / v for a, b in lines], axis=0)
    force = curve(v)
    assert np.all(hull >= force)
    assert np.max(hull - force) <= 1e-6 * 150e3  # min(F, P/v) is concave in 1/v: exact
    table = EffortCurve.from_table([0.0, 5.0, 10.0, 20.0, 30.0], [200e3, 190e3, 120e3, 40e3, 35e3])
    lines = concave_hull_in_slowness(table, 30.0, max_lines=4)
    assert len(lines) <= 4
    hull = np.min([a + b / v for a, b in lines], axis=0)
    assert np.all(hull >= table(v))


@pytest.mark.slow
def test_reference_speeds_are_never_negative_and_the_bound_is_below_it():
    train, route = small_train(), line(3000.0)
    T = SectionSolver(train, route, 0.0, 3000.0).fastest_time_s * 1.2
    ref = solve_reference(train, route, 0.0, 3000.0, T, intervals=300)
    assert ref.status == "ok"
    assert np.all(ref.v >= 0.0) and ref.v[0] == 0.0 and ref.v[-1] == 0.0
    assert ref.running_time_s == pytest.approx(T, abs=1e-3)
    low = lower_bound(train, route, 0.0, 3000.0, T, grid=ref.s, warm_start=ref)
    assert low.status == "ok"
    # a relaxation of the same transcription: below it, and tight (the only slack is c1 v)
    assert low.energy_j <= ref.energy_j * (1 + 1e-7)
    assert low.energy_j >= ref.energy_j * (1 - 2e-4)


@pytest.mark.slow
def test_certified_reference_refines_the_mesh_and_certifies_the_optimal_strategy():
    train, route = small_train(), line(3000.0, ((1000.0, 2000.0, -25.0),))
    solver = SectionSolver(train, route, 0.0, 3000.0)
    T = solver.fastest_time_s * 1.2
    plan = solver.solve(T)
    ref = certified_reference(train, route, 0.0, 3000.0, T, intervals=250, warm_start=(plan.s, plan.v))
    assert ref.status == "ok", ref.status
    assert len(ref.mesh) >= 2
    assert [m[0] for m in ref.mesh] == sorted(m[0] for m in ref.mesh)
    (_, e1, _), (_, e2, _) = ref.mesh[-2:]
    assert abs(e2 - e1) < 1e-4 * abs(e2)
    assert ref.bound_status == "ok"
    assert ref.lower_bound_j <= ref.energy_j
    gap = ref.certified_gap(solver.energy_j(plan))
    assert gap is not None and -1e-3 < gap < 0.01


@pytest.mark.slow
def test_time_limit_reports_the_last_iterate_and_says_so():
    train, route = small_train(), line(3000.0)
    T = SectionSolver(train, route, 0.0, 3000.0).fastest_time_s * 1.2
    ref = solve_reference(train, route, 0.0, 3000.0, T, intervals=2000, time_limit_s=0.2)
    # the limit is CPU time (the machine's load does not change the result) and the status says so
    assert ref.status.startswith("time limit (CPU time)"), ref.status
    assert np.all(ref.v >= 0.0) and np.all(np.isfinite(ref.v))
    # IPOPT stops at the first iteration past the limit: its CPU time is counted, wall time kept too
    assert 0.2 <= ref.solve_cpu_s < 5.0
    assert np.isfinite(ref.solve_time_s) and ref.solve_time_s > 0.0


@pytest.mark.slow
def test_certified_reference_budget_is_cpu_time_and_reported_with_the_wall_time():
    train, route = small_train(), line(3000.0)
    T = SectionSolver(train, route, 0.0, 3000.0).fastest_time_s * 1.2
    # a CPU budget too small for the first grid: its last iterate, and a status that names CPU time
    ref = certified_reference(train, route, 0.0, 3000.0, T, intervals=2000, time_limit_s=0.3, bound=False)
    assert ref.status != "ok"
    assert "CPU time" in ref.status, ref.status
    assert len(ref.mesh) == 1
    assert ref.solve_cpu_s > 0.0
    assert ref.solve_time_s > 0.0


@pytest.mark.slow
def test_reference_meets_a_passing_window_and_an_impossible_one_is_infeasible():
    train, route = small_train(), line(3000.0)
    solver = SectionSolver(train, route, 0.0, 3000.0)
    T = solver.fastest_time_s * 1.3
    free = solve_reference(train, route, 0.0, 3000.0, T, intervals=300)
    t_free = float(np.interp(1500.0, free.s, free.time_s))
    # ask for the passing 10 s earlier than the free optimum passes
    window = TimingPoint(1500.0, earliest_s=None, latest_s=t_free - 10.0, name="P")
    ref = solve_reference(train, route, 0.0, 3000.0, T, intervals=300, timing_points=(window,))
    assert ref.status == "ok"
    assert float(np.interp(1500.0, ref.s, ref.time_s)) <= t_free - 10.0 + 1e-3
    assert ref.energy_j > free.energy_j
    low = lower_bound(train, route, 0.0, 3000.0, T, grid=ref.s, warm_start=ref, timing_points=(window,))
    assert free.energy_j * (1 - 1e-6) <= low.energy_j * (1 + 1e-6) <= ref.energy_j * (1 + 1e-6)
    # 1500 m in 20 s from standstill: beyond what the train can do
    impossible = TimingPoint(1500.0, latest_s=20.0, name="Q")
    bad = solve_reference(
        train, route, 0.0, 3000.0, T, intervals=300, timing_points=(impossible,), time_limit_s=20.0
    )
    assert bad.status != "ok"


@pytest.mark.slow
def test_journey_windows_are_enforced_by_the_reference_and_reported_for_every_strategy():
    from pathlib import Path

    from trainsim.io.ttobench import read_ttobench_journey, read_ttobench_track, read_ttobench_train
    from trainsim.optimize.api import optimize
    from trainsim.optimize.timetable import timetable_from_journey

    data = Path(__file__).resolve().parents[3] / "shared" / "data" / "ttobench"
    if not data.exists():
        pytest.skip("TTOBench data not found beside the checkout")
    tt = read_ttobench_train(data / "trains" / "NL_Intercity_VIRM6.json")
    route = read_ttobench_track(data / "tracks" / "CH_StGallen_Wil.json", tt)
    journey = read_ttobench_journey(data / "journeys" / "CH_StGallen_Wil_Journey_01.json")
    section_route, timetable = timetable_from_journey(journey, route)
    # the window at 20 km is 400-450 s after the departure at 15 km: no run can then reach the stop
    # in the 650 s the section has (the fastest run from 20 km takes 364 s)
    assert [p.latest_s for p in timetable.timing_points] == [540.0, 450.0]
    res = optimize(tt.train, section_route, timetable, strategy="optimal")
    checks = {round(c["position_m"]): c for c in res.timing_points}
    assert set(checks) == {12500, 20000}
    summary = res.summary()
    assert summary["status"] != "ok"
    assert any("20000 m" in w for w in summary["warnings"])
    ref = optimize(tt.train, section_route, timetable, strategy="reference")
    first = {round(c["position_m"]): c for c in ref.timing_points}[12500]
    assert first["met"] and first["time_s"] <= 540.0 + 0.5
    assert ref.summary()["status"] != "ok"
