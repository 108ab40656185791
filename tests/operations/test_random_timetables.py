"""Seeded random lines and timetables: every one ends (ok, conflicts or deadlock), never with an internal
error, and its summary is valid JSON. The invariants (finite trajectories, no resource held by two
trains at once) are checked inside ``simulate`` on every run."""

from __future__ import annotations

import json

import numpy as np
import pytest

import trainsim
from trainsim import Route, RunSettings, SpeedLimit
from trainsim.errors import InputError
from trainsim.operations.line import Signalling, StationLayout, build_line
from trainsim.operations.simulate import ScheduledStop, TrainService, simulate


@pytest.fixture(scope="module")
def train() -> trainsim.Train:
    return trainsim.load_train("examples/metro_b/train.yaml")


@pytest.mark.parametrize("seed", range(12))
def test_random_timetable_ends_with_a_status(train, seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 6))
    pos = np.concatenate([[800.0], 800.0 + np.cumsum(rng.uniform(1500, 4000, n - 1))])
    length = float(pos[-1] + 800)
    names = [f"S{i}" for i in range(n)]
    layout = "single_track" if seed % 2 else "double_track"
    stations = tuple(
        StationLayout(name, float(p), tracks=int(rng.integers(1, 4)), entry_signal_distance_m=300)
        for name, p in zip(names, pos, strict=True)
    )
    system = ("fixed_block", "moving_block")[seed % 3 == 0]
    sig = Signalling(
        system=system,
        aspects=int(rng.integers(2, 5)),
        release=("sectional", "whole_route")[int(rng.integers(0, 2))],
        overlap_m=0.0 if system == "moving_block" else 50.0,
        distant_distance_m=500.0,
    )
    line = build_line("random", length, layout, stations, sig, block_length_m=float(rng.uniform(500, 1500)))
    geometry = Route("geo", 0, length, (), (SpeedLimit(0, length, 80 / 3.6),))
    services = []
    for k in range(int(rng.integers(2, 10))):
        direction = "up" if rng.random() < 0.5 else "down"
        order = names if direction == "up" else names[::-1]
        i0 = int(rng.integers(0, n - 1))
        i1 = int(rng.integers(i0 + 1, n))
        stops = tuple(
            ScheduledStop(order[i], float(rng.uniform(0, 40)))
            for i in range(i0 + 1, i1)
            if rng.random() < 0.6
        )
        delay = float(rng.exponential(60)) if rng.random() < 0.3 else 0.0
        services.append(
            TrainService(
                f"t{k}",
                train,
                direction,
                order[i0],
                order[i1],
                float(rng.uniform(0, 900)),
                stops,
                priority=int(rng.integers(0, 3)),
                entry_delay_s=delay,
            )
        )
    rule = ("fcfs", "priority")[seed % 2]
    try:
        res = simulate(
            line, geometry, services, RunSettings(max_step_m=25), rule=rule, lookahead_s=120.0 * (seed % 2)
        )
    except InputError:  # e.g. a train longer than a platform: a clear error is an allowed outcome
        return
    assert res.status in ("ok", "conflicts", "deadlock")
    assert (res.status == "deadlock") == bool(res.deadlock)
    json.dumps(res.summary(), allow_nan=False)
    for t in res.trains:
        if t.status == "ok":
            assert t.delay_s >= -1e-6 or t.stops[-1].scheduled_arrival_s is None
