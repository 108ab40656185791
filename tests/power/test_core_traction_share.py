"""The core's share of tractive effort per electrification section (ElectrificationSection.traction_share,
honoured by sim.profile.traction_availability), against the closed-form run of a constant force."""

from __future__ import annotations

import dataclasses
import math
from functools import lru_cache

import numpy as np
import pytest

import trainsim
from trainsim.errors import InputError
from trainsim.model.effort import EffortCurve
from trainsim.model.route import ElectrificationSection, Route, SpeedLimit, Station
from trainsim.sim.profile import line_voltage, traction_availability

FORCE_N = 60e3  # constant tractive effort at every speed [N]
SHARE = 0.5
LIMITED_END_M = 300.0  # the section with the share is [0, LIMITED_END_M)
LENGTH_M = 3000.0


@lru_cache(maxsize=1)
def _base():
    return trainsim.load_scenario("examples/power/metro_scenario.yaml")


def _train(electric: bool = True):
    """The metro train with a constant tractive effort and no running resistance: on level track its
    acceleration is share x F / (rho m), so v^2 = 2 share F x / (rho m) from standstill."""
    sc = _base()
    flat = EffortCurve.from_table([0.0, 100.0], [FORCE_N, FORCE_N])
    train = dataclasses.replace(sc.train, traction=flat, resistance=())
    return train if electric else dataclasses.replace(train, electrical=None)


def _route(share: float = SHARE) -> Route:
    nominal = _base().train.electrical.line_voltage_v
    return Route(
        "level",
        0.0,
        LENGTH_M,
        (Station("A", 0.0), Station("B", LENGTH_M)),
        (SpeedLimit(0.0, LENGTH_M, 40.0),),
        electrification=(
            ElectrificationSection(0.0, LIMITED_END_M, nominal, traction_share=share),
            ElectrificationSection(LIMITED_END_M, LENGTH_M, nominal),
        ),
    )


def _speed_at(run, x_m: np.ndarray) -> np.ndarray:
    """Speed at ``x_m`` [m/s], interpolated in v^2, which a constant acceleration makes linear in x."""
    tr = run.trace
    return np.sqrt(np.interp(x_m, tr.position_m, tr.speed_mps**2))


def _settings():
    return dataclasses.replace(_base().settings, max_step_m=5.0)


def test_half_share_halves_the_acceleration_on_its_section():
    train = _train()
    run = trainsim.run_fastest(train, _route(), _settings())
    assert run.status == "ok"
    a_full = FORCE_N / train.inertial_mass_kg  # [m/s^2]
    x = np.linspace(20.0, LIMITED_END_M, 8)
    np.testing.assert_allclose(_speed_at(run, x), np.sqrt(2.0 * SHARE * a_full * x), rtol=1e-6)
    # past the section, the full effort from the speed it reached there
    x2 = np.linspace(LIMITED_END_M + 10.0, 600.0, 8)
    v2 = np.sqrt(2.0 * a_full * (SHARE * LIMITED_END_M + (x2 - LIMITED_END_M)))
    assert v2[-1] < 40.0  # still below the speed limit: pure traction
    np.testing.assert_allclose(_speed_at(run, x2), v2, rtol=1e-6)
    # the force the run reports is the share of the force law
    tr = run.trace
    inside = (tr.position_m > 1.0) & (tr.position_m < LIMITED_END_M - 1.0) & (tr.traction_force_n > 0)
    assert inside.sum() > 5
    np.testing.assert_allclose(tr.traction_force_n[inside], SHARE * FORCE_N, rtol=1e-12)
    assert abs(run.energy_balance["relative_error"]) < 1e-6


def test_share_one_is_the_full_effort():
    train = _train()
    run = trainsim.run_fastest(train, _route(1.0), _settings())
    a_full = FORCE_N / train.inertial_mass_kg
    x = np.linspace(20.0, 600.0, 10)
    np.testing.assert_allclose(_speed_at(run, x), np.sqrt(2.0 * a_full * x), rtol=1e-6)


def test_a_train_without_electrical_data_ignores_the_share():
    """Such a train is not fed by the line (diesel, or no data): the line cannot limit it."""
    train = _train(electric=False)
    run = trainsim.run_fastest(train, _route(), _settings())
    a_full = FORCE_N / train.inertial_mass_kg
    x = np.linspace(20.0, 600.0, 10)
    np.testing.assert_allclose(_speed_at(run, x), np.sqrt(2.0 * a_full * x), rtol=1e-6)


def test_availability_is_the_share_on_electrified_sections_only():
    nominal = _base().train.electrical.line_voltage_v
    route = dataclasses.replace(
        _route(),
        electrification=(
            ElectrificationSection(0.0, 100.0, nominal, traction_share=0.25),
            ElectrificationSection(100.0, 200.0, 0.0, traction_share=0.5),  # not electrified: 0
            ElectrificationSection(500.0, 600.0, nominal, traction_share=0.75),
        ),
    )
    train = _train()
    avail = traction_availability(route, train)
    mid = 0.5 * (avail.x[:-1] + avail.x[1:])
    expected = np.select(
        [mid < 100.0, mid < 200.0, (mid >= 500.0) & (mid < 600.0)], [0.25, 0.0, 0.75], default=1.0
    )
    np.testing.assert_array_equal(avail.left, expected)
    np.testing.assert_array_equal(avail.x, line_voltage(route, train).x)
    ones = traction_availability(route, _train(electric=False)).left
    np.testing.assert_array_equal(ones, np.ones_like(ones))


@pytest.mark.parametrize("bad", [0.0, -0.1, 1.0 + 1e-12, math.nan, math.inf, "0.5", True, None])
def test_bad_share_is_refused_naming_field_value_and_range(bad):
    with pytest.raises(InputError) as info:
        ElectrificationSection(0.0, 10.0, 750.0, traction_share=bad)
    problem = info.value.problems[0]
    assert problem.field == "electrification.traction_share"
    assert "0 < x <= 1" in problem.allowed
    if bad is not None:  # None is shown as no value
        assert problem.value is bad
