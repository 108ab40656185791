"""The optimal strategy's helpers made cheaper for issue 16 give what the versions they replaced gave.

``_interval_of`` (Python's min and max instead of np.clip on a scalar), ``_back_at`` (only the run's
points from the position asked on, first a short window), ``_holding_cost`` (the grid points between
two positions by bisection instead of a mask over the whole grid) and ``_energy_to`` given the state
its caller already has: each against the version it replaced (written here), on runs of a hilly
section, and a whole solve with the replaced versions patched in against the solve as it is, bit for
bit. No timed asserts.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from trainsim.io.ttobench import read_ttobench_track, read_ttobench_train
from trainsim.optimize import _pmp_c as pk
from trainsim.optimize.optimal import SectionSolver
from trainsim.sim import codes

DATA = Path(__file__).resolve().parents[3] / "shared" / "data" / "ttobench"

pytestmark = pytest.mark.skipif(not (DATA / "tracks").is_dir(), reason="TTOBench data not available")


def _interval_of_replaced(self, s_m: float) -> int:
    tr = self.track
    return int(np.clip(np.searchsorted(tr.x, s_m, side="right") - 1, 0, len(tr.a0) - 1))


def _back_at_replaced(seg, after: float, V: float) -> float:
    s, v, _, m = seg
    tol = 1e-6 * max(V, 1.0)
    holding = np.flatnonzero((s >= after - 1e-9) & (m == codes.CRUISE) & (np.abs(v - V) <= tol))
    if not len(holding):
        return after
    j = int(holding[0])
    if j > 0 and m[j - 1] == codes.CRUISE and abs(v[j - 1] - V) <= tol and s[j - 1] <= after:
        return after
    return float(s[j])


def _holding_cost_replaced(self, a: float, b: float, V: float) -> tuple[float, float]:
    if b <= a + 1e-9:
        return 0.0, 0.0
    tr = self.track
    inner = tr.x[(tr.x > a) & (tr.x < b)]
    s = np.concatenate([[a], inner, [b]])
    v = np.full(len(s), V)
    m = np.full(len(s), codes.CRUISE, dtype=np.int8)
    cum = np.empty(len(s))
    pk.path_energy(
        s, v, m, tr.x, tr.a0, tr.a1, tr.b0, tr.b1, tr.traction_scale, self.P, self.curves,
        self.inv_eta_t, self.eta_r, cum, self.tk, self.bk, self.rk,
    )  # fmt: skip
    return float(cum[-1]), (b - a) / V


@pytest.fixture(scope="module")
def flirt_stadelhofen():
    """The FLIRT on CH_Stadelhofen_Altstetten 1690-3530 m: descents with excursions (the run's
    departures and holds that ``_back_at`` and ``_holding_cost`` are asked about) and lower limits."""
    tt = read_ttobench_train(DATA / "trains" / "CH_Stadler_FLIRT_TPF.json")
    route = read_ttobench_track(DATA / "tracks" / "CH_Stadelhofen_Altstetten.json", tt)
    s = [st.position_m for st in route.stations]
    solver = SectionSolver(tt.train, route, s[1], s[2])
    plan = solver.plan(22.0)
    return tt.train, route, s[1], s[2], solver, plan


def _positions(solver: SectionSolver, plan) -> np.ndarray:
    """Grid points, the run's points, points between them and beyond both ends of the section."""
    x = solver.track.x
    mids = 0.5 * (plan.s[1:] + plan.s[:-1])
    rng = np.random.default_rng(16)
    inside = rng.uniform(solver.s0, solver.s1, 200)
    return np.concatenate([x, x + 1e-12, x - 1e-12, plan.s, mids, inside, [-1e3, solver.s1 + 5.0]])


def test_interval_of_is_the_replaced(flirt_stadelhofen):
    *_, solver, plan = flirt_stadelhofen
    for s_m in _positions(solver, plan):
        assert solver._interval_of(float(s_m)) == _interval_of_replaced(solver, float(s_m)), s_m


