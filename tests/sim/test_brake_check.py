"""The brake check of a descent is exact (issue 13): a narrow dip of the braking force between the
speeds a sampled check looked at is found, and the worst surplus matches a dense sampling."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from simcases import make_route, make_train

import trainsim
from trainsim.constants import KMH
from trainsim.model import Braking, EffortCurve, GradientSection, Quadratic
from trainsim.sim import codes
from trainsim.sim.fastest import worst_braking_surplus
from trainsim.sim.parameters import kernel_parameters

VC = 10.14  # speed of the dip [m/s], between the old samples 9.66 and 10.63 m/s (24 up to 80 km/h)
HALF_WIDTH = 0.1  # [m/s]
F_HIGH, F_DIP = 200e3, 40e3  # [N]


def _dip_brakes() -> EffortCurve:
    c = (F_HIGH - F_DIP) / HALF_WIDTH**2  # F_DIP + c (v - VC)^2 reaches F_HIGH at the piece's ends
    return EffortCurve.piecewise(
        [0.0, VC - HALF_WIDTH, VC + HALF_WIDTH],
        [[F_HIGH, 0, 0, 0], [F_DIP + c * VC**2, -2 * c * VC, c, 0], [F_HIGH, 0, 0, 0]],
    )


def _dip_case():
    train = make_train(braking=Braking(service_force=_dip_brakes()), mass_kg=300e3)
    route = make_route(length_m=10_000.0, limit_kmh=80.0)
    route = dataclasses.replace(route, gradients=(GradientSection(3000.0, 6000.0, -20.0),))
    return train, route


def test_the_dip_lies_between_the_old_samples():
    """The sampled check looked at 24 speeds from 0 to the ceiling and the curve's kinks: there the
    service brakes (200 kN) hold the 58.8 kN of the descent."""
    old = np.unique(np.concatenate([np.linspace(0.0, 80 * KMH, 24), [VC - HALF_WIDTH, VC + HALF_WIDTH]]))
    assert np.all(_dip_brakes()(old) >= F_HIGH - 1e-6)


def test_a_narrow_dip_in_the_braking_table_is_brake_limited():
    train, route = _dip_case()
    r = trainsim.run_fastest(train, route)
    assert r.status == "brake_limited"
    downhill = 300e3 * route.gravity_mps2 * 0.020
    surplus_kn = (downhill - F_DIP) / 1e3  # the default braking fraction is 1
    msg = r.warnings[0]
    assert f"at {VC / KMH:.1f} km/h from 3000.0 m" in msg
    assert f"by {surplus_kn:.1f} kN" in msg
    assert r.trace.position_m[-1] == pytest.approx(3000.0) and r.trace.speed_mps[-1] == 0.0
    # without the dip the same descent is fine
    fine = dataclasses.replace(train, braking=Braking(service_force=EffortCurve.constant(F_HIGH)))
    assert trainsim.run_fastest(fine, route).status == "ok"


def _dense_worst(P, curve: EffortCurve, q2_extra: float, v_max: float) -> float:
    v = np.linspace(0.0, v_max, 400_001)
    running = P[codes.P_R0] + P[codes.P_R1] * v + P[codes.P_R2] * v * v
    return float(np.max(-(P[codes.P_BRAKE_FRACTION] * curve(v) + running) - q2_extra * v * v))


@pytest.mark.parametrize("seed", range(6))
def test_the_worst_surplus_matches_a_dense_sampling(seed):
    """Random tables, quadratic and hyperbolic laws, force and power caps, running resistance and
    tunnel v^2 terms: the exact maximum is never below a sampling of 400,001 speeds, and within
    what the sampling's spacing can miss."""
    rng = np.random.default_rng(seed)
    n = 6
    starts = np.concatenate([[0.0], np.sort(rng.uniform(1.0, 30.0, n - 1))])
    coefs = np.column_stack(
        [rng.uniform(50e3, 300e3, n), rng.uniform(-2e4, 2e4, n), rng.uniform(-800, 800, n), np.zeros(n)]
    )
    coefs[1:, 3] = rng.uniform(-5e5, 5e5, n - 1) * (rng.random(n - 1) < 0.5)
    curve = EffortCurve.piecewise(
        starts, coefs, force_cap_n=float(rng.uniform(150e3, 400e3)), power_cap_w=float(rng.uniform(1e6, 6e6))
    )
    resistance = Quadratic(
        float(rng.uniform(0, 5e3)), float(rng.uniform(-50, 200)), float(rng.uniform(0, 20))
    )
    train = make_train(braking=Braking(service_force=curve), resistance=resistance)
    P, _, brake = kernel_parameters(train, trainsim.RunSettings())
    for q2_extra, v_max in ((0.0, 33.0), (float(rng.uniform(0, 60)), 25.0), (-3.0, 12.0)):
        v, exact = worst_braking_surplus(P, brake, q2_extra, v_max)
        dense = _dense_worst(P, curve, q2_extra, v_max)
        assert 0.0 <= v <= v_max
        assert exact >= dense - 1e-6 * abs(dense)
        assert exact - dense <= 1e-3 * max(abs(dense), 1.0)
