"""Source 004's runs do not move with the step (issue 13): on every example, the energies and the
running time change by less than 1e-6 when the step is halved (1.7e-3 on the metro before its
switching points were located as events of the motion)."""

from __future__ import annotations

import dataclasses
import warnings
from pathlib import Path

import pytest

import trainsim
from trainsim.optimize.api import optimize
from trainsim.optimize.timetable import line_supplement

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = sorted(str(p.relative_to(ROOT)) for p in (ROOT / "examples").glob("*/scenario*.yaml"))
#: phase A (holding, optimize/pmp_kernel.holding_segment) switches to coasting and to braking for a
#: lower limit at grid points on the heavy-haul line's descents: its trajectory moves with the step
HOLDING_ON_THE_GRID = pytest.mark.xfail(
    strict=True,
    reason="known gap outside lesov: pmp_kernel.holding_segment snaps coasting on descents to grid points "
    "(1.7e-6 net energy on heavy_haul; 1.0e-4 before lesov gave it the braking curves below its held "
    "speed, which left the grid-point jumps into braking)",
)


def _lesov(scenario, step_m: float):
    timetable = scenario.timetable if scenario.timetable is not None else line_supplement("10%")
    settings = dataclasses.replace(scenario.settings, max_step_m=step_m)
    return optimize(scenario.train, scenario.route, timetable, "lesov", settings)


def _change(a: float, b: float) -> float:
    return abs(a - b) / max(abs(b), 1e-12)


@pytest.mark.parametrize(
    "example", [pytest.param(e, marks=HOLDING_ON_THE_GRID) if "heavy_haul" in e else e for e in EXAMPLES]
)
def test_energy_and_time_do_not_move_when_the_step_is_halved(example):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scenario = trainsim.load_scenario(ROOT / example)
    h = scenario.settings.max_step_m
    coarse, fine = _lesov(scenario, h), _lesov(scenario, h / 2)
    assert coarse.run.status == fine.run.status == "ok"
    a, b = coarse.run, fine.run
    assert _change(a.running_time_s, b.running_time_s) < 1e-6
    for name in ("net", "traction", "braking", "regenerated"):
        ea, eb = getattr(a.energy_kwh, name), getattr(b.energy_kwh, name)
        assert abs(ea - eb) <= 1e-6 * max(abs(eb), 1e-3 * abs(b.energy_kwh.traction)), name
    for sa, sb in zip(a.sections, b.sections, strict=True):
        assert _change(sa.energy_kwh.net, sb.energy_kwh.net) < 1e-6
    # the schedule is met exactly, not within source 004's epsilon of 0.5 s
    assert max(abs(d) for d in coarse.schedule_deviation_s) < 1e-3


def test_the_examples_are_all_here():
    assert len(EXAMPLES) >= 6
