"""Batch throughput (issue 14): metro fastest runs on 1 and 2 workers, the 12-run multi-point study, and
a 1,000-train day on a 100 km line, each against a baseline timed in the same run.

Run: python benchmarks/bench_batch.py [--quick] [--repeat K] [--only metro,multipoint,day]
     [--dask] [--driving]

Every case is a study run with ``run_study`` on the ``processes`` executor into a Parquet dataset in a
temporary directory, as ``trainsim batch`` does; its wall time runs from the call of run_study to the
last chunk written (worker start-up included, study expansion excluded). The cases compared are timed
alternately, pair by pair (A B, then B A, ...), so that a change of the machine's load hits both; the
median of ``--repeat`` repetitions is printed.

1. **Metro fastest runs**: a Monte Carlo over source 002's type B metro (examples/metro_b): load per car
   uniform in [0, 18] t, traction efficiency normal(0.9, 0.02), so that every run validates its own
   train; 5 m steps as the example. Baseline: the same study on 1 worker. Prints runs/s on 1 and 2
   workers and the parallel efficiency rate(2) / (2 rate(1)) (targets: >= 2,000 runs/s on 2 cores,
   >= 90 %), and a run's CPU time as a multiple of the RK4 baseline of benchmarks/_timing.py (a fixed
   amount of compiled work, timed in the same run: comparable across machines).
2. **The 12-run multi-point study** examples/studies/heavy_haul_couplers.yaml (106 vehicles over
   50 km, seconds per run). Baseline: 1 worker. Compared: 2 workers with the cost-sized chunks (one
   run each, longest predicted first) and 2 workers with chunks of 10 runs (the [10, 2] split of the
   chunking by count that issue 14 found). Prints the speed-ups (target x1.8).
3. **A 1,000-train day on a 100 km line**, as a batch study built here from the public API: 11 stations
   every 9.8 km (as benchmarks/bench_operations.py), 160 km/h, a 12 km climb of 5 per mille and its
   descent; the 25 kV EMU of examples/power, in turn an Intercity (no intermediate stop) and a regional
   train (every station, 30 s), 1,000 departures from 05:00, one every 72 s, a timetable study as
   examples/studies/metro_timetable.yaml: each hour's Intercity and regional trains are one entry with
   their departures and the hour's load (seeded). A worker computes each entry's scenario once and
   gives every departure its own row (the runs differ only in their clock times); 3b, the same day
   with one entry and load per train, computes every train.
   Baseline: 1 worker. Prints the wall time on 2 workers (target <= 5 s on 2 cores) and the speed-up.
   (The trains are independent runs: no signalling between them; bench_operations.py times the day
   with signals, in one process.)

Wall time on a machine shared with other work says little. Beside it, each case prints the share of the
cores other processes used meanwhile (all CPU time in /proc/stat less this benchmark's own) and an
**idle-core estimate** from CPU times, which the load changes less than the wall time (but still: CPU
time per run on a loaded machine carries the slowdown of shared caches and cores, and the cases of one
repetition can differ by 20 %; repeat): the CPU time of each worker's runs
(``StudyOutcome.worker_cpu_s``) scaled up by the workers' whole CPU time (start-up, pipes) and the
starting process's CPU time (expansion of the chunks, Parquet writing), as
max(busiest worker, starting process, all of it / cores). It is what the study would take on idle
cores when nothing but the CPU limits it; the speed-ups are quoted from both. For the multi-point
study the **balance** of the workers' runs, sum / (workers x largest), is the chunking's own figure,
whatever the CPU time per run (1 = the workers did equal work).

``--quick`` (a smoke test, about a minute on a quiet machine): 400 metro runs, the multi-point study
with 20 wagons, 100 trains, 1 repetition. ``--dask`` adds the metro study on a local Dask cluster
(start-up included); ``--driving`` runs energy-efficient metro runs (optimal strategy, supplements
5-20 %) instead of fastest ones and prints the cost of ``trainsim.run`` alone beside them.
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from _timing import machine, rk4_line

from trainsim.batch import load_study, run_study, study_from_dict

ROOT = Path(__file__).resolve().parents[1]
CORES = 2  # the targets are for 2 cores
HEAVY = ROOT / "examples" / "studies" / "heavy_haul_couplers.yaml"
EMU = ROOT / "examples" / "power" / "emu_25kv_train.yaml"


# ---------------------------------------------------------------- studies
def metro_study(runs: int, driving: bool = False):
    """The metro Monte Carlo of ``runs`` runs (fastest, or optimal with a drawn supplement)."""
    fields: dict[str, Any] = {
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


def multipoint_study(quick: bool):
    """heavy_haul_couplers.yaml; quick: the same 12 runs with 20 wagons (locomotives at 0 and 11)."""
    if not quick:
        return load_study(HEAVY)
    import yaml

    data = yaml.safe_load(HEAVY.read_text())
    data["base"] = str(ROOT / "examples" / "heavy_haul" / "scenario_dp.yaml")
    data["name"] = "heavy haul couplers, 20 wagons (quick)"
    data["runs"] = [
        {
            "name": "20 wagons",
            "set": {"train.formation[1].count": 20, "multi_point.locomotive_positions": [0, 11]},
        }
    ]
    return study_from_dict(data, str(HEAVY))


def day_study(trains: int, seed: int = 1, distinct: bool = False):
    """``trains`` departures on the 100 km line, Intercity and regional in turn, one every 72 s; one
    entry per hour and kind of train (a worker computes each entry's scenario once and gives every
    departure its row), or with ``distinct`` one entry per train with its own load (every train
    computed)."""
    positions = [1000.0 + 9800.0 * k for k in range(11)]
    names = [f"S{k:02d}" for k in range(11)]
    route = {
        "schema": "trainsim/route",
        "version": 1,
        "name": "100 km main line",
        "length_m": 100_000,
        "stations": [
            {"name": n, "position_m": p, "dwell_s": 30 if 0 < k < 10 else 0}
            for k, (n, p) in enumerate(zip(names, positions, strict=True))
        ],
        "speed_limits": [{"from_m": 0, "limit_kmh": 160}],
        "gradients": [
            {"from_m": 0, "gradient_permille": 0},
            {"from_m": 30_000, "gradient_permille": 5},
            {"from_m": 42_000, "gradient_permille": -5},
            {"from_m": 54_000, "gradient_permille": 0},
        ],
        "line_resistance": {
            "curve_formula": "roeckl",
            "tunnel_formula": "none",
            "gradient_formula": "small_angle",
            "apply_over": "head",
        },
    }
    rng = np.random.default_rng(seed)
    groups: dict[tuple[int, bool], list[str]] = {}  # (hour or train, Intercity) -> departures
    for k in range(trains):
        t = 5 * 3600 + 72 * k
        groups.setdefault((k if distinct else t // 3600, k % 2 == 0), []).append(
            f"{t // 3600:02d}:{t // 60 % 60:02d}:{t % 60:02d}"
        )
    runs = []
    for (group, fast), departures in groups.items():
        run: dict[str, Any] = {
            "name": f"{'Intercity' if fast else 'regional'} {f'train {group}' if distinct else f'{group:02d} h'}",
            "departures": departures,
            # the hour's (or the train's) load per car [t]
            "set": {"train.formation[*].load_t": round(float(rng.uniform(2.0, 12.0)), 2)},
        }
        if fast:
            run["stops"] = [names[0], names[-1]]
        runs.append(run)
    return study_from_dict(
        {
            "schema": "trainsim/study",
            "version": 1,
            "name": f"bench: a day of {trains} trains on a 100 km line"
            + (", each train its own load" if distinct else ""),
            "base": {"name": "main line", "train": str(EMU), "route": route},
            "runs": runs,
        },
        str(ROOT / "benchmarks" / "day.yaml"),
    )


# ---------------------------------------------------------------- measuring
def _cpu() -> tuple[float, float]:
    """CPU time of this process and of its finished child processes [s]."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime, children.ru_utime + children.ru_stime


