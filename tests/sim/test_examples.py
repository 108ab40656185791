"""Every shipped example: invariants, convergence under step halving, energy balance."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import trainsim
from trainsim.model.scenario import RunSettings

EXAMPLES = sorted((Path(__file__).resolve().parents[2] / "examples").glob("*/scenario.yaml"))


def test_examples_exist():
    assert {p.parent.name for p in EXAMPLES} >= {"metro_b", "loco_001", "freight_000"}


@pytest.fixture(scope="module", params=EXAMPLES, ids=lambda p: p.parent.name)
def scenario(request):
    return trainsim.load_scenario(request.param)


def check_invariants(result: trainsim.RunResult) -> None:
    tr = result.trace
    for name in ("time_s", "position_m", "speed_mps", "traction_force_n", "braking_force_n"):
        assert np.all(np.isfinite(getattr(tr, name))), name
    assert np.all(tr.speed_mps >= 0.0)
    assert np.all(np.diff(tr.position_m) >= 0.0)
    assert np.all(np.diff(tr.time_s) >= 0.0)
    assert np.all(tr.speed_mps <= tr.speed_limit_mps + 1e-6)
    assert result.status == "ok", result.warnings


def test_invariants_and_energy_balance(scenario):
    result = trainsim.run(scenario)
    check_invariants(result)
    # traction work = kinetic + potential energy change + resistance work + braking work
    assert abs(result.energy_balance["relative_error"]) < 1e-3
    assert result.distance_m == pytest.approx(
        scenario.route.stops[-1].position_m - scenario.route.stops[0].position_m
    )


def test_convergence_when_halving_the_step(scenario):
    coarse = trainsim.run_fastest(scenario.train, scenario.route, RunSettings(max_step_m=20.0))
    fine = trainsim.run_fastest(scenario.train, scenario.route, RunSettings(max_step_m=10.0))
    finer = trainsim.run_fastest(scenario.train, scenario.route, RunSettings(max_step_m=5.0))
    for a, b in ((coarse, fine), (fine, finer)):
        assert abs(a.running_time_s - b.running_time_s) / b.running_time_s < 1e-4
        assert abs(a.energy_kwh.traction - b.energy_kwh.traction) / b.energy_kwh.traction < 1e-3


def test_metro_peak_current_in_the_papers_convention():
    """Source 002 reports a 4863 A peak current with P = F v eta and I = P / (U cos phi)."""
    metro = trainsim.load_scenario(Path(__file__).resolve().parents[2] / "examples/metro_b/scenario.yaml")
    result = trainsim.run(metro)
    # the peak of F v on the interpolated table is at 55.45 km/h: 4 x 76.25 kN x 15.40 m/s = 4.698 MW
    assert result.peak_paper_current_a == pytest.approx(4863.0, rel=0.01)
    assert result.peak_paper_current_a == pytest.approx(4.698e6 * 0.98 / (1000 * 0.95), rel=1e-3)
    # physically the line supplies F v / eta, more than the paper's F v eta
    assert result.peak_current_a > result.peak_paper_current_a
