"""Many trains together: hindrance at the minimum headway, delays, single-track meets, deadlocks."""

from __future__ import annotations

from itertools import pairwise

import numpy as np
import pytest

import trainsim
from trainsim import Route, RunSettings, SpeedLimit
from trainsim.errors import InputError
from trainsim.operations.line import Signalling, StationLayout, build_line
from trainsim.operations.simulate import ScheduledStop, TrainService, simulate

SETTINGS = RunSettings(max_step_m=20)


@pytest.fixture(scope="module")
def train() -> trainsim.Train:
    return trainsim.load_train("examples/metro_b/train.yaml")


def _double(length_m: float = 6000.0, **sig) -> tuple:
    geometry = Route("geo", 0, length_m, (), (SpeedLimit(0, length_m, 80 / 3.6),))
    stations = (StationLayout("A", 500), StationLayout("B", 3000), StationLayout("C", length_m - 500))
    return build_line(
        "metro", length_m, "double_track", stations, Signalling(**sig), block_length_m=600
    ), geometry


def _pair(train, line, geometry, headway_s: float):
    svcs = [
        TrainService("lead", train, "up", "A", "C", 0.0, (ScheduledStop("B", 30),)),
        TrainService("follow", train, "up", "A", "C", headway_s, (ScheduledStop("B", 30),)),
    ]
    return simulate(line, geometry, svcs, SETTINGS)


def test_follower_at_minimum_headway_is_never_braked_and_one_second_closer_is(train) -> None:
    line, geometry = _double()
    probe = _pair(train, line, geometry, 600.0)
    assert probe.status == "ok"
    (h,) = probe.headways
    assert h.buffer_s > 0
    at = _pair(train, line, geometry, h.min_headway_s)
    follower = at.trains[1]
    assert at.status == "ok" and not at.conflicts
    assert follower.hindrances == [] and follower.delay_s == pytest.approx(0.0, abs=1e-9)
    assert follower.energy_kwh == pytest.approx(follower.planned_energy_kwh)
    closer = _pair(train, line, geometry, h.min_headway_s - 1.0)
    follower = closer.trains[1]
    assert closer.status == "conflicts" and closer.conflicts[0].overlap_s == pytest.approx(1.0, abs=1e-6)
    assert closer.conflicts[0].resource == h.critical_resource
    # the warning aspect is seen 1 s before the route is set: the driver brakes and picks up speed
    # again when the signal clears, without stopping
    assert [h.kind for h in follower.hindrances] == ["slowed"]
    assert follower.delay_s > 0
    assert follower.energy_kwh > follower.planned_energy_kwh
    _assert_never_stops_between_stations(follower)


def _assert_never_stops_between_stations(outcome) -> None:
    tr = outcome.trajectory
    stations = {s.station: s for s in outcome.stops}
    assert stations
    moving = tr.speed_mps > 0
    standing = tr.position_m[~moving]
    planned = outcome.planned_trajectory
    stops = np.unique(planned.position_m[planned.speed_mps == 0])
    # every stand of the operated run is at a stop of the planned run
    assert all(np.min(np.abs(stops - x)) < 1e-6 for x in standing)


def _lead_dwell(train, line, geometry, dwell_s: float):
    svcs = [
        TrainService("lead", train, "up", "A", "C", 0.0, (ScheduledStop("B", dwell_s),)),
        TrainService("follow", train, "up", "A", "C", 130.0, (ScheduledStop("B", 30),)),
    ]
    return simulate(line, geometry, svcs, SETTINGS).trains[1]


def test_a_follower_slowed_by_a_warning_aspect_never_stops_and_one_held_longer_does(train) -> None:
    line, geometry = _double()
    # the leader dwells 60 s at B: the follower sees the warning aspect, brakes, and the entry signal
    # clears before it has to stop
    slowed = _lead_dwell(train, line, geometry, 60.0)
    assert [x.kind for x in slowed.hindrances] == ["slowed"]
    _assert_never_stops_between_stations(slowed)
    tr, plan = slowed.trajectory, slowed.planned_trajectory
    where = slowed.hindrances[0].position_m
    assert tr.speed_at(where) < plan.speed_at(where) - 1.0
    assert 0 < slowed.hindrances[0].wait_s < 30.0
    assert slowed.delay_s > 0
    # the leader dwells 150 s: the signal is still at danger when the follower comes to a stand
    stopped = _lead_dwell(train, line, geometry, 150.0)
    assert stopped.hindrances[0].kind == "signal" and stopped.hindrances[0].wait_s > 30.0
    assert np.min(stopped.trajectory.speed_mps[1:-1]) == 0.0
    standing = stopped.trajectory.position_m[stopped.trajectory.speed_mps == 0]
    assert np.any(np.abs(standing - stopped.hindrances[0].position_m) < 1e-6)
    assert stopped.delay_s > slowed.delay_s


