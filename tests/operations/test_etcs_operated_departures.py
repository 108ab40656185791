"""A lone train under ETCS Level 2 leaves its stops on time (issue 17): its MA is extended over the
routes beyond a stop before its scheduled departure, so the energy-efficient strategies are not
pushed to drive fastest by a late departure."""

from __future__ import annotations

import pytest

import trainsim
from trainsim import Route, RunSettings, SpeedLimit
from trainsim.operations.line import Signalling, StationLayout, build_line
from trainsim.operations.separation import EtcsBraking
from trainsim.operations.simulate import ScheduledStop, TrainService, simulate

SETTINGS = RunSettings(max_step_m=20)
ETCS = EtcsBraking(
    a_brake_emergency_mps2=1.0,
    a_brake_service_mps2=0.7,
    t_brake_emergency_s=1.5,
    t_brake_service_s=2.0,
    t_traction_cut_off_s=1.0,
)
# setup + reaction = 7 s: the lateness the audit found at every stop came from asking for the exit
# route only when the train had already started
SIG = Signalling(system="etcs_l2", overlap_m=50.0, setup_s=3.0, reaction_s=4.0, release_s=2.0)
T0 = 25200.0


@pytest.fixture(scope="module")
def train() -> trainsim.Train:
    return trainsim.load_train("examples/metro_b/train.yaml")


def _run(train: trainsim.Train, strategy: str):
    length = 6000.0
    geometry = Route("geo", 0, length, (), (SpeedLimit(0, length, 80 / 3.6),))
    stations = (StationLayout("A", 500), StationLayout("B", 3000), StationLayout("C", length - 500))
    line = build_line("metro", length, "double_track", stations, SIG, block_length_m=400)
    # 2.5 km stretches: about 150 s fastest under the MA's indication limits; 180 s scheduled
    stops = (
        ScheduledStop("B", 30.0, arrival_s=T0 + 180.0, departure_s=T0 + 210.0),
        ScheduledStop("C", 0.0, arrival_s=T0 + 390.0),
    )
    svc = TrainService("lone", train, "up", "A", "C", T0, stops, strategy=strategy)
    res = simulate(line, geometry, [svc], SETTINGS, etcs=ETCS, conflicts=False, headways=False)
    (out,) = res.trains
    assert res.status == "ok" and out.status == "ok" and not out.hindrances
    return out


def test_a_lone_etcs_train_leaves_every_stop_on_time(train) -> None:
    out = _run(train, "fastest")
    leaves = [(s.station, s.departure_s, s.scheduled_departure_s) for s in out.stops if s.departure_s]
    assert [x[0] for x in leaves] == ["A", "B"]
    for _name, dep, sched in leaves:
        assert dep == pytest.approx(sched, abs=1e-6)


def test_an_optimal_etcs_train_saves_energy_and_arrives_on_time(train) -> None:
    fastest = _run(train, "fastest")
    optimal = _run(train, "optimal")
    assert [s.reason for s in optimal.stretches] == ["", ""]
    assert [s.driven for s in optimal.stretches] == ["optimal", "optimal"]
    assert [s.late_s for s in optimal.stretches] == pytest.approx([0.0, 0.0], abs=1e-6)
    for s in optimal.stops[1:]:
        assert s.arrival_s == pytest.approx(s.scheduled_arrival_s, abs=1.0)
    assert optimal.energy_kwh < 0.95 * fastest.energy_kwh
