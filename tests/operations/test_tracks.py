"""Tracks given explicitly (issue 17): switches with their clearance points, train detection points and a
track's own station signals, against the constant-speed blocking times worked out by hand (Pachl,
*Railway Operation and Control*, 4th ed. 2018, 3.3.4 and 4.2: a resource is released when the rear of
the train has cleared its release point)."""

from __future__ import annotations

import numpy as np
import pytest

from trainsim.errors import InputError
from trainsim.operations.blocking import Trajectory, blocking_times
from trainsim.operations.line import (
    Signalling,
    StationLayout,
    SwitchLayout,
    TrackLayout,
    build_line,
)

V = 20.0  # m/s
L = 100.0  # train length, m
SIG = Signalling(aspects=3, overlap_m=50.0, setup_s=6.0, reaction_s=6.0, release_s=3.0)
# up direction: A's exit signal at 520, B's entry signal at 5500 - 400 = 5100, B's exit signal at 5520
STATIONS = (StationLayout("A", 500.0, tracks=2), StationLayout("B", 5500.0, tracks=2))


def _double(up: TrackLayout | None = None, **kw) -> object:
    tracks = {"up": up} if up is not None else None
    return build_line("t", 6000.0, "double_track", STATIONS, SIG, block_length_m=2000.0, tracks=tracks, **kw)


def _times(line, direction: str = "up") -> dict[str, object]:
    """Blocking times at constant speed V from position 0 at t = 0, by resource."""
    path = line.paths[direction]
    s = np.linspace(0.0, line.length_m, 3001)
    traj = Trajectory(s / V, s, np.full_like(s, V), L)
    steps = [(j, st.alternatives[0]) for j, st in enumerate(path.steps)]
    return {b.resource: b for b in blocking_times("x", traj, path, steps, [], SIG)}


def test_without_tracks_the_line_is_unchanged() -> None:
    # an empty track layout is the standard layout, route for route
    plain, empty = _double(), _double(TrackLayout())
    for d in ("up", "down"):
        assert plain.paths[d].steps == empty.paths[d].steps
    assert _times(plain)["B/U-entry-switch"].clear_s == pytest.approx((5100 + 100 + L) / V, abs=1e-9)


@pytest.mark.parametrize(
    ("detection", "release_m"),
    [((), 5260.0), ((5300.0,), 5300.0)],  # the clearance point itself, or the detection point behind it
)
def test_entry_switch_is_released_at_its_clearance_point(detection, release_m) -> None:
    up = TrackLayout(detection, (SwitchLayout("B1", 5200.0, 5260.0), SwitchLayout("B2", 5800.0, 5750.0)))
    b = _times(_double(up))["B/U-entry-switch"]
    # clearing = (signal -> clearance / detection point + train length) / v, from the head at the signal
    assert b.clear_s - b.entry_s == pytest.approx((release_m - 5100.0 + L) / V, abs=1e-6)
    assert b.end_s - b.clear_s == pytest.approx(SIG.release_s, abs=1e-9)


@pytest.mark.parametrize(("detection", "release_m"), [((), 600.0), ((620.0,), 620.0)])
def test_exit_switch_is_released_behind_its_blade_tip(detection, release_m) -> None:
    # A's exit switch: a train leaving over it fouls it until the rear has passed its tip (or the
    # detection point behind it)
    up = TrackLayout(detection, (SwitchLayout("A2", 600.0, 560.0),))
    b = _times(_double(up))["A/U-exit-switch"]
    assert b.clear_s - b.entry_s == pytest.approx((release_m - 520.0 + L) / V, abs=1e-6)


def test_a_detection_point_cuts_a_block_into_sections_released_one_by_one() -> None:
    line = _double(TrackLayout((1500.0,)))
    t = _times(line)
    route = line.paths["up"].steps[1].alternatives[0]
    assert [r.name for r in route.resources] == ["A/U-exit-switch", "U:A-B block 1/1", "U:A-B block 1/2"]
    # the section that ends at the detection point is released when the rear has passed it
    assert t["U:A-B block 1/1"].clear_s == pytest.approx((1500.0 + L) / V, abs=1e-6)
    # the last one, as a whole block, at the next signal plus the overlap
    b = route.end_m
    assert t["U:A-B block 1/2"].clear_s == pytest.approx((b + SIG.overlap_m + L) / V, abs=1e-6)
    # both sections are claimed together with the route
    assert t["U:A-B block 1/1"].start_s == t["U:A-B block 1/2"].start_s


def test_a_down_track_has_its_own_signals_and_detection_points() -> None:
    down = TrackLayout((3000.0,), station_signals_m={"B": (5800.0, 5450.0), "A": (1000.0, 450.0)})
    line = build_line("t", 6000.0, "double_track", STATIONS, SIG, tracks={"down": down})
    path = line.paths["down"]
    starts = [line.line_position("down", s.start_m) for s in path.steps]
    assert starts[0] == pytest.approx(5800.0) and starts[1] == pytest.approx(5450.0)
    assert starts[-1] == pytest.approx(1000.0)
    names = {r.name for s in path.steps for a in s.alternatives for r in a.resources}
    assert any(n.endswith("/1") for n in names)  # the detection point cut a down block
    assert line.paths["up"].steps == _double().paths["up"].steps  # the up track is untouched


def _single(**kw) -> object:
    stations = (StationLayout("A", 500.0), StationLayout("B", 5000.0, tracks=2), StationLayout("C", 9500.0))
    both = TrackLayout(
        kw.pop("detection", ()),
        kw.pop("switches", (SwitchLayout("W", 4650.0, 4700.0), SwitchLayout("E", 5200.0, 5150.0))),
    )
    return build_line("s", 10000.0, "single_track", stations, SIG, tracks={"both": both}, **kw)