def _machine_busy_s() -> float:
    """CPU time used on the whole machine since boot, all cores [s] (Linux; 0 elsewhere)."""
    try:
        with open("/proc/stat") as fh:
            fields = [int(x) for x in fh.readline().split()[1:]]
    except OSError:
        return 0.0
    user, nice, system, _idle, _iowait, irq, softirq, steal = fields[:8]
    return (user + nice + system + irq + softirq + steal) / os.sysconf("SC_CLK_TCK")


@dataclass
class Sample:
    """One run of a study: wall time [s], CPU of this process and of the workers [s], the CPU time of
    each worker's runs [s], the share of the cores used by other processes, the chunk sizes."""

    wall: float
    parent_cpu: float
    workers_cpu: float
    worker_runs_cpu: tuple[float, ...]
    others: float
    runs: int
    sizes: tuple[int, ...]

    @property
    def balance(self) -> float:
        """How evenly the workers' runs shared the CPU work: sum / (workers x largest) (1 = evenly);
        the speed-up the chunking allows whatever the CPU time per run, over the number of workers."""
        w = self.worker_runs_cpu
        return sum(w) / (len(w) * max(w)) if w and max(w) > 0 else float("nan")

    @property
    def idle(self) -> float:
        """Idle-core estimate of the wall time [s] (module docstring)."""
        runs_cpu = sum(self.worker_runs_cpu)
        scale = self.workers_cpu / runs_cpu if runs_cpu > 0 and self.workers_cpu > 0 else 1.0
        busiest = max(self.worker_runs_cpu, default=0.0) * scale
        return max(busiest, self.parent_cpu, (self.workers_cpu + self.parent_cpu) / CORES)


