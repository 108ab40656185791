"""A stretch with a running-time disturbance is driven as one run: the fastest run under the speed cap
whose running time is the disturbed one. Its trace (positions and speeds over time), the blocking
times from it, and the energy reported are all that run's; the planned run is untouched."""

from __future__ import annotations

from dataclasses import replace
from itertools import pairwise
from pathlib import Path

import numpy as np
import pytest

from trainsim.constants import KWH
from trainsim.io.operation_file import read_operation
from trainsim.io.operation_run import run_operation
from trainsim.model import SpeedLimit
from trainsim.operations.blocking import Trajectory, route_release_points
from trainsim.operations.runs import CAP_TIME_TOLERANCE_S, RunCache, direction_route, service_route
from trainsim.sim.fastest import run_fastest

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "operations" / "metro_fixed_block.yaml"
pytestmark = pytest.mark.filterwarnings("ignore::UserWarning")
AUX_W = 80e3  # auxiliaries, so that standing and running longer both cost energy [W]


@pytest.fixture(scope="module")
def op():
    return read_operation(EXAMPLE)


def _with_aux(svc, aux_w: float = AUX_W):
    el = replace(svc.train.electrical, auxiliary_power_w=aux_w)
    return replace(svc, train=replace(svc.train, electrical=el))


def _stops_m(op, svc) -> list[float]:
    path = op.line.paths[svc.direction]
    names = (svc.origin, *(s.station for s in svc.stops), svc.destination)
    return [path.stop_m[n] for n in names]


def _piece(traj, p0: float, p1: float) -> slice:
    """The trace indices from leaving ``p0`` (its last point there) to arriving at ``p1`` (its first)."""
    a = int(np.flatnonzero(traj.position_m <= p0 + 1e-9)[-1])
    b = int(np.flatnonzero(traj.position_m >= p1 - 1e-9)[0])
    return slice(a, b + 1)


def _capped_run(op, svc, a_m: float, b_m: float, cap_mps: float | None):
    """The stretch's fastest run under ``cap_mps`` over all of it, computed afresh (no cache)."""
    route = direction_route(op.geometry, op.line.length_m, svc.direction)
    limits = [] if cap_mps is None else [SpeedLimit(a_m, b_m, cap_mps)]
    return run_fastest(svc.train, service_route(route, [("a", a_m), ("b", b_m)], limits), op.settings)


def test_the_trace_of_a_disturbed_stretch_is_a_capped_run_of_the_disturbed_time(op) -> None:
    extra = (20.0, 45.0, 8.0)
    svc = _with_aux(next(s for s in op.services if s.id == "D.1"))
    (plain,) = run_operation(op, [svc]).trains
    res = run_operation(op, [replace(svc, running_extra_s=extra)])
    (out,) = res.trains
    assert res.status == "ok" and out.status == "ok" and out.hindrances == []
    assert [d.status for d in out.disturbed] == ["ok"] * 3
    assert "disturbed" in out.to_dict() and not out.trajectory_note
    traj, plan = out.trajectory, out.planned_trajectory
    running = 0.0
    for k, ((p0, p1), x) in enumerate(zip(pairwise(_stops_m(op, svc)), extra, strict=True)):
        planned_s = np.ptp(plan.time_s[_piece(plan, p0, p1)])
        piece = _piece(traj, p0, p1)
        t, s, v = traj.time_s[piece], traj.position_m[piece], traj.speed_mps[piece]
        # the trace takes the disturbed running time
        assert t[-1] - t[0] == pytest.approx(planned_s + x, abs=1e-6)
        assert out.disturbed[k].running_time_s == pytest.approx(planned_s + x, abs=1e-9)
        # ... by its own speeds too: sum of ds / mean speed (exact for constant acceleration only)
        moving = v[:-1] + v[1:] > 0
        assert np.sum(2 * np.diff(s)[moving] / (v[:-1] + v[1:])[moving]) == pytest.approx(
            t[-1] - t[0], abs=5e-3
        )
        # it is the core's run under the reported cap, computed afresh: same points, same speeds
        cap = out.disturbed[k].cap_mps
        run = _capped_run(op, svc, p0, p1, cap)
        n = len(run.trace.position_m)
        np.testing.assert_array_equal(s[:n], run.trace.position_m)
        np.testing.assert_array_equal(v[:n], run.trace.speed_mps)
        np.testing.assert_allclose(t[:n] - t[0], run.trace.time_s - run.trace.time_s[0], rtol=0, atol=1e-9)
        assert run.running_time_s == pytest.approx(planned_s + x, abs=1e-6)
        assert np.max(v) == pytest.approx(cap, abs=1e-9)
        assert cap < np.max(plan.speed_mps[_piece(plan, p0, p1)])
        running += t[-1] - t[0]
        # the reported run of the stretch is that run: same energy
        assert out.runs[k].energy_kwh.net == pytest.approx(run.energy_kwh.net, rel=1e-12)
    # the energy reported is the energy along the reported trace: each run's net energy from the line
    # (its trace's cumulative electrical energy) plus the auxiliaries while standing in the trace
    standing_s = (traj.time_s[-1] - traj.time_s[0]) - running
    along = sum(r.trace.electrical_energy_j[-1] for r in out.runs) / KWH + AUX_W * standing_s / KWH
    assert out.energy_kwh == pytest.approx(along, rel=1e-6)
    # the plan is the undisturbed train's, bit for bit
    assert out.planned_energy_kwh == plain.energy_kwh == plain.planned_energy_kwh
    for name in ("time_s", "position_m", "speed_mps"):
        np.testing.assert_array_equal(getattr(plan, name), getattr(plain.trajectory, name))
    assert out.delay_s == pytest.approx(sum(extra), abs=1e-6)


