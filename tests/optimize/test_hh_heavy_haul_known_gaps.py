"""Issue 16: what is still open on the heavy-haul example (measured at 898226b, docs/OPTIMIZATION.md).

Both are strict xfails: they pass (and so fail the suite) once the strategy is fixed, and must then
become plain tests.

1. Section 26000-50000 m at +20 %: 0.200 % (3.48 kWh) above the reference, whose lower bound makes
   the gap certified (0.200 %). The reference starts full traction at 30970 m, 480 m before the
   strategy (31448.6 m), ahead of the steep stretch (5 per mille with the 800 m curve at 31-32.5 km,
   where 69 km/h cannot be held), runs over it faster, stops powering at 33560 m (strategy: 33664 m)
   and coasts down the -4 per mille descent below the 70 km/h limit at 38000 m, where the strategy
   arrives at 70 km/h and holds it by braking to 38385 m. The strategy has no arc that powers
   ahead of a steep ascent (Albrecht et al. 2016, Part 2); on the energy-time curve the run at +20 %
   lies 2.3 kWh above the chord of +18 % and +22 %.
2. Section 0-26000 m at +36 %: the run is 0.356 s late (+32 %: 0.203 s). At the holding speed
   52.36609 km/h the final phase's adjoint just reaches eta_r at W = 60.23 km/h on the descent and
   the run holds W with regenerative braking; 0.0026 km/h higher it stays above eta_r, the run
   coasts past W and brakes with the friction brakes from 65 km/h, 100 s faster and 311 kWh
   dearer. The running time jumps over the schedule there, and the search returns the slower run
   (within the 0.5 s the variants are compared to).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import pytest

import trainsim
from trainsim.optimize.optimal import SectionSolver

ROOT = Path(__file__).resolve().parents[2]
#: The certified reference on 26000-50000 m at +20 % (2468 intervals, status ok; lower bound 0.200 %
#: below the strategy as well) [kWh].
REFERENCE_KWH = 1741.546
#: Issue 16's target for most cases [-].
GAP = 1e-3


@pytest.fixture(scope="module")
def scenario():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return trainsim.load_scenario(ROOT / "examples" / "heavy_haul" / "scenario_head.yaml")


@pytest.mark.xfail(strict=True, reason="no traction arc ahead of steep ascents (issue 16)")
def test_second_section_at_20_percent_within_a_tenth_of_a_percent_of_the_reference(scenario) -> None:
    solver = SectionSolver(scenario.train, scenario.route, 26000.0, 50000.0)
    plan = solver.solve(solver.fastest_time_s * 1.2)
    kwh = solver.energy_j(plan) / 3.6e6
    assert (kwh - REFERENCE_KWH) / REFERENCE_KWH < GAP, kwh


@pytest.mark.xfail(strict=True, reason="running time jumps where the final phase misses the W arc (issue 16)")
def test_first_section_at_36_percent_keeps_its_schedule(scenario) -> None:
    solver = SectionSolver(scenario.train, scenario.route, 0.0, 26000.0)
    T = solver.fastest_time_s * 1.36
    plan = solver.solve(T)
    assert abs(plan.running_time_s - T) < 1e-6, plan.running_time_s - T