def run_once(study, workers: int, chunk_size: int | None = None, executor: str = "processes") -> Sample:
    with tempfile.TemporaryDirectory() as tmp:
        (p0, c0), m0, t0 = _cpu(), _machine_busy_s(), time.perf_counter()
        outcome = run_study(
            study, Path(tmp) / "out", executor=executor, workers=workers, chunk_size=chunk_size
        )
        wall = time.perf_counter() - t0
        p1, c1 = _cpu()  # the pool's processes have ended: their time is counted
        machine_s = _machine_busy_s() - m0
    assert outcome.complete and outcome.failed == 0 and outcome.stalled == 0, outcome
    ours = (p1 - p0) + (c1 - c0)
    others = max(0.0, machine_s - ours) / (wall * (os.cpu_count() or 1))
    return Sample(wall, p1 - p0, c1 - c0, outcome.worker_cpu_s, others, outcome.computed, outcome.chunk_sizes)


def paired_runs(study, cases: dict[str, tuple[int, int | None]], repeat: int) -> dict[str, list[Sample]]:
    """Each case ``name: (workers, chunk_size)`` ``repeat`` times, the cases alternated and their order
    reversed every round."""
    out: dict[str, list[Sample]] = {name: [] for name in cases}
    names = list(cases)
    for r in range(repeat):
        for name in names if r % 2 == 0 else names[::-1]:
            workers, chunk = cases[name]
            out[name].append(run_once(study, workers, chunk))
    return out


def med(samples: list[Sample], attr: str) -> float:
    return statistics.median(getattr(s, attr) for s in samples)


def ratio(a: list[Sample], b: list[Sample], attr: str) -> float:
    """Median of the pairwise ratios a / b of ``attr`` (pairs taken in the same round)."""
    return statistics.median(getattr(x, attr) / getattr(y, attr) for x, y in zip(a, b, strict=True))


def baseline_ms(repeat: int = 15) -> float:
    """Median CPU time of the RK4 baseline of benchmarks/_timing.py [ms]."""
    rk4_line()
    times = []
    for _ in range(repeat):
        c0 = time.process_time()
        rk4_line()
        times.append(time.process_time() - c0)
    return statistics.median(times) * 1e3


