"""The optimal strategy's speed work (issue 16) changes how the solver searches, not what it finds.

* The final coasting point's search predicts the jump of the outcome (where a run that stops short by
  less than ``pk.REST_AT_STOP_M`` counts as arriving) by interpolating the last short runs and aims
  just short of it, instead of bisecting onto it: same coasting point to the search's own
  tolerance, same run, fewer final-phase runs.
* Departures ahead of descents searched once per solve (``_best_departure``'s memo) and W remembered
  by price of time: the solve is bit for bit the one that searches every time.

No timed asserts: the counts of kernel runs are deterministic.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from trainsim.io.ttobench import read_ttobench_track, read_ttobench_train
from trainsim.optimize import _pmp_c as pk
from trainsim.optimize import optimal
from trainsim.optimize.optimal import SectionSolver, regenerative_holding_speed

DATA = Path(__file__).resolve().parents[3] / "shared" / "data" / "ttobench"

pytestmark = pytest.mark.skipif(not (DATA / "tracks").is_dir(), reason="TTOBench data not available")


@pytest.fixture(scope="module")
def kiss_stadelhofen():
    """The KISS on CH_Stadelhofen_Altstetten's first section (1690 m, -38 to +28 per mille): steep
    descents with excursions, and a final coast that ends at the jump of the outcome."""
    tt = read_ttobench_train(DATA / "trains" / "CH_Stadler_KISS_SBB.json")
    route = read_ttobench_track(DATA / "tracks" / "CH_Stadelhofen_Altstetten.json", tt)
    s = [st.position_m for st in route.stations]
    return tt.train, route, s[0], s[1]


def _counting(monkeypatch) -> dict[str, int]:
    """Counts the final-phase runs of the solver (``pk.final_phase_modes``)."""
    count = {"runs": 0}
    original = pk.final_phase_modes

    def counted(*args):
        count["runs"] += 1
        return original(*args)

    monkeypatch.setattr(pk, "final_phase_modes", counted)
    return count


def test_coast_point_predicted_is_the_bisections(kiss_stadelhofen, monkeypatch):
    """The search predicts the jump from the last short runs; bisection onto it (written here, on
    the solver's own final-phase runs) finds the same point, hence the same run."""
    train, route, s0, s1 = kiss_stadelhofen
    V = 20.0
    count = _counting(monkeypatch)
    solver = SectionSolver(train, route, s0, s1)
    plan = solver.plan(V)
    runs = count["runs"]
    phase_a = solver._phase_a(V)

    def arrives(s_c: float) -> bool:
        return solver._phase_b(phase_a, s_c, plan.price_of_time_w, v_hold=V)[1] == pk.HIT_CEILING

    lo, hi = plan.coast_start_m - 1.0, plan.coast_start_m + 1.0
    assert not arrives(lo) and arrives(hi)
    while hi - lo > 0.25 * optimal.COAST_POINT_TOLERANCE_M:
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if arrives(mid) else (mid, hi)
    assert abs(plan.coast_start_m - hi) <= optimal.COAST_POINT_TOLERANCE_M
    points, _, _ = solver._phase_b(phase_a, hi, plan.price_of_time_w, v_hold=V)
    # 1e-9 m of coasting point moves the run by about 1e-11 relative
    assert plan.running_time_s == pytest.approx(points[2][-1], rel=1e-10)
    # 28 runs with the secant search before (aimed at the line's root, shortened after overshoots)
    assert runs <= 24, runs


def test_coast_point_sits_on_the_jump(kiss_stadelhofen):
    """From the coasting point found the run arrives; from just before it, it stops short by more
    than the kernel's rest tolerance: the point is the jump, located to COAST_POINT_TOLERANCE_M."""
    train, route, s0, s1 = kiss_stadelhofen
    solver = SectionSolver(train, route, s0, s1)
    V = 20.0
    plan = solver.plan(V)
    phase_a = solver._phase_a(V)
    _, status, s_event = solver._phase_b(phase_a, plan.coast_start_m, plan.price_of_time_w, v_hold=V)
    assert status == pk.HIT_CEILING and s_event == s1
    before = plan.coast_start_m - optimal.COAST_POINT_TOLERANCE_M
    _, status, s_event = solver._phase_b(phase_a, before, plan.price_of_time_w, v_hold=V)
    assert status == pk.STOPPED_SHORT
    assert s1 - s_event > pk.REST_AT_STOP_M
    assert s1 - s_event < 10 * pk.REST_AT_STOP_M  # the shortfall falls continuously to the jump


def test_remembered_departures_change_no_figure(kiss_stadelhofen, monkeypatch):
    train, route, s0, s1 = kiss_stadelhofen
    solver = SectionSolver(train, route, s0, s1)
    searched = {"n": 0}
    original = SectionSolver._search_departure

    def counted(self, *args):
        searched["n"] += 1
        return original(self, *args)

    monkeypatch.setattr(SectionSolver, "_search_departure", counted)
    T = solver.fastest_time_s * 1.1
    remembered = solver.solve(T)
    with_memo = searched["n"]

    def every_time(self, seg, p_lo, a, W, V, mu, key, v_rejoin, horizon=np.inf):
        return counted(self, seg, p_lo, a, W, V, mu, key, v_rejoin, horizon)

    monkeypatch.setattr(SectionSolver, "_best_departure", every_time)
    monkeypatch.setattr(
        SectionSolver,
        "_regenerative_holding_speed",
        lambda self, mu: regenerative_holding_speed(self.train, mu, self.eta_r),
    )
    searched["n"] = 0
    fresh = SectionSolver(train, route, s0, s1).solve(T)
    # this section's homotopy between departure choices repeats some searches
    assert with_memo < searched["n"], (with_memo, searched["n"])
    for name in ("s", "v", "t", "regime"):
        np.testing.assert_array_equal(getattr(remembered, name), getattr(fresh, name))
    assert remembered.running_time_s == fresh.running_time_s
    assert remembered.holding_speed_mps == fresh.holding_speed_mps
    assert solver.energy_j(remembered) == solver.energy_j(fresh)
