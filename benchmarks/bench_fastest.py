"""Time per fastest run after warm-up, where it goes, and how it converges (issue 14).

Cases: every shipped example's train on its route (fastest run, single-point model; the heavy-haul
example's multi-point scenarios are run here as single-point fastest runs) and the TrainRuns.jl freight
train on the 101.8 km ``realworld`` path (mass point and homogeneous strip).

Four tables:

1. time: median and best wall time per run at the case's own step, and the median of the per-pair
   ratios to the baseline timed alternately with it (``_timing.rk4_line``: one plain fixed-step RK4 of a
   100 km line compiled by numba, about 0.7 ms on a quiet 2-core Xeon; see there why), in wall time and
   in CPU time (on a machine loaded beyond its cores the CPU-time ratio is the trustworthy one), with
   the trace and without it (``run_fastest(..., trace=False)``, batch mode; CPU time and its ratio).
2. stages (CPU time): one run split into what ``trainsim.sim.fastest.run_fastest`` calls:
   compile_route, the brake check, the segment kernel (sim/_kernel_c, summed over the stops; it places
   the kink points itself since issue 14's stop 26, where ``insert_kink_points`` once ran after it), result
   building, and inside the latter the exact energy integration (``run_works``). The run's own
   functions are timed where the run calls them (each is wrapped by a timer for the instrumented runs
   only; nothing in src/ is edited), so the split follows any change of the pipeline; "other" is the
   rest (Python glue, parameter packing). Each case is split with the trace and without it.
3. convergence: running time and net energy at steps h = 40 m ... 0.625 m and the relative change
   from h to h/2.
4. the converged run: the coarsest h from which every further halving changes both by <= 1e-6, timed
   again (paired), with and without trace: the "full trace, converged to 1e-6" figure of issue 14,
   then issue 14's two run
   targets for freight x realworld (<= 2 ms with trace, <= 0.5 ms without) read as multiples of the
   baseline.

Run: python benchmarks/bench_fastest.py [--repeat N] [--quick] [--case SUBSTRING]
"""

from __future__ import annotations

import argparse
import contextlib
import math
import statistics
import sys
import time
from collections import defaultdict
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import _timing

import trainsim
from trainsim.io.loader import load_route, load_train
from trainsim.model.route import Route
from trainsim.model.scenario import RunSettings
from trainsim.model.train import Train
from trainsim.sim.fastest import run_fastest

ROOT = Path(__file__).resolve().parents[1]
TRAINRUNS_DIRS = (ROOT.parent / "shared" / "data" / "trainruns", ROOT / "tests" / "data" / "trainruns")
#: Steps of the convergence ladder [m]; each is compared with the next (h / 2).
LADDER_M = (40.0, 20.0, 10.0, 5.0, 2.5, 1.25, 0.625)
QUICK_LADDER_M = (20.0, 10.0)
CONVERGED = 1e-6

#: What run_fastest calls, as (module, attribute, label); a stage missing in this version is skipped.
STAGES = (
    ("trainsim.sim.fastest", "compile_route", "compile_route"),
    ("trainsim.sim.fastest", "braking_surplus", "brake check"),
    ("trainsim.sim._kernel_c", "fastest_segment", "kernel"),
    ("trainsim.sim.fastest", "build_result", "result"),
    ("trainsim.sim.result", "run_works", "(energy)"),
)


def trainruns_dir() -> Path | None:
    return next((d for d in TRAINRUNS_DIRS if (d / "paths" / "realworld.yaml").exists()), None)


def cases(quick: bool = False) -> list[tuple[str, Train, Route, RunSettings]]:
    """(name, train, route, settings) of every case; ``quick``: metro and freight x realworld only."""
    out = []
    for example in sorted((ROOT / "examples").iterdir()):
        files = sorted(example.glob("scenario*.yaml"))
        if not files:
            continue
        sc = trainsim.load_scenario(files[0])
        out.append((example.name, sc.train, sc.route, sc.settings))
    data = trainruns_dir()
    if data is not None:
        train = load_train(data / "trains" / "freight.yaml")
        for mass_model in ("mass_point", "homogeneous_strip"):
            route = load_route(data / "paths" / "realworld.yaml", mass_model=mass_model)
            out.append((f"trainruns freight realworld {mass_model}", train, route, RunSettings()))
    if quick:
        out = [c for c in out if c[0] == "metro_b" or c[0].endswith("mass_point")]
    return out