def _table(rows: dict[str, list[Sample]]) -> None:
    """Per case: wall and idle-core estimate [s]; CPU per run [ms] of the workers' runs, of the worker
    processes in all (start-up and pipes included) and of this process; the others' share of the cores."""
    print(
        f"  {'case':36s} {'wall s':>8s} {'idle est s':>10s} {'CPU ms/run: runs':>16s} {'workers':>8s} "
        f"{'parent':>7s} {'others':>7s}"
    )
    for name, samples in rows.items():
        runs = samples[0].runs
        in_runs = statistics.median(sum(s.worker_runs_cpu) / runs * 1e3 for s in samples)
        workers = statistics.median(s.workers_cpu / runs * 1e3 for s in samples)
        parent = statistics.median(s.parent_cpu / runs * 1e3 for s in samples)
        print(
            f"  {name:36s} {med(samples, 'wall'):8.2f} {med(samples, 'idle'):10.2f} {in_runs:16.2f} "
            f"{workers:8.2f} {parent:7.2f} {max(s.others for s in samples):7.0%}"
        )


# ---------------------------------------------------------------- the three figures
def metro(runs: int, repeat: int, dask: bool, driving: bool, base_ms: float) -> None:
    study = metro_study(runs, driving)
    t0 = time.perf_counter()
    study.expand()
    expand_s = time.perf_counter() - t0
    run_study(metro_study(10 if driving else 50, driving), None, executor="serial")  # warm-up
    what = "energy-efficient (optimal) runs" if driving else "fastest runs"
    print(f"\n1. metro Monte Carlo, {runs} {what}; expansion {expand_s * 1e3:.0f} ms (not counted)")
    if driving:
        import trainsim

        scenario = trainsim.load_scenario(ROOT / "examples" / "metro_b" / "scenario_eco.yaml")
        trainsim.run(scenario)
        c0 = time.process_time()
        trainsim.run(scenario)
        print(f"  trainsim.run of the example scenario alone: {(time.process_time() - c0) * 1e3:.0f} ms CPU")
    rows = paired_runs(study, {"1 worker (baseline)": (1, None), "2 workers": (2, None)}, repeat)
    if dask:
        d = {}
        for w in (1, 2):
            d[f"dask, {w} worker(s), start-up included"] = [run_once(study, w, executor="dask")]
        rows.update(d)
    _table(rows)
    one, two = rows["1 worker (baseline)"], rows["2 workers"]
    rate1, rate2 = runs / med(one, "wall"), runs / med(two, "wall")
    idle1, idle2 = runs / med(one, "idle"), runs / med(two, "idle")
    speed, speed_idle = ratio(one, two, "wall"), ratio(one, two, "idle")
    target = "" if driving else " (target >= 2,000)"
    print(
        f"  runs/s on 2 workers: {rate2:,.0f} wall{target}, {idle2:,.0f} idle-core estimate; "
        f"on 1 worker {rate1:,.0f} / {idle1:,.0f}"
    )
    print(
        f"  2 workers vs 1 (same run): x{speed:.2f} wall, parallel efficiency {speed / 2:.0%}; "
        f"idle-core estimate x{speed_idle:.2f}, {speed_idle / 2:.0%} (target >= 90 %)"
    )
    cpu_ms = statistics.median(s.workers_cpu / s.runs * 1e3 for s in two)
    print(
        f"  CPU per run in the workers: {cpu_ms:.2f} ms = {cpu_ms / base_ms:.2f} x the RK4 baseline ({base_ms:.2f} ms)"
    )


