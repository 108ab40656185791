"""A day of trains on a 100 km double-track line: simulation time and its growth with the number of
trains.

The line: 11 stations every 9.8 km, two platform tracks per direction (overtaking), 3-aspect fixed
block of at most 2.5 km, 160 km/h. The day: per direction, in turn an Intercity (TrainRuns.jl's IC2,
no intermediate stop) and a regional train (TrainRuns.jl's Desiro, stopping everywhere for 30 s), one
train every ``HEADWAY_S``, some of them late at entry (seeded). Figures are printed as ratios
against a baseline timed in the same run: one fastest run of the Intercity over the whole line.

Wall time on a shared machine depends on its load: the CPU time of the process is printed beside it
(the target, 1,000 trains in <= 10 s, is wall time on an idle machine, where the two agree).

Speed work must change no figure: ``--save FILE`` writes a digest of every outcome (each size's day
and every example of examples/operations: statuses, warnings, stop times, delays, energies,
hindrances, blocking times, headways, conflicts, and a hash of every trajectory array) and
``--compare FILE`` exits 1 unless a later run gives the same digest bit for bit.

``--disturbed N`` times a day of ``N`` trains with sampled running-time disturbances (seeded; not
part of the digest) both ways: driven as capped runs of the disturbed running times (trajectory,
blocking times and energy one run's; the default) and time-scaled (``disturbed_energy=False``, the
cheap path for delay studies), with the statuses of the disturbed stretches.

Run: python benchmarks/bench_operations.py [--sizes 125,250,500,1000] [--save|--compare FILE]
[--disturbed N]
"""

from __future__ import annotations

import argparse
import hashlib
import pickle
import sys
import time
import warnings
from pathlib import Path
from typing import Any

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


#: Running-time disturbances of the ``--disturbed`` day: a third of the stretches, 20 s on average.
DISTURBED_RUNNING = {"kind": "exponential", "mean_s": 20.0, "probability": 0.3}


def disturbed_day(n: int, ic, local, line, geometry, names) -> None:
    """Time a day of ``n`` trains with sampled running-time disturbances, capped and time-scaled."""
    from trainsim.operations.disturbances import disturbances_from_dict

    dist = disturbances_from_dict({"seed": 5, "running": DISTURBED_RUNNING})
    svcs = dist.sample(services(n, ic, local, names), np.random.default_rng(dist.seed))
    n_dist = sum(1 for s in svcs for x in s.running_extra_s if x > 0)
    for capped in (True, False):
        t0, c0 = time.perf_counter(), time.process_time()
        res = simulate(line, geometry, svcs, SETTINGS, rule="priority", disturbed_energy=capped)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        statuses: dict[str, int] = {}
        for t in res.trains:
            for d in getattr(t, "disturbed", ()):
                statuses[d.status] = statuses.get(d.status, 0) + 1
        energy = sum(t.energy_kwh for t in res.trains)
        print(
            f"{n:5d} trains, {n_dist} disturbed stretches, {'capped runs' if capped else 'time-scaled'}: "
            f"{wall:6.2f} s (CPU {cpu:.2f} s); status {res.status}, runs computed {res.runs_computed} / "
            f"reused {res.runs_reused}, stretches {statuses}, total delay "
            f"{sum(t.delay_s for t in res.trains) / 60:.1f} min, energy {energy:.1f} kWh"
        )


def _array_digest(a) -> tuple:
    a = np.ascontiguousarray(np.asarray(a, dtype=float))
    return a.shape, hashlib.sha256(a.tobytes()).hexdigest()


def digest(res) -> dict[str, Any]:
    """Every figure of an ``OperationResult``, floats by their repr and arrays by a hash of their bytes."""

    def traj(t):
        if t is None:
            return None
        return (
            _array_digest(t.time_s),
            _array_digest(t.position_m),
            _array_digest(t.speed_mps),
            repr(t.length_m),
        )

    return {
        "status": res.status,
        "warnings": list(res.warnings),
        "deadlock": list(res.deadlock),
        "conflicts": [repr(c) for c in res.conflicts],
        "headways": [repr(h) for h in res.headways],
        "blocking": [repr(b) for b in res.blocking],
        "planned_blocking": [repr(b) for b in res.planned_blocking],
        "runs": (res.runs_computed, res.runs_reused),
        "trains": [
            {
                "id": t.id, "status": t.status, "stops": [repr(s) for s in t.stops], "delay": repr(t.delay_s),
                "energy": repr(t.energy_kwh), "planned_energy": repr(t.planned_energy_kwh),
                "energy_note": getattr(t, "energy_note", ""), "hindrances": [repr(h) for h in t.hindrances],
                # running-time disturbances only (undisturbed digests stay comparable with older ones)
                **({"trajectory_note": t.trajectory_note} if getattr(t, "trajectory_note", "") else {}),
                **({"disturbed": [repr(d) for d in t.disturbed]} if getattr(t, "disturbed", ()) else {}),
                "trajectory": traj(t.trajectory), "planned_trajectory": traj(t.planned_trajectory),
                "routes": [(j, r.name) for j, r in t.routes], "warnings": list(t.warnings),
            }
            for t in res.trains
        ],
    }  # fmt: skip


