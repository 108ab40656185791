"""The operation's ETCS curves (issue 17): the release speed in the minimum headway (analytic), the
line's gradients and speed limits in the movement authority's indication steps."""

from __future__ import annotations

import numpy as np
import pytest

from trainsim.constants import KMH
from trainsim.model import Braking, EffortCurve, GradientSection, Route, SpeedLimit, Train
from trainsim.operations.blocking import Trajectory, blocking_times, minimum_headway
from trainsim.operations.line import Signalling, StationLayout, build_line
from trainsim.operations.separation import (
    EtcsBraking,
    etcs_approach_distance,
    ma_curves,
    ma_indication_steps,
    mrsp_profile,
)

V = 8.0  # constant running speed of the headway case [m/s]
L = 200.0  # train length [m]
# 59.5 / 1.02: the approach table's speed grid (120 points up to 1.02 v_max) then has V as a node
V_MAX = 59.5 / 1.02
SIG = Signalling(system="etcs_l2", overlap_m=50.0, setup_s=3.0, reaction_s=4.0, release_s=2.0)


@pytest.fixture(scope="module")
def train() -> Train:
    return Train("t", 400e3, 1.06, L, V_MAX, EffortCurve.constant(200e3), Braking(deceleration_mps2=0.7), ())


def _headway(approach) -> tuple[float, float]:
    stations = (StationLayout("A", 1000.0), StationLayout("B", 40000.0))
    line = build_line("test", 41000.0, "double_track", stations, SIG, block_length_m=2000.0)
    path = line.paths["up"]
    steps = [(j, st.alternatives[0]) for j, st in enumerate(path.steps)]
    s = np.linspace(0.0, line.length_m, 2001)
    traj = Trajectory(s / V, s, np.full_like(s, V), L)
    bt = [
        b
        for b in blocking_times("a", traj, path, steps, [], SIG, approach_distance_m=approach)
        if "block" in b.resource
    ]
    block = float(np.diff(path.signal_positions())[3])
    return minimum_headway("a", bt, 0.0, "b", bt, 0.0).min_headway_s, block


def test_a_train_below_the_release_speed_needs_no_approach_distance(train) -> None:
    """Level track, A_brake_emergency 1.0, A_brake_service 0.8 m/s^2, T_be 2 s, T_bs 3 s, T_traction_cut_off
    1 s, overlap 50 m, default national/fixed values, at V = 8 m/s, by hand (SUBSET-026-3 3.13.9):
    T_traction = max(1 - (2 + 3), 0) = 0, T_berem = 2 s, so d_EBI = 50 - V^2/2 - 2 V = 2 m,
    SBI2 = d_EBI - 3 V = -22 m, SBI1 = -V^2/1.6 - 3 V = -64 m, P = min(SBI1, SBI2) - 4 V = -96 m,
    T_indication = max(0.8 x 3, 5) + 4 = 9 s, I = P - 9 V = -168 m: the approach distance is 168 m
    without release speed. The calculated release speed (level track, 3.13.9.4.8) is
    -A T + sqrt((A T)^2 + 2 A D) with A = 1, T = T_traction_cut_off + T_berem = 2 s, D = 50 m:
    sqrt(104) - 2 = 8.198 m/s > V, and a given 10 m/s too: no indication, approach distance 0. The
    minimum headway (V constant, as test_blocking) is (approach + block + overlap + L) / V + setup +
    reaction + release."""
    times = SIG.setup_s + SIG.reaction_s + SIG.release_s
    for release, approach_m in ((0.0, 168.0), (10.0, 0.0), ("calculated", 0.0)):
        etcs = EtcsBraking(1.0, 0.8, 2.0, 3.0, 1.0, release_speed=release)
        approach = etcs_approach_distance(train, etcs, SIG.overlap_m)
        assert approach(V) == pytest.approx(approach_m, abs=1e-9)
        h, block = _headway(approach)
        assert h == pytest.approx((approach_m + block + SIG.overlap_m + L) / V + times, abs=1e-6)
    calculated = ma_curves(train, EtcsBraking(1.0, 0.8, 2.0, 3.0, 1.0), 0.0, SIG.overlap_m)
    assert calculated.release_speed_mps == pytest.approx(np.sqrt(104.0) - 2.0, abs=1e-6)
    # above the release speed it changes nothing: at 20 m/s, I = -(250 + 60) - 80 - 180 = -570 m
    for release in (0.0, 10.0, "calculated"):
        etcs = EtcsBraking(1.0, 0.8, 2.0, 3.0, 1.0, release_speed=release)
        assert etcs_approach_distance(train, etcs, SIG.overlap_m)(20.0) == pytest.approx(570.0, abs=1e-9)


