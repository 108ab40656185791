"""Wall time per fastest run after warm-up, for every shipped example and the TrainRuns.jl
freight train on the 101.8 km `realworld` path.

Run: python benchmarks/bench_fastest.py [--repeat N]
Prints one line per case: median and best wall time per run, trace points, running time.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import trainsim
from trainsim.io.loader import load_route, load_train
from trainsim.model.scenario import RunSettings, Scenario

ROOT = Path(__file__).resolve().parents[1]
TRAINRUNS = ROOT.parent / "shared" / "data" / "trainruns"


def cases() -> list[tuple[str, Scenario]]:
    out = []
    for scenario_file in sorted((ROOT / "examples").glob("*/scenario.yaml")):
        out.append((scenario_file.parent.name, trainsim.load_scenario(scenario_file)))
    if TRAINRUNS.exists():
        train = load_train(TRAINRUNS / "trains" / "freight.yaml")
        for mass_model in ("mass_point", "homogeneous_strip"):
            route = load_route(TRAINRUNS / "paths" / "realworld.yaml", mass_model=mass_model)
            out.append(
                (
                    f"trainruns freight realworld ({mass_model})",
                    Scenario("bench", train, route, RunSettings()),
                )
            )
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeat", type=int, default=30)
    args = parser.parse_args()
    print(f"{'case':48s} {'median ms':>10s} {'best ms':>9s} {'points':>7s} {'run time s':>11s} {'km':>7s}")
    for name, scenario in cases():
        trainsim.run(scenario)  # warm-up: numba compilation and caches
        times = []
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            result = trainsim.run(scenario)
            times.append(time.perf_counter() - t0)
        print(
            f"{name:48s} {statistics.median(times) * 1e3:10.2f} {min(times) * 1e3:9.2f} "
            f"{len(result.trace):7d} {result.running_time_s:11.1f} {result.distance_m / 1000:7.1f}"
        )


if __name__ == "__main__":
    main()