def test_delays_propagate_to_the_following_trains(train) -> None:
    line, geometry = _double()
    svcs = [
        TrainService(
            f"T{k}",
            train,
            "up",
            "A",
            "C",
            180.0 * k,
            (ScheduledStop("B", 30),),
            entry_delay_s=150.0 if k == 0 else 0.0,
        )
        for k in range(4)
    ]
    res = simulate(line, geometry, svcs, SETTINGS)
    delays = [t.delay_s for t in res.trains]
    assert delays[0] == pytest.approx(150.0, abs=1e-6)
    assert delays[1] > 0 and delays[2] >= 0
    assert delays[1] < 150.0  # the buffer absorbs part of it
    # no resource is ever held by two trains at once (checked inside simulate as well)
    # the two stretches of an unhindered train, then for every signal a train brakes for: the run
    # braking to a stand there and at most one run picking up speed again when it clears
    hindered = sum(1 for t in res.trains for h in t.hindrances if h.kind in ("signal", "slowed"))
    assert res.runs_computed <= 2 + 2 * 2 * hindered


def _single(train, n_tracks: int = 2):
    length = 12_000.0
    geometry = Route("geo", 0, length, (), (SpeedLimit(0, length, 80 / 3.6),))
    stations = (
        StationLayout("A", 600, tracks=n_tracks),
        StationLayout("B", 6000, tracks=n_tracks),
        StationLayout("C", 11_400, tracks=n_tracks),
    )
    return build_line("single", length, "single_track", stations, Signalling()), geometry


@pytest.mark.parametrize("rule", ["fcfs", "priority"])
def test_single_track_meets_at_the_passing_loop(train, rule) -> None:
    line, geometry = _single(train)
    svcs = [
        TrainService("up1", train, "up", "A", "C", 0.0, (ScheduledStop("B", 20),), priority=1),
        TrainService("down1", train, "down", "C", "A", 30.0, (ScheduledStop("B", 20),), priority=2),
    ]
    res = simulate(line, geometry, svcs, SETTINGS, rule=rule)
    assert res.status in ("ok", "conflicts") and not res.deadlock
    tracks = {t.id: next(s.track for s in t.stops if s.station == "B") for t in res.trains}
    assert tracks["up1"] != tracks["down1"]  # they meet at B on different tracks
    # single-track sections are never used by both at once
    for section in ("A-B", "B-C"):
        spans = sorted((b.start_s, b.end_s) for b in res.blocking if b.resource == section)
        assert all(e0 <= s1 + 1e-3 for (_s0, e0), (s1, _e1) in pairwise(spans))
    # the later train waits at B for the other one to clear the section ahead
    assert sum(len(t.hindrances) for t in res.trains) >= 1


def test_single_track_without_loops_deadlock_is_reported(train) -> None:
    line, geometry = _single(train, n_tracks=1)
    svcs = [
        TrainService("up1", train, "up", "A", "C", 0.0),
        TrainService("up2", train, "up", "B", "C", 0.0),
        TrainService("down1", train, "down", "C", "A", 0.0),
    ]
    res = simulate(line, geometry, svcs, SETTINGS)
    assert res.status == "deadlock"
    assert any("waits for route" in d for d in res.deadlock)
    assert any(t.status == "deadlocked" for t in res.trains)


def test_bad_timetables_are_input_errors(train) -> None:
    line, geometry = _double()
    with pytest.raises(InputError) as e:
        simulate(
            line,
            geometry,
            [
                TrainService("x", train, "up", "C", "A", 0.0),
                TrainService("x", train, "up", "A", "Z", 0.0),
                TrainService("y", train, "up", "A", "C", 0.0, (ScheduledStop("B", 10, track=3),)),
            ],
        )
    text = str(e.value)
    assert "not connected" in text and "unique" in text and "unknown station" in text
    assert any(p.field == "trains[2].stops[0].track" for p in e.value.problems)


