"""``trainsim run``: the fastest run of a scenario (or of a train file on a route file), with its
summary, trace, plots; a scenario with ``model: multi_point`` runs with the multi-point model, and one
with a ``driving`` block is driven by its strategy."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Annotated

import typer

from trainsim.cli.context import (
    MassModel,
    console,
    echo_warnings,
    exit_for_status,
    load_scenario,
    readers,
    user_errors,
)


def run(
    scenario: Annotated[
        Path | None,
        typer.Argument(
            help="Scenario: trainsim YAML, railML, a workbook or a folder of CSV tables; or give --train and "
            "--route.",
            show_default=False,
        ),
    ] = None,
    train: Annotated[Path | None, typer.Option("--train", "-t", help="Train file (format detected).")] = None,
    route: Annotated[Path | None, typer.Option("--route", "-r", help="Route file (format detected).")] = None,
    mass_model: Annotated[
        MassModel | None,
        typer.Option(
            "--mass-model", help="Line resistance at the head or over the train (railtoolkit routes)."
        ),
    ] = None,
    out: Annotated[
        Path | None, typer.Option("--out", "-o", help="Directory for trace.csv, summary.json and the plots.")
    ] = None,
    as_json: Annotated[
        bool, typer.Option("--json/--no-json", help="Print only the summary as JSON on stdout.")
    ] = False,
    step: Annotated[
        float | None,
        typer.Option("--step", help="Largest integration step in metres (overrides the scenario)."),
    ] = None,
    plots: Annotated[bool, typer.Option("--plots/--no-plots", help="Write PNG plots with --out.")] = True,
) -> None:
    """Simulate the fastest run of a train over a route, stopping at its stations.

    A scenario with 'model: multi_point' runs with the multi-point model (couplers, in-train forces);
    one with a 'driving' block is driven by its strategy to its timetable. Exit code 3 when the run's
    status is not ok (the summary says why).
    """
    no_plots = not plots
    with user_errors():
        if scenario is not None and train is None and route is None and scenario.is_file():
            readers()
            from trainsim.io.trainsim_yaml import read_yaml

            data = read_yaml(scenario)
            if isinstance(data, dict) and data.get("model") == "multi_point":
                from trainsim.cli.multipoint import run_and_report

                status = run_and_report(scenario, out, as_json, no_plots)
                exit_for_status(status)
                return
        scn = load_scenario(scenario, train, route, mass_model)
        if step is not None:
            # RunSettings validates on construction, so a bad step is an InputError like any other
            scn = dataclasses.replace(scn, settings=dataclasses.replace(scn.settings, max_step_m=step))
        import trainsim

        result = trainsim.run(scn)
        written: list[Path] = []
        if out is not None:
            from trainsim.io.export import write_summary_json, write_trace_csv

            out.mkdir(parents=True, exist_ok=True)
            written.append(write_trace_csv(result, out / "trace.csv"))
            written.append(write_summary_json(result, out / "summary.json"))
            if not no_plots:
                from trainsim.plots import save_all

                written += save_all(result, scn.route, scn.train, out)

    summary = result.summary()
    if as_json:
        typer.echo(json.dumps(summary, indent=2, allow_nan=False))
        exit_for_status(summary["status"])
        return
    from trainsim.io.export import summary_table

    out_console = console()
    out_console.print(summary_table(result))
    out_console.print(
        f"total time {result.total_time_s:.1f} s (running {result.running_time_s:.1f} s, "
        f"dwell {result.dwell_s:.0f} s), net energy {result.energy_kwh.net:.2f} kWh"
    )
    if summary["status"] != "ok":
        out_console.print(f"status: {summary['status']}", markup=False, highlight=False)
    echo_warnings(list(result.warnings))
    for path in written:
        out_console.print(f"wrote {path}", markup=False, highlight=False)
    exit_for_status(summary["status"])
