"""The operated energy of a stretch with a running-time disturbance is that of a slower run of the
disturbed running time (the fastest run under a lower speed cap), not the undisturbed run's; the
fallback where no capped run takes the time: tests/operations/test_disturbed_runs.py."""

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
from trainsim.operations.runs import direction_route, service_route
from trainsim.sim.fastest import run_fastest

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "operations" / "metro_fixed_block.yaml"
pytestmark = pytest.mark.filterwarnings("ignore::UserWarning")


def _lone_down_train(extra_s: tuple[float, ...], auxiliary_power_w: float = 0.0):
    """The example's lone down train (nobody hinders it), with running-time disturbances ``extra_s``
    and auxiliaries drawing ``auxiliary_power_w`` [W]."""
    op = read_operation(EXAMPLE)
    svc = next(s for s in op.services if s.direction == "down")
    train = replace(svc.train, electrical=replace(svc.train.electrical, auxiliary_power_w=auxiliary_power_w))
    return op, replace(svc, train=train, running_extra_s=extra_s)


def _capped_run_of_time(train, route, a_m: float, b_m: float, target_s: float, settings):
    """The fastest run of ``route`` under a cap over the whole of it whose running time is
    ``target_s`` [s], found by bisection on the cap (to 1e-9 m/s: independent of the simulation's
    root-find)."""
    lo, hi = 0.5, 40.0
    while hi - lo > 1e-9:
        cap = 0.5 * (lo + hi)
        run = run_fastest(train, service_route(route, [("a", a_m), ("b", b_m)], [SpeedLimit(a_m, b_m, cap)]),
                          settings, trace=False)  # fmt: skip
        if run.running_time_s > target_s:
            lo = cap
        else:
            hi = cap
    return run


@pytest.mark.parametrize("aux_w", [0.0, 80e3])
def test_disturbed_energy_is_that_of_a_capped_run_of_the_disturbed_time(aux_w: float) -> None:
    extra = (20.0, 45.0, 8.0)
    op, svc = _lone_down_train(extra, aux_w)
    plain = next(t for t in run_operation(op, [replace(svc, running_extra_s=())]).trains)
    res = run_operation(op, [svc])
    (out,) = res.trains
    assert res.status == "ok" and out.status == "ok"
    # independently: each stretch's fastest run and the capped run that takes the disturbed time
    path = op.line.paths["down"]
    stops_m = [
        path.stop_m[svc.origin],
        *(path.stop_m[s.station] for s in svc.stops),
        path.stop_m[svc.destination],
    ]
    route = direction_route(op.geometry, op.line.length_m, "down")
    expected_delta = 0.0
    for (a_m, b_m), x in zip(pairwise(stops_m), extra, strict=True):
        fast = run_fastest(
            svc.train, service_route(route, [("a", a_m), ("b", b_m)]), op.settings, trace=False
        )
        slow = _capped_run_of_time(svc.train, route, a_m, b_m, fast.running_time_s + x, op.settings)
        assert slow.running_time_s == pytest.approx(fast.running_time_s + x, abs=1e-6)
        assert slow.energy_kwh.net < fast.energy_kwh.net  # slower: less energy on this line
        # the auxiliaries run the longer time too
        assert slow.energy_kwh.auxiliary == pytest.approx(aux_w * slow.running_time_s / KWH, rel=1e-6)
        expected_delta += slow.energy_kwh.net - fast.energy_kwh.net
    # the standing times are the same (no extra dwell): the whole difference is the slower running,
    # the capped runs' own energies (no interpolation)
    assert out.energy_kwh - plain.energy_kwh == pytest.approx(expected_delta, rel=1e-6)
    assert out.planned_energy_kwh == plain.energy_kwh  # the plan has no disturbance
    assert "running-time disturbances" in out.energy_note and not plain.energy_note
    assert "energy_note" in out.to_dict() and "energy_note" not in plain.to_dict()


def test_the_capped_runs_of_a_stretch_get_slower_and_start_at_the_undisturbed_run() -> None:
    op, svc = _lone_down_train(())
    from trainsim.operations.runs import SLOWED_CAP_FRACTIONS, RunCache

    cache = RunCache(op.settings)
    directed = cache.directed(op.geometry, op.line.length_m, "down")
    path = op.line.paths["down"]
    a = (svc.origin, path.stop_m[svc.origin])
    b = (svc.stops[0].station, path.stop_m[svc.stops[0].station])
    caps, times, energies = cache.slowed(svc.train, directed, a, b)
    _s, v, t, fast = cache.stretch(svc.train, directed, a, b)
    assert caps[0] == np.max(v) and times[0] == t[-1] - t[0] and energies[0] == fast.energy_kwh.net
    assert len(times) == len(SLOWED_CAP_FRACTIONS) and np.all(np.diff(times) > 0)
    assert caps[1:] == pytest.approx(np.max(v) * np.array(SLOWED_CAP_FRACTIONS[1:]), rel=1e-12)
    # slower runs draw less on this line (less braking of what traction put in)
    assert np.all(np.diff(energies[:5]) < 0)
