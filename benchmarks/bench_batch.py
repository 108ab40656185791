"""Fastest runs per second of a batch study on the metro example, on 1 and 2 workers.

Run: python benchmarks/bench_batch.py [--runs N] [--repeat K] [--dask]

The study is a Monte Carlo over source 002's type B metro (examples/metro_b): passenger load per car
uniform in [0, 18] t and traction efficiency normal(0.9, 0.02), so that every run has its own train
(read and validated from its YAML data like any sweep value) and nothing is cached between runs. Every
run is a full fastest run with max_step_m 5 m (the example's setting), written to a Parquet dataset in
a temporary directory, as `trainsim batch` does.

Prints, for each executor and number of workers, the wall time from the call of run_study to the last
chunk written (worker start-up included, study expansion excluded), the rate in runs per second and the
CPU time per run (this process and its worker processes: the cost of a run whatever else the machine
is doing); then the parallel efficiency of 2 workers: rate(2) / (2 x rate(1)). The median of --repeat
repetitions is reported. Targets (issue 7): >= 500 runs/s on 2 cores, > 80 % efficiency.

Wall-clock figures only mean something on an otherwise idle machine: the load average is printed
before and after, with a warning when other processes were using the cores.
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import tempfile
import time
from pathlib import Path

from trainsim.batch import default_workers, run_study, study_from_dict

ROOT = Path(__file__).resolve().parents[1]


def make_study(runs: int):
    return study_from_dict(
        {
            "schema": "trainsim/study",
            "version": 1,
            "name": "bench: metro Monte Carlo",
            "base": str(ROOT / "examples" / "metro_b" / "scenario.yaml"),
            "samples": {
                "count": runs,
                "seed": 7,
                "fields": {
                    "train.formation[*].load_t": {"distribution": "uniform", "low": 0, "high": 18},
                    "train.electrical.traction_efficiency": {
                        "distribution": "normal",
                        "mean": 0.9,
                        "std": 0.02,
                        "max": 0.99,
                    },
                },
            },
        },
        "bench",
    )


def _cpu_s() -> float:
    """CPU time of this process and of its finished child processes [s]."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def measure(study, executor: str, workers: int, repeat: int) -> tuple[float, float, float, int, int]:
    """Median wall time [s], rate [runs/s] and CPU time per run [ms] over ``repeat`` fresh runs."""
    times, cpus = [], []
    for _ in range(repeat):
        with tempfile.TemporaryDirectory() as tmp:
            c0, t0 = _cpu_s(), time.perf_counter()
            outcome = run_study(study, Path(tmp) / "out", executor=executor, workers=workers)
            times.append(time.perf_counter() - t0)
            cpus.append(_cpu_s() - c0)  # the pool's processes have ended: their time is counted
            assert outcome.complete and outcome.failed == 0, outcome
    wall = statistics.median(times)
    cpu_ms = statistics.median(cpus) / outcome.computed * 1e3
    return wall, outcome.computed / wall, cpu_ms, outcome.chunk_size, outcome.chunks


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--runs", type=int, default=4000, help="runs of the study (default 4000)")
    parser.add_argument("--repeat", type=int, default=3, help="repetitions, median reported (default 3)")
    parser.add_argument("--dask", action="store_true", help="also on a local Dask cluster")
    args = parser.parse_args()

    study = make_study(args.runs)
    t0 = time.perf_counter()
    study.expand()
    expand_s = time.perf_counter() - t0
    run_study(make_study(50), None, executor="serial")  # warm-up: numba cache in this process
    load0 = os.getloadavg()[0]
    print(
        f"metro Monte Carlo, {args.runs} fastest runs; {default_workers()} cores available; "
        f"expansion {expand_s * 1e3:.0f} ms (not counted); load average {load0:.2f}"
    )
    print(
        f"{'executor':10s} {'workers':>7s} {'wall s':>8s} {'runs/s':>8s} {'CPU ms/run':>10s} "
        f"{'chunk':>6s} {'chunks':>6s}"
    )
    rates: dict[tuple[str, int], float] = {}
    cases = [("serial", 1), ("processes", 1), ("processes", 2)]
    if args.dask:
        cases += [("dask", 1), ("dask", 2)]
    for executor, workers in cases:
        wall, rate, cpu_ms, chunk, chunks = measure(study, executor, workers, args.repeat)
        rates[(executor, workers)] = rate
        print(f"{executor:10s} {workers:7d} {wall:8.2f} {rate:8.0f} {cpu_ms:10.2f} {chunk:6d} {chunks:6d}")
    one, two = rates[("processes", 1)], rates[("processes", 2)]
    print(
        f"processes: {two:.0f} runs/s on 2 workers (target >= 500), scaling 1 -> 2 workers "
        f"x{two / one:.2f}, parallel efficiency {two / (2 * one):.0%} (target > 80 %)"
    )
    if args.dask:
        d1, d2 = rates[("dask", 1)], rates[("dask", 2)]
        print(f"dask (local cluster start-up included): x{d2 / d1:.2f}, efficiency {d2 / (2 * d1):.0%}")
    load1 = os.getloadavg()[0]
    # an idle machine running this benchmark shows a load of about the number of workers
    if load0 > 0.5 or load1 > default_workers() + 0.5:
        print(
            f"WARNING: other processes were using the cores (load average {load0:.2f} before, {load1:.2f} "
            "after): the wall-clock figures are not representative; CPU ms/run still is"
        )


if __name__ == "__main__":
    main()
