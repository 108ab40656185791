"""Source 004's runs stop at every stop (issue 13): a recuperative brake stronger than the service
braking curve (0.8 x the traction of two freight locomotives, 640 kN, against 486 kN of service
braking) stopped the run 68 m short of its last stop with status did_not_reach_stop."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from trainsim.optimize.api import optimize
from trainsim.optimize.timetable import line_supplement

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "multipoint"))
from mpcases import freight_train, hilly_route


@pytest.mark.parametrize("regen_fraction", [0.8, 0.3])
def test_every_section_ends_at_its_stop_at_standstill(regen_fraction):
    train = freight_train(15, locos=2, regen_fraction=regen_fraction, electrical=True)
    route = hilly_route()
    result = optimize(train, route, line_supplement("10%"), "lesov")
    run = result.run
    assert run.status == "ok", run.warnings
    tr = run.trace
    for stop in route.stops[1:]:
        at = np.flatnonzero(np.abs(tr.position_m - stop.position_m) < 1e-6)
        assert at.size, f"the run never reaches {stop.name}"
        assert tr.speed_mps[at[0]] == pytest.approx(0.0, abs=1e-6)
    assert tr.position_m[-1] == pytest.approx(route.stops[-1].position_m, abs=1e-6)
    # and meets its schedule (source 004's epsilon, 0.5 s)
    for dev in result.schedule_deviation_s:
        assert abs(dev) <= 0.5
    assert abs(run.energy_balance["relative_error"]) < 1e-6
