"""Diverging-switch speeds (issue 17): a train routed to a platform track over a switch's diverging
branch keeps to the switch's speed from the blade tip to the clearance point until its rear has
cleared it. Checked on the route model (which limits each platform track's route carries) and on a
run of a train with constant acceleration and constant deceleration on a level line, whose lost time
is worked out by hand from the kinematics of constant acceleration."""

from __future__ import annotations

import numpy as np
import pytest

from trainsim.constants import KMH
from trainsim.errors import InputError
from trainsim.model import (
    Braking,
    EffortCurve,
    LineResistanceSettings,
    Quadratic,
    ResistanceTerm,
    Route,
    SpeedLimit,
    Station,
    Train,
)
from trainsim.model.scenario import RunSettings
from trainsim.operations.line import Signalling, StationLayout, SwitchLayout, TrackLayout, build_line
from trainsim.operations.runs import service_route
from trainsim.sim.fastest import run_fastest

V_DIV = 40 * KMH  # diverging speed, m/s
SIG = Signalling(aspects=3, overlap_m=50.0)
STATIONS = (StationLayout("A", 500.0), StationLayout("B", 5500.0, tracks=2), StationLayout("C", 9500.0))
# B's loop (track 2) between the clearance points 5260 and 7350 of its switches B1 (5200) and B2 (7400)
B1 = SwitchLayout("B1", 5200.0, 5260.0, diverging_speed_mps=V_DIV)
B2 = SwitchLayout("B2", 7400.0, 7350.0, diverging_speed_mps=V_DIV)


def _line(*switches: SwitchLayout, layout: str = "double_track"):
    key = "both" if layout == "single_track" else "up"
    # one block between B and C: B's exit switch lies far out
    tracks = {key: TrackLayout((), switches)}
    return build_line("t", 10_000.0, layout, STATIONS, SIG, block_length_m=5000.0, tracks=tracks)


def _entry(line, direction: str, station: str, track: int):
    step = next(s for s in line.paths[direction].steps if s.kind == "entry" and s.station == station)
    return next(r for r in step.alternatives if r.track == track)


def test_the_route_into_the_loop_carries_the_diverging_speed_of_both_switches() -> None:
    line = _line(B1, B2)
    loop = _entry(line, "up", "B", 2)
    # in: tip -> clearance point; out of the loop: clearance point -> tip (running coordinate)
    assert loop.speed_limits == (SpeedLimit(5200.0, 5260.0, V_DIV), SpeedLimit(7350.0, 7400.0, V_DIV))
    assert _entry(line, "up", "B", 1).speed_limits == ()  # the through track, straight over both
    assert line.paths["up"].track_speed_limits("B", 2) == loop.speed_limits
    assert line.paths["up"].track_speed_limits("B", 1) == ()
    # no diverging speed given: line speed
    plain = _line(SwitchLayout("B1", 5200.0, 5260.0), SwitchLayout("B2", 7400.0, 7350.0))
    assert _entry(plain, "up", "B", 2).speed_limits == ()


def test_single_track_both_directions_see_the_loop_switches_in_their_own_coordinate() -> None:
    # B2 within the down entry signal's reach (400 m) on single track
    b2 = SwitchLayout("B2", 5800.0, 5750.0, diverging_speed_mps=V_DIV)
    line = _line(B1, b2, layout="single_track")
    down = _entry(line, "down", "B", 2)
    # down: running coordinate x = 10000 - position; B2 is now the entry switch, B1 the exit switch
    assert down.speed_limits == (SpeedLimit(4200.0, 4250.0, V_DIV), SpeedLimit(4740.0, 4800.0, V_DIV))
    up = (SpeedLimit(5200.0, 5260.0, V_DIV), SpeedLimit(5750.0, 5800.0, V_DIV))
    assert _entry(line, "up", "B", 2).speed_limits == up


def test_the_tracks_over_the_diverging_branch_can_be_named() -> None:
    # B1 diverges into track 1 (the loop is straight ahead), B2 keeps the default (all but track 1)
    line = _line(SwitchLayout("B1", 5200.0, 5260.0, V_DIV, diverging_tracks=(1,)), B2)
    assert _entry(line, "up", "B", 1).speed_limits == (SpeedLimit(5200.0, 5260.0, V_DIV),)
    assert _entry(line, "up", "B", 2).speed_limits == (SpeedLimit(7350.0, 7400.0, V_DIV),)


