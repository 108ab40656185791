"""Running-time allowances as planners write them: percent, minutes per 100 km, fixed seconds, on
ranges, shared by time, by distance or energy-optimally; the 2 % band between timing points."""

from __future__ import annotations

from itertools import pairwise
from pathlib import Path

import numpy as np
import pytest

import trainsim
from trainsim.errors import InputError
from trainsim.optimize.allowances import Allowance, allowance_s, allowance_spread, allowance_timetable
from trainsim.optimize.api import optimize
from trainsim.optimize.optimal import SectionSolver
from trainsim.optimize.timetable import line_supplement

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def metro():
    return trainsim.load_scenario(ROOT / "examples" / "metro_b" / "scenario.yaml")


@pytest.fixture(scope="module")
def fastest_s(metro):
    stops = [s.position_m for s in metro.route.stops]
    return np.array(
        [SectionSolver(metro.train, metro.route, a, b).fastest_time_s for a, b in pairwise(stops)]
    )


def targets(timetable):
    return np.array([s.running_time_s for s in timetable.sections])


def test_allowance_formulas():
    assert allowance_s("percent", 5.0, 600.0, 1.0) == pytest.approx(30.0)
    assert allowance_s("min_per_100km", 1.5, 1.0, 50_000.0) == pytest.approx(45.0)  # 0.75 min
    assert allowance_s("seconds", 12.0, 600.0, 1.0) == 12.0


def test_percent_on_the_whole_line_by_time_is_uniform(metro, fastest_s):
    tt, rows = allowance_timetable(metro.train, metro.route, [Allowance("percent", 7.0)])
    assert np.allclose(targets(tt), fastest_s * 1.07)
    assert rows[0]["allowance_s"] == pytest.approx(0.07 * fastest_s.sum())


def test_minutes_per_100km_by_distance(metro, fastest_s):
    stops = np.array([s.position_m for s in metro.route.stops])
    tt, rows = allowance_timetable(
        metro.train, metro.route, [Allowance("min_per_100km", 3.0, distribution="distance")]
    )
    total = 3.0 * 60.0 * (stops[-1] - stops[0]) / 100_000.0
    assert rows[0]["allowance_s"] == pytest.approx(total)
    assert np.allclose(targets(tt) - fastest_s, total * np.diff(stops) / (stops[-1] - stops[0]))


def test_construction_margin_on_a_range_adds_to_the_standard_allowance(metro, fastest_s):
    stops = [s.position_m for s in metro.route.stops]
    inside = (stops[1] + 100.0, stops[1] + 600.0)  # inside the second section only
    tt, rows = allowance_timetable(
        metro.train,
        metro.route,
        [Allowance("percent", 5.0), Allowance("seconds", 20.0, *inside, label="construction margin")],
    )
    extra = targets(tt) - fastest_s * 1.05
    assert extra == pytest.approx([0.0, 20.0, 0.0], abs=1e-9)
    assert rows[1]["per_section_s"][1] == pytest.approx(20.0)


def test_energy_optimal_split_is_the_line_supplement_split(metro, fastest_s):
    tt, _ = allowance_timetable(
        metro.train, metro.route, [Allowance("percent", 12.8, distribution="optimal")]
    )
    assert targets(tt).sum() == pytest.approx(fastest_s.sum() * 1.128, abs=1e-6)
    split = optimize(metro.train, metro.route, line_supplement("12.8%")).scheduled_running_time_s
    assert np.allclose(targets(tt), split, atol=0.1)
    # not the uniform split: the sections have different prices of time at a uniform percentage
    assert not np.allclose(targets(tt), fastest_s * 1.128, atol=0.5)
    # and it saves energy against the uniform split at the same total time
    uniform, _ = allowance_timetable(metro.train, metro.route, [Allowance("percent", 12.8)])
    e_opt = optimize(metro.train, metro.route, tt).run.energy_kwh.net
    e_uni = optimize(metro.train, metro.route, uniform).run.energy_kwh.net
    assert e_opt <= e_uni + 1e-6


def test_bad_allowances_are_input_errors(metro):
    with pytest.raises(InputError, match="kind"):
        Allowance("percentage", 5.0)
    with pytest.raises(InputError, match="distribution"):
        Allowance("percent", 5.0, distribution="mareco")
    with pytest.raises(InputError):
        Allowance("percent", float("nan"))
    with pytest.raises(InputError):
        Allowance("seconds", 5.0, 100.0, 50.0)
    stops = [s.position_m for s in metro.route.stops]
    with pytest.raises(InputError, match="whole sections"):
        allowance_timetable(
            metro.train, metro.route, [Allowance("percent", 5.0, stops[0], stops[1] + 10.0, "optimal")]
        )
    with pytest.raises(InputError, match="outside"):
        allowance_timetable(metro.train, metro.route, [Allowance("percent", 5.0, -10.0, stops[1])])


def test_allowance_spread_between_timing_points():
    def fast(x):
        return x / 20.0  # 20 m/s

    def even(x):
        return 1.10 * x / 20.0  # 10 % everywhere

    def uneven(x):
        return x / 20.0 * (1.02 if x <= 1000.0 else 1.0) + (max(0.0, x - 1000.0) / 20.0) * 0.18

    assert allowance_spread([0.0, 1000.0, 2000.0], even, fast) == []
    messages = allowance_spread([0.0, 1000.0, 2000.0], uneven, fast)
    assert len(messages) == 2 and "0-1000 m" in messages[0]