def multipoint(quick: bool, repeat: int) -> None:
    study = multipoint_study(quick)
    n = len(study.expand())
    print(f"\n2. {study.name}: {n} multi-point runs")
    rows = paired_runs(
        study,
        {
            "1 worker (baseline)": (1, None),
            "2 workers, cost-sized chunks": (2, None),
            "2 workers, chunks of 10": (2, 10),
        },
        repeat,
    )
    _table(rows)
    for name, samples in rows.items():
        cpu = ", ".join(f"{c:.1f}" for c in samples[-1].worker_runs_cpu)
        sizes = ",".join(str(x) for x in samples[-1].sizes)
        print(
            f"  {name:36s} chunks {sizes}; CPU s of each worker's runs: {cpu} "
            f"(balance {med(samples, 'balance'):.0%})"
        )
    one = rows["1 worker (baseline)"]
    for name in ("2 workers, cost-sized chunks", "2 workers, chunks of 10"):
        print(
            f"  speed-up 1 -> 2 workers, {name[11:]}: x{ratio(one, rows[name], 'wall'):.2f} wall, "
            f"x{ratio(one, rows[name], 'idle'):.2f} idle-core estimate (target x1.8)"
        )


def day(trains: int, repeat: int, base_ms: float) -> None:
    for distinct in (False, True):
        t0 = time.perf_counter()
        study = day_study(trains, distinct=distinct)
        study.expand()
        expand_s = time.perf_counter() - t0
        print(
            f"\n3{'b' if distinct else ''}. {study.name} (batch); reading and expansion {expand_s:.2f} s (not counted)"
        )
        rows = paired_runs(study, {"1 worker (baseline)": (1, None), "2 workers": (2, None)}, repeat)
        _table(rows)
        one, two = rows["1 worker (baseline)"], rows["2 workers"]
        print(
            f"  {trains} trains on 2 workers: {med(two, 'wall'):.2f} s wall, {med(two, 'idle'):.2f} s idle-core "
            f"estimate (target <= 5 s for 1,000); 1 worker {med(one, 'wall'):.2f} / {med(one, 'idle'):.2f} s"
        )
        cpu_ms = statistics.median(s.workers_cpu / s.runs * 1e3 for s in two)
        print(
            f"  speed-up x{ratio(one, two, 'wall'):.2f} wall, x{ratio(one, two, 'idle'):.2f} idle-core "
            f"estimate; CPU per train {cpu_ms:.1f} ms = {cpu_ms / base_ms:.1f} x the RK4 baseline"
        )


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--quick", action="store_true", help="small cases, 1 repetition (a smoke test)")
    parser.add_argument("--repeat", type=int, default=None, help="paired repetitions (default 3, quick 1)")
    parser.add_argument(
        "--mp-repeat", type=int, default=1, help="repetitions of the multi-point study (default 1)"
    )
    parser.add_argument(
        "--runs", type=int, default=None, help="metro runs (default 4000, quick 400, driving 100)"
    )
    parser.add_argument(
        "--trains", type=int, default=None, help="trains of the day (default 1000, quick 100)"
    )
    parser.add_argument("--only", default="metro,multipoint,day", help="comma-separated cases to run")
    parser.add_argument("--dask", action="store_true", help="also the metro study on a local Dask cluster")
    parser.add_argument("--driving", action="store_true", help="metro: energy-efficient runs")
    parser.add_argument(
        "--multipoint", action="store_true", help="only the multi-point study (as --only multipoint)"
    )
    args = parser.parse_args()
    only = {"multipoint"} if args.multipoint else set(args.only.split(","))
    unknown = only - {"metro", "multipoint", "day"}
    if unknown:
        parser.error(f"--only: unknown case(s) {', '.join(sorted(unknown))}; allowed: metro, multipoint, day")
    repeat = args.repeat or (1 if args.quick else 3)
    print(machine())
    base_ms = baseline_ms()
    print(f"baseline: RK4 of a 100 km line {base_ms:.2f} ms CPU (benchmarks/_timing.py)")
    if "metro" in only:
        runs = args.runs or (100 if args.driving else 400 if args.quick else 4000)
        metro(runs, repeat, args.dask, args.driving, base_ms)
    if "multipoint" in only:
        multipoint(args.quick, args.mp_repeat)
    if "day" in only:
        day(args.trains or (100 if args.quick else 1000), repeat, base_ms)
    print(f"\nload average at the end: {'/'.join(f'{x:.1f}' for x in os.getloadavg())} (1/5/15 min)")


if __name__ == "__main__":
    main()
