"""Wall time of the power-supply simulation: a 20 km metro line, 30 trains, one hour at 1 s steps.

Issue 18's target: at most 10 s on the 2-core development machine. The line: two tracks, 750 V DC,
substations every 2.5 km (9 diode rectifiers, 850 V, 0.012 ohm), paralleling posts half way between them
(the network data of examples/power/metro_750v_diode.yaml); source
002's type B metro (regenerative braking at 0.8 of traction, 50 kW auxiliaries) stopping every
1.25 km (30 s dwell), 15 trains per direction on the line at any time. The trains' runs are computed
once (one fastest run per direction); the benchmark times the network solution over the hour.

Because the machine is shared, every figure is also printed as a ratio to a baseline timed in the
same run: one fastest run of the train over the 20 km (the single-train simulation trainsim already
had), both in CPU time (process_time), which other processes on a shared machine disturb much less
than the wall time. Prints the load average too.

--day: a whole day instead (issue 18), examples/power/metro_750v_diode_day.yaml (source 002's metro,
3-minute headway each way from 05:00 to 23:00, 720 departures): memory per train-step of full traces
(time x train arrays) and of traces kept while each train runs, measured with tracemalloc on the
first hour, and the CPU time of the whole 18 h day with compact traces, each as a ratio to the
baseline (here one fastest run of that metro over its 4.6 km line, timed in the same run).

Run: python benchmarks/bench_power.py [--repeat N] [--reversible] [--sparse] [--day]
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import time
from pathlib import Path

import numpy as np

import trainsim
from trainsim.constants import KMH
from trainsim.model import Route, SpeedLimit, Station
from trainsim.power import (
    Connection,
    Network,
    Substation,
    Track,
    simulate,
    standard_limits,
    train_load_from_run,
)

ROOT = Path(__file__).resolve().parents[1]
LENGTH_M = 20_000.0


def line_and_trains(reversible: bool):
    scenario = trainsim.load_scenario(ROOT / "examples" / "metro_b" / "scenario.yaml")
    train = scenario.train
    train = dataclasses.replace(
        train, braking=dataclasses.replace(train.braking, regenerative=train.traction.scaled(0.8))
    )
    stations = tuple(Station(f"S{k}", k * 1250.0, 30.0 if 0 < k < 16 else 0.0) for k in range(17))
    route = Route("20 km metro", 0.0, LENGTH_M, stations, (SpeedLimit(0.0, LENGTH_M, 80 * KMH),))
    settings = trainsim.RunSettings(max_step_m=10.0)
    run = trainsim.run_fastest(train, route, settings)
    tracks = tuple(Track(t, 0.0, LENGTH_M, 0.018e-3, 0.012e-3, 0.1e-6) for t in ("up", "down"))
    subs = tuple(
        Substation(
            f"SS{k}", k * 2500.0, ("up", "down"), 850.0, 0.012, rated_power_w=3e6, reversible=reversible
        )
        for k in range(9)
    )
    posts = tuple(Connection(f"PP{k}", k * 2500.0 + 1250.0, ("up", "down")) for k in range(8))
    net = Network("20 km metro", "dc", standard_limits("dc_750"), tracks, subs, posts)
    trip = run.trace.time_s[-1] - run.trace.time_s[0]
    headway = trip / 15
    loads = []
    for k in range(-16, int(3600 / headway) + 1):
        dep = k * headway
        if dep + trip < 0 or dep > 3600:
            continue
        common = {"traction_efficiency": 0.98, "regenerative_efficiency": 0.98, "auxiliary_power_w": 50e3}
        loads.append(train_load_from_run(run, id=f"up{k}", track="up", departure_s=dep, **common))
        loads.append(
            train_load_from_run(
                run,
                id=f"down{k}",
                track="down",
                departure_s=dep + headway / 2,
                origin_m=LENGTH_M,
                direction=-1,
                **common,
            )
        )
    return net, loads, (train, route, settings), trip


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--reversible", action="store_true", help="inverter substations")
    parser.add_argument(
        "--sparse",
        action="store_true",
        help="also time the sparse Newton (SuperLU, numpy) the compiled one replaced, in the same run",
    )
    parser.add_argument("--day", action="store_true", help="an 18 h day with compact traces (see above)")
    args = parser.parse_args()
    if args.day:
        day()
        return
    net, loads, (train, route, settings), trip = line_and_trains(args.reversible)
    baseline = []
    for _ in range(5):
        c0 = time.process_time()
        trainsim.run_fastest(train, route, settings)
        baseline.append(time.process_time() - c0)
    base = statistics.median(baseline)
    times, cpu = [], []
    for _ in range(args.repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        res = simulate(net, loads, dt_s=1.0, start_s=0.0, end_s=3599.0)
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    on_line = np.sum(np.isfinite(res.train_position_m), axis=1)
    s = res.summary()
    med = statistics.median(times)
    print(
        f"20 km line, {len(net.substations)} substations ({'reversible' if args.reversible else 'diode'}), "
        f"trip {trip:.0f} s, trains on the line {on_line.min()}..{on_line.max()} (mean {on_line.mean():.1f}), "
        f"{len(res.time_s)} steps of 1 s"
    )
    print(f"baseline (one fastest run over 20 km, CPU time): {base * 1e3:.1f} ms")
    print(
        f"network over the hour: median {med:.2f} s, best {min(times):.2f} s "
        f"({med / len(res.time_s) * 1e3:.2f} ms per step); CPU time {statistics.median(cpu):.2f} s "
        f"(= {statistics.median(cpu) / base:.0f} x the baseline); target 10 s"
    )
    print(
        f"status {s['status']}, Newton iterations {s['solver']['iterations_total']} "
        f"(max {s['solver']['iterations_max']} per step), energy balance {s['energy_balance_error']:.1e}, "
        f"substations {s['substations_energy_kwh']:.0f} kWh, losses {s['losses_kwh']:.0f} kWh, "
        f"regen dissipated {s['regen_kwh']['dissipated']:.0f} kWh"
    )
    if args.sparse:
        from trainsim.power import solver

        sparse_cpu = []
        limit = solver.DENSE_NEWTON_MAX_NODES
        solver.DENSE_NEWTON_MAX_NODES = 0
        try:
            for _ in range(args.repeat):
                c0 = time.process_time()
                ref = simulate(net, loads, dt_s=1.0, start_s=0.0, end_s=3599.0)
                sparse_cpu.append(time.process_time() - c0)
        finally:
            solver.DENSE_NEWTON_MAX_NODES = limit
        scale = float(np.max(np.abs(ref.substation_power_w)))
        diff = float(np.max(np.abs(ref.substation_power_w - res.substation_power_w))) / scale
        print(
            f"sparse Newton: CPU time {statistics.median(sparse_cpu):.2f} s "
            f"(= {statistics.median(sparse_cpu) / base:.0f} x the baseline); compiled / sparse "
            f"{statistics.median(cpu) / statistics.median(sparse_cpu):.2f}; substation powers agree to {diff:.1e}"
        )
    print(f"load average: {os.getloadavg()[0]:.2f}")


def day() -> None:
    """Memory per train-step and the time of an 18 h day (module doc)."""
    import resource
    import tracemalloc

    from trainsim.io.power_file import load_power_file
    from trainsim.power.day import departure_loads

    _, net, services = load_power_file(ROOT / "examples" / "power" / "metro_750v_diode_day.yaml")
    loads, _ = departure_loads(services)
    sc = services[0].scenario
    baseline = []
    for _ in range(5):
        c0 = time.process_time()
        trainsim.run_fastest(sc.train, sc.route, sc.settings)
        baseline.append(time.process_time() - c0)
    base = statistics.median(baseline)
    print(f"baseline (one fastest run of the metro, CPU time): {base * 1e3:.1f} ms")
    hour = (18000.0, 21599.0)
    first = [ld for ld in loads if ld.time_s[0] <= hour[1] and ld.time_s[-1] >= hour[0]]
    peaks, results, cpus = {}, {}, {}
    for traces in ("full", "on_network"):
        # CPU without tracemalloc (it slows numpy's allocations several times), memory with it
        c0 = time.process_time()
        results[traces] = simulate(net, first, dt_s=1.0, start_s=hour[0], end_s=hour[1], traces=traces)
        cpus[traces] = time.process_time() - c0
        tracemalloc.start()
        simulate(net, first, dt_s=1.0, start_s=hour[0], end_s=hour[1], traces=traces)
        peaks[traces] = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    full, compact = results["full"], results["on_network"]
    same = np.array_equal(full.substation_power_w, compact.substation_power_w)
    steps, on = len(full.time_s) * len(first), int(compact.train_offset[-1])
    print(
        f"first hour, {len(first)} trains, {len(full.time_s)} steps: full traces peak {peaks['full'] / 1e6:.1f} MB "
        f"({peaks['full'] / steps:.0f} bytes per step x train), compact {peaks['on_network'] / 1e6:.1f} MB "
        f"({peaks['on_network'] / on:.0f} bytes per train-step on the network, {on} of them); CPU full "
        f"{cpus['full']:.2f} s, compact {cpus['on_network']:.2f} s (compact / full {cpus['on_network'] / cpus['full']:.2f}); "
        f"substation series identical: {same}"
    )
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    t0, c0 = time.perf_counter(), time.process_time()
    res = simulate(net, loads, dt_s=1.0, traces="on_network")
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    rss1 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    s = res.summary()
    n_full = len(res.time_s) * len(loads)
    print(
        f"18 h day, {len(loads)} departures, {len(res.time_s)} steps of 1 s: CPU {cpu:.1f} s "
        f"(= {cpu / base:.0f} x the baseline, {cpu / len(res.time_s) * 1e3:.2f} ms per step), wall {wall:.1f} s; "
        f"result {res.memory_bytes() / 1e6:.1f} MB for {int(res.train_offset[-1])} train-steps on the network "
        f"(peak RSS grew {(rss1 - rss0) / 1024:.0f} MB); full traces would hold {n_full:.2e} steps x trains "
        f"(about {n_full * peaks['full'] / steps / 1e9:.1f} GB, cap {trainsim.power.simulation.MAX_FULL_TRAIN_STEPS:.0e})"
    )
    print(
        f"status {s['status']}, substations {s['substations_energy_kwh']:.0f} kWh, largest 1 h RMS current "
        f"{max(x['rms_current_max_a']['3600s'] for x in s['substations']):.0f} A, energy balance "
        f"{s['energy_balance_error']:.1e}"
    )
    print(f"load average: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