@contextlib.contextmanager
def instrumented(acc: dict[str, float]):
    """Wrap the run's stage functions with timers that add their CPU time to ``acc`` [s]."""
    import importlib

    saved = []
    for module_name, attr, label in STAGES:
        module = importlib.import_module(module_name)
        fn = getattr(module, attr, None)
        if fn is None:
            continue

        def timed(*args, _fn=fn, _label=label, **kwargs):
            t0 = time.process_time()
            try:
                return _fn(*args, **kwargs)
            finally:
                acc[_label] += time.process_time() - t0

        saved.append((module, attr, fn))
        setattr(module, attr, timed)
    try:
        yield
    finally:
        for module, attr, fn in reversed(saved):
            setattr(module, attr, fn)


def stage_split(train, route, settings, repeat: int, trace: bool = True) -> dict[str, float]:
    """Median CPU time of each stage and of the whole instrumented run [s]."""
    samples: dict[str, list[float]] = defaultdict(list)
    for _ in range(repeat):
        acc: dict[str, float] = defaultdict(float)
        with instrumented(acc):
            t0 = time.process_time()
            run_fastest(train, route, settings, trace=trace)
            acc["total"] = time.process_time() - t0
        stages = ("compile_route", "brake check", "kernel", "result")
        acc["other"] = acc["total"] - sum(acc[k] for k in stages)
        for k, x in acc.items():
            samples[k].append(x)
    return {k: statistics.median(x) for k, x in samples.items()}


def convergence(train, route, ladder) -> list[tuple[float, float, float, int]]:
    """(h, running time [s], net energy [kWh], trace points) at each step of the ladder."""
    rows = []
    for h in ladder:
        r = run_fastest(train, route, RunSettings(max_step_m=h))
        rows.append((h, r.running_time_s, r.energy_kwh.net, len(r.trace)))
    return rows


