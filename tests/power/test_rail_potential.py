"""Rail potential and stray current on a uniformly leaking rail (cosh/sinh closed form)."""

from __future__ import annotations

import numpy as np
import pytest
from powercases import NO_LIMITS
from scipy.integrate import quad

from trainsim.power import Network, StepLoads, Substation, Track, solve_step
from trainsim.power.rail import (
    leaky_rail_pi,
    rail_profile_v,
    segment_leakage_a,
    train_substation_rail_potential_v,
)

R_RAIL = 0.015e-3  # ohm/m
G_EARTH = 2.0 / 1000  # S/m: a poorly insulated track (2 S/km), alpha L ~ 0.5 over 3 km
LENGTH = 3000.0


def _network(g=G_EARTH, earthed=False) -> Network:
    return Network(
        "leaky", "dc", NO_LIMITS, (Track("A", 0.0, LENGTH, 0.02e-3, R_RAIL, g),),
        (Substation("S", 0.0, ("A",), 850.0, 0.02, reversible=True),),
        negative_earthed=earthed, contact_leakage_s=1e-13,
    )  # fmt: skip


def _loads(x, p) -> StepLoads:
    z = np.zeros(1)
    return StepLoads(np.array([0]), np.array([x]), np.array([p]), z, z, z)


def test_train_and_substation_rail_potentials_closed_form():
    """The train at x = L injects its current I into the rails, the substation (floating negative)
    at 0 draws it out: V_train = (I r / alpha) tanh(alpha L / 2) = -V_substation, and the stray
    current is I (1 - 1 / cosh(alpha L / 2)), to 1e-9."""
    sol = solve_step(_network(), _loads(LENGTH, 2e6))
    assert sol.converged
    i = sol.train_current_a[0]
    alpha = np.sqrt(R_RAIL * G_EARTH)
    assert 0.3 < alpha * LENGTH < 1.0  # far from the lumped limit
    v_train = i * R_RAIL / alpha * np.tanh(alpha * LENGTH / 2)
    rails = np.sort(sol.rail_potential_v)
    assert rails == pytest.approx([-v_train, v_train], rel=1e-9)
    assert train_substation_rail_potential_v(i, R_RAIL, G_EARTH, LENGTH, [0.0, LENGTH]) == pytest.approx(
        [v_train, -v_train], rel=1e-12
    )
    assert sol.stray_current_a == pytest.approx(i * (1 - 1 / np.cosh(alpha * LENGTH / 2)), rel=1e-9)


def test_profile_between_nodes_matches_the_closed_form_and_the_ode():
    i = 2500.0
    alpha = np.sqrt(R_RAIL * G_EARTH)
    x = np.linspace(0.0, LENGTH, 31)
    closed = train_substation_rail_potential_v(i, R_RAIL, G_EARTH, LENGTH, x)
    profile = rail_profile_v(closed[0], closed[-1], LENGTH, R_RAIL, G_EARTH, x)
    assert profile == pytest.approx(closed, rel=1e-10, abs=1e-10)
    # V'' = alpha^2 V by finite differences, and dV/dx = -r I at the train
    h = 1e-1
    for xm in (700.0, 1500.0, 2600.0):
        v = rail_profile_v(closed[0], closed[-1], LENGTH, R_RAIL, G_EARTH, [xm - h, xm, xm + h])
        assert (v[0] - 2 * v[1] + v[2]) / h**2 == pytest.approx(alpha**2 * v[1], rel=1e-5)
    v = rail_profile_v(closed[0], closed[-1], LENGTH, R_RAIL, G_EARTH, [0.0, h])
    assert (v[1] - v[0]) / h == pytest.approx(-R_RAIL * i, rel=1e-4)


def test_segment_leakage_against_quadrature():
    for va, vb in ((12.0, -7.0), (-3.0, 9.0), (5.0, 2.0), (-4.0, -1.0), (0.0, 6.0)):
        expected, _ = quad(
            lambda x, va=va, vb=vb: G_EARTH * max(rail_profile_v(va, vb, LENGTH, R_RAIL, G_EARTH, x), 0.0),
            0.0,
            LENGTH,
            limit=200,
            epsabs=1e-14,
        )
        got = float(segment_leakage_a(va, vb, LENGTH, R_RAIL, G_EARTH))
        assert got == pytest.approx(expected, rel=1e-8, abs=1e-14)
    # the short-segment (linear) branch
    assert float(segment_leakage_a(4.0, -4.0, 1.0, R_RAIL, G_EARTH)) == pytest.approx(G_EARTH * 4.0 * 0.5 / 2)


def test_pi_equivalent_limits():
    ys, yp = leaky_rail_pi(R_RAIL, 0.0, np.array([100.0]))
    assert ys == pytest.approx(1 / (R_RAIL * 100.0)) and yp == 0.0
    ys, yp = leaky_rail_pi(R_RAIL, 1e-12, np.array([100.0]))  # tiny leakage: lumped halves
    assert ys == pytest.approx(1 / (R_RAIL * 100.0), rel=1e-9)
    assert yp == pytest.approx(1e-12 * 50.0, rel=1e-6)


def test_earthed_negative_has_no_potential_at_the_substation_and_more_stray_current():
    floating = solve_step(_network(), _loads(LENGTH, 2e6))
    earthed = solve_step(_network(earthed=True), _loads(LENGTH, 2e6))
    assert earthed.stray_current_a > floating.stray_current_a
    i = earthed.train_current_a[0]
    alpha = np.sqrt(R_RAIL * G_EARTH)
    # earthed at 0: V(L) = I r sinh(alpha L) / (alpha cosh(alpha L)) (all current may leave the rails)
    assert np.max(earthed.rail_potential_v) == pytest.approx(
        i * R_RAIL / alpha * np.tanh(alpha * LENGTH), rel=1e-9
    )
