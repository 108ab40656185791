"""Regime rules of ATO (issue 16): a minimum time in every regime and coasting only above a speed, applied
to the optimal strategy on the metro example and on a hilly line; bad values rejected."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import numpy as np
import pytest

import trainsim
from trainsim.constants import KMH
from trainsim.errors import InputError
from trainsim.optimize.api import optimize
from trainsim.optimize.constraints import DrivingConstraints
from trainsim.optimize.timetable import SectionSchedule, Timetable
from trainsim.sim import codes

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests" / "multipoint"))
from mpcases import freight_train, hilly_route  # noqa: E402


def tolerance(T: float) -> float:
    return max(0.5, 5e-4 * T)


@pytest.mark.parametrize("name", ["min_regime_time_s", "coast_min_speed_mps"])
@pytest.mark.parametrize("bad", [-1.0, float("nan"), float("inf"), 1e9])
def test_bad_values_name_the_field_and_the_range(name, bad):
    with pytest.raises(InputError, match=name) as err:
        DrivingConstraints(**{name: bad})
    assert ">= 0" in str(err.value)


def arcs(tr) -> list[tuple[int, float, float, float, float]]:
    """(regime, start m, end m, duration s, lowest speed m/s) of every arc of a run's trace (dwell out)."""
    r, s, t, v = tr.regime, tr.position_m, tr.time_s, tr.speed_mps
    out, k = [], 0
    while k < len(r) - 1:
        q = k
        while q + 1 < len(r) - 1 and r[q + 1] == r[k]:
            q += 1
        if r[k] != codes.DWELL and t[q + 1] - t[k] > 1e-6:
            out.append(
                (int(r[k]), float(s[k]), float(s[q + 1]), float(t[q + 1] - t[k]), float(v[k : q + 2].min()))
            )
        k = q + 1
    return out


def same_time(train, route, supplement: float):
    """The free optimum and a timetable of its running times (the same schedule for both runs)."""
    n = len(route.stops) - 1
    free = optimize(
        train,
        route,
        Timetable(sections=tuple(SectionSchedule(supplement_fraction=supplement) for _ in range(n))),
    )
    tt = Timetable(sections=tuple(SectionSchedule(running_time_s=T) for T in free.scheduled_running_time_s))
    return free, tt


def check(free, res, dc: DrivingConstraints, unmerged: bool = False) -> None:
    """The rules hold in the run; with ``unmerged``, arcs that no merge lengthens within the schedule
    may stay shorter than the minimum, each named in a note."""
    # the running time is still met, the rules cost energy and say how much
    for T, dev in zip(res.scheduled_running_time_s, res.schedule_deviation_s, strict=True):
        assert abs(dev) <= tolerance(T), (T, dev, res.warnings)
    assert res.run.energy_kwh.net >= free.run.energy_kwh.net * (1.0 - 1e-4)
    assert any("regime rules cost" in n for n in res.notes)
    assert res.summary()["status"] == "ok", res.warnings
    # gravity included: the net energy balance of the recorded motion closes
    assert abs(res.run.energy_balance["relative_error"]) < 1e-6
    for regime, a, b, dur, vmin in arcs(res.run.trace):
        if dc.coast_min_speed_mps and regime == codes.COAST:
            assert vmin >= dc.coast_min_speed_mps - 1e-6, (a, b, vmin / KMH)
        if dc.min_regime_time_s and dur < dc.min_regime_time_s - 1e-6:
            # only where a limit, the stop or a gradient forces it, and said in a note
            named = [n for n in res.notes if re.search(rf"\b{a:.0f}-{b:.0f} m lasts", n)]
            assert named, (codes.REGIME_NAMES[regime], a, b, dur, res.notes)
            assert "forced by the" in named[0] or (unmerged and "no merge lengthens it" in named[0]), named


@pytest.fixture(scope="module")
def metro():
    sc = trainsim.load_scenario(ROOT / "examples" / "metro_b" / "scenario.yaml")
    return (sc.train, sc.route, *same_time(sc.train, sc.route, 0.1))


def test_metro_coasts_only_above_the_speed(metro):
    train, route, free, tt = metro
    # the free optimum coasts down to about 64 km/h: 67 km/h binds
    assert any(r == codes.COAST and v < 66 * KMH for r, *_, v in arcs(free.run.trace))
    dc = DrivingConstraints(coast_min_speed_mps=67 * KMH)
    res = optimize(train, route, tt, constraints=dc)
    check(free, res, dc)
    assert res.run.energy_kwh.net > free.run.energy_kwh.net * (1.0 + 1e-4)
    # below the speed it holds it (the coast-remotor)
    assert any(r == codes.CRUISE and abs(v - 67 * KMH) < 1e-6 for r, *_, v in arcs(res.run.trace))