def rel(a: float, b: float) -> float:
    return abs(a - b) / max(abs(b), 1e-300)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--repeat", type=int, default=21, help="pairs per timing (default 21)")
    parser.add_argument("--quick", action="store_true", help="two cases, 3 pairs, a 2-step ladder")
    parser.add_argument("--case", default="", help="only cases whose name contains this")
    args = parser.parse_args(argv)
    repeat = 3 if args.quick else args.repeat
    ladder = QUICK_LADDER_M if args.quick else LADDER_M
    print(f"machine: {_timing.machine()}")
    base = _timing.paired(_timing.rk4_line, repeat)
    print(
        f"baseline: fixed-step RK4, {_timing.BASELINE_STEP_M:g} m over {_timing.BASELINE_LENGTH_M / 1e3:g} km "
        f"(numba): median {base.median * 1e3:.3f} ms, best {base.best * 1e3:.3f} ms, cpu {base.cpu * 1e3:.3f} ms"
    )
    selected = [c for c in cases(args.quick) if args.case in c[0]]
    for _, train, route, settings in selected:
        run_fastest(train, route, settings)  # warm-up: numba compilation or cache loading

    print("\n1. wall time per fastest run at the case's step (paired with the baseline)")
    print(
        f"{'case':46s} {'km':>6s} {'step m':>6s} {'points':>7s} {'median ms':>9s} {'best ms':>8s} "
        f"{'x base':>7s} {'cpu ms':>7s} {'cpu x base':>10s} {'no trace cpu ms':>15s} {'cpu x base':>10s}"
    )
    for name, train, route, settings in selected:
        result = run_fastest(train, route, settings)
        p = _timing.paired(lambda t=train, r=route, s=settings: run_fastest(t, r, s), repeat)
        q = _timing.paired(lambda t=train, r=route, s=settings: run_fastest(t, r, s, trace=False), repeat)
        print(
            f"{name:46s} {route.length_m / 1e3:6.1f} {settings.max_step_m:6g} {len(result.trace):7d} "
            f"{p.median * 1e3:9.2f} {p.best * 1e3:8.2f} {p.ratio:7.2f} {p.cpu * 1e3:7.2f} {p.ratio_cpu:10.2f} "
            f"{q.cpu * 1e3:15.2f} {q.ratio_cpu:10.2f}"
        )

    print("\n2. where one run goes (median CPU ms of instrumented runs; (energy) is part of result)")
    labels = ("compile_route", "brake check", "kernel", "result", "(energy)", "other", "total")
    print(f"{'case':46s} {'trace':>5s} " + " ".join(f"{x:>13s}" for x in labels))
    for name, train, route, settings in selected:
        for trace in (True, False):
            split = stage_split(train, route, settings, repeat, trace)
            total = split["total"]
            cells = []
            for x in labels:
                ms = split.get(x, math.nan) * 1e3
                cells.append(
                    f"{ms:6.2f}" + ("       " if x == "total" else f" ({split.get(x, 0) / total:4.0%})")
                )
            print(f"{name:46s} {'yes' if trace else 'no':>5s} " + " ".join(f"{c:>13s}" for c in cells))

    print(f"\n3. convergence: change from h to h/2 (converged: both <= {CONVERGED:g})")
    print(
        f"{'case':46s} {'h m':>6s} {'points':>7s} {'running time s':>15s} {'d time':>8s} "
        f"{'net kWh':>12s} {'d energy':>8s}"
    )
    converged_at = {}
    for name, train, route, _settings in selected:
        rows = convergence(train, route, ladder)
        changes = []
        for (h, t, e, n), (_, t2, e2, _) in zip(rows, [*rows[1:], (math.nan,) * 4], strict=True):
            dt, de = rel(t, t2), rel(e, e2)
            changes.append((h, max(dt, de)))
            print(
                f"{name:46s} {h:6g} {n:7d} {t:15.6f} {dt:8.1e} {e:12.6f} {de:8.1e}"
                if not math.isnan(t2)
                else f"{name:46s} {h:6g} {n:7d} {t:15.6f} {'':8s} {e:12.6f}"
            )
        # converged at h: every change from h' to h'/2 with h' <= h is within the tolerance (a single
        # small change can be a coincidence of a non-monotone sequence)
        for k, (h, _) in enumerate(changes[:-1]):
            if all(c <= CONVERGED for _, c in changes[k:-1]):
                converged_at[name] = h
                break

    print("\n4. converged run: the coarsest step converged to 1e-6, timed (paired)")
    print(
        f"{'case':46s} {'h m':>6s} {'median ms':>9s} {'best ms':>8s} {'x base':>7s} {'cpu ms':>7s} "
        f"{'cpu x base':>10s} {'no trace cpu ms':>15s} {'cpu x base':>10s}"
    )
    targets = []
    for name, train, route, _settings in selected:
        h = converged_at.get(name)
        if h is None:
            print(f"{name:46s} not converged to {CONVERGED:g} down to h = {ladder[-1]:g} m")
            continue
        s = RunSettings(max_step_m=h)
        p = _timing.paired(lambda t=train, r=route, s=s: run_fastest(t, r, s), repeat)
        q = _timing.paired(lambda t=train, r=route, s=s: run_fastest(t, r, s, trace=False), repeat)
        print(
            f"{name:46s} {h:6g} {p.median * 1e3:9.2f} {p.best * 1e3:8.2f} {p.ratio:7.2f} "
            f"{p.cpu * 1e3:7.2f} {p.ratio_cpu:10.2f} {q.cpu * 1e3:15.2f} {q.ratio_cpu:10.2f}"
        )
        if name.endswith("realworld mass_point"):
            targets.append((p, q))
    for p, q in targets:
        # issue 14's targets are absolute times of a quiet machine: read them as multiples of the baseline
        print(
            f"\nissue 14, freight x realworld: with trace, converged: {p.ratio_cpu:.1f} x baseline (CPU) = "
            f"{p.ratio_cpu * base.cpu * 1e3:.2f} ms at the baseline's {base.cpu * 1e3:.3f} ms; target 2 ms = "
            f"{2e-3 / base.cpu:.1f} x. Without trace (run_fastest(..., trace=False)): {q.ratio_cpu:.1f} x = "
            f"{q.ratio_cpu * base.cpu * 1e3:.2f} ms; target 0.5 ms = {0.5e-3 / base.cpu:.2f} x."
        )
    print(f"\nmachine at the end: {_timing.machine()}")


if __name__ == "__main__":
    main()
