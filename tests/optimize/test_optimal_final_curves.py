"""The final phase brakes to lower limits with the electric brake alone and to the stop with the
service brake (``SectionSolver._final_phase_curves``, ``_pmp_c.final_phase_modes``)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from test_optimal_structure import (
    TTOBENCH,
    lower_limit_route,
    net_energy_j,
    reference_energy_j,
    regen_train,
    ttobench_solver,
)

from trainsim.optimize.optimal import SectionSolver
from trainsim.sim import codes

pytestmark = pytest.mark.skipif(not TTOBENCH.exists(), reason="TTOBench data not found beside the checkout")

#: |optimal - reference| net energy [J]: 0.01 kWh. Braking to the lower limits on the service
#: curves instead was 0.09 to 0.99 kWh off on these sections.
TOLERANCE_J = 0.01 * 3.6e6


@pytest.mark.parametrize(
    ("train", "s0", "s1", "factor"),
    [
        ("CH_Stadler_KISS_SBB", 3906.0, 6272.0, 1.05),
        ("CH_Stadler_FLIRT_TPF", 3906.0, 6272.0, 1.05),
        ("CH_Stadler_KISS_SBB", 3906.0, 6272.0, 1.10),
        ("CH_Stadler_KISS_SBB", 21394.0, 22728.0, 1.05),
    ],
)
def test_final_phase_regenerates_to_lower_limits_as_the_reference(train, s0, s1, factor):
    solver = ttobench_solver(train, "CN_Songjiazhuang_Yizhuang", s0, s1)
    T = solver.fastest_time_s * factor
    plan = solver.solve(T)
    assert plan.feasible
    assert abs(plan.running_time_s - T) <= max(0.5, 5e-4 * T)
    energy, reference = net_energy_j(solver, plan), reference_energy_j(solver, T)
    assert abs(energy - reference) <= TOLERANCE_J, (energy / 3.6e6, reference / 3.6e6)


def test_final_curve_modes_regenerative_before_the_stop_curve():
    solver = ttobench_solver("CH_Stadler_KISS_SBB", "CN_Songjiazhuang_Yizhuang", 3906.0, 6272.0)
    modes = solver.final_curve_modes
    tr = solver.track
    assert len(modes) == len(solver.Cr_final) == solver.i1 - solver.i0
    # the stop's service curve: from the last interval partly at the limit to the stop
    at_limit = np.flatnonzero(solver.US > 0.0)
    assert len(at_limit) > 0
    first_stop = int(at_limit[-1])
    assert np.all(modes[first_stop:] == codes.BRAKE)
    assert np.all(modes[:first_stop] == codes.REGEN)
    np.testing.assert_array_equal(solver.Cr_final[first_stop:], solver.Cr[first_stop:])
    # the section has lower limits: their regenerative curves reach further back than the service ones
    lower = solver.Cr_final[:first_stop] < tr.vlim[solver.i0 : solver.i0 + first_stop] - 1e-9
    assert lower.any()
    assert np.all(solver.US_final[:first_stop] <= solver.US[:first_stop] + 1e-9)
    assert (solver.US_final[:first_stop] < solver.US[:first_stop] - 1e-6).any()


def test_without_regeneration_the_final_phase_meets_the_service_curves():
    train = regen_train()
    plain = dataclasses.replace(train, braking=dataclasses.replace(train.braking, regenerative=None))
    solver = SectionSolver(plain, lower_limit_route(), 0.0, 10_000.0)
    assert np.all(solver.final_curve_modes == codes.BRAKE)
    np.testing.assert_array_equal(solver.Cr_final, solver.Cr)
    np.testing.assert_array_equal(solver.US_final, solver.US)
