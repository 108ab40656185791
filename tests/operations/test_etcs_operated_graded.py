"""ETCS Level 2 in operation on a graded line (issue 17): the blocking times' approach distance on the
line's gradients, and an operated follower under the permitted speed of its movement authority."""

from __future__ import annotations

import numpy as np
import pytest

import trainsim
from trainsim import Route, RunSettings, SpeedLimit
from trainsim.model import GradientSection
from trainsim.operations.blocking import Trajectory, approach_start_m, blocking_times
from trainsim.operations.etcs import supervision_curves
from trainsim.operations.line import Signalling, StationLayout, build_line
from trainsim.operations.runs import direction_route
from trainsim.operations.separation import EtcsBraking, etcs_approach_distance
from trainsim.operations.simulate import ScheduledStop, TrainService, simulate

SETTINGS = RunSettings(max_step_m=20)
ETCS = EtcsBraking(
    a_brake_emergency_mps2=1.0,
    a_brake_service_mps2=0.7,
    t_brake_emergency_s=1.5,
    t_brake_service_s=2.0,
    t_traction_cut_off_s=1.0,
)
SIG = Signalling(system="etcs_l2", overlap_m=50.0, setup_s=3.0, reaction_s=4.0, release_s=2.0)
LENGTH = 6000.0
GRADE = 20.0  # per mille, down in the up direction from 1000 m to 5000 m


@pytest.fixture(scope="module")
def train() -> trainsim.Train:
    return trainsim.load_train("examples/metro_b/train.yaml")


def _geometry(gradient_permille: float) -> Route:
    grades = () if gradient_permille == 0 else (GradientSection(1000.0, 5000.0, gradient_permille),)
    return Route("geo", 0, LENGTH, (), (SpeedLimit(0, LENGTH, 80 / 3.6),), gradients=grades)


def _line():
    stations = (StationLayout("A", 500), StationLayout("B", 3000), StationLayout("C", LENGTH - 500))
    return build_line("metro", LENGTH, "double_track", stations, SIG, block_length_m=400)


def test_the_approach_distance_follows_the_gradient_of_each_marker(train) -> None:
    line = _line()
    path = line.paths["up"]
    v = 15.0
    s = np.linspace(0.0, LENGTH, 3001)
    traj = Trajectory(s / v, s, np.full_like(s, v), train.length_m)
    level = etcs_approach_distance(train, ETCS, SIG.overlap_m)
    found = {}
    for grade in (-GRADE, 0.0, GRADE):
        directed = direction_route(_geometry(grade), LENGTH, "up")
        fn = etcs_approach_distance(train, ETCS, SIG.overlap_m, directed)
        for j, step in enumerate(path.steps):
            x = step.start_m
            # independent: the indication point of an MA ending at the marker, from the supervision
            # curves on the same route (EoA and SvL only)
            c = supervision_curves(
                ETCS.train_data(train), ETCS.national, directed, x, svl_position_m=x + SIG.overlap_m
            )
            expected = float(c.indication_point_m(v))
            assert approach_start_m(path, j, SIG, traj, fn) == pytest.approx(expected, abs=0.5)
            if 2000.0 < x < 5000.0:
                found.setdefault(grade, []).append(x - expected)
            if x < 900.0 - 2 * level(v):
                # far before the grade: level track
                assert x - expected == pytest.approx(level(v), abs=0.5)
    down, flat, up = (np.array(found[g]) for g in (-GRADE, 0.0, GRADE))
    np.testing.assert_allclose(flat, level(v), atol=0.5)
    # 20 per mille is 0.196 m/s^2 more (or less) to brake: the distance grows (shrinks) markedly
    assert np.all(down > flat + 10.0) and np.all(up < flat - 10.0)
    # the blocking times start earlier on the down grade by (longer distance) / speed
    steps = [(j, st.alternatives[0]) for j, st in enumerate(path.steps)]
    starts = {}
    for grade in (-GRADE, 0.0):
        fn = etcs_approach_distance(
            train, ETCS, SIG.overlap_m, direction_route(_geometry(grade), LENGTH, "up")
        )
        bt = blocking_times("a", traj, path, steps, [], SIG, approach_distance_m=fn)
        starts[grade] = {b.resource: b.start_s for b in bt if 2000.0 < path.steps[b.step].start_m < 5000.0}
    gained = np.array([starts[0.0][r] - starts[-GRADE][r] for r in starts[0.0]])
    # a uniform grade: the same longer distance at every marker inside it
    assert np.ptp(down - flat) < 0.5 and gained.size >= 5
    np.testing.assert_allclose(gained, np.mean(down - flat) / v, atol=0.5 / v)


