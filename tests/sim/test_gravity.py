"""Gravity is a setting of the route: every weight force of a run takes it from there."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from simcases import make_route, make_train

import trainsim
from trainsim import constants
from trainsim.errors import InputError
from trainsim.model import EffortCurve
from trainsim.physics import resistance as res


def test_gravity_conventions_of_the_sources():
    assert constants.STANDARD_GRAVITY == 9.80665  # CGPM 1901
    assert constants.TRAINRUNS_GRAVITY == 9.80665  # TrainRuns.jl formulary
    assert constants.TTOBENCH_GRAVITY == 9.81  # TTOBench / ms-eetc
    assert constants.ALTRIOS_GRAVITY == 9.80155  # ALTRIOS uc::ACC_GRAV
    assert make_route().gravity_mps2 == constants.STANDARD_GRAVITY


@pytest.mark.parametrize("g", [0.0, 9.81e3, float("nan"), -9.81, 1.62])
def test_implausible_gravity_is_refused_with_the_allowed_range(g):
    with pytest.raises(InputError) as err:
        dataclasses.replace(make_route(), gravity_mps2=g)
    assert err.value.field == "gravity_mps2"
    assert "9.7 .. 9.9" in str(err.value.allowed)


@pytest.mark.parametrize("g", [9.80665, 9.81, 9.80155])
def test_gradient_force_and_cruising_traction_use_the_route_gravity(g):
    """On a uniform 8 per mille climb the train cruises with traction = m g i (no running
    resistance), and its gradient resistance is m g i at every point."""
    train = make_train(traction_n=300e3, mass_kg=300e3)
    route = dataclasses.replace(make_route(gradient_permille=8.0), gravity_mps2=g)
    tr = trainsim.run_fastest(train, route).trace
    assert np.allclose(tr.gradient_resistance_n, 300e3 * g * 8e-3, rtol=1e-12)
    cruise = tr.regime == trainsim.sim.codes.CRUISE
    assert cruise.sum() > 10
    assert np.allclose(tr.traction_force_n[cruise], 300e3 * g * 8e-3, rtol=1e-12)


def test_running_time_follows_gravity_on_a_grade():
    """Uphill, a larger g means a slower climb: the acceleration phase a = (F - m g i) / (rho m)
    lasts v / a, so the time grows with g (analytic comparison of two runs)."""
    train = make_train(traction_n=150e3, braking_n=400e3, mass_kg=300e3, rho=1.1)
    base = make_route(length_m=8000.0, limit_kmh=80.0, gradient_permille=20.0)
    times = {
        g: trainsim.run_fastest(train, dataclasses.replace(base, gravity_mps2=g)).running_time_s
        for g in (9.80665, 9.81)
    }
    v, m, rho, i, F, B = 80 / 3.6, 300e3, 1.1, 20e-3, 150e3, 400e3

    def analytic(g: float) -> float:
        a = (F - m * g * i) / (m * rho)
        b = (B + m * g * i) / (m * rho)
        return v / a + (8000.0 - v**2 / (2 * a) - v**2 / (2 * b)) / v + v / b

    for g, t in times.items():
        assert t == pytest.approx(analytic(g), rel=1e-6)
    assert times[9.81] > times[9.80665]


def test_adhesion_limit_takes_gravity_at_run_time():
    """An adhesion limit mu m_adh g is stored as mu m_adh [kg] and resolved with the route's g."""
    curve = EffortCurve.constant(500e3).capped()
    curve = dataclasses.replace(curve, adhesion_limit_kg=0.3 * 72e3)
    assert curve(1.0) == pytest.approx(0.3 * 72e3 * 9.80665)  # standard g when evaluated directly
    assert curve.at_gravity(9.81)(1.0) == pytest.approx(0.3 * 72e3 * 9.81)
    assert curve.scaled(2.0).at_gravity(9.81)(1.0) == pytest.approx(2 * 0.3 * 72e3 * 9.81)
    train = make_train(traction=curve)
    assert train.at_gravity(9.81).traction(0.0) == pytest.approx(0.3 * 72e3 * 9.81)
    plain = make_train()
    assert plain.at_gravity(9.81) is plain


def test_weight_based_resistance_laws_take_gravity():
    for g in (9.80665, 9.81):
        law = res.strahl(1e6, 1.0, 0.0, gravity_mps2=g)
        assert law(10.0) == pytest.approx(1e6 * g * 1e-3)
        assert res.altrios(1e5, 4, 0.0, 1e-3, 0.0, 0.0, gravity_mps2=g)(0.0) == pytest.approx(1e5 * g * 1e-3)
