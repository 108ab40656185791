"""The optimiser runs on compiled code only (issue 14): importing it loads no numba, and the compiled
final phase checks its arrays at entry, naming the argument, instead of reading past them."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

import trainsim
from trainsim.optimize import _pmp_c
from trainsim.optimize.optimal import ADJOINT_STEP_M, SectionSolver


def test_importing_the_optimizer_loads_no_numba() -> None:
    code = (
        "import sys, trainsim.optimize.api, trainsim.optimize.optimal, trainsim.optimize.lesov, "
        "trainsim.optimize.windows, trainsim.optimize.regime_rules; print('numba' in sys.modules)"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120
    )
    assert out.stdout.strip() == "False"


@pytest.fixture(scope="module")
def solver() -> SectionSolver:
    sc = trainsim.load_scenario("examples/metro_b/scenario.yaml")
    stops = [s.position_m for s in sc.route.stations]
    return SectionSolver(sc.train, sc.route, stops[0], stops[1])


def _final_phase_args(solver: SectionSolver, out_m: np.ndarray) -> tuple:
    tr = solver.track
    n_max = len(out_m)
    i0, i1 = solver.i0, solver.i1
    return (
        tr.x, tr.a0, tr.a1, tr.b0, tr.b1, tr.vlim, tr.traction_scale, i0, 0.0, 10.0, 0.0, i1,
        solver.P, solver.curves, solver.tk, solver.bk, solver.Cr_final, solver.US_final, 1e4,
        solver.inv_eta_t, solver.eta_r, solver.has_regen, ADJOINT_STEP_M, np.empty(n_max), np.empty(n_max), np.empty(n_max),
        out_m, 0, -1, np.inf, -1.0, solver.final_curve_modes, solver.rk, -1.0, np.inf,
    )  # fmt: skip


def test_the_final_phase_runs_to_the_stop_and_checks_its_arrays(solver) -> None:
    n, status, pos, _, _ = _pmp_c.final_phase_modes(*_final_phase_args(solver, np.empty(4000, dtype=np.int8)))
    assert status in (_pmp_c.HIT_CEILING, _pmp_c.STOPPED_SHORT) and n > 2
    assert pos <= solver.track.x[solver.i1] + 1e-9
    with pytest.raises(ValueError, match="out_m"):
        _pmp_c.final_phase_modes(*_final_phase_args(solver, np.empty(4000, dtype=np.int64)))
