"""Operated trains on the network move as the operation ran them, approaches to signals included.

Regression (issue 18): the train held at a signal approached it under the operation's speed ceiling,
but the power simulation re-ran that movement as an unhindered fastest run and placed its power at
the operated times: the rerun was 7.4 s (earlier 13.2 s) shorter than the operated movement, so the
network saw the wrong power profile along it. The operation's own runs (``TrainOutcome.runs``) are
the movements; the loads must be them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from trainsim.io.operation_file import read_operation
from trainsim.io.operation_run import run_operation
from trainsim.io.power_file import operated_train_loads
from trainsim.operations.runs import direction_route, service_route
from trainsim.sim.fastest import run_fastest

ROOT = Path(__file__).resolve().parents[2]
OPERATION = ROOT / "examples" / "operations" / "metro_fixed_block.yaml"


@pytest.fixture(scope="module")
def operated():
    outcomes = {o.id: o for o in run_operation(read_operation(OPERATION)).trains}
    loads, info = operated_train_loads(OPERATION, {"up": "up", "down": "down"})
    return outcomes, loads, info


def test_every_movement_lasts_as_operated(operated):
    """Every movement, the held train's approach to its signal included, lasts as long on the
    network as in the operation (round-off only)."""
    _, _, info = operated
    held = next(t for t in info["trains"] if t["id"] == "after")
    assert held["movements"] == 4  # three stretches and the stop at the signal
    for t in info["trains"]:
        assert t["movement_time_mismatch_s"] < 1e-6, t


def test_the_approach_to_the_signal_asks_what_the_operation_ran(operated):
    """The held train's traction energy asked along its approach equals the integral of F v /
    eta_t over the operation's own run of that movement (trapezoidal in time on both sides), and
    the operation's run is the slower one: the ceiling was active, so a fastest rerun differs."""
    outcomes, loads, _ = operated
    outcome = outcomes["after"]
    load = next(ld for ld in loads if ld.id == "after")
    approach = outcome.runs[0]
    tr = approach.trace
    op = read_operation(OPERATION)
    svc = next(svc for svc in op.services if svc.id == "after")
    eta = svc.train.electrical.traction_efficiency
    directed = direction_route(op.geometry, op.line.length_m, "up")
    rerun = run_fastest(
        svc.train, service_route(directed, [("a", 0.0), ("b", tr.position_m[-1])]), op.settings
    )
    assert tr.time_s[-1] - tr.time_s[0] > rerun.trace.time_s[-1] - rerun.trace.time_s[0] + 1.0
    p_run = tr.traction_force_n * tr.speed_mps / eta
    e_run = float(np.sum(np.diff(tr.time_s) * (p_run[1:] + p_run[:-1]) / 2))
    end = tr.position_m[-1]
    on_approach = load.position_m <= end + 1e-9
    t, p = load.time_s[on_approach], load.traction_power_w[on_approach]
    e_load = float(np.sum(np.diff(t) * (p[1:] + p[:-1]) / 2))
    assert e_load == pytest.approx(e_run, rel=1e-9)
    # the load is at the signal when the operation says it stops there
    k = int(np.flatnonzero(load.position_m >= end - 1e-9)[0])
    traj = outcome.trajectory
    operated_stop = traj.time_s[int(np.flatnonzero(traj.position_m >= end - 1e-9)[0])]
    assert load.time_s[k] == pytest.approx(operated_stop, abs=1e-6)
