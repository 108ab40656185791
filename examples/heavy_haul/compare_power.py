"""Heavy haul with distributed power against all power at the head (issue 4's example).

The same 10,700 t train (2 locomotives + 104 wagons, 1290 m) over the same 50 km line, once with one
locomotive at the head and one in the middle (scenario_dp.yaml), once with both at the head
(scenario_head.yaml), both with the multi-point model following the single-point fastest run.
Prints running time, energy and the largest draft and buff forces with where and when they occur;
with --out DIR also writes the coupler-force heat maps and the force at the worst coupling.

Run: python examples/heavy_haul/compare_power.py [--out out/heavy_haul]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import trainsim
from trainsim.io.multipoint_spec import load_multipoint_scenario, run_multipoint_scenario
from trainsim.multipoint.plots import save_multipoint_plots

HERE = Path(__file__).resolve().parent


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--out", type=Path, help="directory for plots (one sub-directory per case)")
    args = parser.parse_args()

    scenario, _ = load_multipoint_scenario(HERE / "scenario_dp.yaml")
    single = trainsim.run(scenario)
    print(
        f"{scenario.train.name}: {scenario.train.mass_kg / 1e3:,.0f} t, {scenario.train.length_m:.0f} m, "
        f"{len(scenario.train.vehicles)} vehicles; {scenario.route.name}"
    )
    print(
        f"single-point fastest run: running time {single.running_time_s:.0f} s, "
        f"traction energy {single.energy_kwh.traction:.0f} kWh, net {single.energy_kwh.net:.0f} kWh\n"
    )

    header = f"{'case':22s} {'time s':>7s} {'kWh':>7s} {'max draft kN':>13s} {'where':>30s} {'max buff kN':>12s} {'where':>30s} {'wall s':>7s}"
    print(header)
    print("-" * len(header))
    for name, file in (("head + middle (DP)", "scenario_dp.yaml"), ("all at the head", "scenario_head.yaml")):
        scn, spec = load_multipoint_scenario(HERE / file)
        t0 = time.perf_counter()
        result = run_multipoint_scenario(scn, spec, base_dir=HERE)
        wall = time.perf_counter() - t0
        d, b = result.max_draft, result.max_buff
        where_d = f"c{d.coupler} at {d.coupler_position_m / 1e3:.2f} km, {d.time_s:.0f} s"
        where_b = f"c{b.coupler} at {b.coupler_position_m / 1e3:.2f} km, {b.time_s:.0f} s"
        print(
            f"{name:22s} {result.running_time_s:7.0f} {result.energy_kwh.traction:7.0f} "
            f"{d.force_n / 1e3:13.0f} {where_d:>30s} {b.force_n / 1e3:12.0f} {where_b:>30s} {wall:7.1f}"
        )
        for w in result.warnings:
            print(f"    warning: {w}")
        if args.out:
            paths = save_multipoint_plots(result, args.out / file.removesuffix(".yaml"))
            print(f"    plots: {', '.join(str(p) for p in paths)}")
    print(
        "\nc<k>: coupling k, between vehicles k and k+1 (0 = behind the head vehicle); positions are the "
        "coupling's on the line."
    )


if __name__ == "__main__":
    main()
