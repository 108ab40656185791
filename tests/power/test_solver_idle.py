"""Idle and lightly loaded DC networks with diode rectifiers (issue 18): the diode's rounding has a
finite tail, so a blocked rectifier gives exactly 0 A and a section with no load sits at the highest
no-load voltage E (the exact physics: every rectifier current 0), not hundreds of volts above it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from powercases import NO_LIMITS, two_substations

from trainsim.io.power_file import load_power_file
from trainsim.power import Network, StepLoads, Substation, Track, solve_step, solver, standard_limits
from trainsim.power.network import regulation_points

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "power" / "metro_750v_diode.yaml"
E_METRO_V = 850.0
#: the rounding width d of the diode law at 750 V [V]
D_750_V = solver.DIODE_SMOOTHING_SHARE * 750.0


def _one_train(x_m: float, auxiliary_w: float, regen_w: float = 0.0, track: int = 0) -> StepLoads:
    z = np.zeros(1)
    return StepLoads(np.array([track]), np.array([x_m]), z, np.array([regen_w]), np.array([auxiliary_w]), z)


def _constant_power_voltage_v(e_v: float, r_ohm: float, p_w: float) -> float:
    """Voltage of a constant-power load P fed by a source E through R: P = I (E - R I), the smaller
    root I = 2 P / (E + sqrt(E^2 - 4 R P)) (the form without cancellation), U = E - R I."""
    i = 2 * p_w / (e_v + np.sqrt(e_v**2 - 4 * r_ohm * p_w))
    return e_v - r_ohm * i


def test_diode_law_values_and_slope():
    """0 below -d, (x + d)^2 / (4 d) inside, x above d; continuous value and slope at +-d; the slope
    is the derivative (central differences); the compiled scalars give the same doubles."""
    d = 0.01
    x = np.array([-1.0, -d, -0.5 * d, 0.0, 0.5 * d, d, 2.0])
    assert solver._diode_forward(x, d).tolist() == pytest.approx(
        [0.0, 0.0, 0.25 * d / 4, d / 4, 2.25 * d / 4, d, 2.0], rel=1e-15, abs=0.0
    )
    assert solver._diode_forward_slope(x, d).tolist() == pytest.approx([0, 0, 0.25, 0.5, 0.75, 1, 1])
    for edge in (-d, d):
        for f in (solver._diode_forward, solver._diode_forward_slope):
            below, above = f(np.array([edge * (1 - 1e-12), edge * (1 + 1e-12)]), d)
            assert below == pytest.approx(above, abs=1e-12)
    xs = np.linspace(-2 * d, 2 * d, 41) + 1e-4 * d  # off the joints, where the slope is not smooth
    h = 1e-7 * d
    numeric = (solver._diode_forward(xs + h, d) - solver._diode_forward(xs - h, d)) / (2 * h)
    assert numeric == pytest.approx(solver._diode_forward_slope(xs, d), abs=1e-7)
    for v in xs:
        assert solver._diode_forward_scalar(v, d) == solver._diode_forward(np.array([v]), d)[0]
        assert solver._diode_forward_slope_scalar(v, d) == solver._diode_forward_slope(np.array([v]), d)[0]


@pytest.fixture(scope="module")
def metro():
    _, net, _ = load_power_file(EXAMPLE)
    return net


def test_idle_train_on_the_diode_metro_sits_at_the_no_load_voltage(metro):
    """The issue's case: one train at 0 W and no other load. Exact: every rectifier current 0 and the
    line at E = 850 V; the rounding lets a rectifier conduct the leakage's microamperes up to d above E,
    so E to within d (the old law gave 920 V)."""
    sol = solve_step(metro, _one_train(1000.0, 0.0))
    assert sol.converged
    assert abs(sol.train_voltage_v[0] - E_METRO_V) <= D_750_V
    # what the rectifiers give is the contact leakage only (1e-9 S at each of fewer than 1000 nodes),
    # within Newton's Kirchhoff tolerance (a share of the three short-circuit currents E / R_i)
    assert np.all(sol.substation_current_a >= 0.0)
    tolerance_a = solver.CURRENT_TOLERANCE_SHARE * 3 * E_METRO_V / 0.012
    assert np.sum(sol.substation_current_a) < 1e-9 * 1000 * 1.01 * E_METRO_V + tolerance_a


@pytest.mark.parametrize("p_w", [1.0, 1e3])
def test_small_load_on_the_diode_metro_between_bounds(metro, p_w):
    """A train at 1 km on track up drawing P: exactly, U = E - R_th I with I = P / U and R_th at most
    the one path to SS-S1 (1 km of contact, 18 mohm, and rail, 12 mohm, plus R_i 12 mohm: 42 mohm;
    other paths in parallel only lower it); the rounding moves a rectifier's busbar by less than d."""
    sol = solve_step(metro, _one_train(1000.0, p_w))
    assert sol.converged
    u = sol.train_voltage_v[0]
    lowest = _constant_power_voltage_v(E_METRO_V, 0.042, p_w)
    assert lowest - D_750_V <= u <= E_METRO_V + D_750_V  # the old law: 852.9 V at 1 W
    assert sol.train_power_w[0] == pytest.approx(p_w, rel=1e-12)


