"""The strategies of the multi-point model: following a profile, driving by command; the results."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from mpcases import freight_train, hilly_route, level_route

import trainsim
from trainsim.errors import InputError
from trainsim.model import GradientSection
from trainsim.multipoint import (
    CouplerModel,
    MultiPointSession,
    MultiPointSettings,
    SpeedProfile,
    build_multipoint_train,
    follow_profile,
    run_multipoint_fastest,
)
from trainsim.sim.codes import DWELL


@pytest.fixture(scope="module")
def train():
    return freight_train(15, locos=2, regen_fraction=0.8, electrical=True)


def test_follows_a_profile_given_by_positions_and_speeds_only(train):
    route = hilly_route()
    ref = trainsim.run_fastest(train, route)
    tr = ref.trace
    moving = tr.regime != DWELL
    keep = moving | np.concatenate([[True], ~moving[:-1]])  # drop the regime codes, keep the arrivals
    profile = SpeedProfile(tr.position_m[keep], tr.speed_mps[keep])
    result = follow_profile(train, route, profile, MultiPointSettings())
    assert result.status == "ok", result.warnings
    assert result.run.sections[0].dwell_s == pytest.approx(30.0)
    assert result.running_time_s == pytest.approx(ref.running_time_s, rel=1e-2)


def test_follows_a_slower_profile_than_the_fastest(train):
    # e.g. an optimizer's profile: 60 % of the fastest run's speeds in traction; the train must not run
    # faster than it (track_profile follows the speed in traction too)
    route = hilly_route(stop_at=None)
    ref = trainsim.run_fastest(train, route)
    tr = ref.trace
    slow = np.minimum(tr.speed_mps, 0.6 * tr.speed_mps.max())
    profile = SpeedProfile(tr.position_m, slow)
    result = follow_profile(train, route, profile, MultiPointSettings())
    assert result.status == "ok", result.warnings
    v_ref = np.interp(result.run.trace.position_m, tr.position_m, slow)
    assert np.max(result.run.trace.speed_mps - v_ref) < 0.3
    assert result.running_time_s > 1.3 * ref.running_time_s


def test_result_summary_has_the_single_point_keys_and_the_multi_point_block(train):
    route = hilly_route()
    ref = trainsim.run_fastest(train, route)
    result = run_multipoint_fastest(train, route, MultiPointSettings(), reference=ref)
    summary = result.summary()
    assert set(ref.summary()) <= set(summary)
    mp = summary["multi_point"]
    assert mp["vehicles"] == 17
    assert mp["max_draft"]["force_n"] > 0 > mp["max_buff"]["force_n"]
    assert 0 <= mp["max_draft"]["coupler"] < 16
    assert abs(mp["energy_j"]["balance_error"]) < 1e-4
    assert summary["kind"] == "multi_point fastest"
    # per-vehicle arrays and frames
    n_t = len(result.time_s)
    assert result.position_m.shape == result.speed_mps.shape == result.acceleration_mps2.shape == (n_t, 17)
    assert result.coupler_force_n.shape == (n_t, 16)
    assert np.all(np.diff(result.time_s) > 0)
    assert np.all(result.position_m[:, :-1] > result.position_m[:, 1:])
    assert len(result.vehicle_dataframe()) == n_t * 17
    assert list(result.coupler_dataframe().columns)[:2] == ["c0", "c1"]
    # the extreme is where the recorded forces peak (records are a subset of the steps)
    assert result.max_draft.force_n >= result.coupler_force_n.max() - 1e-6
    # trace invariants as for the single-point model
    df = result.run.to_dataframe()
    assert np.all(np.diff(df["position_m"]) >= 0) and np.all(df["speed_mps"] >= 0)


def test_session_drives_to_the_next_stop_and_dwells():
    train = freight_train(10, locos=1)
    route = hilly_route(3_000.0, stop_at=1_000.0, dwell_s=20.0, curves=False)
    session = MultiPointSession(train, route, MultiPointSettings(couplers=CouplerModel(slack_m=0.02)))
    state = session.state()
    assert state.next_stop_name == "B" and state.next_stop_distance_m == pytest.approx(1000.0)
    # accelerate, then brake so as to stop near B
    b = 0.75 * 0.45  # service deceleration of the test trains [m/s^2]
    while True:
        state = session.step(1.0, 1.0)
        if state.speed_mps**2 / (2 * 0.8 * b) > state.next_stop_distance_m - 5:
            break
    while not state.dwell_remaining_s and not state.finished:
        d = state.next_stop_distance_m
        need = state.speed_mps**2 / (2 * max(d, 0.5)) if state.speed_mps > 0.2 else 0.0
        command = -min(1.0, need / b) if d < 50 or need > 0.1 else 0.2
        state = session.step(command if state.speed_mps > 0.05 or d < 3 else 0.3, 0.5)
    assert "stopped at B" in state.message
    assert state.next_stop_name == "C"
    assert session.positions_m[0] == pytest.approx(1000.0, abs=5.0)
    # commands are ignored while dwelling
    t0 = session.time_s
    state = session.step(1.0, 10.0)
    assert session.positions_m[0] == pytest.approx(1000.0, abs=5.0)
    assert state.dwell_remaining_s == pytest.approx(10.0)
    assert session.time_s == pytest.approx(t0 + 10.0)
    result = session.result()
    assert result.status == "in progress"
    assert result.run.sections[0].to_station == "B"
    assert result.run.sections[0].dwell_s == pytest.approx(10.0, abs=0.01)


def test_per_locomotive_commands_pull_against_each_other():
    # asynchronous distributed power: the head locomotive pulls, the rear one brakes electrically,
    # so every coupling between them is in tension
    train = freight_train(10, locos=2, regen_fraction=0.8)
    mp = build_multipoint_train(train, MultiPointSettings(locomotive_positions=(0, 11)))
    session = MultiPointSession(mp, level_route())
    for _ in range(30):
        session.step(1.0, 1.0)
    for _ in range(20):
        session.step(0.0, 1.0, loco_commands=[1.0, -0.5])
    forces = session.coupler_forces_n()
    assert np.all(forces > 0)
    # the rear locomotive's electric brake is held by the couplings: about half its share of 0.8 x traction
    assert forces[-1] > 0.5 * 0.5 * 0.8 * train.traction(session.speeds_mps[-1]) * 0.5


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"command": 1.5, "dt_s": 1.0}, "command"),
        ({"command": 0.5, "dt_s": 0.0}, "time step"),
        ({"command": 0.5, "dt_s": 1.0, "loco_commands": [1.0]}, "one command"),
        ({"command": 0.5, "dt_s": 1.0, "loco_commands": [1.0, 1.0]}, "train brake only"),
    ],
)
def test_session_rejects_bad_commands(kwargs, match):
    session = MultiPointSession(freight_train(5, locos=2), level_route())
    with pytest.raises(InputError, match=match):
        session.step(**kwargs)


def test_a_train_too_weak_for_the_grade_stalls():
    train = freight_train(60, locos=1, traction_kn_per_loco=250.0)
    route = level_route(6_000.0)
    route = dataclasses.replace(
        route,
        gradients=(GradientSection(500.0, 6_000.0, 8.0),),
        line_resistance=dataclasses.replace(route.line_resistance, apply_over="train_length"),
    )
    ref = trainsim.run_fastest(train, route)
    assert ref.status == "stalled"
    result = run_multipoint_fastest(train, route, MultiPointSettings(), reference=ref)
    assert result.status == "stalled"
    # where the single-point model, with the grade averaged over the train, stalls too
    assert result.run.trace.position_m[-1] == pytest.approx(ref.trace.position_m[-1], abs=10.0)
    assert any("stalls at 180" in w for w in result.warnings)


@pytest.mark.parametrize(
    "strategy",
    [
        "optimal",
        "lesov",
    ],
)
def test_follows_the_timetable_optimizers_energy_efficient_run(train, strategy):
    # coasting, cruising and regenerative-braking phases followed as the optimizer planned them
    from trainsim.optimize.api import optimize
    from trainsim.optimize.timetable import line_supplement

    route = hilly_route()
    optimized = optimize(train, route, line_supplement("10%"), strategy)
    assert not optimized.warnings
    result = follow_profile(train, route, optimized, MultiPointSettings(couplers=CouplerModel(slack_m=0.025)))
    assert result.status == "ok", result.warnings
    for got, want in zip(result.run.sections, optimized.run.sections, strict=True):
        # measured: 0.50 % longer on the second section with the friction draft gears (the viscous
        # couplers before them stayed within 0.5 %)
        assert got.running_time_s == pytest.approx(want.running_time_s, rel=7e-3)
    assert result.energy_kwh.traction == pytest.approx(optimized.run.energy_kwh.traction, rel=1.5e-2)
    assert result.energy_kwh.regenerated == pytest.approx(optimized.run.energy_kwh.regenerated, rel=3e-2)
    # and saves what the optimizer saves against the fastest run
    assert result.energy_kwh.net < 0.85 * optimized.fastest.energy_kwh.net


def test_follows_a_profile_prescribed_point_by_point(train):
    # the FOLLOW regime: the profile's own accelerations, not maximum effort
    from trainsim.sim.codes import FOLLOW

    route = hilly_route(stop_at=None)
    ref = trainsim.run_fastest(train, route)
    tr = ref.trace
    slow = 0.8 * tr.speed_mps
    regime = np.where(tr.regime == DWELL, DWELL, FOLLOW).astype(np.int8)
    result = follow_profile(
        train, route, SpeedProfile(tr.position_m, slow, regime, None), MultiPointSettings()
    )
    assert result.status == "ok", result.warnings
    v_ref = np.interp(result.run.trace.position_m, tr.position_m, slow)
    away = result.run.trace.position_m > 100.0
    assert np.max(np.abs(result.run.trace.speed_mps[away] - v_ref[away])) < 0.3