def test_rules_that_do_not_bind_leave_the_optimum_unchanged(metro):
    train, route, free, tt = metro
    res = optimize(
        train, route, tt, constraints=DrivingConstraints(min_regime_time_s=1.0, coast_min_speed_mps=10 * KMH)
    )
    assert res.run.energy_kwh.net == pytest.approx(free.run.energy_kwh.net, rel=1e-9)
    assert not res.notes


@pytest.fixture(scope="module")
def hilly():
    train = freight_train(15, locos=2, regen_fraction=0.8, electrical=True)
    route = hilly_route()
    return (train, route, *same_time(train, route, 0.1))


@pytest.mark.parametrize(
    "dc",
    [
        DrivingConstraints(coast_min_speed_mps=60 * KMH),
        DrivingConstraints(min_regime_time_s=8.0),
        DrivingConstraints(min_regime_time_s=8.0, coast_min_speed_mps=60 * KMH),
    ],
    ids=["coast above 60 km/h", "8 s per regime", "both"],
)
def test_hilly_line(hilly, dc):
    train, route, free, tt = hilly
    res = optimize(train, route, tt, constraints=dc)
    check(free, res, dc, unmerged=True)
    if dc.min_regime_time_s:
        # fewer short arcs than the optimum: the 3.3 s and 2 s regenerative arcs are merged
        def short(r):
            return sum(d < dc.min_regime_time_s for _, _, _, d, _ in arcs(r.run.trace))

        assert short(res) < short(free)


@pytest.mark.parametrize("tmin", [22.0, 25.0, 120.0])
def test_a_minimum_the_schedule_does_not_allow_is_said(metro, tmin):
    """The metro's optimum drives about 20 s of full traction and coasts (its coast barely slows it): 22 s
    or 25 s of full traction (the latter reaches the 80 km/h limit) make every run that keeps them
    faster than the schedule, which only partial traction or braking could slow down; 120 s is longer
    than any metro section's running time. Said, status not ok, never silently."""
    train, route, _free, tt = metro
    res = optimize(train, route, tt, constraints=DrivingConstraints(min_regime_time_s=tmin))
    missed = [w for w in res.warnings if "no run that keeps them takes the scheduled" in w]
    short = [n for n in res.notes if f"shorter than {tmin:g} s" in n]
    assert missed or short
    if missed:
        assert res.summary()["status"] != "ok"
        assert any(
            abs(d) > tolerance(T)
            for d, T in zip(res.schedule_deviation_s, res.scheduled_running_time_s, strict=False)
        )


@pytest.mark.parametrize("strategy", ["lesov", "fastest"])
def test_strategies_without_the_rules_refuse_them(metro, strategy):
    """Run without the rules, their warning made the status "infeasible schedule" (issue 13)."""
    train, route, _, tt = metro
    for rules in (
        DrivingConstraints(coast_min_speed_mps=60 * KMH),
        DrivingConstraints(min_regime_time_s=5.0),
    ):
        with pytest.raises(InputError) as err:
            optimize(train, route, tt, strategy, constraints=rules)
        assert f"strategy {strategy} does not apply them" in str(err.value)
    # the other constraints still apply to every strategy
    res = optimize(train, route, tt, strategy, constraints=DrivingConstraints(speed_margin_mps=1.0))
    assert res.summary()["status"] == "ok" and np.isfinite(res.run.energy_kwh.net)


def test_reference_coasts_only_above_the_speed(metro):
    pytest.importorskip("casadi")
    from trainsim.optimize.reference import solve_reference

    train, route, _, tt = metro
    s0, s1 = route.stops[0].position_m, route.stops[1].position_m
    T = tt.sections[0].running_time_s
    v_c = 67 * KMH
    free = solve_reference(train, route, s0, s1, T, intervals=300)
    ref = solve_reference(
        train, route, s0, s1, T, intervals=300, constraints=DrivingConstraints(coast_min_speed_mps=v_c)
    )
    assert free.status == "ok" and ref.status == "ok", (free.status, ref.status)
    assert free.v.max() > v_c and np.any((free.v < v_c - 0.05) & (free.s > s0 + 400) & (free.s < s1 - 300))
    # from the end of the departure's acceleration to the start of the final braking, never below v_c
    first = int(np.argmax(ref.v >= v_c - 1e-6))
    last = len(ref.v) - 1 - int(np.argmax(ref.v[::-1] >= v_c - 1e-6))
    assert ref.v[first : last + 1].min() >= v_c - 1e-6
    assert ref.energy_j >= free.energy_j * (1.0 - 1e-6)
    assert ref.running_time_s <= T + 1e-3
