"""The holding-speed search of the optimal strategy (issue 16) grows its bracket along the secant of
the last two runs it built: the same holding speed (to the time tolerance) as the geometric steps
used before, in fewer runs.

No timed asserts: the counts of runs (``SectionSolver.plan``) are deterministic.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from trainsim.io.ttobench import read_ttobench_track, read_ttobench_train
from trainsim.optimize import optimal
from trainsim.optimize.optimal import TIME_TOLERANCE_S, SectionSolver

DATA = Path(__file__).resolve().parents[3] / "shared" / "data" / "ttobench"

pytestmark = pytest.mark.skipif(not (DATA / "tracks").is_dir(), reason="TTOBench data not available")


@pytest.fixture(scope="module")
def virm_stadelhofen():
    """The VIRM6 on CH_Stadelhofen_Altstetten's third section (2260 m): a long final coast, so the
    holding speed (38.7 m/s) is far above the schedule's average speed (16.4 m/s at +10 %)."""
    tt = read_ttobench_train(DATA / "trains" / "NL_Intercity_VIRM6.json")
    route = read_ttobench_track(DATA / "tracks" / "CH_Stadelhofen_Altstetten.json", tt)
    s = [st.position_m for st in route.stations]
    return tt.train, route, s[2], s[3]


def _solve_counting(monkeypatch, train, route, s0, s1):
    count = {"runs": 0}
    original = SectionSolver.plan

    def counted(self, holding_speed_mps):
        count["runs"] += 1
        return original(self, holding_speed_mps)

    monkeypatch.setattr(SectionSolver, "plan", counted)
    solver = SectionSolver(train, route, s0, s1)
    target = 1.1 * solver.fastest_time_s
    plan = solver.solve(target)
    monkeypatch.setattr(SectionSolver, "plan", original)
    return plan, target, solver.energy_j(plan), count["runs"]


def test_secant_bracket_finds_the_same_holding_speed_in_fewer_runs(virm_stadelhofen, monkeypatch):
    train, route, s0, s1 = virm_stadelhofen
    plan, target, energy, runs = _solve_counting(monkeypatch, train, route, s0, s1)
    # the search before: steps growing by 1.5 each
    monkeypatch.setattr(optimal, "BRACKET_OVERSHOOT", 0.0)
    before, _, energy_before, runs_before = _solve_counting(monkeypatch, train, route, s0, s1)

    assert abs(plan.running_time_s - target) <= TIME_TOLERANCE_S
    assert abs(before.running_time_s - target) <= TIME_TOLERANCE_S
    # the running time moves by about 60 s per unit of log V here: 1e-8 s is 2e-10 in log V
    assert abs(np.log(plan.holding_speed_mps / before.holding_speed_mps)) < 1e-9
    assert energy == pytest.approx(energy_before, rel=1e-9)
    assert runs < runs_before