@pytest.mark.parametrize(("rule", "lookahead_s"), [("fcfs", 0.0), ("priority", 150.0)])
def test_priority_with_lookahead_holds_the_slow_train_for_the_fast_one(train, rule, lookahead_s) -> None:
    length = 6000.0
    geometry = Route("geo", 0, length, (), (SpeedLimit(0, length, 80 / 3.6),))
    stations = (StationLayout("A", 500), StationLayout("B", 3000, tracks=2), StationLayout("C", 5500))
    line = build_line("loop", length, "double_track", stations, Signalling(), block_length_m=600)
    svcs = [
        TrainService(
            "slow", train, "up", "A", "C", 0.0, (ScheduledStop("B", 30, departure_s=170.0, track=2),)
        ),
        TrainService("fast", train, "up", "A", "C", 120.0, priority=5),
    ]
    res = simulate(line, geometry, svcs, SETTINGS, rule=rule, lookahead_s=lookahead_s)
    slow, fast = res.trains
    assert res.status == "conflicts"  # the plan lets the slow train leave B before the fast one passes
    if rule == "fcfs":
        assert fast.delay_s > 0 and slow.delay_s == 0  # the fast train follows the slow one to C
    else:
        assert fast.delay_s == pytest.approx(0.0, abs=1e-9)  # overtakes at B
        assert slow.delay_s > 0 and slow.hindrances[0].where == "B"


def test_a_stalled_train_is_reported_and_blocks_the_one_behind(train) -> None:
    from trainsim import GradientSection

    geometry = Route(
        "geo",
        0,
        12000,
        (),
        (SpeedLimit(0, 12000, 80 / 3.6),),
        gradients=(GradientSection(3000, 9000, 180.0),),
    )
    line = build_line(
        "steep", 12000, "double_track", (StationLayout("A", 1000), StationLayout("B", 11000)), Signalling()
    )
    svcs = [
        TrainService("first", train, "up", "A", "B", 0.0),
        TrainService("second", train, "up", "A", "B", 300.0),
    ]
    res = simulate(line, geometry, svcs, SETTINGS)
    assert res.status == "stalled"
    first = res.trains[0]
    assert first.status == "stalled" and "stalls" in " ".join(first.warnings)
    assert first.stops[-1].arrival_s is None and first.to_dict()["delay_s"] is None
    assert any("held by first" in d for d in res.deadlock) or res.trains[1].status == "stalled"


def test_a_lone_train_matches_its_single_train_run(train) -> None:
    """The stop-to-stop runs joined by the operations layer give the core's own run with dwell times."""
    from trainsim import Station

    line, geometry = _double()
    res = simulate(
        line, geometry, [TrainService("t", train, "up", "A", "C", 0.0, (ScheduledStop("B", 30),))], SETTINGS
    )
    limits = (SpeedLimit(500, 5500, 80 / 3.6),)
    one = trainsim.run_fastest(
        train,
        Route("r", 500, 5500, (Station("A", 500), Station("B", 3000, 30.0), Station("C", 5500)), limits),
        SETTINGS,
    )
    (t,) = res.trains
    assert t.stops[-1].arrival_s == pytest.approx(one.total_time_s, abs=1e-6)
    assert t.energy_kwh == pytest.approx(one.energy_kwh.net, rel=1e-9)
    assert t.stops[1].departure_s - t.stops[1].arrival_s == pytest.approx(30.0)


def test_a_train_held_at_its_origin_leaves_the_switches_behind_it_free(train) -> None:
    """Regression (found by a seeded random search): the operated blocking times are the dispatcher's own,
    so a train waiting on its origin platform does not seem to hold the switch zone behind it."""
    line, geometry = _single(train)
    svcs = [
        TrainService("down", train, "down", "C", "A", 0.0),
        TrainService("up", train, "up", "B", "C", 60.0),  # waits at B until 'down' has cleared B-C
    ]
    res = simulate(line, geometry, svcs, SETTINGS)
    up = res.trains[1]
    assert up.hindrances and up.hindrances[0].where == "B" and up.delay_s > 0
    zone = sorted((b.start_s, b.end_s, b.train) for b in res.blocking if b.resource == "B/switchW")
    assert [z[2] for z in zone] == ["up", "down"]
    assert zone[0][1] <= zone[1][0] + 1e-3  # given and left behind before the other train came
