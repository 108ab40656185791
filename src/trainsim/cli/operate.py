"""``trainsim operate``: many trains on a signalled line (a thin layer over trainsim.operations)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from trainsim.cli.context import console, echo_warnings, exit_for_status, require_file, user_errors


def operate(
    file: Annotated[Path, typer.Argument(help="Operation file (schema: trainsim/operation).")],
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
    seed: Annotated[int | None, typer.Option("--seed", help="Seed of the Monte Carlo samples.")] = None,
) -> None:
    """Simulate the trains of an operation file together: delays, conflicts, headways, capacity.

    Exit code 3 when the status is not ok: 'conflicts' (the planned timetable has overlapping blocking
    times), 'deadlock' (trains could not finish; the summary names them) or 'stalled'.
    """
    with user_errors():
        require_file(file, "operation file")
        from trainsim.io.operation_run import run_operation_file

        summary, status = run_operation_file(
            file, out, parquet=parquet, plots=plots, samples=samples, seed=seed
        )
    if as_json:
        typer.echo(json.dumps(summary, indent=2, allow_nan=False))
        exit_for_status(status)
        return
    _print(summary, out)
    exit_for_status(status)


def _print(summary: dict, out: Path | None) -> None:
    from rich.table import Table

    con = console()
    con.print(
        f"[bold]{summary['name']}[/bold] ({summary['signalling']}): status [bold]{summary['status']}[/bold]"
    )
    table = Table(
        "train",
        "dir",
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
            t["id"], t["direction"], first["station"], last["station"],
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
    echo_warnings(summary["warnings"])
    if out is not None:
        con.print(f"written to {out}/")


def _num(x: float | None, digits: int = 1) -> str:
    return "-" if x is None else f"{x:.{digits}f}"
