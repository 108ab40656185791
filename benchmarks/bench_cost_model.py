"""The cost model of a run, measured (issue 14): time per km, per stop, per effort-curve point, per
trace point, and per vehicle of the multi-point model, each with its growth exponent.

Every dimension is varied alone around a synthetic case built with the public API: source 000's heavy
freight train (``examples/freight_000/train.yaml``) on a generated line with the density of features
of a real main line (a gradient change every km, a curve every 2.5 km, a speed-limit change every
5 km), 20 m step, stops only at both ends unless the stops are the dimension:

* km: lines of 10 .. 200 km;
* stops: 2 .. 50 evenly spaced stops (30 s dwell) on a 50 km line;
* effort-curve points: the traction curve resampled as a table of 5 .. 200 points, 50 km line;
* trace points: max_step 40 m .. 1 m on the 50 km line (the dimension is the trace length);
* vehicles: the heavy-haul example (``examples/heavy_haul``, all power at the head) with 25 .. 200
  wagons on a 5 km line with a 4 per mille bank, multi-point model; a heavier train with the same
  locomotives runs longer, so the time per integrator step is fitted as well.

Every point is timed pair by pair with the baseline of ``_timing.py`` (a fixed-step RK4 of a 100 km
line in numba); the CPU time per run is quoted (the machine is shared: wall times are inflated by
preemption, see ``_timing.Paired``) with its ratio to the baseline. For each dimension two fits:
the log-log slope of the whole time over the dimension, and t = a + b x^p (a: the part that does not
depend on the dimension; p: the growth exponent of the rest, 1 = linear). "marginal" is the cost per
unit between the first and the last point.

Run: python benchmarks/bench_cost_model.py [--repeat N] [--quick] [--only km,stops,...]
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import re
import shutil
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import _timing

import trainsim
from trainsim.model.effort import EffortCurve
from trainsim.model.route import Curve, GradientSection, Route, SpeedLimit, Station
from trainsim.model.scenario import RunSettings
from trainsim.sim.fastest import run_fastest

ROOT = Path(__file__).resolve().parents[1]
KMH = 1 / 3.6

FULL = {
    "km": (10, 25, 50, 100, 200),
    "stops": (2, 5, 10, 25, 50),
    "effort points": (5, 10, 25, 50, 100, 200),
    "trace points": (40.0, 20.0, 10.0, 5.0, 2.0, 1.0),
    "vehicles": (25, 50, 100, 200),
}
QUICK = {
    "km": (5, 10),
    "stops": (2, 4),
    "effort points": (5, 20),
    "trace points": (40.0, 20.0),
    "vehicles": (10, 20),
}


def synthetic_line(length_km: float, stops: int = 2, dwell_s: float = 30.0) -> Route:
    """A main line of ``length_km`` with a gradient change every km, a 600 m curve of 800 m radius
    every 2.5 km, speed limits 80 / 60 km/h changing every 5 km, and ``stops`` evenly spaced stops."""
    length = length_km * 1000.0
    grades = (0.0, 4.0, 2.0, -3.0, 6.0, -5.0, 1.0, -2.0)
    gradients = [
        GradientSection(a, min(a + 1000.0, length), grades[k % len(grades)])
        for k, a in enumerate(np.arange(0.0, length, 1000.0))
    ]
    curves = [Curve(a + 1000.0, a + 1600.0, 800.0) for a in np.arange(0.0, length - 1600.0, 2500.0)]
    limits = [
        SpeedLimit(a, min(a + 5000.0, length), (80.0 if k % 2 == 0 else 60.0) * KMH)
        for k, a in enumerate(np.arange(0.0, length, 5000.0))
    ]
    positions = np.linspace(0.0, length, stops)
    stations = [
        Station(f"S{k}", float(x), dwell_s if 0 < k < stops - 1 else 0.0) for k, x in enumerate(positions)
    ]
    return Route(
        f"synthetic {length_km:g} km",
        0.0,
        length,
        tuple(stations),
        tuple(limits),
        tuple(gradients),
        tuple(curves),
    )


def freight_train():
    return trainsim.load_train(ROOT / "examples" / "freight_000" / "train.yaml")


def with_traction_table(train, points: int):
    """The train with its traction curve resampled as a table of ``points`` speeds up to its top speed."""
    v = np.linspace(0.0, train.max_speed_mps, points)
    return dataclasses.replace(train, traction=EffortCurve.from_table(v, np.asarray(train.traction(v))))


def fit(x: list[float], t: list[float]) -> tuple[float, float, float, float]:
    """(log-log slope, a, b, p) of t = a + b x^p, least squares on the relative error."""
    from scipy.optimize import curve_fit

    slope = _timing.loglog_slope(x, t)
    xs, ts = np.asarray(x, float), np.asarray(t, float)
    if len(xs) < 4:
        return slope, math.nan, math.nan, math.nan
    try:
        (a, b, p), _ = curve_fit(
            lambda z, a, b, p: a + b * z**p,
            xs,
            ts,
            p0=(0.5 * ts[0], (ts[-1] - 0.5 * ts[0]) / xs[-1], 1.0),
            sigma=ts,
            bounds=([0.0, 0.0, 0.2], [ts[0], np.inf, 3.0]),
            maxfev=20000,
        )
    except (RuntimeError, ValueError):
        return slope, math.nan, math.nan, math.nan
    return slope, float(a), float(b), float(p)


def measure(
    dimension: str,
    unit: str,
    runs: list[tuple[float, Callable[[], object], str]],
    repeat: int,
    per: list[float] | None = None,
    per_name: str = "",
) -> tuple[list[float], list[float]]:
    """Time each run (paired with the baseline) and print one row per point; returns x and CPU times.
    ``per``: a count per run (integrator steps) by which the time is also divided and fitted."""
    print(f"\n{dimension} [{unit}]")
    print(f"{'x':>9s} {'cpu ms':>10s} {'x base':>8s} {'wall ms':>10s} {'ms per unit':>11s}  detail")
    xs, ts = [], []
    for x, fn, detail in runs:
        p = _timing.paired(fn, repeat)
        xs.append(x)
        ts.append(p.cpu)
        print(
            f"{x:9g} {p.cpu * 1e3:10.3f} {p.ratio_cpu:8.2f} {p.median * 1e3:10.2f} "
            f"{p.cpu * 1e3 / x:11.4f}  {detail}"
        )
    slope, a, _b, p = fit(xs, ts)
    marginal = (ts[-1] - ts[0]) / (xs[-1] - xs[0]) * 1e3
    note = "too few points to fit" if math.isnan(p) else "linear" if 0.9 <= p <= 1.1 else "NOT linear"
    print(
        f"growth: log-log slope {slope:.2f}; t = a + b x^p: a = {a * 1e3:.2f} ms, p = {p:.2f} ({note}); "
        f"marginal {marginal:.4f} ms per {unit}"
    )
    if per:
        tn = [t / k for t, k in zip(ts, per, strict=True)]
        slope, a, _b, p = fit(xs, tn)
        print(
            f"per {per_name}: "
            + ", ".join(f"{t * 1e6:.2f}" for t in tn)
            + f" us; log-log slope {slope:.2f}; "
            f"t = a + b x^p: p = {p:.2f}; per {per_name} and {unit}: "
            + ", ".join(f"{t / x * 1e9:.0f}" for t, x in zip(tn, xs, strict=True))
            + " ns"
        )
    return xs, ts


def single_point_runs(
    dimension: str, values, train, line_km: float
) -> list[tuple[float, Callable[[], object], str]]:
    """Runs along one dimension; the others stay at the synthetic case on a ``line_km`` line."""
    runs = []
    for value in values:
        if dimension == "km":
            route, t, s = synthetic_line(value), train, RunSettings()
        elif dimension == "stops":
            route, t, s = synthetic_line(line_km, stops=value), train, RunSettings()
        elif dimension == "effort points":
            route, t, s = synthetic_line(line_km), with_traction_table(train, value), RunSettings()
        else:
            route, t, s = synthetic_line(line_km), train, RunSettings(max_step_m=value)
        result = run_fastest(t, route, s)  # warm-up, and the trace length
        x = float(len(result.trace)) if dimension == "trace points" else float(value)
        detail = f"{route.length_m / 1e3:g} km, {len(result.trace)} points, step {s.max_step_m:g} m"
        runs.append((x, lambda t=t, r=route, s=s: run_fastest(t, r, s), detail))
    return runs


def multipoint_runs(values, tmp: Path) -> tuple[list[tuple[float, Callable[[], object], str]], list[float]]:
    """Copies of the heavy-haul example with ``n`` wagons on a 5 km line, and the integrator steps of
    each (a heavier train runs longer on the same line: more steps)."""
    src = ROOT / "examples" / "heavy_haul"
    (tmp / "route.yaml").write_text(
        "schema: trainsim/route\nversion: 1\nname: 5 km bank\nlength_m: 5000\n"
        "stations:\n  - {name: A, position_m: 0}\n  - {name: B, position_m: 5000}\n"
        "speed_limits:\n  - {from_m: 0, limit_kmh: 80}\n"
        "gradients:\n  - {from_m: 0, gradient_permille: 0}\n  - {from_m: 1500, gradient_permille: 4.0}\n"
        "  - {from_m: 3500, gradient_permille: -2.0}\n"
        "line_resistance:\n  curve_formula: tbt1407\n  tunnel_formula: tbt1407\n"
        "  gradient_formula: small_angle\n  apply_over: train_length\n"
    )
    shutil.copy(src / "scenario_head.yaml", tmp / "scenario.yaml")
    text = (src / "train.yaml").read_text()
    runs, steps = [], []
    for n in values:
        folder = tmp / f"w{n}"
        folder.mkdir()
        (folder / "train.yaml").write_text(re.sub(r"count: 104\b", f"count: {n}", text))
        shutil.copy(tmp / "route.yaml", folder / "route.yaml")
        shutil.copy(tmp / "scenario.yaml", folder / "scenario.yaml")
        scenario = trainsim.load_scenario(folder / "scenario.yaml")
        result = trainsim.run(scenario)  # warm-up
        st = result.statistics
        detail = (
            f"{len(scenario.train.vehicles)} vehicles, {st['steps']:.0f} steps, "
            f"{st['newton_iterations'] / st['steps']:.2f} Newton it./step"
        )
        runs.append((float(n), lambda sc=scenario: trainsim.run(sc), detail))
        steps.append(float(st["steps"]))
    return runs, steps


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--repeat", type=int, default=7, help="pairs per point (default 7)")
    parser.add_argument("--quick", action="store_true", help="two small points per dimension, 1 pair")
    parser.add_argument("--only", default="", help="comma-separated dimensions: " + ", ".join(FULL))
    args = parser.parse_args(argv)
    grid = QUICK if args.quick else FULL
    repeat = 1 if args.quick else args.repeat
    only = [d.strip() for d in args.only.split(",") if d.strip()] or list(grid)
    print(f"machine: {_timing.machine()}")
    base = _timing.paired(_timing.rk4_line, max(repeat, 3))
    print(f"baseline (fixed-step RK4, 100 km at 10 m, numba): cpu {base.cpu * 1e3:.3f} ms")
    train = freight_train()
    units = {
        "km": "km",
        "stops": "stop",
        "effort points": "point",
        "trace points": "point",
        "vehicles": "wagon",
    }
    for dimension in only:
        if dimension == "vehicles":
            with tempfile.TemporaryDirectory() as tmp:
                runs, steps = multipoint_runs(grid[dimension], Path(tmp))
                measure(dimension, units[dimension], runs, max(1, repeat // 2), steps, "integrator step")
        else:
            measure(
                dimension,
                units[dimension],
                single_point_runs(dimension, grid[dimension], train, 10 if args.quick else 50),
                repeat,
            )
    print(f"\nmachine at the end: {_timing.machine()}")


if __name__ == "__main__":
    main()
