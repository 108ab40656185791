"""Run an operation file: simulate its trains, compare separation systems, write tables and plots.

``run_operation_file`` is what ``trainsim operate FILE`` calls; it returns the JSON-ready summary and
the status (``ok`` or the reason it is not).
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path
from typing import Any

from trainsim.errors import InputError
from trainsim.io.operation_file import Operation, read_operation
from trainsim.operations.blocking import compression
from trainsim.operations.runs import RunCache
from trainsim.operations.simulate import STRATEGIES, OperationResult, TrainService, simulate


def run_operation(
    op: Operation, services: list[TrainService] | None = None, cache: RunCache | None = None, **options: Any
) -> OperationResult:
    """Simulate an operation read by ``read_operation`` (its services, or ``services``)."""
    try:
        return simulate(
            op.line, op.geometry, op.services if services is None else services, op.settings, op.rule,
            etcs=op.etcs, lookahead_s=op.lookahead_s, cache=cache, **options,
        )  # fmt: skip
    except InputError as e:
        raise e.located(op.file) from None


def monte_carlo(op: Operation, samples: int, seed: int | None = None) -> dict[str, Any]:
    """Simulate ``samples`` days with entry delays sampled from the file's ``delays`` block (seeded by
    ``seed``, default the file's seed; sample ``k`` uses the generator's ``k``-th spawned stream), and
    summarise the delays: per train and in total, mean, median, 95th percentile and maximum [s], and
    how often each status came out. The single-train runs are shared between the samples."""
    import numpy as np

    sampler = op.disturbances if op.disturbances is not None else op.delays
    if sampler is None:
        raise InputError(
            "Monte Carlo samples need a 'delays' block (probability, mean_s, seed) or a 'disturbances' block",
            file=op.file,
            field="delays",
        )
    if not 1 <= samples <= 10_000:
        raise InputError("invalid number of samples", field="--samples", value=samples, allowed="1 .. 10000")
    streams = np.random.SeedSequence(sampler.seed if seed is None else seed).spawn(samples)
    cache = RunCache(op.settings)
    delays: dict[str, list[float]] = {s.id: [] for s in op.given_services}
    totals, statuses = [], {}
    for stream in streams:
        services = sampler.sample(op.given_services, np.random.default_rng(stream))
        # delays only: the energy of disturbed runs (slower runs per stretch) is not needed here
        res = run_operation(op, services, cache, conflicts=False, headways=False, disturbed_energy=False)
        statuses[res.status] = statuses.get(res.status, 0) + 1
        for t in res.trains:
            delays[t.id].append(t.delay_s)
        totals.append(sum(t.delay_s for t in res.trains))

    return {
        "samples": samples,
        "seed": sampler.seed if seed is None else seed,
        "statuses": statuses,
        "total_delay_s": delay_stats(totals),
        "trains": [{"id": k, "delay_s": delay_stats(v)} for k, v in delays.items()],
        "runs": {"computed": cache.computed, "reused": cache.hits},
    }


def delay_stats(delays_s: list[float | None]) -> dict[str, float | int | None]:
    """Mean, median, 95th percentile and maximum of delays over sampled days [s] (numpy's linear
    percentile), rounded to 1 ms; when a train did not finish on some day (delay infinite or None)
    the figures are None and ``unfinished`` counts those days: a mean over the days it finished would
    hide them."""
    import numpy as np

    a = np.asarray([np.inf if x is None else x for x in delays_s], dtype=float)
    if not np.all(np.isfinite(a)):
        return {
            "mean": None,
            "p50": None,
            "p95": None,
            "max": None,
            "unfinished": int(np.sum(~np.isfinite(a))),
        }
    return {
        "mean": round(float(a.mean()), 3),
        "p50": round(float(np.percentile(a, 50)), 3),
        "p95": round(float(np.percentile(a, 95)), 3),
        "max": round(float(a.max()), 3),
    }


def capacity(result: OperationResult, period_s: float) -> dict[str, Any]:
    """UIC 406 compression of each direction's planned trains over ``period_s`` [s]."""
    out: dict[str, Any] = {}
    for direction in ("up", "down"):
        trains = sorted(
            (t for t in result.trains if t.direction == direction),
            key=lambda t: t.planned_trajectory.time_s[0],
        )
        if not trains:
            continue
        by = {t.id: [] for t in trains}
        for b in result.planned_blocking:
            if b.train in by:
                by[b.train].append(b)
        out[direction] = compression([by[t.id] for t in trains], period_s).to_dict()
    return out


def compare_systems(op: Operation, systems: list[str]) -> dict[str, Any]:
    """Minimum headways of consecutive planned trains and UIC 406 consumption under each separation
    system, the line's layout and times otherwise unchanged."""
    out: dict[str, Any] = {}
    for system in systems:
        line = op.with_system(system)
        res = simulate(
            line, op.geometry, op.services, op.settings, op.rule, etcs=op.etcs, conflicts=False,
            lookahead_s=op.lookahead_s,
        )  # fmt: skip
        entry: dict[str, Any] = {"headways": [h.to_dict() for h in res.headways]}
        if op.pattern_period_s:
            entry["capacity"] = capacity(res, op.pattern_period_s)
        out[system] = entry
    return out


