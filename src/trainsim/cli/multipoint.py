"""Command line of the multi-point model: ``trainsim multipoint SCENARIO [--out DIR] [--json]``.

Registration in ``trainsim.cli`` (by the lead)::

    from trainsim.cli_multipoint import multipoint
    app.command("multipoint")(multipoint)

``trainsim run`` can dispatch to :func:`run_and_report` when a scenario says ``model: multi_point``.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from trainsim.errors import InputError, TrainsimError

__all__ = ["multipoint", "run_and_report", "write_multipoint_outputs"]


def write_multipoint_outputs(result, out: Path, *, plots: bool = True) -> list[Path]:
    """Write ``trace.csv`` and ``summary.json`` (as for a single-point run, the summary with its
    ``multi_point`` block), ``coupler_forces.csv`` (kN, one column per coupling, one row per recorded
    instant), ``vehicle_speeds.csv`` (km/h, one column per vehicle) and, with ``plots``, the coupler
    heat map, the force at the worst couplings and the vehicle speeds as PNG files."""
    import numpy as np
    import pandas as pd

    from trainsim.constants import KMH
    from trainsim.io.export import write_trace_csv

    out.mkdir(parents=True, exist_ok=True)
    written = [write_trace_csv(result.run, out / "trace.csv")]
    path = out / "summary.json"
    path.write_text(json.dumps(result.summary(), indent=2, allow_nan=False))
    written.append(path)
    index = pd.Index(np.round(result.time_s, 6), name="time_s")
    forces = pd.DataFrame(
        result.coupler_force_n / 1e3,
        index=index,
        columns=[f"c{k}_kn" for k in range(result.coupler_force_n.shape[1])],
    )
    path = out / "coupler_forces.csv"
    forces.to_csv(path, float_format="%.3f")
    written.append(path)
    speeds = pd.DataFrame(
        result.speed_mps / KMH, index=index, columns=[f"v{i}_kmh" for i in range(result.speed_mps.shape[1])]
    )
    path = out / "vehicle_speeds.csv"
    speeds.to_csv(path, float_format="%.4f")
    written.append(path)
    if plots:
        from trainsim.multipoint.plots import save_multipoint_plots

        written += save_multipoint_plots(result, out)
    return written


def run_and_report(scenario_path: Path, out: Path | None, as_json: bool, no_plots: bool) -> None:
    """Run a scenario file with the multi-point model and print the summary (the CLI's body)."""
    from trainsim.multipoint.spec import load_multipoint_scenario, run_multipoint_scenario

    scenario, spec = load_multipoint_scenario(scenario_path)
    if spec is None:
        raise InputError(
            "this scenario does not choose the multi-point model; add 'model: multi_point'",
            file=str(scenario_path),
            field="model",
        )
    result = run_multipoint_scenario(scenario, spec, base_dir=scenario_path.parent)
    written = write_multipoint_outputs(result, out, plots=not no_plots) if out is not None else []
    if as_json:
        typer.echo(json.dumps(result.summary(), indent=2, allow_nan=False))
        return
    from rich.console import Console

    from trainsim.io.export import summary_table

    console = Console(width=160)
    console.print(summary_table(result.run))
    d, b = result.max_draft, result.max_buff
    typer.echo(
        f"running time {result.running_time_s:.1f} s, traction {result.energy_kwh.traction:.1f} kWh, "
        f"net {result.energy_kwh.net:.1f} kWh; energy balance {result.energy.balance_error:.1e}"
    )
    for label, e in (("max draft", d), ("max buff", b)):
        typer.echo(
            f"{label}: {e.force_n / 1e3:.0f} kN at coupling {e.coupler} (behind vehicle {e.coupler}, "
            f"{e.behind_vehicle}), at {e.coupler_position_m:.0f} m, t = {e.time_s:.1f} s"
        )
    for warning in result.warnings:
        typer.echo(f"warning: {warning}", err=True)
    for path in written:
        typer.echo(f"wrote {path}")


def multipoint(
    scenario: Annotated[Path, typer.Argument(help="Scenario file with 'model: multi_point'.")],
    out: Annotated[
        Path | None,
        typer.Option("--out", "-o", help="Directory for trace, summary, coupler forces and plots."),
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print only the summary as JSON.")] = False,
    no_plots: Annotated[bool, typer.Option("--no-plots", help="Do not write PNG plots with --out.")] = False,
) -> None:
    """Run a scenario with the multi-point model (couplers, in-train forces, distributed power)."""
    try:
        if not scenario.is_file():
            raise InputError("scenario file not found", file=str(scenario))
        run_and_report(scenario, out, as_json, no_plots)
    except TrainsimError as exc:
        typer.echo(f"error: {exc}", err=True)
        raise typer.Exit(code=2) from None


app = typer.Typer(add_completion=False, pretty_exceptions_enable=False)
app.command("multipoint")(multipoint)