def test_single_track_loop_from_the_switch_positions() -> None:
    line = _single(detection=(2000.0, 3000.0, 4600.0))
    up, down = line.paths["up"], line.paths["down"]
    # the loop between the clearance points, in each direction's running coordinate
    lo, hi = up.platform_m["B"]
    assert hi - lo == pytest.approx(5150.0 - 4700.0)
    lo, hi = down.platform_m["B"]
    assert hi - lo == pytest.approx(5150.0 - 4700.0)
    # a train standing at the stopping point (5000) must be clear of both clearance points: up the room is
    # 5000 - 4700, down 5150 - 5000
    for d, room, ends in (("up", 300.0, ("A", "C")), ("down", 150.0, ("C", "A"))):
        assert line.loop_problems(d, *ends, room, "trains[0]") == []
        problems = line.loop_problems(d, *ends, room + 1.0, "trains[0]")
        assert len(problems) == 1 and "'B'" in problems[0].reason and problems[0].field == "trains[0].train"
        assert f"at most {room:g} m" in problems[0].allowed
    assert line.loop_problems("up", "A", "A", 451.0, "trains[0]") == []  # B is not on its way
    # the up entry over W is released at W's clearance point, the down exit over W at the border of its
    # detection section (the detection point at 4600 behind its tip)
    t_up, t_down = _times(line, "up"), _times(line, "down")
    assert t_up["B/switchW"].clear_s - t_up["B/switchW"].entry_s == pytest.approx(
        (4700.0 - 4600.0 + L) / V, abs=1e-6
    )
    b = t_down["B/switchW"]
    assert b.clear_s - b.entry_s == pytest.approx((5000.0 - 20.0 - 4600.0 + L) / V, abs=1e-6)
    # both directions claim the same cells of the single-track section A-B (a head-on meet is a conflict)
    sec_up = {
        r.name for s in up.steps for a in s.alternatives for r in a.resources if r.name.startswith("A-B")
    }
    sec_dn = {
        r.name for s in down.steps for a in s.alternatives for r in a.resources if r.name.startswith("A-B")
    }
    assert sec_up == sec_dn == {"A-B/1", "A-B/2", "A-B/3"}


def _error(fn) -> InputError:
    with pytest.raises(InputError) as err:
        fn()
    return err.value


def test_bad_tracks_are_clear_errors() -> None:
    e = _error(lambda: _single(switches=(SwitchLayout("W", 12000.0, 4700.0),)))
    assert e.problems[0].field == "line.tracks.both.switches[0].position_m" and "off the line" in str(e)
    e = _error(lambda: _single(switches=(SwitchLayout("X", 2500.0, 2450.0),)))
    assert "lies outside its station 'A' in the down direction" in str(e) and e.problems[0].value == 2500.0
    e = _error(
        lambda: _single(switches=(SwitchLayout("W", 4650.0, 4600.0), SwitchLayout("E", 5200.0, 5150.0)))
    )
    assert e.problems[0].field == "line.tracks.both.switches[0].clearance_m" and "4650 < x < 5000" in str(e)
    e = _error(lambda: _single(switches=(SwitchLayout("W", 4650.0),)))
    assert "needs its clearance point" in str(e)
    e = _error(lambda: _single(switches=(SwitchLayout("W", 4650.0, 4700.0),)))
    assert "not connected at their exit end" in str(e)
    # the detection point behind A's exit switch beyond the first automatic block signal (at 2046.7 m)
    e = _error(lambda: _double(TrackLayout((2100.0,), (SwitchLayout("A2", 600.0, 560.0),))))
    assert "beyond the next signal" in str(e) and e.problems[0].value == pytest.approx(2100.0)
    e = _error(lambda: build_line("t", 6000.0, "double_track", STATIONS, SIG, tracks={"both": TrackLayout()}))
    assert e.problems[0].field == "line.tracks.both" and "up, down" in str(e)
    e = _error(
        lambda: build_line(
            "t",
            6000.0,
            "double_track",
            STATIONS,
            SIG,
            tracks={"down": TrackLayout(station_signals_m={"B": (5400.0, 5450.0)})},
        )
    )
    assert e.problems[0].field == "line.tracks.down.station_signals_m.B"


def test_headway_into_a_loop_on_the_other_track_is_set_by_the_clearance_point() -> None:
    # a follower routed to B's other platform track shares only the entry switch zone with the leader:
    # the headway there is (clearance point - approach start + L) / v + setup + reaction + release
    from trainsim.operations.blocking import minimum_headway

    line = _double(TrackLayout((), (SwitchLayout("B1", 5200.0, 5260.0), SwitchLayout("B2", 5800.0, 5750.0))))
    path = line.paths["up"]
    s = np.linspace(0.0, line.length_m, 3001)
    traj = Trajectory(s / V, s, np.full_like(s, V), L)
    j_b = next(j for j, st in enumerate(path.steps) if st.station == "B" and st.kind == "entry")

    def times(track: int) -> list:
        steps = [(j, st.alternatives[track - 1 if j == j_b else 0]) for j, st in enumerate(path.steps)]
        return [b for b in blocking_times("x", traj, path, steps, [], SIG) if b.resource.startswith("B/")]

    lead, follow = times(1), times(2)
    assert {b.resource for b in lead} & {b.resource for b in follow} == {"B/U-entry-switch"}
    h = minimum_headway("a", lead, 0.0, "b", follow, 0.0)
    approach = path.steps[j_b - 1].start_m - SIG.sighting_distance_m  # 3 aspects: the previous signal
    expected = (5260.0 - approach + L) / V + SIG.setup_s + SIG.reaction_s + SIG.release_s
    assert h.min_headway_s == pytest.approx(expected, abs=1e-6) and h.critical_resource == "B/U-entry-switch"