def _simulate(train, grade: float):
    services = [
        TrainService("lead", train, "up", "A", "C", 0.0, (ScheduledStop("B", 90.0),)),
        TrainService("follow", train, "up", "A", "C", 100.0, (ScheduledStop("B", 30.0),)),
    ]
    line = _line()
    return line, simulate(line, _geometry(grade), services, SETTINGS, etcs=ETCS, headways=False)


def _current_eoa(line, res, train_id: str):
    """EoA over time from the dispatcher's record: an MA reaches a route's end from when the route was
    given plus the setup time [m]."""
    path = line.paths["up"]
    given = sorted(
        (b.start_s + SIG.setup_s, path.steps[b.step].alternatives[0].end_m)
        for b in res.blocking
        if b.train == train_id
    )
    times = np.array([g for g, _e in given])
    ends = np.maximum.accumulate(np.array([e for _g, e in given]))

    def eoa(t: float) -> float:
        k = int(np.searchsorted(times, t, side="right")) - 1
        return float(ends[k]) if k >= 0 else float(path.stop_m["A"])

    return eoa


def test_an_operated_follower_on_a_down_grade_stays_under_its_permitted_speed(train) -> None:
    line, res = _simulate(train, -GRADE)
    _line0, flat = _simulate(train, 0.0)
    follow = next(t for t in res.trains if t.id == "follow")
    assert res.status in ("ok", "conflicts") and follow.status == "ok" and follow.hindrances
    directed = direction_route(_geometry(-GRADE), LENGTH, "up")
    eoa_at = _current_eoa(line, res, "follow")
    tr = follow.trajectory
    curves: dict[float, object] = {}
    for t, x, v in zip(tr.time_s, tr.position_m, tr.speed_mps, strict=True):
        eoa = eoa_at(t)
        if eoa not in curves:
            # from the ETCS data on the graded route, not through the simulation's staircase
            curves[eoa] = supervision_curves(
                ETCS.train_data(train), ETCS.national, directed, eoa, svl_position_m=eoa + SIG.overlap_m,
                mrsp=(np.array([0.0]), np.array([80 / 3.6])),
            )  # fmt: skip
        assert x <= eoa + 1e-9
        assert v <= float(curves[eoa].permitted(x)) + 1e-9, (t, x, v, eoa)

    # toward the stop at B (EoA at the exit marker, 3020 m) the down grade lowers the indication limit:
    # the lead runs in slower there than on level track, and so takes longer from A to B
    def speed_at(result, train_id: str, x: float) -> float:
        o = next(t for t in result.trains if t.id == train_id)
        return float(np.interp(x, o.planned_trajectory.position_m, o.planned_trajectory.speed_mps))

    for x in (2700.0, 2800.0, 2900.0):
        assert speed_at(res, "lead", x) < speed_at(flat, "lead", x) - 0.3
    # and its approach starts farther from each marker it passes at line speed in both runs (the same
    # speed: the longer indication distance on the down grade, not a lower speed, makes the difference)
    path = line.paths["up"]

    def approach_m(result) -> dict[str, float]:
        o = next(t for t in result.trains if t.id == "lead")
        tr = o.trajectory
        out = {}
        for b in result.blocking:
            x = path.steps[b.step].start_m
            if b.train == "lead" and 1500.0 < x < 2500.0 and np.interp(x, tr.position_m, tr.speed_mps) > 21.5:
                out[b.resource] = x - float(np.interp(b.approach_s, tr.time_s, tr.position_m))
        return out

    down, level = approach_m(res), approach_m(flat)
    assert len(set(down) & set(level)) >= 2
    for r in set(down) & set(level):
        assert down[r] > level[r] + 10.0, (r, down[r], level[r])
