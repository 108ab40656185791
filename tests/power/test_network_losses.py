"""The losses of one step split into contact line, return and substation internal (issue 18), each
against a closed form."""

from __future__ import annotations

import numpy as np
import pytest
from powercases import NO_LIMITS

from trainsim.power import Network, StepLoads, Substation, Track, solve_step

E_V, R_I, L_M, P_W = 850.0, 0.03, 3000.0, 0.6e6
R_C, R_R = 0.025e-3, 0.018e-3  # ohm/m


def _one_train(rail_ohm_per_m: float, g_s_per_m: float = 0.0, system: str = "dc", x_ohm_per_m: float = 0.0):
    """One substation at 0 and one train drawing P_W at L_M."""
    net = Network(
        "one train",
        system,
        NO_LIMITS,
        (Track("A", 0.0, L_M, R_C, rail_ohm_per_m, g_s_per_m, x_ohm_per_m),),
        (Substation("S", 0.0, ("A",), E_V, R_I, reversible=True),),
        contact_leakage_s=1e-13,
    )
    one = np.ones(1)
    return solve_step(net, StepLoads(np.zeros(1, dtype=int), L_M * one, P_W * one, 0 * one, 0 * one, 0 * one))


def _closed_form_current_a(r_total_ohm: float) -> float:
    """The train's current: U (E - U) / R = P with U the larger root, I = P / U."""
    u = 0.5 * (E_V + np.sqrt(E_V**2 - 4 * r_total_ohm * P_W))
    return P_W / u


def test_split_on_a_resistive_line_against_the_closed_form():
    sol = _one_train(R_R)
    assert sol.converged
    i = _closed_form_current_a(R_I + (R_C + R_R) * L_M)
    assert sol.train_current_a[0] == pytest.approx(i, rel=1e-9)
    assert sol.contact_loss_w == pytest.approx(i**2 * R_C * L_M, rel=1e-9)
    assert sol.return_loss_w == pytest.approx(i**2 * R_R * L_M, rel=1e-9)
    assert sol.substation_loss_w == pytest.approx(i**2 * R_I, rel=1e-9)
    assert sol.line_loss_w == sol.contact_loss_w + sol.return_loss_w
    total = sol.train_power_w[0] + sol.contact_loss_w + sol.return_loss_w + sol.substation_loss_w
    assert sol.substation_source_w[0] == pytest.approx(total, rel=1e-9)
    assert sol.substation_power_w[0] == pytest.approx(total - sol.substation_loss_w, rel=1e-9)


def test_return_losses_of_a_leaking_rail_against_the_cosh_sinh_closed_form():
    """Rails leaking to earth (alpha L = 0.95): the rail potentials are +-(I r / alpha)
    tanh(alpha L / 2) at the train and the substation (trainsim.power.rail), so the power the return
    takes, series and leakage together, is I (V_train - V_substation) = 2 I^2 (r / alpha) tanh(alpha L / 2)."""
    g = 5e-3  # S/m: a badly insulated track, so that the leakage matters
    sol = _one_train(R_R, g)
    i = sol.train_current_a[0]
    alpha = np.sqrt(R_R * g)
    assert 0.5 < alpha * L_M < 2
    expected = 2 * i**2 * R_R / alpha * np.tanh(alpha * L_M / 2)
    assert sol.return_loss_w == pytest.approx(expected, rel=1e-9)
    assert sol.return_loss_w < i**2 * R_R * L_M  # leaking, less current flows all the way back
    assert sol.contact_loss_w == pytest.approx(i**2 * R_C * L_M, rel=1e-9)
    total = sol.train_power_w[0] + sol.line_loss_w + sol.substation_loss_w
    assert sol.substation_source_w[0] == pytest.approx(total, rel=1e-9)


def test_ideal_return_and_ac_put_every_line_loss_on_the_contact_line():
    sol = _one_train(0.0)
    i = _closed_form_current_a(R_I + R_C * L_M)
    assert sol.return_loss_w == 0.0
    assert sol.contact_loss_w == pytest.approx(i**2 * R_C * L_M, rel=1e-9)
    ac = _one_train(0.0, system="ac", x_ohm_per_m=0.04e-3)
    assert ac.converged and ac.return_loss_w == 0.0
    # AC: R |I|^2 of the loop and of the transformer, I the current magnitude
    i_ac = abs(ac.train_current_a[0])
    assert ac.contact_loss_w == pytest.approx(i_ac**2 * R_C * L_M, rel=1e-9)
    assert ac.substation_loss_w == pytest.approx(i_ac**2 * R_I, rel=1e-9)
