"""A schedule counts as met within max(0.5 s, 0.05 %), not more: a run 2 s late is reported late (a
seeded widening of the acceptance to 5 s must make this fail)."""

from __future__ import annotations

from pathlib import Path

import pytest

import trainsim
from trainsim.optimize.api import optimize
from trainsim.optimize.timetable import SectionSchedule, Timetable

METRO = Path(__file__).resolve().parents[2] / "examples" / "metro_b" / "scenario.yaml"


@pytest.mark.parametrize("late_s", [0.0, 2.0])
def test_a_run_two_seconds_late_is_not_ok(late_s):
    scenario = trainsim.load_scenario(METRO)
    fastest = trainsim.run_fastest(scenario.train, scenario.route, scenario.settings)
    # every section scheduled late_s faster than the train can run it
    sections = tuple(SectionSchedule(running_time_s=s.running_time_s - late_s) for s in fastest.sections)
    result = optimize(scenario.train, scenario.route, Timetable(sections=sections), strategy="optimal")
    summary = result.summary()
    if late_s == 0.0:
        assert summary["status"] == "ok"
        assert all(abs(d) <= 0.5 for d in summary["schedule_deviation_s"])
    else:
        assert summary["status"] == "infeasible schedule"
        assert all(d == pytest.approx(late_s, abs=0.05) for d in summary["schedule_deviation_s"])
        assert len(summary["warnings"]) == len(sections)
