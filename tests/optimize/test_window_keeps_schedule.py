"""A latest passing time that would leave more time to the stop than the run can take after it: the
optimal strategy keeps the section's schedule, passes the point as early as that allows, and says so.
(Found through the web form: a metro run with a 5 s window at 800 m was refused as "longer than a run
at walking pace".)"""

from __future__ import annotations

import numpy as np
import pytest

import trainsim
from trainsim.model.timetable import SectionSchedule, Timetable, TimingPoint
from trainsim.optimize.api import optimize
from trainsim.sim import codes


@pytest.fixture(scope="module")
def metro():
    return trainsim.load_train("examples/metro_b/train.yaml"), trainsim.load_route(
        "examples/metro_b/route.yaml"
    )


def _optimize(metro, point: TimingPoint):
    train, route = metro
    timetable = Timetable(line=SectionSchedule(supplement_fraction=0.1), timing_points=(point,))
    return optimize(train, route, timetable, "optimal", trainsim.RunSettings())


@pytest.mark.parametrize("latest_s", [5.0, 48.0])
def test_a_window_that_leaves_too_much_time_keeps_the_schedule(metro, latest_s) -> None:
    free = _optimize(metro, TimingPoint(position_m=800.0, earliest_s=0.0, latest_s=1e4, name="P1"))
    res = _optimize(metro, TimingPoint(position_m=800.0, latest_s=latest_s, name="P1"))
    # every section keeps the time the line supplement gave it
    assert np.allclose(res.scheduled_running_time_s, free.scheduled_running_time_s, atol=1e-3)
    assert max(abs(d) for d in res.schedule_deviation_s) < 1e-3
    (p,) = res.timing_points
    assert not p["met"] and p["time_s"] > latest_s
    # passing earlier is impossible while keeping the schedule: from the point on the train only
    # coasts and brakes (no traction), so the run after it is the slowest it can drive from there
    run = res.run
    t, s, regime = run.trace.time_s, run.trace.position_m, run.trace.regime
    after = (s > 800.0 + 1.0) & (t < res.scheduled_running_time_s[0])
    assert after.any() and not np.any(regime[after] == codes.TRACTION)
    # the stretches held to the point pass it later than the optimum without the window, whose final
    # coast starts before it: that run is kept (it is the closest to the window)
    (q,) = free.timing_points
    assert p["time_s"] == pytest.approx(q["time_s"], abs=1e-9)
    assert any("P1: no run of the optimal strategy" in w for w in res.warnings)
    assert res.summary()["status"] != "ok"
