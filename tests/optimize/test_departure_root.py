"""Departure points ahead of steep descents located as roots of their switching condition
(``SectionSolver._departure_root``, ``_pmp_c.coast_excursion``'s residual; issue 13).

Before, golden section on energy + mu x time placed the freight example's departure ahead of its
last descent at 31276.57 / 31276.92 / 31275.63 m at steps of 20 / 10 / 5 m."""

from __future__ import annotations

import numpy as np
import pytest
from optimize_freight_case import FREIGHT_V, freight_section_2

from trainsim.optimize import _pmp_c as pk
from trainsim.optimize.optimal import SectionSolver


def _descent_departure(solver: SectionSolver) -> tuple[float, list]:
    """(departure point [m], [(p, cost, residual), ...] the search tried) of the section's descent."""
    tried = []
    original = SectionSolver._departure_root

    def spy(cost, conditions, p, dj, lo, hi, scale):
        found = original(cost, conditions, p, dj, lo, hi, scale)
        tried.append((cost, conditions, found))
        return found

    SectionSolver._departure_root = staticmethod(spy)
    try:
        solver.plan(FREIGHT_V)
    finally:
        SectionSolver._departure_root = staticmethod(original)
    points = [d[0] for k, d in solver._decisions.items() if k[0] == "descent" and d[0] < d[2] - 1e-9]
    assert len(points) == 1
    # the search that chose it
    chosen = [entry for entry in tried if abs(entry[2][0] - points[0]) < 1e-9]
    assert chosen
    return points[0], chosen


def test_departure_ahead_of_a_descent_does_not_move_with_the_step():
    coarse, _ = _descent_departure(freight_section_2(20.0))
    fine, tried = _descent_departure(freight_section_2(10.0))
    assert 31000.0 < coarse < 31500.0
    assert abs(coarse - fine) < 1e-6
    # it is the switching condition's root, not the cost's golden-section minimum
    _, (residuals, _), (p, _) = tried[-1]
    assert p == pytest.approx(fine, abs=1e-9)
    assert abs(residuals[p]) < 1e-9


def test_root_of_the_switching_condition_is_the_minimum_of_the_cost():
    """The adjoint's condition and a direct minimisation of energy + mu x time (independent of the
    adjoint: golden section to 1e-5 m on the cost alone) find the same departure point."""
    solver = freight_section_2(20.0)
    p_root, tried = _descent_departure(solver)
    cost, (residuals, _), _ = tried[-1]
    p_min, _ = SectionSolver._golden(cost, p_root - 20.0, p_root + 20.0, tol_m=1e-5)
    # the cost is quadratic at its minimum (about 260 J/m^2 here): its minimum is located to about
    # a millimetre by the cost's rounding at 1.8e8 J
    assert p_min == pytest.approx(p_root, abs=5e-3)
    # and the residual changes sign there, rising (a minimum, not a maximum)
    cost(p_root - 1.0)
    cost(p_root + 1.0)
    assert residuals[p_root - 1.0] < 0.0 < residuals[p_root + 1.0]


def _hump_line(solver: SectionSolver, s_m: float):
    tr = solver.track
    i = solver._interval_of(s_m)
    return (tr.a0[i], tr.a1[i], tr.b0[i], tr.b1[i]), s_m - tr.x[i]


def test_held_adjoint_is_the_hamiltonian_switching_value():
    """phi at which coasting and holding v cost the same: 1/eta_t where holding needs traction;
    eta_r where it needs braking the electric brake can give; eta_r F_regen / (-R) where it needs
    more (the rest is friction); 0 without regeneration."""
    from test_optimal_crest import hump_solver

    solver = hump_solver()
    v = 15.0
    level, u = _hump_line(solver, 500.0)
    assert pk.held_adjoint(v, u, level, solver.P, solver.curves, solver.inv_eta_t, solver.eta_r) == (
        pytest.approx(solver.inv_eta_t)
    )
    descent, u = _hump_line(solver, 2500.0)
    push = -pk.resistance_force(v, u, descent, solver.P)
    assert push > 0.0
    assert pk.held_adjoint(v, u, descent, solver.P, solver.curves, solver.inv_eta_t, solver.eta_r) == (
        pytest.approx(solver.eta_r)
    )
    assert pk.held_adjoint(v, u, descent, solver.P, solver.curves, solver.inv_eta_t, 0.0) == 0.0
    # an electric brake of a quarter of the push: a quarter of eta_r
    weak = list(solver.curves)
    cap = 0.25 * push
    weak[8:12] = (np.array([0.0]), np.array([[cap, 0.0, 0.0, 0.0]]), np.inf, np.inf)
    assert pk.held_adjoint(v, u, descent, solver.P, tuple(weak), solver.inv_eta_t, solver.eta_r) == (
        pytest.approx(0.25 * solver.eta_r)
    )
