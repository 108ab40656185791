"""Fastest runs per second of a batch study on the metro example, on 1 and 2 workers.

Run: python benchmarks/bench_batch.py [--runs N] [--repeat K] [--dask] [--driving] [--multipoint]

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

With --driving the runs are energy-efficient runs instead (examples/metro_b/scenario_eco.yaml: the
optimal strategy, 10 m steps) with the line supplement drawn from 5, 10, 15 and 20 % as well, and the
cost of the same run by trainsim.run alone is printed for comparison (the batch overhead per run);
--runs defaults to 100 there.

With --multipoint the study is examples/studies/heavy_haul_couplers.yaml (12 multi-point runs of
seconds each) on 1 and 2 worker processes with the automatic chunks (one run per chunk: sized by the
predicted cost of a run) and, as the baseline of the same run, on 2 workers with chunks of 10 runs (the
[10, 2] split of the chunking that ignored the cost); prints the speed-ups (target x1.8).

Wall-clock figures only mean something on an otherwise idle machine: the share of the cores used by
other processes during each measurement (all CPU time counted by the kernel in /proc/stat, less this
benchmark's own) is printed, with a warning above 5 %.
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


def make_study(runs: int, driving: bool = False):
    fields = {
        "train.formation[*].load_t": {"distribution": "uniform", "low": 0, "high": 18},
        "train.electrical.traction_efficiency": {
            "distribution": "normal",
            "mean": 0.9,
            "std": 0.02,
            "max": 0.99,
        },
    }
    if driving:
        fields["driving.supplement"] = {"distribution": "choice", "values": ["5%", "10%", "15%", "20%"]}
    scenario = "scenario_eco.yaml" if driving else "scenario.yaml"
    return study_from_dict(
        {
            "schema": "trainsim/study",
            "version": 1,
            "name": "bench: metro Monte Carlo" + (", optimal driving" if driving else ""),
            "base": str(ROOT / "examples" / "metro_b" / scenario),
            "samples": {"count": runs, "seed": 7, "fields": fields},
        },
        "bench",
    )


def single_run_ms(repeat: int = 5) -> float:
    """Median time of trainsim.run on the energy-efficient example scenario [ms]."""
    import trainsim

    scenario = trainsim.load_scenario(ROOT / "examples" / "metro_b" / "scenario_eco.yaml")
    trainsim.run(scenario)  # warm-up
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        trainsim.run(scenario)
        times.append(time.perf_counter() - t0)
    return statistics.median(times) * 1e3


def _cpu_s() -> float:
    """CPU time of this process and of its finished child processes [s]."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def _machine_busy_s() -> float:
    """CPU time used on the whole machine since boot, all cores [s] (Linux; 0 elsewhere)."""
    try:
        with open("/proc/stat") as fh:
            fields = [int(x) for x in fh.readline().split()[1:]]
    except OSError:
        return 0.0
    user, nice, system, _idle, _iowait, irq, softirq, steal = fields[:8]
    return (user + nice + system + irq + softirq + steal) / os.sysconf("SC_CLK_TCK")


def measure(
    study, executor: str, workers: int, repeat: int, chunk_size: int | None = None
) -> dict[str, float]:
    """Median wall time [s], rate [runs/s], CPU time per run [ms] and the share of the cores used by
    other processes over ``repeat`` fresh runs."""
    times, cpus, others = [], [], []
    for _ in range(repeat):
        with tempfile.TemporaryDirectory() as tmp:
            c0, m0, t0 = _cpu_s(), _machine_busy_s(), time.perf_counter()
            outcome = run_study(
                study, Path(tmp) / "out", executor=executor, workers=workers, chunk_size=chunk_size
            )
            wall = time.perf_counter() - t0
            ours = _cpu_s() - c0  # the pool's processes have ended: their time is counted
            times.append(wall)
            cpus.append(ours)
            others.append(max(0.0, _machine_busy_s() - m0 - ours) / (wall * default_workers()))
            assert outcome.complete and outcome.failed == 0, outcome
    wall = statistics.median(times)
    return {
        "wall": wall,
        "rate": outcome.computed / wall,
        "cpu_ms": statistics.median(cpus) / outcome.computed * 1e3,
        "others": max(others),
        "chunk": outcome.chunk_size,
        "chunks": outcome.chunks,
        "sizes": outcome.chunk_sizes,
    }


