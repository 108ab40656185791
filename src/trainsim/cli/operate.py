"""``trainsim operate``: many trains on a signalled line, or a network-day of several lines (a thin
layer over trainsim.operations and trainsim.batch.network_day)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from trainsim.cli.context import (
    ExitCode,
    console,
    echo_warnings,
    exit_for_status,
    fail,
    require_file,
    user_errors,
)
from trainsim.errors import InputError

#: The most sampled days of a network-day (as many as the batch layer's Monte Carlo samples).
MAX_DAYS = 10_000


def operate(
    files: Annotated[
        list[Path],
        typer.Argument(
            help="Operation file (schema: trainsim/operation); several files: a network-day of those lines."
        ),
    ],
    out: Annotated[
        Path | None, typer.Option("--out", "-o", help="Directory for summary, tables (CSV) and plots.")
    ] = None,
    as_json: Annotated[
        bool, typer.Option("--json/--no-json", help="Print only the summary JSON on stdout.")
    ] = False,
    parquet: Annotated[bool, typer.Option("--parquet", help="Also write the tables as Parquet.")] = False,
    plots: Annotated[bool, typer.Option("--plots/--no-plots", help="Write the plots (with --out).")] = True,
    samples: Annotated[
        int, typer.Option("--samples", help="Monte Carlo: days with entry delays sampled from 'delays'.")
    ] = 0,
    seed: Annotated[
        int | None,
        typer.Option("--seed", help="Seed of the Monte Carlo samples or of the network-day's sampled days."),
    ] = None,
    days: Annotated[
        int,
        typer.Option(
            "--days",
            help="Network-day: simulate this many sampled days of every line (its 'delays' or "
            "'disturbances' block; each line and day its own random stream); 0: each line's own "
            "timetable once, checked for conflicts.",
        ),
    ] = 0,
    scheduler: Annotated[
        str | None,
        typer.Option(
            "--scheduler", help="Network-day on the Dask scheduler at this address (tcp://host:8786)."
        ),
    ] = None,
    local_workers: Annotated[
        int | None,
        typer.Option("--local-workers", help="Network-day on a local Dask cluster of this many processes."),
    ] = None,
    compare_strategies: Annotated[
        str | None,
        typer.Option(
            "--compare-strategies",
            help="Also simulate the timetable with every train driving each of these strategies "
            "(comma-separated: fastest, optimal, signal_aware) and print total and per-train energy "
            "and delay per strategy.",
        ),
    ] = None,
) -> None:
    """Simulate the trains of an operation file together: delays, conflicts, headways, capacity.

    With several files, --days, --scheduler or --local-workers: a network-day, locally or on Dask with
    the same results. Each line is simulated on its own, except lines joined by a file's
    'connections' (a train waiting for a train of another line): those are simulated together,
    feeders first, and a late feeder delays the waiting train. The files are read here and the lines
    sent to the workers (relative paths work on a remote cluster). Day k of each line draws from its
    own stream of --seed (or the file's seed), keyed by the line's name and the day: the lines draw
    independently, and a seed gives the same result every time. Summary per line and train: mean,
    median, 95th percentile and maximum delay over the days, planned conflicts, statuses. In the JSON,
    each entry of 'line_days' has 'conflicts': the planned conflicts of the line's own timetable, or
    null on a sampled day (sampled days are not checked for conflicts).

    Each train drives its 'strategy': fastest, optimal (each stretch between stops energy-efficiently
    in its scheduled running time) or signal_aware (optimal, passing each approach start only when its
    route is set, from the blocking times of the trains ahead); --compare-strategies runs the
    timetable once per strategy for all trains.

    Exit code 3 when the status is not ok (of the file's run or of a compared strategy): 'conflicts' (the planned timetable has overlapping blocking
    times), 'deadlock' (trains could not finish; the summary names them) or 'stalled'. Exit code 4 when
    the Dask scheduler cannot be reached, or the scheduler or the workers are lost during the run
    (nothing is written; run the command again).
    """
    if len(files) > 1 or days or scheduler is not None or local_workers is not None:
        if compare_strategies is not None:
            with user_errors():
                raise InputError(
                    "--compare-strategies compares the strategies on a single operation file",
                    field="--compare-strategies",
                    value=compare_strategies,
                )
        _network_day(files, out, as_json, parquet, samples, seed, days, scheduler, local_workers)
        return
    file = files[0]
    with user_errors():
        require_file(file, "operation file")
        from trainsim.io.operation_run import run_operation_file

        strategies = None
        if compare_strategies is not None:
            strategies = [x.strip() for x in compare_strategies.split(",") if x.strip()]
        summary, status = run_operation_file(
            file, out, parquet=parquet, plots=plots, samples=samples, seed=seed, strategies=strategies
        )
    if as_json:
        typer.echo(json.dumps(summary, indent=2, allow_nan=False))
        exit_for_status(status)
        return
    _print(summary, out)
    exit_for_status(status)


def _network_day(
    files: list[Path],
    out: Path | None,
    as_json: bool,
    parquet: bool,
    samples: int,
    seed: int | None,
    days: int,
    scheduler: str | None,
    local_workers: int | None,
) -> None:
    with user_errors():
        if samples:
            raise InputError(
                "a network-day samples its days with --days, not --samples", field="--samples", value=samples
            )
        if not 0 <= days <= MAX_DAYS:
            raise InputError("invalid number of days", field="--days", value=days, allowed=f"0 .. {MAX_DAYS}")
        if parquet:
            raise InputError("--parquet writes the tables of a single operation file", field="--parquet")
        for f in files:
            require_file(f, "operation file")
        from trainsim.batch.executors import ClusterLostError
        from trainsim.batch.network_day import run_network_day

        try:
            summary = run_network_day(files, days, seed, scheduler, local_workers)
        except ClusterLostError as exc:
            raise fail(str(exc), ExitCode.INFRASTRUCTURE) from None
        if out is not None:
            out.mkdir(parents=True, exist_ok=True)
            (out / "network_day.json").write_text(json.dumps(summary, indent=2, allow_nan=False))
    if as_json:
        typer.echo(json.dumps(summary, indent=2, allow_nan=False))
    else:
        _print_network_day(summary, out)
    exit_for_status(summary["status"])


def _print_network_day(summary: dict, out: Path | None) -> None:
    from rich.table import Table

    con = console()
    n = summary["samples"]
    what = f"{n} sampled days" if n else "the timetable of each line"
    con.print(f"[bold]network-day[/bold], {what}: status [bold]{summary['status']}[/bold]")
    for line in summary["lines"]:
        conflicts = "" if line["conflicts"] is None else f", {line['conflicts']} conflicts"
        con.print(f"[bold]{line['line']}[/bold] ({line['file']}): {line['statuses']}{conflicts}")
        table = Table("train", "mean delay s", "p50 s", "p95 s", "max s", "energy kWh")
        for t in line["trains"]:
            d = t["delay_s"]
            table.add_row(
                t["id"], _num(d["mean"]), _num(d["p50"]), _num(d["p95"]), _num(d["max"]),
                _num(t["energy_kwh_mean"], 2),
            )  # fmt: skip
        con.print(table)
    con.print(f"total delay {summary['total_delay_s']:.1f} s, energy {summary['energy_kwh']:.1f} kWh")
    if out is not None:
        con.print(f"written to {out}/network_day.json")


def _print(summary: dict, out: Path | None) -> None:
    from rich.table import Table

    con = console()
    con.print(
        f"[bold]{summary['name']}[/bold] ({summary['signalling']}): status [bold]{summary['status']}[/bold]"
    )
    table = Table(
        "train",
        "dir",
        "strategy",
        "from",
        "to",
        "departure s",
        "arrival s",
        "delay s",
        "energy kWh",
        "planned kWh",
        "waits",
    )
    for t in summary["trains"]:
        first, last = t["stops"][0], t["stops"][-1]
        table.add_row(
            t["id"], t["direction"], t["strategy"], first["station"], last["station"],
            _num(first["departure_s"]), _num(last["arrival_s"]), _num(t["delay_s"]),
            _num(t["energy_kwh"], 2), _num(t["planned_energy_kwh"], 2), str(len(t["hindrances"])),
        )  # fmt: skip
    con.print(table)
    if summary["headways"]:
        heads = Table("leader", "follower", "min headway s", "planned s", "buffer s", "critical block")
        for h in summary["headways"]:
            heads.add_row(
                h["leader"], h["follower"], _num(h["min_headway_s"]), _num(h["planned_headway_s"]),
                _num(h["buffer_s"]), h["critical_block"],
            )  # fmt: skip
        con.print(heads)
    con.print(f"{len(summary['conflicts'])} conflicts in the planned timetable")
    for c in summary["conflicts"][:10]:
        con.print(
            f"  {c['trains'][0]} / {c['trains'][1]}: {c['block']} at {c['time_s']:.0f} s, overlap {c['overlap_s']:.1f} s"
        )
    for line in summary.get("deadlock", []):
        con.print(f"[red]deadlock:[/red] {line}")
    if "monte_carlo" in summary:
        mc = summary["monte_carlo"]
        con.print(
            f"Monte Carlo, {mc['samples']} samples: total delay {mc['total_delay_s']} s; statuses {mc['statuses']}"
        )
    if "strategies" in summary:
        _print_strategies(summary["strategies"])
    echo_warnings(summary["warnings"])
    if out is not None:
        con.print(f"written to {out}/")


def _print_strategies(compared: dict) -> None:
    from rich.table import Table

    con = console()
    totals = Table("strategy", "status", "simulations", "energy kWh", "planned kWh", "total delay s")
    for name, c in compared.items():
        totals.add_row(
            name, c["status"], str(c["iterations"]), _num(c["energy_kwh"]["operated"], 2),
            _num(c["energy_kwh"]["planned"], 2), _num(c["total_delay_s"]),
        )  # fmt: skip
    con.print(totals)
    names = list(compared)
    per_train = Table("train", *[f"{n} {what}" for n in names for what in ("kWh", "delay s")])
    rows = zip(*[compared[n]["trains"] for n in names], strict=True)
    for row in rows:
        cells = [x for t in row for x in (_num(t["energy_kwh"], 2), _num(t["delay_s"]))]
        per_train.add_row(row[0]["id"], *cells)
    con.print(per_train)
    for name, c in compared.items():
        echo_warnings([f"{name}: {w}" for w in c["warnings"]])


def _num(x: float | None, digits: int = 1) -> str:
    return "-" if x is None else f"{x:.{digits}f}"
