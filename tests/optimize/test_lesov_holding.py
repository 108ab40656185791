"""Source 004's steady running is held through the end of every descent (issue 13).

The holding phase (``_pmp_c.holding_segment``) chose its regime by the sign of the force needed
to hold the speed at the point where the previous hold ended. A braking hold on a descent ends where
that force crosses 0, so there it is 0 to rounding: half the time the run coasted (or ran traction
clamped to the held speed) from there to the next grid point. On the heavy-haul line's first section
that moved the net energy by 1.7e-6 on halving the step, and made the running time jump by 1.4e-3 s
as the steady speed crossed a value, so that the schedule could only be met to 5.0e-4 s."""

from __future__ import annotations

import dataclasses
import warnings
from pathlib import Path

import numpy as np
import pytest

import trainsim
from trainsim.constants import KMH
from trainsim.optimize import _pmp_c as pk
from trainsim.optimize import lesov
from trainsim.optimize.optimal import SectionSolver
from trainsim.sim import _kernel_c, codes

ROOT = Path(__file__).resolve().parents[2]
#: the line's first section: descents that end on grades that need traction to hold the speed
SECTION_M = (0.0, 26_000.0)
#: steady speeds [km/h] below the 80 km/h limit, where phase A holds V on both kinds of grade
STEADY_KMH = (66.0, 68.7380266, 71.0)


@pytest.fixture(scope="module")
def heavy_haul():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scenario = trainsim.load_scenario(ROOT / "examples/heavy_haul/scenario_head.yaml")
    return lesov.lesov_train(scenario.train), scenario.route, scenario.settings


def _solver(heavy_haul, step_m: float) -> SectionSolver:
    train, route, settings = heavy_haul
    return SectionSolver(train, route, *SECTION_M, dataclasses.replace(settings, max_step_m=step_m))


def _phase_a(solver: SectionSolver, v_mps: float):
    """holding_segment as source 004 drives it: held and top speed both min(limit, V)."""
    tr = solver.track
    vhold = np.minimum(tr.vlim, v_mps)
    Cr, _, US = _kernel_c.braking_ceiling(
        tr.x, tr.a0, tr.a1, tr.b0, tr.b1, vhold, solver.i0, solver.i1, solver.P, solver.curves, solver.bk
    )
    modes = np.full(len(tr.a0), codes.BRAKE, dtype=np.int64)
    out = [np.empty(solver.n_max) for _ in range(3)] + [np.empty(solver.n_max, dtype=np.int8)]
    n, status = pk.holding_segment(
        tr.x, tr.a0, tr.a1, tr.b0, tr.b1, vhold, vhold, tr.traction_scale, solver.i0, solver.i1,
        solver.P, solver.curves, solver.tk, solver.bk, solver.rk, Cr, US, modes, *out,
    )  # fmt: skip
    assert status == 0
    s, v, _, m = (a[:n] for a in out)
    i = np.clip(np.searchsorted(tr.x, s, side="right") - 1, solver.i0, solver.i1 - 1)
    return s, v, m, vhold[i]


@pytest.mark.parametrize("v_kmh", STEADY_KMH)
def test_the_held_speed_is_held_where_a_descent_ends(heavy_haul, v_kmh):
    s, v, m, vh = _phase_a(_solver(heavy_haul, 20.0), v_kmh * KMH)
    assert np.any(m == codes.CRUISE)
    steps = slice(0, len(s) - 1)
    # with held speed = top speed nothing calls for coasting
    assert not np.any(m[steps] == codes.COAST), s[steps][m[steps] == codes.COAST]
    # maximum traction from the held speed only where holding it needs more (a climb): the speed falls
    at_hold = (m[steps] == codes.TRACTION) & (np.abs(v[:-1] - vh[:-1]) <= 1e-9 * vh[:-1]) & (s[1:] > s[:-1])
    assert np.all(v[1:][at_hold] < v[:-1][at_hold] - 1e-9), s[:-1][at_hold]
    # and every hold is at the held speed itself, not at a speed it drifted to by coasting
    held = m[steps] == codes.CRUISE
    assert np.allclose(v[:-1][held], vh[:-1][held], rtol=1e-12, atol=0.0)


@pytest.mark.parametrize("v_kmh", STEADY_KMH)
def test_the_regime_switches_do_not_move_with_the_step(heavy_haul, v_kmh):
    switches = []
    for step_m in (20.0, 10.0):
        s, _, m, _ = _phase_a(_solver(heavy_haul, step_m), v_kmh * KMH)
        k = np.flatnonzero(np.diff(m) != 0) + 1
        switches.append((s[k], m[k - 1], m[k]))
    (s_a, from_a, to_a), (s_b, from_b, to_b) = switches
    assert len(s_a) == len(s_b), (s_a, s_b)
    assert np.array_equal(from_a, from_b) and np.array_equal(to_a, to_b)
    # events of the motion, located as such (1e-7 m where they meet a braking curve)
    assert np.max(np.abs(s_a - s_b)) < 1e-6