def multipoint(repeat: int) -> None:
    """heavy_haul_couplers on 1 and 2 workers: cost-sized chunks against chunks of 10 runs."""
    from trainsim.batch import load_study

    study = load_study(ROOT / "examples" / "studies" / "heavy_haul_couplers.yaml")
    load = os.getloadavg()[0]
    print(f"{study.name}: {len(study.expand())} multi-point runs; load average {load:.1f}")
    print(f"{'case':34s} {'wall s':>8s} {'CPU s/run':>9s} {'chunks':>20s} {'others':>7s}")
    rows = {}
    for name, workers, chunk in (
        ("baseline: 2 workers, chunks of 10", 2, 10),
        ("1 worker, cost-sized chunks", 1, None),
        ("2 workers, cost-sized chunks", 2, None),
    ):
        m = measure(study, "processes", workers, repeat, chunk)
        rows[name] = m["wall"]
        sizes = ",".join(str(n) for n in m["sizes"])
        print(f"{name:34s} {m['wall']:8.1f} {m['cpu_ms'] / 1e3:9.2f} {sizes:>20s} {m['others']:7.0%}")
    one = rows["1 worker, cost-sized chunks"]
    print(
        f"speed-up 1 -> 2 workers: x{one / rows['2 workers, cost-sized chunks']:.2f} with cost-sized chunks "
        f"(target x1.8), x{one / rows['baseline: 2 workers, chunks of 10']:.2f} with chunks of 10"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument(
        "--runs", type=int, default=None, help="runs of the study (default 4000, 100 with --driving)"
    )
    parser.add_argument("--repeat", type=int, default=3, help="repetitions, median reported (default 3)")
    parser.add_argument("--dask", action="store_true", help="also on a local Dask cluster")
    parser.add_argument(
        "--driving", action="store_true", help="energy-efficient runs (optimal strategy, supplements)"
    )
    parser.add_argument(
        "--multipoint", action="store_true", help="the 12 multi-point runs of heavy_haul_couplers.yaml"
    )
    args = parser.parse_args()
    if args.multipoint:
        multipoint(args.repeat)
        return
    runs = args.runs or (100 if args.driving else 4000)

    study = make_study(runs, args.driving)
    t0 = time.perf_counter()
    study.expand()
    expand_s = time.perf_counter() - t0
    run_study(make_study(10 if args.driving else 50, args.driving), None, executor="serial")  # warm-up
    what = "energy-efficient (optimal) runs" if args.driving else "fastest runs"
    print(
        f"metro Monte Carlo, {runs} {what}; {default_workers()} cores available; "
        f"expansion {expand_s * 1e3:.0f} ms (not counted)"
    )
    if args.driving:
        print(f"trainsim.run of the example scenario alone: {single_run_ms():.1f} ms per run")
    print(
        f"{'executor':10s} {'workers':>7s} {'wall s':>8s} {'runs/s':>8s} {'CPU ms/run':>10s} "
        f"{'chunk':>6s} {'chunks':>6s} {'others':>7s}"
    )
    busiest = 0.0
    rates: dict[tuple[str, int], float] = {}
    cases = [("serial", 1), ("processes", 1), ("processes", 2)]
    if args.dask:
        cases += [("dask", 1), ("dask", 2)]
    for executor, workers in cases:
        m = measure(study, executor, workers, args.repeat)
        rates[(executor, workers)] = m["rate"]
        busiest = max(busiest, m["others"])
        print(
            f"{executor:10s} {workers:7d} {m['wall']:8.2f} {m['rate']:8.0f} {m['cpu_ms']:10.2f} "
            f"{m['chunk']:6d} {m['chunks']:6d} {m['others']:7.0%}"
        )
    one, two = rates[("processes", 1)], rates[("processes", 2)]
    target = "" if args.driving else " (target >= 500)"
    print(
        f"processes: {two:.0f} runs/s on 2 workers{target}, scaling 1 -> 2 workers "
        f"x{two / one:.2f}, parallel efficiency {two / (2 * one):.0%} (target > 80 %)"
    )
    if args.dask:
        d1, d2 = rates[("dask", 1)], rates[("dask", 2)]
        print(f"dask (local cluster start-up included): x{d2 / d1:.2f}, efficiency {d2 / (2 * d1):.0%}")
    if busiest > 0.05:
        print(
            f"WARNING: other processes used up to {busiest:.0%} of the cores during a measurement: the "
            "wall-clock figures are not representative (CPU ms/run still is)"
        )


if __name__ == "__main__":
    main()
