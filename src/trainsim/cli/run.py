"""The ``trainsim`` command line: run a scenario, check an input file, analyse a train's acceleration.

A thin layer: it reads files through :mod:`trainsim.io.loader`, runs through the public API and
writes through :mod:`trainsim.io.export` and :mod:`trainsim.plots`. User errors (bad input, missing
files) end with one ``error: ...`` paragraph on stderr and exit code 2, never a traceback.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Iterator
from contextlib import contextmanager
from enum import StrEnum
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from trainsim.errors import InputError, TrainsimError

if TYPE_CHECKING:
    from rich.console import Console

    from trainsim.model.scenario import Scenario

# matplotlib, pandas and the file readers are imported inside the commands that need them, so
# that `trainsim --help` and `trainsim check` do not pay for them

app = typer.Typer(
    name="trainsim",
    help="Train performance calculator: fastest runs, energy, line current and plots.",
    no_args_is_help=True,
    add_completion=False,
    # a traceback is only ever shown for a bug; plain tracebacks are easier to report than rich ones
    pretty_exceptions_enable=False,
)

#: Exit code of every user error (bad input, missing file, wrong options); click uses 2 for usage errors.
USER_ERROR = 2


class MassModel(StrEnum):
    """How line resistance applies over the train (railtoolkit / TrainRuns.jl ``massModel``)."""

    mass_point = "mass_point"
    homogeneous_strip = "homogeneous_strip"


def _fail(message: str) -> typer.Exit:
    # click.echo, not rich: rich would wrap the message into several lines at the terminal width
    typer.echo(f"error: {message}", err=True)
    return typer.Exit(code=USER_ERROR)


@contextmanager
def _user_errors() -> Iterator[None]:
    """Turn trainsim's errors and file-system errors into ``error: ...`` and exit code 2."""
    try:
        yield
    except TrainsimError as exc:
        raise _fail(str(exc)) from None
    except OSError as exc:
        where = f"{exc.filename}: " if exc.filename else ""
        raise _fail(f"{where}{exc.strerror or exc}") from None


def _require_file(path: Path, what: str) -> None:
    if not path.exists():
        raise InputError(f"{what} not found", file=str(path))
    if not path.is_file():
        raise InputError(f"{what} is not a file", file=str(path))


def _console() -> Console:
    from rich.console import Console

    console = Console()
    if not console.is_terminal:
        # piped or captured output: the default 80 columns would fold the section table
        console = Console(width=160)
    return console


def _load_scenario(
    scenario: Path | None, train: Path | None, route: Path | None, mass_model: MassModel | None
) -> Scenario:
    from trainsim.io import loader

    if scenario is not None:
        if train is not None or route is not None:
            raise InputError("give a scenario file or --train and --route, not both")
        if mass_model is not None:
            raise InputError(
                "--mass-model applies to a route given with --route; "
                "a scenario file says itself how its route is read"
            )
        _require_file(scenario, "scenario file")
        return loader.load_scenario(scenario)
    if train is None or route is None:
        raise InputError("give a scenario file, or both --train and --route")
    _require_file(train, "train file")
    _require_file(route, "route file")
    if mass_model is None:
        return loader.scenario_from_files(train, route)
    from trainsim.model.scenario import Scenario

    t = loader.load_train(train)
    r = loader.load_route(route, mass_model=mass_model.value)
    return Scenario(name=f"{t.name} on {r.name}", train=t, route=r)