def test_the_cap_is_found_to_the_tolerance_and_the_table_brackets_it(op) -> None:
    svc = next(s for s in op.services if s.id == "D.1")
    cache = RunCache(op.settings)
    directed = cache.directed(op.geometry, op.line.length_m, "down")
    p = _stops_m(op, svc)
    a, b = (svc.origin, p[0]), (svc.stops[0].station, p[1])
    caps, times, _e = cache.slowed(svc.train, directed, a, b)
    for target in (times[0] + 0.3, 0.5 * (times[2] + times[3]), times[-1] - 1.0):
        c = cache.capped(svc.train, directed, a, b, (), float(target))
        assert c.status == "ok" and c.hold_s == 0.0
        assert abs(c.running_time_s - target) <= CAP_TIME_TOLERANCE_S
        k = int(np.searchsorted(times, target))
        assert caps[k] < c.limit.limit_mps < caps[k - 1]
    # a table entry's own time gives its own cap
    c = cache.capped(svc.train, directed, a, b, (), float(times[4]))
    assert c.limit.limit_mps == pytest.approx(caps[4], rel=1e-9)
    # a disturbance below the tolerance is no disturbance
    c = cache.capped(svc.train, directed, a, b, (), float(times[0]) + 1e-9)
    assert c.limit is None and c.status == "undisturbed" and c.hold_s == 0.0
    (out,) = run_operation(op, [replace(svc, running_extra_s=(1e-9, 0.0, 0.0))]).trains
    assert [d.status for d in out.disturbed] == ["undisturbed"] and not out.warnings


def test_no_capped_run_takes_the_time_falls_back_to_a_stand_and_says_so(op) -> None:
    svc = _with_aux(next(s for s in op.services if s.id == "D.1"))
    outs = []
    for x in (1500.0, 2000.0):
        res = run_operation(op, [replace(svc, running_extra_s=(x, 0.0, 0.0))])
        (out,) = res.trains
        outs.append(out)
        (d,) = out.disturbed
        assert res.status == "ok" and d.status == "beyond_lowest_cap"
        assert d.hold_s == pytest.approx(d.running_time_s - d.driven_s, abs=1e-9) and d.hold_s > 0
        assert any("beyond_lowest_cap" in w and "standing" in w for w in res.warnings)
        assert "longer than any capped run" in out.energy_note
        # the stand is in the trace: the train leaves its origin later, then drives the lowest cap
        assert out.stops[0].departure_s - out.stops[0].scheduled_departure_s == pytest.approx(
            d.hold_s, abs=1e-6
        )
        traj = out.trajectory
        p0, p1 = _stops_m(op, svc)[:2]
        assert (
            traj.time_s[0] == out.stops[0].scheduled_departure_s and traj.position_m[1] == traj.position_m[0]
        )
        piece = _piece(traj, p0, p1)
        assert traj.time_s[piece.start] == pytest.approx(out.stops[0].departure_s, abs=1e-6)
        assert np.ptp(traj.time_s[piece]) == pytest.approx(d.driven_s, abs=1e-9)
        assert out.delay_s == pytest.approx(x, abs=1e-6)
        # the energy is the runs' along the trace plus the auxiliaries for every stand in it
        running = sum(r.running_time_s for r in out.runs)
        standing_s = np.ptp(traj.time_s) - running
        along = sum(r.trace.electrical_energy_j[-1] for r in out.runs) / KWH + AUX_W * standing_s / KWH
        assert out.energy_kwh == pytest.approx(along, rel=1e-6)
    # the 500 s between the two are standing: auxiliaries only
    assert outs[1].energy_kwh - outs[0].energy_kwh == pytest.approx(AUX_W * 500.0 / KWH, rel=1e-9)