@pytest.mark.parametrize(
    ("switch", "field", "value"),
    [
        (SwitchLayout("B1", 5200.0, 5260.0, -3.0), "line.tracks.up.switches[0].diverging_speed_mps", -3.0),
        (SwitchLayout("B1", 5200.0, 5260.0, np.nan), "line.tracks.up.switches[0].diverging_speed_mps", None),
        (SwitchLayout("B1", 5200.0, 5260.0, V_DIV, (3,)), "line.tracks.up.switches[0].diverging_tracks", [3]),
    ],
)
def test_bad_diverging_data_is_a_clear_error(switch, field, value) -> None:
    with pytest.raises(InputError) as e:
        _line(switch, B2)
    p = e.value.problems[0]
    assert p.field == field
    if value is not None:
        assert p.value == value
    assert p.allowed


# ---------------------------------------------------------------------- a run over the switch
M = 400e3  # kg
A_TRACTION = 0.5  # m/s^2: constant traction force, no resistance, rho = 1
B_SERVICE = 0.8  # m/s^2
L = 150.0  # train length, m
V_LINE = 100 * KMH


def _train() -> Train:
    return Train(
        name="constant a, b",
        mass_kg=M,
        rotating_mass_factor=1.0,
        length_m=L,
        max_speed_mps=200 * KMH,
        traction=EffortCurve.constant(M * A_TRACTION),
        braking=Braking(deceleration_mps2=B_SERVICE),
        resistance=(ResistanceTerm("none", Quadratic(0.0)),),
    )


def _geometry() -> Route:
    return Route(
        name="level",
        start_m=0.0,
        end_m=10_000.0,
        stations=(Station("A", 500.0, 0.0), Station("C", 9500.0, 0.0)),
        speed_limits=(SpeedLimit(0.0, 10_000.0, V_LINE),),
        line_resistance=LineResistanceSettings(curve_formula="none", tunnel_formula="none"),
    )


@pytest.fixture(scope="module")
def runs():
    """The fastest runs from A to C through B on the through track and on the loop."""
    line = _line(B1, B2)
    stops = [("A", 500.0), ("C", 9500.0)]
    out = {}
    for track in (1, 2):
        limits = line.paths["up"].track_speed_limits("B", track)
        out[track] = run_fastest(
            _train(), service_route(_geometry(), stops, limits), RunSettings(max_step_m=10.0)
        )
    return out


def test_the_train_keeps_to_the_diverging_speed_until_its_rear_has_cleared_the_switches(runs) -> None:
    loop = runs[2]
    assert loop.status == "ok"
    tr = loop.trace
    s, v = tr.position_m, tr.speed_mps
    for lo, hi in ((5200.0, 5260.0), (7350.0, 7400.0)):
        # from the blade tip (head) until the rear has passed the end of the span
        held = (s >= lo - 1e-9) & (s <= hi + L + 1e-9)
        assert held.any() and v[held].max() <= V_DIV + 1e-6
        assert np.interp(lo, s, v) == pytest.approx(V_DIV, abs=1e-6)
    # on the through track it runs at line speed there
    through = runs[1].trace
    assert np.interp(5500.0, through.position_m, through.speed_mps) == pytest.approx(V_LINE, abs=1e-6)


def test_the_time_lost_over_the_loop_is_the_kinematic_one(runs) -> None:
    # each switch: brake V -> v at b, run at v over the span plus the train length, accelerate v -> V
    # at a; against running the same distance at V. Between the switches the train is back at line
    # speed (room enough to accelerate and brake again, checked below).
    v, big = V_DIV, V_LINE
    brake_m = (big**2 - v**2) / (2 * B_SERVICE)
    accel_m = (big**2 - v**2) / (2 * A_TRACTION)
    lost = 0.0
    for span in (60.0, 50.0):
        slow_m = span + L
        t_slow = (big - v) / B_SERVICE + slow_m / v + (big - v) / A_TRACTION
        lost += t_slow - (brake_m + slow_m + accel_m) / big
    # room between the two slow stretches for the acceleration and the braking
    assert accel_m + brake_m <= 7350.0 - (5260.0 + L)
    assert runs[2].running_time_s - runs[1].running_time_s == pytest.approx(lost, abs=1e-3)
