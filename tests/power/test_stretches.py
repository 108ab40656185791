"""Runs joined per stretch between stops (the per-stretch voltage feedback)."""

from __future__ import annotations

import numpy as np
import pytest

import trainsim
from trainsim.power.stretches import joined_run, stop_positions


@pytest.fixture(scope="module")
def metro():
    sc = trainsim.load_scenario("examples/power/metro_scenario.yaml")
    return sc, trainsim.run_fastest(sc.train, sc.route, sc.settings)


def test_joined_without_caps_is_the_whole_run(metro):
    """From rest to rest the stretches are independent: joined, they give the whole run's
    running time and traction work (the metro's line has no speed limit behind a stop that the
    rear would still hold)."""
    sc, run = metro
    stops = stop_positions(sc.route)
    assert len(stops) == 4
    joined = joined_run(sc.train, sc.route, sc.settings, np.full(len(stops) - 1, np.inf))
    assert joined.status == "ok"
    assert joined.running_time_s == pytest.approx(run.running_time_s, abs=1e-6)
    tr, jt = run.trace, joined.trace
    work = np.trapezoid(tr.traction_force_n, tr.position_m)
    assert np.trapezoid(jt.traction_force_n, jt.position_m) == pytest.approx(work, rel=1e-6)
    assert np.all(np.diff(jt.time_s) >= 0) and np.all(np.diff(jt.position_m) >= 0)


def test_a_cap_on_one_stretch_slows_only_that_stretch(metro):
    sc, _ = metro
    stops = stop_positions(sc.route)
    free = joined_run(sc.train, sc.route, sc.settings, np.full(3, np.inf))
    capped = joined_run(sc.train, sc.route, sc.settings, np.array([np.inf, 500e3, np.inf]))
    assert capped.running_time_s > free.running_time_s
    for k in (0, 2):  # the other stretches take the same time

        def duration(r, k=k):
            t = r.trace
            inside = (t.position_m >= stops[k]) & (t.position_m <= stops[k + 1])
            return np.ptp(t.time_s[inside])

        assert duration(capped) == pytest.approx(duration(free), abs=1e-9)
    mid = (capped.trace.position_m > stops[1]) & (capped.trace.position_m < stops[2])
    power = capped.trace.traction_force_n[mid] * capped.trace.speed_mps[mid]
    assert power.max() <= 500e3 * (1 + 1e-9)