def test_blocking_times_follow_the_capped_run_and_the_follower_sees_the_later_release(op) -> None:
    lead, follow = (s for s in op.services if s.id in ("U.1", "U.2"))
    extra = 120.0  # the leader crawls from S1 to S2: the follower meets its blocks in the stretch
    disturbed = [replace(lead, running_extra_s=(extra, 0.0, 0.0)), follow]
    res = run_operation(op, disturbed)
    scaled = run_operation(op, disturbed, disturbed_energy=False)
    base = run_operation(op, [lead, follow])
    assert res.status == scaled.status == base.status == "ok"
    leader = res.trains[0]
    (d,) = leader.disturbed
    p0, p1 = _stops_m(op, lead)[:2]
    run = _capped_run(op, lead, p0, p1, d.cap_mps)
    t0 = leader.stops[0].departure_s

    alone = Trajectory(run.trace.time_s + t0, run.trace.position_m, run.trace.speed_mps, lead.train.length_m)

    def at(x_m: float) -> float:  # when the independent capped run's head is at x_m
        return alone.first_time_s(x_m)

    sig = op.line.signalling
    blocks = {(b.route, b.resource): b for b in res.blocking if b.train == "U.1"}
    scaled_blocks = {(b.route, b.resource): b for b in scaled.blocking if b.train == "U.1"}
    checked, apart = 0, 0.0
    for _j, route in leader.routes:
        if not p0 + 1.0 < route.start_m < p1 - 1.0:
            continue
        for res_, point in zip(route.resources, route_release_points(route, sig.release), strict=True):
            head = point + lead.train.length_m
            if head >= p1:
                continue
            b = blocks[(route.name, res_.name)]
            assert b.entry_s == pytest.approx(at(route.start_m), abs=1e-6)
            assert b.clear_s == pytest.approx(at(head), abs=1e-6)
            assert b.end_s == pytest.approx(at(head) + sig.release_s, abs=1e-6)
            apart = max(apart, abs(b.clear_s - scaled_blocks[(route.name, res_.name)].clear_s))
            checked += 1
    assert checked >= 2
    assert apart > 1.0  # not the time-scaled trace's releases
    # the follower gets a route at the leader's later release, and is later than behind the plain leader
    mine = {b.resource: b for b in res.blocking if b.train == "U.1"}
    waits = [b for b in res.blocking if b.train == "U.2" and b.resource in mine]
    assert all(b.start_s >= mine[b.resource].end_s - 1e-6 for b in waits)
    assert any(abs(b.start_s - mine[b.resource].end_s) <= 1e-6 for b in waits)
    assert res.trains[1].hindrances and res.trains[1].delay_s > base.trains[1].delay_s + 1.0
    assert res.trains[1].delay_s != pytest.approx(scaled.trains[1].delay_s, abs=1.0)


def test_a_hindered_disturbed_train_keeps_its_cap_on_the_split_stretch(op) -> None:
    lead, follow = (s for s in op.services if s.id in ("U.1", "U.2"))
    res = run_operation(
        op,
        [replace(lead, running_extra_s=(120.0, 0.0, 0.0)), replace(follow, running_extra_s=(10.0, 0.0, 0.0))],
    )
    out = res.trains[1]
    (d,) = out.disturbed
    assert res.status == "ok" and d.status == "ok" and out.hindrances
    p0, p1 = _stops_m(op, follow)[:2]
    piece = _piece(out.trajectory, p0, p1)
    assert np.max(out.trajectory.speed_mps[piece]) <= d.cap_mps + 1e-9
    # stopped or slowed on the way: the stretch takes longer than the disturbed time
    assert np.ptp(out.trajectory.time_s[piece]) > d.running_time_s + 0.1


def test_delays_only_label_the_time_scaled_trajectory(op) -> None:
    svc = next(s for s in op.services if s.id == "D.1")
    disturbed = replace(svc, running_extra_s=(20.0, 45.0, 8.0))
    full = run_operation(op, [disturbed]).trains[0]
    quick = run_operation(op, [disturbed], disturbed_energy=False).trains[0]
    assert "time-scaled" in quick.trajectory_note and quick.to_dict()["trajectory_note"]
    assert [d.status for d in quick.disturbed] == ["time_scaled"] * 3
    assert np.isnan(quick.energy_kwh) and "not computed" in quick.energy_note
    assert not full.trajectory_note and np.isfinite(full.energy_kwh)
    # the same arrival either way (to the cap's tolerance), by different traces
    assert quick.delay_s == pytest.approx(full.delay_s, abs=1e-6)
    assert len(quick.trajectory.time_s) != len(full.trajectory.time_s) or not np.array_equal(
        quick.trajectory.speed_mps, full.trajectory.speed_mps
    )


def test_undisturbed_trains_and_plans_are_bit_for_bit_unchanged(op) -> None:
    up, down = (s for s in op.services if s.id in ("U.1", "D.1"))
    plain = run_operation(op, [up, down])
    mixed = run_operation(op, [replace(up, running_extra_s=(30.0, 0.0, 10.0)), down])
    assert mixed.trains[0].disturbed and not mixed.trains[1].disturbed
    before, after = plain.trains[1], mixed.trains[1]  # the down train, on its own track
    assert (after.energy_kwh, after.delay_s, after.stops) == (before.energy_kwh, before.delay_s, before.stops)
    for name in ("time_s", "position_m", "speed_mps"):
        np.testing.assert_array_equal(getattr(after.trajectory, name), getattr(before.trajectory, name))
        # the disturbed train's plan is its undisturbed run
        np.testing.assert_array_equal(
            getattr(mixed.trains[0].planned_trajectory, name), getattr(plain.trains[0].trajectory, name)
        )
    assert [b for b in mixed.blocking if b.train == "D.1"] == [b for b in plain.blocking if b.train == "D.1"]
    assert mixed.planned_blocking == plain.planned_blocking
