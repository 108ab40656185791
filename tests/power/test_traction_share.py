"""Voltage-limited traction fed back per time step (trainsim.power.traction_share, method per_step)."""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import pytest

import trainsim
from trainsim.power import Network, Substation, Track, standard_limits
from trainsim.power.stretches import joined_run, stop_positions
from trainsim.power.study import FeedbackSettings, TrainService, run_study
from trainsim.power.traction_share import (
    SHARE_RESOLUTION_M,
    ShareProfile,
    route_with_share,
    step_spans,
)


@lru_cache(maxsize=1)
def _metro():
    return trainsim.load_scenario("examples/power/metro_scenario.yaml")


def _weak_line() -> Network:
    """The metro's 4.6 km line fed from one end only, through a thin contact line (0.05 ohm/km):
    far from the substation an accelerating train pulls its pantograph into the EN 50388 ramp."""
    sc = _metro()
    length = sc.route.end_m - sc.route.start_m
    return Network(
        "weak",
        "dc",
        standard_limits("dc_750"),
        (Track("up", 0.0, length, 0.05e-3, 0.012e-3),),
        (Substation("S", 0.0, ("up",), 850.0, 0.02, reversible=False),),
    )


def _study(method: str, tolerance: float = 1e-3):
    service = TrainService("up", _metro(), "up", 0.0, 1, (0.0,))
    fb = FeedbackSettings(enabled=True, max_iterations=30, tolerance=tolerance, method=method)
    return run_study(_weak_line(), [service], feedback=fb)


def test_step_spans_cover_the_run_half_way_between_steps():
    lo, hi = step_spans(np.array([0.0, 10.0, 30.0, 30.0, 60.0]))
    np.testing.assert_array_equal(lo, [0.0, 5.0, 20.0, 30.0, 45.0])
    np.testing.assert_array_equal(hi, [5.0, 20.0, 30.0, 45.0, 60.0])


def test_lowered_takes_the_lower_share_and_merges_equal_pieces():
    p = ShareProfile.full(0.0, 100.0).lowered(
        np.array([10.0, 30.0]), np.array([30.0, 50.0]), np.array([0.5, 0.5])
    )
    np.testing.assert_array_equal(p.x_m, [0.0, 10.0, 50.0, 100.0])
    np.testing.assert_array_equal(p.share, [1.0, 0.5, 1.0])
    q = p.lowered(np.array([20.0]), np.array([70.04]), np.array([0.7]))  # 0.7 only where it is lower
    np.testing.assert_allclose(q.x_m, [0.0, 10.0, 50.0, 70.0, 100.0], atol=1e-12)  # rounded to 0.1 m
    np.testing.assert_array_equal(q.share, [1.0, 0.5, 0.7, 1.0])
    assert SHARE_RESOLUTION_M == 0.1
    np.testing.assert_array_equal(q.at(np.array([0.0, 9.99, 10.0, 49.9, 50.0, 99.0, 100.0])),
                                  [1.0, 1.0, 0.5, 0.5, 0.7, 1.0, 1.0])  # fmt: skip


def test_a_constant_share_per_stretch_equals_the_joined_run():
    """Where the share is constant over each stretch between two stops, the run over the marked route
    is the per-stretch run with the tractive effort scaled on each stretch (EffortCurve.scaled)."""
    sc = _metro()
    stops = stop_positions(sc.route)
    shares = np.array([1.0, 0.55, 0.8])
    profile = ShareProfile(stops, shares)
    marked = route_with_share(sc.route, sc.train, profile)
    run = trainsim.run_fastest(sc.train, marked, sc.settings)
    joined = joined_run(sc.train, sc.route, sc.settings, np.full(3, np.inf), shares)
    free = trainsim.run_fastest(sc.train, sc.route, sc.settings)
    assert run.status == "ok" and joined.status == "ok"
    assert run.running_time_s > free.running_time_s + 1.0
    assert run.running_time_s == pytest.approx(joined.running_time_s, rel=1e-9)
    tr, jt = run.trace, joined.trace
    work = np.trapezoid(tr.traction_force_n, tr.position_m)
    assert work == pytest.approx(np.trapezoid(jt.traction_force_n, jt.position_m), rel=1e-9)
    # the same motion: time at every position of the joined trace between the stops (at a stop the
    # position repeats over the dwell)
    moving = np.min(np.abs(jt.position_m[:, None] - stops[None, :]), axis=1) > 1e-6
    at = np.interp(jt.position_m[moving], tr.position_m, tr.time_s)
    np.testing.assert_allclose(at, jt.time_s[moving], atol=1e-6)
    assert abs(run.energy_balance["relative_error"]) < 1e-6


def test_weak_feed_per_step_loses_time_converges_and_the_books_close():
    result = _study("per_step", tolerance=1e-4)
    summary = result.summary()
    train = summary["trains"][0]
    fb = summary["feedback"]
    assert fb["consistent"] and 2 <= fb["iterations"] < 30 and summary["status"] == "time_lost"
    assert train["time_lost_s"] > 10.0
    assert 0.0 < train["traction_share_min"] < 1.0 and train["traction_limited_length_m"] > 100.0
    # the network's books
    assert result.energy_balance_error() < 1e-6
    # run and network agree: what the network delivered is what the run used (its share of the full demand)
    assert train["traction_delivered_kwh"] == pytest.approx(train["traction_used_kwh"], rel=1e-4)
    assert fb["mismatch"] <= 1e-4
    # the limitation is real: at full supply the train would have asked more than it got
    assert train["traction_demand_kwh"] > 1.5 * train["traction_delivered_kwh"]


def test_per_step_is_never_more_conservative_than_per_stretch():
    """per_stretch caps each stretch at the least power delivered at a limited step, until the line
    delivers all it is asked (the pantograph kept above the ramp); per_step lets the train draw what
    EN 50388 lets it draw at its voltage at each step: it loses less time."""
    step = _study("per_step").summary()["trains"][0]
    stretch = _study("per_stretch").summary()["trains"][0]
    assert 0.0 < step["time_lost_s"] < stretch["time_lost_s"]
