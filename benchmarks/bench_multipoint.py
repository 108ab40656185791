"""Wall time of the multi-point model: a 100-wagon train over 50 km (issue 4: under 10 s on one core).

Cases: the heavy-haul example (2 locomotives + 104 wagons, 10,700 t, 50 km with a stop, slack, brake
propagation delay, distributed power and all power at the head), the same train with the default
settings, and with a 0.02 s step. Each case runs once to compile / warm up, then ``--repeat`` times; the
process is pinned to one core and numba to one thread. Prints per case the median and best wall time,
the CPU time, integrator steps, Newton iterations per step, the simulated running time, and the
machine's load average (other processes on the machine slow the wall time down).

Run: python benchmarks/bench_multipoint.py [--repeat N]
"""

from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse
import dataclasses
import statistics
import time
from pathlib import Path

import trainsim
from trainsim.multipoint import MultiPointSettings, run_multipoint_fastest
from trainsim.multipoint.spec import load_multipoint_scenario

ROOT = Path(__file__).resolve().parents[1]
HEAVY = ROOT / "examples" / "heavy_haul"


def cases():
    scenario, dp = load_multipoint_scenario(HEAVY / "scenario_dp.yaml")
    _, head = load_multipoint_scenario(HEAVY / "scenario_head.yaml")
    dp_settings = dp.build()
    return scenario, [
        ("example, head + middle (DP)", dp_settings),
        ("example, all at the head", head.build()),
        ("defaults (no slack, no delay)", MultiPointSettings(locomotive_positions=(0, 53))),
        ("example DP, step 0.02 s", dataclasses.replace(dp_settings, time_step_s=0.02)),
    ]


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    scenario, settings_list = cases()
    reference = trainsim.run(scenario)
    train = scenario.train
    wagons = sum(1 for v in train.vehicles if not v.powered)
    print(
        f"{train.name}: {len(train.vehicles)} vehicles ({wagons} wagons), {train.mass_kg / 1e3:,.0f} t, "
        f"{scenario.route.length_m / 1e3:.0f} km; single-point running time {reference.running_time_s:.0f} s"
    )
    print(
        f"{'case':32s} {'median s':>9s} {'best s':>7s} {'cpu s':>6s} {'steps':>7s} {'it/step':>7s} {'run s':>7s} {'load':>5s}"
    )
    for name, settings in settings_list:
        run_multipoint_fastest(
            train, scenario.route, settings, scenario.settings, reference=reference
        )  # warm-up
        walls, cpus = [], []
        for _ in range(args.repeat):
            t0, c0 = time.perf_counter(), time.process_time()
            result = run_multipoint_fastest(
                train, scenario.route, settings, scenario.settings, reference=reference
            )
            walls.append(time.perf_counter() - t0)
            cpus.append(time.process_time() - c0)
        st = result.statistics
        load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
        print(
            f"{name:32s} {statistics.median(walls):9.2f} {min(walls):7.2f} {min(cpus):6.2f} {st['steps']:7.0f} "
            f"{st['newton_iterations'] / st['steps']:7.2f} {result.running_time_s:7.0f} {load:5.1f}"
        )


if __name__ == "__main__":
    main()