def test_the_mrsp_holds_each_limit_until_the_rear_has_cleared_it(train) -> None:
    route = Route(
        "r",
        0.0,
        6000.0,
        (),
        (SpeedLimit(0, 2000, 40.0), SpeedLimit(2000, 3000, 20.0), SpeedLimit(3000, 6000, 70.0)),
    )
    x, v = mrsp_profile(route, train)
    # 70 m/s is above the train's maximum speed; the 20 m/s limit binds until 3000 m + L
    np.testing.assert_array_equal(x, [0.0, 2000.0, 3000.0 + L])
    np.testing.assert_array_equal(v, [40.0, 20.0, V_MAX])
    x, v = mrsp_profile(route, train, start_m=2500.0)
    np.testing.assert_array_equal(x, [2000.0, 3000.0 + L])


@pytest.fixture(scope="module")
def graded() -> tuple[Route, Route]:
    """A 10 km line at 120 km/h with an 80 km/h section at 5 - 6 km, level, and the same with a
    constant 10 per mille down-gradient."""
    limits = (
        SpeedLimit(0, 5000, 120 * KMH),
        SpeedLimit(5000, 6000, 80 * KMH),
        SpeedLimit(6000, 10000, 120 * KMH),
    )
    level = Route("level", 0.0, 10000.0, (), limits)
    down = Route("down", 0.0, 10000.0, (), limits, gradients=(GradientSection(0.0, 10000.0, -10.0),))
    return level, down


def test_ma_steps_follow_the_speed_decrease_and_the_gradient(train, graded) -> None:
    level, down = graded
    etcs = EtcsBraking(1.0, 0.8, 2.0, 3.0, 1.0)
    eoa = 9000.0
    per_route = {}
    for route in (level, down):
        steps = ma_indication_steps(train, etcs, 50.0, route)(eoa, 0.0, eoa - 10.0)
        c = ma_curves(train, etcs, eoa, 50.0, route, 0.0)
        x_m, v_m = mrsp_profile(route, train)
        assert steps
        for s in steps:
            dense = np.linspace(s.start_m, s.end_m, 41)
            # never above the indication curve, always below the line's own limit (else not handed over)
            assert s.limit_mps <= float(np.min(c.indication(dense))) + 1e-12
            assert s.limit_mps < float(np.min(v_m[np.searchsorted(x_m, dense, side="right") - 1]))
        # the driver brakes for the 80 km/h section before it starts (its indication limit)
        before = [s for s in steps if s.end_m <= 5000.0]
        assert before and min(s.limit_mps for s in before) < 120 * KMH
        assert float(c.indication(4990.0)) < 80 * KMH + 1e-9
        per_route[route.name] = (steps, c)
    # downhill the brakes are weaker: the EoA's indication limit is lower at the same place
    s = np.linspace(8000.0, eoa - 50.0, 50)
    assert np.all(per_route["down"][1].indication(s) <= per_route["level"][1].indication(s) + 1e-12)
    assert np.any(per_route["down"][1].indication(s) < per_route["level"][1].indication(s) - 0.1)
    first = {k: min(x.start_m for x in st if x.start_m > 6000.0) for k, (st, _c) in per_route.items()}
    assert first["down"] < first["level"]