@pytest.mark.parametrize("x_m", [0.0, 1500.0, 4000.0])
def test_two_diode_substations_no_load_take_the_higher_voltage(x_m):
    """E1 = 835 V, E2 = 825 V, an idle train anywhere: the line sits at 835 V (to within d), S2 is
    10 V above its E and blocks with exactly 0 A (the old law: ys d^2 / (4 |x|), 3e-5 A, which the
    1e-12 S leakage of this network could not take), S1 gives the leakage's current, within Newton's
    Kirchhoff tolerance (CURRENT_TOLERANCE_SHARE of the short-circuit currents, 4.4e-6 A here)."""
    sol = solve_step(two_substations(reversible=False), _one_train(x_m, 0.0))
    assert sol.converged
    assert abs(sol.train_voltage_v[0] - 835.0) <= D_750_V
    assert sol.substation_current_a[1] == 0.0
    assert sol.substation_power_w[1] == 0.0
    assert not sol.substation_on[1]
    tolerance_a = solver.CURRENT_TOLERANCE_SHARE * (835.0 / 0.03 + 825.0 / 0.05)
    assert 0.0 <= sol.substation_current_a[0] <= tolerance_a


@pytest.mark.parametrize("p_w", [1.0, 1e3])
def test_constant_power_load_closed_form_with_one_rectifier_blocked(p_w):
    """The same network with a train at 1 km drawing P: S2 stays blocked (0 A), so S1 alone feeds the
    train through R = R1 + (r_contact + r_rail) x = 0.03 + 0.035 ohm: closed form U = E1 - R I,
    P = U I. At 1 kW S1's R1 I = 36 mV is beyond the rounding (exact law, 1e-9); at 1 W R1 I = 36 uV
    is inside it and the busbar moves by less than d + R1 I."""
    x_m = 1000.0
    r_ohm = 0.03 + (0.02e-3 + 0.015e-3) * x_m
    sol = solve_step(two_substations(reversible=False), _one_train(x_m, p_w))
    assert sol.converged
    expected = _constant_power_voltage_v(835.0, r_ohm, p_w)
    if p_w >= 1e3:
        assert sol.train_voltage_v[0] == pytest.approx(expected, rel=1e-9)
        # plus the 1e-12 S contact leakage at the network's few nodes (2.5e-9 A)
        assert sol.substation_current_a[0] == pytest.approx(p_w / expected, rel=1e-9, abs=1e-12 * 835.0 * 10)
    else:
        assert abs(sol.train_voltage_v[0] - expected) <= D_750_V + 0.03 * p_w / expected
    assert sol.substation_current_a[1] == 0.0


def test_idle_rectifier_with_regulation_curve_sits_at_its_no_load_voltage():
    """The numpy Newton (a regulation curve rules out the compiled one) uses the same law: a diode
    given by the two-point curve of E = 850 V, R_i = 10 mohm, no load: 850 V to within d, the current
    within Newton's Kirchhoff tolerance."""
    curve = ((0.0, 850.0), (1000.0, 840.0))
    e, r = regulation_points(list(curve))
    net = Network(
        "regulated",
        "dc",
        NO_LIMITS,
        (Track("A", 0.0, 2000.0, 0.01e-3),),
        (Substation("S", 0.0, ("A",), e, r, reversible=False, regulation=curve),),
        contact_leakage_s=1e-12,
    )
    sol = solve_step(net, _one_train(2000.0, 0.0))
    assert sol.converged
    assert abs(sol.train_voltage_v[0] - 850.0) <= D_750_V
    assert 0.0 <= sol.substation_current_a[0] <= solver.CURRENT_TOLERANCE_SHARE * 850.0 / 0.01


def test_regeneration_with_every_diode_blocked_rises_to_the_curtailment_ramp():
    """A train regenerating 1.5 MW with 50 kW of auxiliaries between two diode rectifiers (835 and
    825 V) and no other train: both block (0 A), so the train takes its own power only,
    P_regen r(U) = P_aux, on the EN 50163 ramp r(U) = (1000 - U) / (1000 - 900):
    U = 1000 - 100 x 50 / 1500 = 996.67 V (the existing continuation in solve_step finds it)."""
    lim = standard_limits("dc_750")
    net = two_substations(reversible=False, limits=lim)
    sol = solve_step(net, _one_train(2000.0, 50e3, regen_w=1.5e6))
    assert sol.converged
    expected = lim.regen_zero_v - (lim.regen_zero_v - lim.regen_full_v) * 50e3 / 1.5e6
    assert sol.train_voltage_v[0] == pytest.approx(expected, rel=1e-9)
    assert sol.substation_current_a.tolist() == [0.0, 0.0]
    assert not sol.substation_on.any()
    assert sol.train_power_w[0] == pytest.approx(0.0, abs=1e-3)