def compare_strategies(op: Operation, strategies: list[str], cache: RunCache | None = None) -> dict[str, Any]:
    """The file's timetable simulated once per driving strategy, every train driving it: per strategy
    the status, the simulations made, total operated and planned energy [kWh] and total delay [s], and
    per train its energy, planned energy, delay, status and waits at signals and stops."""
    unknown = [x for x in strategies if x not in STRATEGIES]
    if unknown or not strategies or len(set(strategies)) != len(strategies):
        raise InputError(
            "unknown, repeated or no driving strategy to compare",
            field="--compare-strategies",
            value=",".join(strategies),
            allowed="a comma-separated list of " + ", ".join(STRATEGIES),
        )
    cache = cache or RunCache(op.settings)
    out: dict[str, Any] = {}
    for strategy in strategies:
        services = [replace(s, strategy=strategy) for s in op.services]
        res = run_operation(op, services, cache, conflicts=False, headways=False)
        summary = res.summary()
        out[strategy] = {
            "status": res.status,
            "iterations": res.iterations,
            "energy_kwh": summary["energy_kwh"],
            "total_delay_s": summary["total_delay_s"],
            "trains": [
                {
                    "id": t["id"],
                    "status": t["status"],
                    "energy_kwh": t["energy_kwh"],
                    "planned_energy_kwh": t["planned_energy_kwh"],
                    "delay_s": t["delay_s"],
                    "waits": len(t["hindrances"]),
                    **({"stretches": t["stretches"]} if "stretches" in t else {}),
                }
                for t in summary["trains"]
            ],
            "warnings": res.warnings,
        }
    return out


def run_operation_file(
    path: str | Path,
    out_dir: str | Path | None = None,
    parquet: bool = False,
    plots: bool = True,
    samples: int = 0,
    seed: int | None = None,
    strategies: list[str] | None = None,
) -> tuple[dict[str, Any], str]:
    """Read, simulate and report an operation file.

    Returns the summary (``status``, ``trains`` with per-stop scheduled and simulated times and delay,
    ``energy_kwh``, ``conflicts``, ``headways``, ``capacity`` and ``separation`` when asked for) and the
    status. With ``samples`` > 0 also ``monte_carlo`` (delay statistics over that many sampled days).
    With ``strategies``, ``strategies``: the timetable driven by every train with each of them
    (``compare_strategies``); the status is then the first that is not ok of the file's run and those.
    With ``out_dir``: ``summary.json``, ``trains.csv`` (stop times), ``blocking_times.csv``
    (operated and planned), ``traces.csv`` (every train's position and speed over time), Parquet copies
    with ``parquet``, and the plots (``train_graph.png``, ``delays.png``, ``headways.png``).
    """
    op = read_operation(path)
    cache = RunCache(op.settings)
    result = run_operation(op, cache=cache)
    summary: dict[str, Any] = {"name": op.name, "file": str(path), "signalling": op.line.signalling.system}
    summary.update(result.summary())
    if op.connections:
        # the feeders run on other lines: only a network-day of those files has them
        summary["warnings"] = [
            *summary["warnings"],
            f"{len(op.connections)} connection(s) to trains of other lines not applied: the trains leave "
            "as planned; give the files of those lines too (a network-day) to apply them",
        ]
    if op.pattern_period_s:
        summary["capacity"] = capacity(result, op.pattern_period_s)
    if op.compare_systems:
        summary["separation"] = compare_systems(op, op.compare_systems)
    if samples:
        summary["monte_carlo"] = monte_carlo(op, samples, seed)
    status = result.status
    if strategies:
        try:
            summary["strategies"] = compare_strategies(op, strategies, cache)
        except InputError as e:
            raise e.located(op.file) from None
        if status == "ok":
            # a comparison run that is not ok is not hidden behind the file's own
            status = next((v["status"] for v in summary["strategies"].values() if v["status"] != "ok"), "ok")
    if out_dir is not None:
        write_outputs(op, result, summary, Path(out_dir), parquet, plots)
    return summary, status


def tables(op: Operation, result: OperationResult):  # -> dict[str, pandas.DataFrame]
    """The result as tables: stop times, blocking times (operated and planned) and traces."""
    import numpy as np
    import pandas as pd

    stops = [{"train": t.id, "direction": t.direction, **s.to_dict()} for t in result.trains for s in t.stops]
    blocking = [
        {"kind": kind, **b.__dict__}
        for kind, items in (("operated", result.blocking), ("planned", result.planned_blocking))
        for b in items
    ]
    traces = []
    for t in result.trains:
        for kind, tr in (("operated", t.trajectory), ("planned", t.planned_trajectory)):
            if tr is None:
                continue
            pos = op.line.line_position(t.direction, tr.position_m)
            traces.append(
                pd.DataFrame(
                    {
                        "train": t.id,
                        "kind": kind,
                        "time_s": tr.time_s,
                        "line_position_m": np.asarray(pos, dtype=float),
                        "speed_kmh": tr.speed_mps * 3.6,
                    }
                )
            )
    return {
        "trains": pd.DataFrame(stops),
        "blocking_times": pd.DataFrame(blocking),
        "traces": pd.concat(traces, ignore_index=True) if traces else pd.DataFrame(),
    }


def write_outputs(
    op: Operation, result: OperationResult, summary: dict[str, Any], out: Path, parquet: bool, plots: bool
) -> list[Path]:
    """Write the summary, the tables and the plots into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    written = [out / "summary.json"]
    written[0].write_text(json.dumps(summary, indent=2, allow_nan=False))
    for name, df in tables(op, result).items():
        p = out / f"{name}.csv"
        df.to_csv(p, index=False)
        written.append(p)
        if parquet:
            p = out / f"{name}.parquet"
            df.to_parquet(p, index=False)
            written.append(p)
    if plots:
        from trainsim.operations.plots import write_plots

        written.extend(write_plots(op.line, result, out))
    return written
