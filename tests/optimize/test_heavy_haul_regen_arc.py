"""Issue 16: on the heavy-haul example the optimal strategy's final phase holds the regenerative
holding speed W on the descent before the Junction and leaves it to coast and brake regeneratively
to the stop.

Before, the final phase had no arc that holds W: where the adjoint came down to eta_r at W it coasted
on and from 25.4 km braked with the friction brakes from 65 km/h, 14 % (+20 %) and 11 % (+30 %) above
the certified reference, and the energy was not monotone in running time (1873.54 kWh at +10 %,
1970.97 kWh at +20 %)."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

import trainsim
from trainsim.optimize.optimal import SectionSolver, regenerative_holding_speed
from trainsim.sim import codes

ROOT = Path(__file__).resolve().parents[2]
#: Net energy [kWh] of the certified reference (docs/optimization_benchmark.md, section 0-26000 m).
REFERENCE_KWH = {0.2: 1727.271, 0.3: 1630.329}
#: Largest accepted excess over the reference [-] (issue 16 asks 0.1 % on most cases).
GAP = 1e-3


@pytest.fixture(scope="module")
def runs():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scenario = trainsim.load_scenario(ROOT / "examples" / "heavy_haul" / "scenario_head.yaml")
    solver = SectionSolver(scenario.train, scenario.route, 0.0, 26000.0)
    plans = {sup: solver.solve(solver.fastest_time_s * (1.0 + sup)) for sup in (0.1, 0.2, 0.3)}
    return solver, plans


def test_energy_decreases_with_running_time(runs) -> None:
    solver, plans = runs
    kwh = [solver.energy_j(plans[sup]) / 3.6e6 for sup in (0.1, 0.2, 0.3)]
    assert kwh[0] > kwh[1] > kwh[2], kwh
    for sup, plan in plans.items():
        assert abs(plan.running_time_s - solver.fastest_time_s * (1.0 + sup)) < 1e-3


@pytest.mark.parametrize("sup", sorted(REFERENCE_KWH))
def test_within_a_tenth_of_a_percent_of_the_reference(runs, sup: float) -> None:
    solver, plans = runs
    kwh = solver.energy_j(plans[sup]) / 3.6e6
    assert abs(kwh - REFERENCE_KWH[sup]) / REFERENCE_KWH[sup] < GAP, kwh


def test_holds_w_on_the_descent_and_brakes_regeneratively_to_the_stop(runs) -> None:
    solver, plans = runs
    plan = plans[0.3]
    W = regenerative_holding_speed(solver.train, plan.price_of_time_w, solver.eta_r)
    s, v, m = plan.s[:-1], plan.v[:-1], plan.regime[:-1]
    held = (m == codes.CRUISE) & (np.abs(v - W) < 1e-6 * W) & (s > 18790.0) & (s < 24000.0)
    assert held.any(), "no regenerative holding arc at W on the descent"
    # the service (friction) brakes only take the last metres, not a run from 65 km/h
    braking = m == codes.BRAKE
    assert braking.any() and v[braking].max() < 15.0 / 3.6
    assert (m == codes.REGEN).any()