@app.command()
def run(
    scenario: Annotated[
        Path | None,
        typer.Argument(
            help="Scenario file (trainsim YAML); or give --train and --route.", show_default=False
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
        bool, typer.Option("--json", help="Print only the summary as JSON on stdout.")
    ] = False,
    step: Annotated[
        float | None,
        typer.Option("--step", help="Largest integration step in metres (overrides the scenario)."),
    ] = None,
    no_plots: Annotated[bool, typer.Option("--no-plots", help="Do not write PNG plots with --out.")] = False,
) -> None:
    """Simulate the fastest run of a train over a route, stopping at its stations."""
    with _user_errors():
        if scenario is not None and train is None and route is None and scenario.is_file():
            from trainsim.io.trainsim_yaml import read_yaml

            data = read_yaml(scenario)
            if isinstance(data, dict) and data.get("model") == "multi_point":
                from trainsim.cli_multipoint import run_and_report

                run_and_report(scenario, out, as_json, no_plots)
                return
        scn = _load_scenario(scenario, train, route, mass_model)
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

    if as_json:
        typer.echo(json.dumps(result.summary(), indent=2, allow_nan=False))
        return
    from trainsim.io.export import summary_table

    console = _console()
    console.print(summary_table(result))
    console.print(
        f"total time {result.total_time_s:.1f} s (running {result.running_time_s:.1f} s, "
        f"dwell {result.dwell_s:.0f} s), net energy {result.energy_kwh.net:.2f} kWh"
    )
    for warning in result.warnings:
        typer.echo(f"warning: {warning}", err=True)
    for path in written:
        console.print(f"wrote {path}", markup=False, highlight=False)


@app.command()
def check(
    file: Annotated[Path, typer.Argument(help="Train, route or scenario file, any supported format.")],
) -> None:
    """Read a file and print what it holds, or why it cannot be used."""
    with _user_errors():
        _require_file(file, "file")
        from trainsim.io import loader

        report = loader.check_file(file)
    # plain text: file names and figures may hold '[...]' that rich would take for markup
    typer.echo(report.to_text())


@app.command("analyze-acceleration")
def analyze_acceleration(
    train: Annotated[Path, typer.Argument(help="Train file (format detected).")],
    power_kw: Annotated[float, typer.Option("--power-kw", help="Nominal traction power P_nom in kW.")],
    efficiency: Annotated[
        float, typer.Option("--efficiency", help="Nominal-to-wheel efficiency eta (0 < eta <= 1).")
    ],
    dt: Annotated[float, typer.Option("--dt", help="Time step of the speed increment in seconds.")] = 1.0,
    out: Annotated[
        Path | None, typer.Option("--out", "-o", help="Directory for acceleration_analysis.png.")
    ] = None,
) -> None:
    """Source 001's power-limited acceleration analysis: P_available(v), dv(v) and the balancing speed."""
    from trainsim.constants import KMH, KW

    with _user_errors():
        _require_file(train, "train file")
        from trainsim.analysis.acceleration import acceleration_analysis
        from trainsim.io import loader

        t = loader.load_train(train)
        analysis = acceleration_analysis(t, power_kw * KW, efficiency, dt_s=dt)
        written: Path | None = None
        if out is not None:
            from trainsim.plots import plot_acceleration_analysis

            out.mkdir(parents=True, exist_ok=True)
            written = out / "acceleration_analysis.png"
            plot_acceleration_analysis(analysis).savefig(written, dpi=120)

    from rich.table import Table
    from rich.text import Text

    console = _console()
    vb = analysis.balancing_speed_mps
    console.print(
        f"{t.name}: P_nom {power_kw:g} kW, efficiency {efficiency:g}, k {analysis.mass_factor:g}",
        markup=False,
        highlight=False,
    )
    if vb is None:
        console.print("balancing speed: none (the resistance never takes the whole power)")
    else:
        note = " (above the train's maximum speed)" if vb > t.max_speed_mps else ""
        console.print(f"balancing speed: {vb / KMH:.1f} km/h{note}", highlight=False)
    table = Table(title="available power and speed increment")
    for name in ("speed [km/h]", "P_available [kW]", f"dv in {dt:g} s [m/s]", "mean acceleration [m/s²]"):
        table.add_column(Text(name), justify="right")  # Text: '[km/h]' is not markup
    n = len(analysis.speed_mps)
    for k in sorted({*range(0, n, max(1, n // 10)), n - 1}):
        table.add_row(
            f"{analysis.speed_mps[k] / KMH:.1f}",
            f"{analysis.available_power_w[k] / KW:.0f}",
            f"{analysis.delta_v_mps[k]:.3f}",
            f"{analysis.mean_acceleration_mps2[k]:.3f}",
        )
    console.print(table)
    if written is not None:
        console.print(f"wrote {written}", markup=False, highlight=False)


if __name__ == "__main__":  # pragma: no cover
    app()


def _register_extensions() -> None:
    """Commands that live in their own modules (each a thin layer over its part of the API)."""
    from trainsim import cli_interchange
    from trainsim.cli_batch import batch
    from trainsim.cli_multipoint import multipoint
    from trainsim.cli_optimize import optimize
    from trainsim.cli_web import serve

    app.command("optimize")(optimize)
    app.command("serve")(serve)
    app.command("convert")(cli_interchange.convert)
    app.command("export-results")(cli_interchange.export_results)
    app.command("runtimes")(cli_interchange.runtimes)
    app.command("multipoint")(multipoint)
    app.command("batch")(batch)


_register_extensions()
