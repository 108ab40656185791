"""Electrification: no traction for an electric train where the line is not electrified, and the
line current follows the section voltage."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from simcases import make_route, make_train

import trainsim
from trainsim.model import Electrical, ElectrificationSection, Quadratic
from trainsim.sim.codes import TRACTION


def electric(train):
    return dataclasses.replace(
        train, electrical=Electrical(line_voltage_v=1500.0, traction_efficiency=0.9, power_factor=1.0)
    )


def test_no_traction_in_a_gap_of_the_overhead_line():
    train = electric(make_train(resistance=Quadratic(3000.0, 0.0, 5.0)))
    route = dataclasses.replace(
        make_route(length_m=10_000.0, limit_kmh=160.0),
        electrification=(
            ElectrificationSection(0.0, 4000.0, 1500.0),
            ElectrificationSection(4000.0, 4500.0, 0.0),
            ElectrificationSection(4500.0, 10_000.0, 1500.0),
        ),
    )
    tr = trainsim.run_fastest(train, route).trace
    gap = (tr.position_m > 4000.0 + 1e-6) & (tr.position_m < 4500.0 - 1e-6)
    assert gap.any()
    assert np.all(tr.traction_force_n[gap] == 0.0)
    assert np.all(tr.line_current_a[gap] == 0.0)
    # without traction it coasts: no regime change to traction inside the gap has any effect
    assert np.all(np.diff(tr.speed_mps[gap]) <= 1e-12)
    # a diesel train is not affected
    diesel = trainsim.run_fastest(make_train(resistance=Quadratic(3000.0, 0.0, 5.0)), route).trace
    assert (diesel.traction_force_n[(diesel.position_m > 4000.0) & (diesel.position_m < 4500.0)] > 0).any()


def test_current_follows_the_section_voltage():
    train = electric(make_train())
    route = dataclasses.replace(
        make_route(length_m=6_000.0),
        electrification=(
            ElectrificationSection(0.0, 3000.0, 1500.0),
            ElectrificationSection(3000.0, 6000.0, 750.0),
        ),
    )
    tr = trainsim.run_fastest(train, route).trace
    power = tr.electrical_power_w
    first = (tr.position_m < 3000.0) & (tr.regime == TRACTION)
    second = (tr.position_m > 3000.0) & (power > 0)
    assert np.allclose(tr.line_current_a[first], power[first] / 1500.0)
    assert np.allclose(tr.line_current_a[second], power[second] / 750.0)


def test_electric_train_cannot_start_without_supply():
    train = electric(make_train())
    route = dataclasses.replace(
        make_route(length_m=5_000.0),
        electrification=(
            ElectrificationSection(0.0, 200.0, 0.0),
            ElectrificationSection(200.0, 5000.0, 1500.0),
        ),
    )
    result = trainsim.run_fastest(train, route)
    assert result.status == "stalled"
    assert "not electrified" in result.warnings[0]
    assert result.sections[-1].to_station.startswith("(stalled at")


def test_stall_message_gives_effort_and_resistance():
    train = make_train(traction_n=50e3, mass_kg=500e3)
    result = trainsim.run_fastest(train, make_route(gradient_permille=20.0))
    # 500 t x 9.81 x 0.020 = 98.1 kN of grade resistance against 50 kN
    assert "50.0 kN" in result.warnings[0] and "98.1 kN" in result.warnings[0]
    assert result.summary()["status"] == "stalled"


def test_driving_session_has_no_traction_in_the_gap():
    train = electric(make_train())
    route = dataclasses.replace(
        make_route(length_m=3_000.0),
        electrification=(
            ElectrificationSection(0.0, 50.0, 0.0),
            ElectrificationSection(50.0, 3000.0, 1500.0),
        ),
    )
    session = trainsim.DrivingSession(train=train, route=route)
    state = session.step(1.0, 2.0)
    assert state.speed_mps == pytest.approx(0.0)
    assert state.traction_force_n == 0.0
