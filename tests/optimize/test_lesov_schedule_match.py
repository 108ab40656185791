"""Source 004's runs meet their schedule to 1e-6 s, and say so where they cannot (issue 13).

freight_000 and heavy_haul met theirs to 6.6e-5 s and 5.0e-4 s only, without a word: the running
time, as a function of the steady speed, jumped over the schedule (the holding phase switched at
grid points), and the search for the steady speed closed its bracket on the jump."""

from __future__ import annotations

import dataclasses
import warnings
from pathlib import Path

import pytest

import trainsim
from trainsim.constants import KMH
from trainsim.optimize import lesov
from trainsim.optimize.api import _solvers, optimize, proportional_targets
from trainsim.optimize.timetable import line_supplement

ROOT = Path(__file__).resolve().parents[2]
#: an artificial jump of the running time [s], far above what counts as meeting the schedule
JUMP_S = 1e-3


def _scenario(name: str):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return trainsim.load_scenario(ROOT / "examples" / name)


@pytest.mark.parametrize("example", ["freight_000/scenario.yaml", "heavy_haul/scenario_head.yaml"])
@pytest.mark.parametrize("supplement", ["5%", "20%", "40%"])
def test_every_section_meets_its_schedule(example, supplement):
    scenario = _scenario(example)
    result = optimize(scenario.train, scenario.route, line_supplement(supplement), "lesov", scenario.settings)
    assert result.run.status == "ok"
    assert not result.warnings
    assert max(abs(d) for d in result.schedule_deviation_s) <= lesov.SCHEDULE_MATCH_S


def test_a_schedule_met_only_across_a_jump_is_reported(monkeypatch):
    scenario = _scenario("metro_b/scenario.yaml")
    train, route, settings = scenario.train, scenario.route, scenario.settings
    solvers = _solvers(train, route, settings)[:1]
    targets = proportional_targets(line_supplement("10%"), [sv.fastest_time_s for sv in solvers])
    (plan,), notes = lesov.lesov_plans(train, route, solvers, targets, settings)
    assert not notes
    assert abs(plan.running_time_s - targets[0]) <= lesov.SCHEDULE_MATCH_S
    # the same runs, with their running time jumping by JUMP_S where the steady speed passes the one
    # that meets the schedule: no steady speed meets it any more
    v_star_kmh = plan.holding_speed_mps / KMH
    execute = lesov._execute

    def jumping(solver, sw):
        p = execute(solver, sw)
        shift = -0.5 * JUMP_S if sw.steady_speed_kmh > v_star_kmh else 0.5 * JUMP_S
        return dataclasses.replace(p, running_time_s=p.running_time_s + shift)

    monkeypatch.setattr(lesov, "_execute", jumping)
    (plan,), notes = lesov.lesov_plans(train, route, solvers, targets, settings)
    off_s = plan.running_time_s - targets[0]
    assert lesov.SCHEDULE_MATCH_S < abs(off_s) <= 0.5 * JUMP_S * (1.0 + 1e-6)
    assert len(notes) == 1 and "jumps over it" in notes[0], notes
    assert f"{off_s:+.2g} s" in notes[0]
