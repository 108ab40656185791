"""Runs under an ETCS supervision limit: never above the curve, the plain run when the EoA is far."""

from __future__ import annotations

import numpy as np
import pytest

import trainsim
from trainsim import Route, RunSettings, SpeedLimit, Station
from trainsim.constants import KMH
from trainsim.errors import InputError
from trainsim.model.timetable import SectionSchedule, Timetable
from trainsim.operations.etcs import EtcsNationalValues, EtcsTrainData, supervision_curves
from trainsim.operations.supervised import supervised_run

SETTINGS = RunSettings(max_step_m=10)


@pytest.fixture(scope="module")
def train() -> trainsim.Train:
    return trainsim.load_train("examples/metro_b/train.yaml")


def _etcs(train) -> EtcsTrainData:
    return EtcsTrainData(
        a_brake_emergency=1.0,
        a_brake_service=0.7,
        t_brake_emergency_s=1.5,
        t_brake_service_s=2.0,
        t_traction_cut_off_s=1.0,
        length_m=train.length_m,
        max_speed_mps=train.max_speed_mps,
    )


def _route(stop_m: float) -> Route:
    return Route("level", 0, 3000, (Station("A", 0), Station("B", stop_m)), (SpeedLimit(0, 3000, 80 * KMH),))


def test_the_fastest_run_never_exceeds_the_permitted_curve(train) -> None:
    route = _route(2500.0)
    curves = supervision_curves(_etcs(train), EtcsNationalValues(), None, eoa_position_m=2500.0)
    sup = supervised_run(train, route, curves, SETTINGS)
    plain = trainsim.run_fastest(train, route, SETTINGS)
    tr = sup.run.trace
    assert sup.run.status == "ok"
    assert np.all(tr.speed_mps <= np.asarray(curves.permitted(tr.position_m)) + 1e-9)
    # the plain run brakes later than the permitted curve allows: it exceeds it somewhere
    assert np.any(plain.trace.speed_mps > np.asarray(curves.permitted(plain.trace.position_m)) + 0.1)
    assert sup.run.running_time_s > plain.running_time_s
    # refined until the running time changed by less than 0.1 s
    assert abs(sup.refinements[-1] - sup.refinements[-2]) < 0.1 and len(sup.refinements) >= 2


def test_with_the_authority_far_away_it_is_the_plain_fastest_run(train) -> None:
    route = _route(2500.0)
    curves = supervision_curves(_etcs(train), EtcsNationalValues(), None, eoa_position_m=50_000.0)
    sup = supervised_run(train, route, curves, SETTINGS)
    plain = trainsim.run_fastest(train, route, SETTINGS)
    assert sup.run.running_time_s == pytest.approx(plain.running_time_s, abs=1e-9)
    assert sup.run.energy_kwh.net == pytest.approx(plain.energy_kwh.net, abs=1e-9)


def test_the_energy_efficient_run_respects_the_ceiling_too(train) -> None:
    route = _route(2500.0)
    curves = supervision_curves(_etcs(train), EtcsNationalValues(), None, eoa_position_m=2500.0)
    timetable = Timetable(sections=(SectionSchedule(supplement_fraction=0.1),))
    sup = supervised_run(train, route, curves, SETTINGS, strategy="lesov", timetable=timetable)
    tr = sup.run.trace
    assert np.all(tr.speed_mps <= np.asarray(curves.permitted(tr.position_m)) + 1e-9)
    assert (
        sup.optimization is not None
        and sup.run.energy_kwh.net < supervised_run(train, route, curves, SETTINGS).run.energy_kwh.net
    )


def test_a_run_beyond_the_authority_is_an_input_error(train) -> None:
    curves = supervision_curves(_etcs(train), EtcsNationalValues(), None, eoa_position_m=2000.0)
    with pytest.raises(InputError, match="end of authority"):
        supervised_run(train, _route(2500.0), curves, SETTINGS)
    with pytest.raises(InputError, match="unknown supervision curve"):
        supervised_run(train, _route(1500.0), curves, SETTINGS, ceiling="bogus")
