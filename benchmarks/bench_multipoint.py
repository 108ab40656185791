"""Wall time of the multi-point model: a 100-wagon train over 50 km (issue 4: under 10 s on one core).

Cases: the heavy-haul example (2 locomotives + 104 wagons, 10,700 t, 50 km with a stop, slack, brake
propagation delay, distributed power and all power at the head), the same train with the default
settings, and with a 0.02 s step. Each case runs once to compile / warm up, then ``--repeat`` times; the
process is pinned to one core and numba to one thread. Prints per case the median and best wall time,
the CPU time, integrator steps, Newton iterations per step, steps halved because Newton did not
converge, the simulated running time, and the machine's load average (other processes on the machine
slow the wall time down).

With ``--scaling`` it also runs the example's train with 50, 100 and 200 wagons (the wagons repeated or
cut, locomotives at the head and in the middle) over the same line and prints each wall time as a ratio
to the 100-wagon run of the same process (median CPU time), its ratio to the baseline, the CPU time per
vehicle and step, and the growth exponent of the CPU time in the number of vehicles (least-squares
log-log slope; 1 = linear).

Run: python benchmarks/bench_multipoint.py [--repeat N] [--scaling]
"""

from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse
import dataclasses
from pathlib import Path

from _timing import loglog_slope, machine, paired

import trainsim
from trainsim.io.multipoint_spec import load_multipoint_scenario
from trainsim.multipoint import MultiPointSettings, run_multipoint_fastest

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
    parser.add_argument("--scaling", action="store_true", help="time 50, 100, 200 wagons as well")
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
    print(machine())
    print(
        f"{'case':32s} {'median s':>9s} {'best s':>7s} {'cpu s':>6s} {'x base':>7s} {'x base cpu':>10s} "
        f"{'steps':>7s} {'it/step':>7s} {'halved':>6s} {'run s':>7s}"
    )
    for name, settings in settings_list:
        out = []

        def case(settings=settings, out=out):
            out[:] = [
                run_multipoint_fastest(
                    train, scenario.route, settings, scenario.settings, reference=reference
                )
            ]

        p = paired(case, args.repeat)
        result = out[0]
        st = result.statistics
        print(
            f"{name:32s} {p.median:9.2f} {p.best:7.2f} {p.cpu:6.2f} {p.ratio:7.1f} {p.ratio_cpu:10.1f} "
            f"{st['steps']:7.0f} {st['newton_iterations'] / st['steps']:7.2f} {st['halved_steps']:6.0f} "
            f"{result.running_time_s:7.0f}"
        )
    if args.scaling:
        scaling(scenario, args.repeat)


def with_wagons(train, wagons: int):
    """The train with ``wagons`` wagons (the first wagon repeated), its locomotives kept."""
    locos = [v for v in train.vehicles if v.powered]
    wagon = next(v for v in train.vehicles if not v.powered)
    vehicles = (*locos, *([wagon] * wagons))
    k = wagons / sum(1 for v in train.vehicles if not v.powered)
    resistance = tuple(
        dataclasses.replace(t, law=t.law.scaled(k)) if "Wagon" in t.label else t for t in train.resistance
    )
    return dataclasses.replace(
        train,
        vehicles=vehicles,
        mass_kg=sum(v.total_mass_kg for v in vehicles),
        length_m=sum(v.length_m for v in vehicles),
        resistance=resistance,
    )


def scaling(scenario, repeat: int) -> None:
    """CPU time against the number of vehicles, as ratios to the 100-wagon run and to the baseline."""
    rows = []
    for wagons in (100, 50, 200):
        train = with_wagons(scenario.train, wagons)
        settings = MultiPointSettings(locomotive_positions=(0, (wagons + 2) // 2))
        reference = trainsim.run_fastest(train, scenario.route, scenario.settings)
        out = []

        def case(train=train, settings=settings, reference=reference, out=out):
            out[:] = [
                run_multipoint_fastest(
                    train, scenario.route, settings, scenario.settings, reference=reference
                )
            ]

        p = paired(case, repeat)
        st = out[0].statistics
        rows.append((len(train.vehicles), p, st["steps"], st["newton_iterations"] / st["steps"]))
    base = rows[0][1].cpu
    print(
        f"{'vehicles':>8s} {'best s':>7s} {'cpu s':>6s} {'ratio to 102':>12s} {'x base cpu':>10s} "
        f"{'steps':>7s} {'it/step':>7s} {'ns/veh/step':>11s}"
    )
    for n, p, steps, its in sorted(rows, key=lambda r: r[0]):
        print(
            f"{n:8d} {p.best:7.2f} {p.cpu:6.2f} {p.cpu / base:12.2f} {p.ratio_cpu:10.1f} {steps:7.0f} "
            f"{its:7.2f} {p.cpu / steps / n * 1e9:11.0f}"
        )
    ns = [r[0] for r in rows]
    print(
        f"growth exponent of the CPU time in vehicles (log-log, {min(ns)} -> {max(ns)}): "
        f"{loglog_slope(ns, [r[1].cpu for r in rows]):.2f}; of the steps: "
        f"{loglog_slope(ns, [r[2] for r in rows]):.2f}"
    )


if __name__ == "__main__":
    main()