def example_digests() -> dict[str, Any]:
    """``digest`` of every operation file of examples/operations."""
    from trainsim.io.operation_file import read_operation
    from trainsim.io.operation_run import run_operation

    out = {}
    for path in sorted((ROOT / "examples" / "operations").rglob("*.yaml")):
        if "schema: trainsim/operation" in path.read_text():
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                out[str(path.relative_to(ROOT))] = digest(run_operation(read_operation(path)))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="125,250,500,1000")
    parser.add_argument("--save", metavar="FILE", help="write the digest of every outcome")
    parser.add_argument("--compare", metavar="FILE", help="exit 1 unless every outcome is as saved")
    parser.add_argument(
        "--disturbed", type=int, default=0, metavar="N", help="time a disturbed day of N trains"
    )
    args = parser.parse_args()
    digests: dict[str, Any] = {}
    ic, local, line, geometry, names, positions = setup()
    route = Route(
        "baseline", 0.0, LENGTH_M, (Station("a", 1000.0), Station("b", positions[-1])), geometry.speed_limits
    )
    trainsim.run_fastest(ic, route, SETTINGS)  # warm-up (numba)
    t0, c0 = time.perf_counter(), time.process_time()
    for _ in range(20):
        trainsim.run_fastest(ic, route, SETTINGS)
    base, base_cpu = (time.perf_counter() - t0) / 20, (time.process_time() - c0) / 20
    print(
        f"baseline: one fastest run of the Intercity over 98 km: {base * 1e3:.2f} ms (CPU {base_cpu * 1e3:.2f} ms)"
    )
    simulate(line, geometry, services(8, ic, local, names), SETTINGS)  # warm-up
    previous = None
    for n in [int(x) for x in args.sizes.split(",")]:
        svcs = services(n, ic, local, names)
        t0, c0 = time.perf_counter(), time.process_time()
        res = simulate(line, geometry, svcs, SETTINGS, rule="priority")
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        digests[f"day of {n} trains"] = digest(res)
        hindered = sum(1 for t in res.trains if t.hindrances)
        growth = "" if previous is None else f", x{wall / previous[1]:.2f} for x{n / previous[0]:.1f} trains"
        print(
            f"{n:5d} trains: {wall:6.2f} s = {wall / base:8.0f} baseline runs ({wall / n * 1e3:.1f} ms/train{growth}; "
            f"CPU {cpu:.2f} s = {cpu / base_cpu:.0f} baseline runs); "
            f"status {res.status}, runs computed {res.runs_computed} / reused {res.runs_reused}, hindered {hindered}, "
            f"total delay {sum(t.delay_s for t in res.trains) / 60:.0f} min, conflicts {len(res.conflicts)}"
        )
        previous = (n, wall)
    if args.disturbed:
        disturbed_day(args.disturbed, ic, local, line, geometry, names)
    if args.save or args.compare:
        digests.update(example_digests())
    if args.save:
        Path(args.save).write_bytes(pickle.dumps(digests))
        print(f"saved {len(digests)} outcomes to {args.save}")
    if args.compare:
        saved = pickle.loads(Path(args.compare).read_bytes())
        differ = [k for k in sorted(set(saved) | set(digests)) if saved.get(k) != digests.get(k)]
        for k in differ:
            fields = [f for f in saved.get(k, {}) if saved[k][f] != digests.get(k, {}).get(f)]
            print(f"DIFFERS: {k} {fields}")
        print(f"compared {len(digests)} outcomes: {len(differ)} differ")
        if differ:
            sys.exit(1)


if __name__ == "__main__":
    main()