def test_back_at_is_the_replaced(flirt_stadelhofen):
    *_, solver, plan = flirt_stadelhofen
    runs = [
        (plan.s, plan.v, plan.t, plan.regime),
        solver._phase_a(plan.holding_speed_mps),
        solver.fastest,
    ]
    held = 0
    for seg in runs:
        assert np.all(np.diff(seg[0]) >= 0.0)  # what the window relies on
        speeds = {plan.holding_speed_mps, *map(float, seg[1][seg[3] == codes.CRUISE][:5])}
        for V in speeds:
            for after in _positions(solver, plan):
                got = SectionSolver._back_at(seg, float(after), V)
                assert got == _back_at_replaced(seg, float(after), V), (after, V)
                held += got != after
    assert held > 100  # the holds were found, not only the fallback ``after``


def test_holding_cost_is_the_replaced(flirt_stadelhofen):
    *_, solver, plan = flirt_stadelhofen
    x = solver.track.x
    positions = _positions(solver, plan)
    positions = positions[(positions >= solver.s0) & (positions <= solver.s1)]
    rng = np.random.default_rng(7)
    pairs = [(float(a), float(b)) for a, b in zip(positions, rng.permutation(positions), strict=True)]
    pairs += [(float(x[k]), float(x[k + 3])) for k in range(0, len(x) - 3, 5)]  # ends on grid points
    for a, b in pairs:
        for V in (plan.holding_speed_mps, 15.0):
            assert solver._holding_cost(a, b, V) == _holding_cost_replaced(solver, a, b, V), (a, b, V)


def test_energy_to_with_the_callers_state(flirt_stadelhofen):
    *_, solver, plan = flirt_stadelhofen
    tr = solver.track
    seg = solver._phase_a(plan.holding_speed_mps)
    cum = np.empty(len(seg[0]))
    pk.path_energy(
        seg[0], seg[1], seg[3], tr.x, tr.a0, tr.a1, tr.b0, tr.b1, tr.traction_scale, solver.P,
        solver.curves, solver.inv_eta_t, solver.eta_r, cum, solver.tk, solver.bk, solver.rk,
    )  # fmt: skip
    for s_m in _positions(solver, plan):
        s_m = float(min(max(s_m, solver.s0), solver.s1))
        state = solver._state_at(seg, s_m)
        assert solver._energy_to(seg, cum, s_m, state) == solver._energy_to(seg, cum, s_m)
    # the two-point stretch against path_energy on fresh arrays (the buffers are reused)
    s_m = 0.5 * (seg[0][3] + seg[0][4])
    _, _, v, _, j = solver._state_at(seg, s_m)
    out = np.empty(2)
    pk.path_energy(
        np.array([seg[0][j], s_m]), np.array([seg[1][j], v]), np.array([seg[3][j]] * 2, dtype=np.int8),
        tr.x, tr.a0, tr.a1, tr.b0, tr.b1, tr.traction_scale, solver.P, solver.curves, solver.inv_eta_t,
        solver.eta_r, out, solver.tk, solver.bk, solver.rk,
    )  # fmt: skip
    assert solver._energy_to(seg, cum, s_m) == float(cum[j]) + float(out[1])


def test_solve_is_the_replaced_helpers_solve(flirt_stadelhofen, monkeypatch):
    """The whole solve, bit for bit, with the replaced helpers patched in."""
    train, route, s0, s1, *_ = flirt_stadelhofen
    solver = SectionSolver(train, route, s0, s1)
    T = solver.fastest_time_s * 1.1
    now = solver.solve(T)
    monkeypatch.setattr(SectionSolver, "_interval_of", _interval_of_replaced)
    monkeypatch.setattr(SectionSolver, "_back_at", staticmethod(_back_at_replaced))
    monkeypatch.setattr(SectionSolver, "_holding_cost", _holding_cost_replaced)
    before = SectionSolver(train, route, s0, s1).solve(T)
    for name in ("s", "v", "t", "regime"):
        np.testing.assert_array_equal(getattr(now, name), getattr(before, name))
    assert now.running_time_s == before.running_time_s
    assert now.holding_speed_mps == before.holding_speed_mps
    assert now.coast_start_m == before.coast_start_m
    assert abs(now.running_time_s - T) <= 1e-8
