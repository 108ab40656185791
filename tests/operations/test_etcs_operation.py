"""ETCS Level 2 trains in operation run under their movement authority's supervision limits."""

from __future__ import annotations

import numpy as np
import pytest

import trainsim
from trainsim import Route, RunSettings, SpeedLimit
from trainsim.operations.etcs import supervision_curves
from trainsim.operations.line import Signalling, StationLayout, build_line
from trainsim.operations.separation import EtcsBraking, ma_curves, ma_indication_steps
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


@pytest.fixture(scope="module")
def train() -> trainsim.Train:
    return trainsim.load_train("examples/metro_b/train.yaml")


def _simulate(train: trainsim.Train, lead_dwell_s: float):
    length = 6000.0
    geometry = Route("geo", 0, length, (), (SpeedLimit(0, length, 80 / 3.6),))
    stations = (StationLayout("A", 500), StationLayout("B", 3000), StationLayout("C", length - 500))
    line = build_line("metro", length, "double_track", stations, SIG, block_length_m=400)
    services = [
        TrainService("lead", train, "up", "A", "C", 0.0, (ScheduledStop("B", lead_dwell_s),)),
        TrainService("follow", train, "up", "A", "C", 100.0, (ScheduledStop("B", 30),)),
    ]
    return line, simulate(line, geometry, services, SETTINGS, etcs=ETCS, headways=False)


def _current_eoa(line, res, train_id: str):
    """EoA over time from the dispatcher's own record: the MA reaches the end of a route from when
    the route was given plus the setup time (then the RBC sends it) [m]."""
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


@pytest.mark.parametrize("lead_dwell_s", [90.0, 60.0])
def test_an_etcs_follower_never_exceeds_the_permitted_speed_of_its_current_ma(train, lead_dwell_s) -> None:
    line, res = _simulate(train, lead_dwell_s)
    follow = next(t for t in res.trains if t.id == "follow")
    assert follow.status == "ok" and follow.hindrances  # held or slowed behind the train ahead
    eoa_at = _current_eoa(line, res, "follow")
    tr = follow.trajectory
    curves: dict[float, object] = {}
    braking = []
    slowing = np.append(np.diff(tr.speed_mps) < 0.0, False)
    for t, x, v, slows in zip(tr.time_s, tr.position_m, tr.speed_mps, slowing, strict=True):
        eoa = eoa_at(t)
        if eoa not in curves:
            # computed here from the ETCS data, not through the simulation's staircase
            curves[eoa] = supervision_curves(
                ETCS.train_data(train), ETCS.national, None, eoa, svl_position_m=eoa + SIG.overlap_m
            )
        c = curves[eoa]
        assert x <= eoa + 1e-9
        permitted, indication = float(c.permitted(x)), float(c.indication(x))
        assert v <= permitted + 1e-9, (t, x, v, permitted, eoa)
        assert v <= indication + 1e-9, (t, x, v, indication, eoa)
        if slows and indication < 0.9 * train.max_speed_mps and v > c.release_speed_mps + 0.5:
            braking.append(indication - v)
    # where it slows down, the driver brakes to the indication curve (the staircase's steps are 20 m),
    # not far below it (after an MA is extended the train accelerates toward the new curve: not counted)
    assert len(braking) > 20
    assert np.median(braking) < 1.0 and max(braking) < 3.0


def test_the_unhindered_etcs_train_approaches_its_stops_under_the_indication_limit(train) -> None:
    # the route beyond a stop is asked for while the train stands there: it runs in under an MA ending
    # at the exit marker (3020 m for the stop at 3000 m), slower than its own brakes would allow
    _line, res = _simulate(train, 90.0)
    lead = next(t for t in res.trains if t.id == "lead")
    c = ma_curves(train, ETCS, 3020.0, SIG.overlap_m)
    tr = lead.planned_trajectory
    near = (tr.position_m > 2000) & (tr.position_m < 3000)
    assert np.all(tr.speed_mps[near] <= np.asarray(c.indication(tr.position_m[near])) + 1e-9)
    # at 2800 m, 220 m before the EoA, the indication limit is 35.8 km/h (supervision_curves); the
    # train's own 335 kN service brake would still allow about 80 km/h there
    assert float(np.interp(2800.0, tr.position_m, tr.speed_mps)) * 3.6 == pytest.approx(35.8, abs=1.5)


def test_ma_steps_stay_under_the_indication_curve(train) -> None:
    steps = ma_indication_steps(train, ETCS, SIG.overlap_m)
    out = steps(2600.0, 500.0, 2590.0)
    c = ma_curves(train, ETCS, 2600.0, SIG.overlap_m)
    assert out and out[-1].end_m == pytest.approx(2590.0)
    assert all(x.limit_mps < train.max_speed_mps for x in out)
    for x in out:
        dense = np.linspace(x.start_m, x.end_m, 50)
        assert x.limit_mps <= float(np.min(c.indication(dense))) + 1e-9
    # no step before the curve falls below the top speed (less one step)
    assert out[0].start_m >= float(c.limit_position_m("indication", train.max_speed_mps)) - 20.0 - 1e-9
    assert steps(2600.0, 500.0, 2590.0) is out  # cached
