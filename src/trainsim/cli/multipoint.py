"""Multi-point runs on the command line: ``trainsim run`` dispatches here when a scenario says
``model: multi_point``; ``trainsim multipoint SCENARIO`` (hidden, kept for scripts) does the same.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from trainsim.cli.context import exit_for_status, require_input, user_errors
from trainsim.errors import InputError

if TYPE_CHECKING:
    import numpy as np

__all__ = ["multipoint", "run_and_report", "write_multipoint_outputs"]


def write_multipoint_outputs(result, out: Path, *, plots: bool = True) -> list[Path]:
    """Write ``trace.csv`` and ``summary.json`` (as for a single-point run, the summary with its
    ``multi_point`` block), ``coupler_forces.csv`` (kN, one column per coupling, one row per recorded
    instant), ``vehicle_speeds.csv`` (km/h, one column per vehicle) and, with ``plots``, the coupler
    heat map, the force at the worst couplings and the vehicle speeds as PNG files."""
    import numpy as np

    from trainsim.constants import KMH
    from trainsim.io.export import write_trace_csv

    out.mkdir(parents=True, exist_ok=True)
    written = [write_trace_csv(result.run, out / "trace.csv")]
    path = out / "summary.json"
    path.write_text(json.dumps(result.summary(), indent=2, allow_nan=False))
    written.append(path)
    time_s = np.round(result.time_s, 6)
    forces = result.coupler_force_n / 1e3
    written.append(
        _write_table(
            out / "coupler_forces.csv", time_s, forces, [f"c{k}_kn" for k in range(forces.shape[1])], "%.3f"
        )
    )
    speeds = result.speed_mps / KMH
    written.append(
        _write_table(
            out / "vehicle_speeds.csv", time_s, speeds, [f"v{i}_kmh" for i in range(speeds.shape[1])], "%.4f"
        )
    )
    if plots:
        from trainsim.multipoint.plots import save_multipoint_plots

        written += save_multipoint_plots(result, out)
    return written


def _write_table(
    path: Path, time_s: np.ndarray, values: np.ndarray, columns: list[str], number_format: str
) -> Path:
    """A CSV table: a ``time_s`` column, then one column per name, every number (the time too) written
    with ``number_format`` and NaN as an empty field; the same bytes as pandas' ``DataFrame.to_csv``
    with that ``float_format`` wrote before, without importing pandas (0.4 s CPU per process)."""
    with path.open("w", encoding="utf-8", newline="") as f:
        f.write(",".join(["time_s", *columns]) + "\n")
        for t, row in zip(time_s.tolist(), values.tolist(), strict=True):
            cells = ["" if math.isnan(v) else number_format % v for v in (t, *row)]
            f.write(",".join(cells) + "\n")
    return path


def run_and_report(scenario_path: Path, out: Path | None, as_json: bool, no_plots: bool) -> str:
    """Run a scenario file with the multi-point model and print the summary; returns its status."""
    from trainsim.io.multipoint_spec import load_multipoint_scenario, run_multipoint_scenario

    scenario, spec = load_multipoint_scenario(scenario_path)
    if spec is None:
        raise InputError(
            "this scenario does not choose the multi-point model; add 'model: multi_point'",
            file=str(scenario_path),
            field="model",
        )
    # the multi-point kernel is compiled at install (multipoint/_mp_c.pyx): no numba, no first-compile note
    result = run_multipoint_scenario(scenario, spec, base_dir=scenario_path.parent)
    written = write_multipoint_outputs(result, out, plots=not no_plots) if out is not None else []
    summary = result.summary()
    if as_json:
        typer.echo(json.dumps(summary, indent=2, allow_nan=False))
        return str(summary["status"])
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
    if summary["status"] != "ok":
        typer.echo(f"status: {summary['status']}")
    for path in written:
        typer.echo(f"wrote {path}")
    return str(summary["status"])


def multipoint(
    scenario: Annotated[Path, typer.Argument(help="Scenario file with 'model: multi_point'.")],
    out: Annotated[
        Path | None,
        typer.Option("--out", "-o", help="Directory for trace, summary, coupler forces and plots."),
    ] = None,
    as_json: Annotated[
        bool, typer.Option("--json/--no-json", help="Print only the summary as JSON.")
    ] = False,
    plots: Annotated[bool, typer.Option("--plots/--no-plots", help="Write PNG plots with --out.")] = True,
) -> None:
    """Run a scenario with the multi-point model (the same as `trainsim run` on such a scenario)."""
    with user_errors():
        require_input(scenario, "scenario file")
        if scenario.is_dir():
            # trainsim check reads a CSV folder as a train and a route (issue 13): say why it is no
            # multi-point scenario, as for a trainsim scenario without 'model: multi_point'
            raise InputError(
                "a folder of CSV tables is a train and a route, not a multi-point scenario; write a scenario "
                "file with 'model: multi_point' that names them",
                file=str(scenario),
                field="model",
            )
        status = run_and_report(scenario, out, as_json, not plots)
    exit_for_status(status)
