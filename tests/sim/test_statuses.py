"""Statuses that tell the truth for impossible physics (issue 13): each case with its status, its
message and its best feasible result."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from simcases import make_route, make_train

import trainsim
from trainsim.sim.result import STATUSES

DATA = Path(__file__).resolve().parents[1] / "data" / "trainruns"


def test_every_run_ends_at_standstill_at_its_stop_with_the_strip_model_and_a_fine_step():
    """The strip mass model on TrainRuns.jl's freight x realworld with 1.25 m steps ended 20 mm short
    of the final stop at 0.09 m/s with status ok: a stretch starting and ending at a kink speed was
    counted as -1 kinks, so the kink insertion wrote past its arrays and lost the last points."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        train = trainsim.load_train(DATA / "trains" / "freight.yaml")
        route = trainsim.load_route(DATA / "paths" / "realworld.yaml", mass_model="homogeneous_strip")
    r = trainsim.run_fastest(train, route, trainsim.RunSettings(max_step_m=1.25))
    assert r.status == "ok", r.warnings
    assert r.trace.position_m[-1] == route.stops[-1].position_m
    assert r.trace.speed_mps[-1] == 0.0
    assert abs(r.energy_balance["relative_error"]) < 1e-6


def test_a_run_that_does_not_end_at_its_stop_says_so():
    """The check behind every result: a trace that ends short of the last stop, or moving, is not ok."""
    from trainsim.sim.profile import line_resistance_profile, speed_ceiling
    from trainsim.sim.result import build_result

    train, route = make_train(), make_route(length_m=1000.0)
    s = np.array([0.0, 500.0, 999.9])
    v = np.array([0.0, 10.0, 0.5])
    r = build_result(
        train=train,
        route=route,
        settings=trainsim.RunSettings(),
        profile=line_resistance_profile(route, train),
        ceiling=speed_ceiling(route, train),
        s=s,
        v=v,
        t=np.array([0.0, 100.0, 120.0]),
        regime=np.array([0, 3, 4], dtype=np.int8),
        status="ok",
    )
    assert r.status == "did_not_reach_stop"
    assert "0.100 m short of B" in r.warnings[-1] and "1.800 km/h" in r.warnings[-1]
    assert r.status in STATUSES


def test_statuses_are_a_documented_vocabulary():
    assert {"ok", "stalled", "brake_limited", "did_not_reach_stop"} <= set(STATUSES)
    assert all(isinstance(text, str) and text for text in STATUSES.values())


def test_stall_on_a_grade_gives_the_best_feasible_run():
    train = make_train(traction_n=100e3, mass_kg=300e3)
    route = make_route(length_m=5000.0, gradient_permille=40.0)  # 118 kN of grade > 100 kN
    r = trainsim.run_fastest(train, route)
    assert r.status == "stalled"
    assert "stalls at 0.0 m" in r.warnings[0] and "100.0 kN" in r.warnings[0] and "117.7 kN" in r.warnings[0]
    assert r.trace.speed_mps[-1] == 0.0


def test_zero_speed_limit_is_refused_by_the_route():
    with pytest.raises(trainsim.InputError):
        make_route(limit_kmh=0.0)
