"""The adjoint of the final phase integrated in sub-steps where the speed changes fast against the
step (``_pmp_c.phi_advance``; issue 13).

Its slope carries mu / v^3 (``_pmp_c.phi_slope``), which changes by a factor of 4 over a 20 m
step braking to the stop at 3 m/s. With one RK4 step per grid step, the adjoint's zero, where
the freight example's final regenerative braking meets the service braking curve, lay at
3.33471 / 3.33415 / 3.33405 m/s at steps of 20 / 10 / 5 m (holding speed fixed), the coasting point
moved with it, and the final phase ended 1.1 ms later at 10 m than at 20 m."""

from __future__ import annotations

import numpy as np
import pytest
from optimize_freight_case import FREIGHT_V, freight_section_2

from trainsim.optimize import _pmp_c as pk
from trainsim.optimize.optimal import SectionSolver, price_of_time_w
from trainsim.sim import _kernel_c, codes


def _regen_stretch(solver: SectionSolver, v0: float = 4.0):
    """(E0, E1, Em, u, h, line, mu, interval) of maximum regenerative braking from v0 [m/s] over the
    longest grid interval within 60 m of the stop."""
    tr = solver.track
    near = np.flatnonzero(tr.x[:-1] > solver.s1 - 60.0)
    i = int(near[np.argmax(np.diff(tr.x)[near])])
    h = float(tr.x[i + 1] - tr.x[i])
    line = (tr.a0[i], tr.a1[i], tr.b0[i], tr.b1[i])
    solver.P[codes.P_TRACTION_SCALE] = tr.traction_scale[i]
    E0 = 0.5 * v0 * v0
    E1 = _kernel_c.step_energy(E0, 0.0, h, codes.REGEN, line, solver.P, solver.curves, solver.rk)
    Em = _kernel_c.step_energy(E0, 0.0, 0.5 * h, codes.REGEN, line, solver.P, solver.curves, solver.rk)
    return E0, E1, Em, 0.0, h, line, price_of_time_w(solver.train, FREIGHT_V), i


def _reference_phi(
    solver: SectionSolver, phi: float, E0: float, u: float, h: float, line, mu: float
) -> float:
    """The adjoint after h integrated in 4000 RK4 steps, E along the way in the regime."""
    n = 4000
    d = h / n
    E = E0
    for k in range(n):
        uk = u + k * d
        args = (codes.REGEN, line, solver.P, solver.curves, solver.rk)
        Em = _kernel_c.step_energy(E, uk, 0.5 * d, *args)
        E1 = _kernel_c.step_energy(E, uk, d, *args)
        phi = pk.phi_step(phi, E, E1, uk, d, line[2], line[3], solver.P, mu, Em)
        E = E1
    return phi


def test_the_adjoint_over_a_slow_braking_step_matches_a_fine_integration() -> None:
    solver = freight_section_2(20.0)
    E0, E1, Em, u, h, line, mu, _ = _regen_stretch(solver)
    assert h > 15.0 and E1 < 0.7 * E0  # a long step that brakes the train hard: the case at stake
    phi0 = solver.eta_r
    reference = _reference_phi(solver, phi0, E0, u, h, line, mu)
    advanced = pk.phi_advance(
        phi0, E0, E1, u, h, codes.REGEN, line, solver.P, solver.curves, solver.rk, mu, Em
    )
    one_step = pk.phi_step(phi0, E0, E1, u, h, line[2], line[3], solver.P, mu, Em)
    change = abs(reference - phi0)
    # the sub-stepped adjoint is as good as the fine one to 1e-7 of its change over the step ...
    assert abs(advanced - reference) < 1e-7 * change, (advanced, reference)
    # ... where one RK4 step (what the kernel did) misses by far more
    assert abs(one_step - reference) > 100.0 * abs(advanced - reference)


def test_at_cruising_speeds_the_adjoint_takes_one_step_as_before() -> None:
    """Sub-steps only where the speed changes fast: holding speeds and coasting keep one RK4 step
    (what the departure roots and the adjoint's thresholds were located with)."""
    solver = freight_section_2(20.0)
    tr = solver.track
    i = len(tr.a0) // 2
    line = (tr.a0[i], tr.a1[i], tr.b0[i], tr.b1[i])
    h = float(tr.x[i + 1] - tr.x[i])
    mu = price_of_time_w(solver.train, FREIGHT_V)
    E0 = 0.5 * FREIGHT_V**2
    E1 = _kernel_c.step_energy(E0, 0.0, h, codes.COAST, line, solver.P, solver.curves, solver.bk)
    Em = _kernel_c.step_energy(E0, 0.0, 0.5 * h, codes.COAST, line, solver.P, solver.curves, solver.bk)
    phi0 = solver.inv_eta_t
    advanced = pk.phi_advance(
        phi0, E0, E1, 0.0, h, codes.COAST, line, solver.P, solver.curves, solver.bk, mu, Em
    )
    assert advanced == pk.phi_step(phi0, E0, E1, 0.0, h, line[2], line[3], solver.P, mu, Em)


def _final_phase(step_m: float) -> tuple[float, float]:
    """(duration [s] of the final phase from the coasting point to the stop, speed [m/s] where it
    meets the service braking curve) of freight section 2 at the fixed holding speed FREIGHT_V."""
    solver = freight_section_2(step_m)
    plan = solver.plan(FREIGHT_V)
    s, v, t, m = plan.s, plan.v, plan.t, plan.regime
    start = int(np.searchsorted(s, plan.coast_start_m - 1e-9))
    braking = np.flatnonzero((m[:-1] == codes.BRAKE) & (s[:-1] > plan.coast_start_m))
    assert len(braking), "the final phase meets the service braking curve"
    return float(t[-1] - t[start]), float(v[braking[0]])


@pytest.mark.slow
def test_the_final_phase_does_not_move_with_the_step() -> None:
    """At a fixed holding speed the final phase (coast, regenerative braking, the service curve to
    the stop) takes the same time and meets the service curve at the same speed at 20 and 10 m
    (before: 1.2 ms, 2.6e-6 of the phase, and 1.7e-4 of the speed)."""
    (d20, v20), (d10, v10) = _final_phase(20.0), _final_phase(10.0)
    assert abs(d20 - d10) < 1e-7 * d10, (d20, d10)
    assert abs(v20 - v10) < 1e-6 * v10, (v20, v10)