def test_without_a_route_the_steps_are_those_on_level_track(train) -> None:
    """No directed route: level track and the train's maximum speed (the approach-distance case)."""
    etcs = EtcsBraking(1.0, 0.8, 2.0, 3.0, 1.0)
    flat = Route("flat", 0.0, 10000.0, (), (SpeedLimit(0, 10000, 150.0),))
    a = ma_indication_steps(train, etcs, 50.0)(9000.0, 0.0, 8990.0)
    c_none, c_flat = ma_curves(train, etcs, 9000.0, 50.0), ma_curves(train, etcs, 9000.0, 50.0, flat)
    s = np.linspace(5000.0, 9050.0, 200)
    np.testing.assert_allclose(c_none.indication(s), c_flat.indication(s), rtol=1e-12)
    assert a and all(
        x.limit_mps <= float(np.min(c_none.indication(np.linspace(x.start_m, x.end_m, 9)))) for x in a
    )


@pytest.mark.parametrize("strategy", ["fastest", "lesov"])
def test_supervised_runs_respect_the_curves_of_a_graded_line(strategy: str) -> None:
    """The fastest and an energy-efficient run under the permitted limit of an MA built as the operation
    builds it (file-like data: Kdry, Kwet, a given release speed; a 10 per mille down-gradient and a
    50 km/h section as targets) never exceed it, and the fastest one is slower than the plain run,
    which does not respect it."""
    import trainsim
    from trainsim import RunSettings, Station
    from trainsim.model.timetable import SectionSchedule, Timetable
    from trainsim.operations.supervised import supervised_run

    metro = trainsim.load_train("examples/metro_b/train.yaml")
    settings = RunSettings(max_step_m=10)
    limits = (
        SpeedLimit(0, 1200, 80 * KMH),
        SpeedLimit(1200, 1500, 50 * KMH),
        SpeedLimit(1500, 3000, 80 * KMH),
    )
    route = Route(
        "graded",
        0.0,
        3000.0,
        (Station("A", 0.0), Station("B", 2500.0)),
        limits,
        gradients=(GradientSection(0.0, 3000.0, -10.0),),
    )
    etcs = EtcsBraking(
        1.0, 0.7, 1.5, 2.0, 1.0, train_fields=(("kdry_rst", 0.95), ("kwet_rst", 0.9)), release_speed=3.0
    )
    curves = ma_curves(metro, etcs, 2500.0, 0.0, route, 0.0)
    timetable = (
        Timetable(sections=(SectionSchedule(supplement_fraction=0.1),)) if strategy != "fastest" else None
    )
    # an energy-efficient run per refinement costs more: refined to 1 s (the limit holds at every step)
    tolerance_s = 0.1 if strategy == "fastest" else 1.0
    sup = supervised_run(
        metro, route, curves, settings, strategy=strategy, timetable=timetable, tolerance_s=tolerance_s
    )
    tr = sup.run.trace
    assert sup.run.status == "ok"
    assert np.all(tr.speed_mps <= np.asarray(curves.permitted(tr.position_m)) + 1e-9)
    if strategy == "fastest":
        plain = trainsim.run_fastest(metro, route, settings)
        assert np.any(plain.trace.speed_mps > np.asarray(curves.permitted(plain.trace.position_m)) + 0.1)
        assert sup.run.running_time_s > plain.running_time_s
        # at the release speed up to the EoA (the limits are 0 from the EoA on, not before), and the
        # refinements only raise the staircase: the running time never grows
        assert sup.limits[-1].end_m == pytest.approx(2500.0, abs=1e-9) and sup.limits[-1].limit_mps == 3.0
        assert tr.position_m[-1] == pytest.approx(2500.0, abs=1e-6)
        assert np.all(np.diff(sup.refinements) <= 1e-9)
