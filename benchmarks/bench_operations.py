"""A day of trains on a 100 km double-track line: simulation time and its growth with the number of
trains.

The line: 11 stations every 9.8 km, two platform tracks per direction (overtaking), 3-aspect fixed
block of at most 2.5 km, 160 km/h. The day: per direction, in turn an Intercity (TrainRuns.jl's IC2,
no intermediate stop) and a regional train (TrainRuns.jl's Desiro, stopping everywhere for 30 s), one
train every ``HEADWAY_S``, some of them late at entry (seeded). Figures are printed as ratios
against a baseline timed in the same run: one fastest run of the Intercity over the whole line.

Run: python benchmarks/bench_operations.py [--trains 1000] [--sizes 125,250,500,1000]
"""

from __future__ import annotations

import argparse
import time
import warnings
from pathlib import Path

import numpy as np

import trainsim
from trainsim import Route, RunSettings, SpeedLimit, Station
from trainsim.operations.line import Signalling, StationLayout, build_line
from trainsim.operations.simulate import ScheduledStop, TrainService, simulate

ROOT = Path(__file__).resolve().parents[1]
LENGTH_M = 100_000.0
HEADWAY_S = 144.0
#: alternate Intercity and regional trains (heavy overtaking: most regional trains are held)
MIXED = False  # 25 trains an hour per direction: 1,000 trains in 20 hours
SETTINGS = RunSettings(max_step_m=50)


def setup():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # TrainRuns.jl's documented braking default
        ic = trainsim.load_train(ROOT / "tests/data/trainruns/trains/longdistance.yaml")
        local = trainsim.load_train(ROOT / "tests/data/trainruns/trains/local.yaml")
    positions = [1000.0 + 9800.0 * k for k in range(11)]
    names = [f"S{k:02d}" for k in range(11)]
    geometry = Route("main line", 0.0, LENGTH_M, (), (SpeedLimit(0.0, LENGTH_M, 160 / 3.6),))
    stations = tuple(
        StationLayout(n, p, tracks=2, entry_signal_distance_m=600)
        for n, p in zip(names, positions, strict=True)
    )
    sig = Signalling(aspects=3, sighting_distance_m=300, overlap_m=100, setup_s=6, reaction_s=6, release_s=3)
    line = build_line("100 km main line", LENGTH_M, "double_track", stations, sig, block_length_m=2500)
    return ic, local, line, geometry, names, positions


def services(n: int, ic, local, names, seed: int = 1) -> list[TrainService]:
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        direction = "up" if k % 2 == 0 else "down"
        order = names if direction == "up" else names[::-1]
        i = k // 2
        fast = MIXED and i % 2 == 0
        delay = float(rng.exponential(60.0)) if rng.random() < 0.1 else 0.0
        stops = () if fast else tuple(ScheduledStop(s, 30.0) for s in order[1:-1])
        out.append(
            TrainService(
                f"{'IC' if fast else 'RB'}{k}",
                ic if fast else local,
                direction,
                order[0],
                order[-1],
                6 * 3600 + i * HEADWAY_S * 2,
                stops,
                priority=2 if fast else 1,
                entry_delay_s=delay,
            )
        )
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="125,250,500,1000")
    args = parser.parse_args()
    ic, local, line, geometry, names, positions = setup()
    route = Route(
        "baseline", 0.0, LENGTH_M, (Station("a", 1000.0), Station("b", positions[-1])), geometry.speed_limits
    )
    trainsim.run_fastest(ic, route, SETTINGS)  # warm-up (numba)
    t0 = time.perf_counter()
    for _ in range(20):
        trainsim.run_fastest(ic, route, SETTINGS)
    base = (time.perf_counter() - t0) / 20
    print(f"baseline: one fastest run of the Intercity over 98 km: {base * 1e3:.2f} ms")
    simulate(line, geometry, services(8, ic, local, names), SETTINGS)  # warm-up
    previous = None
    for n in [int(x) for x in args.sizes.split(",")]:
        svcs = services(n, ic, local, names)
        t0 = time.perf_counter()
        res = simulate(line, geometry, svcs, SETTINGS, rule="priority")
        wall = time.perf_counter() - t0
        hindered = sum(1 for t in res.trains if t.hindrances)
        growth = "" if previous is None else f", x{wall / previous[1]:.2f} for x{n / previous[0]:.1f} trains"
        print(
            f"{n:5d} trains: {wall:6.2f} s = {wall / base:8.0f} baseline runs ({wall / n * 1e3:.1f} ms/train{growth}); "
            f"status {res.status}, runs computed {res.runs_computed} / reused {res.runs_reused}, hindered {hindered}, "
            f"total delay {sum(t.delay_s for t in res.trains) / 60:.0f} min, conflicts {len(res.conflicts)}"
        )
        previous = (n, wall)


if __name__ == "__main__":
    main()
