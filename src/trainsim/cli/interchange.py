"""Command functions for data interchange: ``convert``, ``check`` (every format, railML and
spreadsheets included), ``export-results`` and ``runtimes``.

Listed in :data:`trainsim.cli.app.COMMANDS`. User errors end with one ``error: ...`` paragraph on
stderr and exit code 2, as the other commands.
"""

from __future__ import annotations

import json
from enum import StrEnum
from pathlib import Path
from typing import Annotated, Any

import typer

from trainsim.cli.context import user_errors
from trainsim.errors import InputError

__all__ = ["check", "convert", "export_results", "runtimes"]


class Kind(StrEnum):
    train = "train"
    route = "route"
    scenario = "scenario"


class CurveFormula(StrEnum):
    roeckl = "roeckl"
    wang = "wang"
    tbt1407 = "tbt1407"
    french800 = "french800"
    none = "none"


class TunnelFormula(StrEnum):
    wang = "wang"
    tbt1407 = "tbt1407"
    none = "none"


class GradientFormula(StrEnum):
    small_angle = "small_angle"
    exact = "exact"


class ApplyOver(StrEnum):
    head = "head"
    train_length = "train_length"


TrainId = Annotated[
    str | None,
    typer.Option(
        "--train-id", help="railML: the timetable train (id, number or name) whose path is the route."
    ),
]
FormationId = Annotated[str | None, typer.Option("--formation-id", help="railML: the formation to read.")]
Ocps = Annotated[
    str | None,
    typer.Option(
        "--ocps",
        help="railML: the operational points of the route, comma-separated ids or names (not a timetable's).",
    ),
]
Curve = Annotated[
    CurveFormula | None, typer.Option("--curve-formula", help="Curve resistance formula of the route.")
]
Tunnel = Annotated[
    TunnelFormula | None, typer.Option("--tunnel-formula", help="Tunnel resistance formula of the route.")
]
Gradient = Annotated[
    GradientFormula | None,
    typer.Option("--gradient-formula", help="Gradient resistance: small_angle or exact."),
]
Over = Annotated[
    ApplyOver | None,
    typer.Option("--apply-over", help="Line resistance at the head or over the train length."),
]
Rho = Annotated[
    float | None,
    typer.Option(
        "--rotating-mass-factor", help="railML: the train's rotating mass factor when the vehicles give none."
    ),
]


#: The reader options a command may take, in the order ``check`` names the first one given.
_READER_OPTIONS = (
    "train_id",
    "formation_id",
    "ocps",
    "curve_formula",
    "tunnel_formula",
    "gradient_formula",
    "apply_over",
    "rotating_mass_factor",
)


def _options(params: dict[str, Any]) -> dict[str, Any]:
    """The reader options among a command's parameters (pass its ``locals()``): the ones given,
    enumerations as their values. One place, so that the four commands cannot drift apart."""
    options = {k: params.get(k) for k in _READER_OPTIONS}
    return {k: v.value if isinstance(v, StrEnum) else v for k, v in options.items() if v is not None}


def convert(
    inp: Annotated[
        Path, typer.Argument(help="railML 2/3, a workbook or CSV folder, trainsim or railtoolkit YAML.")
    ],
    out: Annotated[Path, typer.Argument(help="The trainsim YAML file to write.")],
    kind: Annotated[
        Kind | None,
        typer.Option(
            "--kind", help="What to write (default: scenario if the input has a train and a route)."
        ),
    ] = None,
    train_id: TrainId = None,
    formation_id: FormationId = None,
    ocps: Ocps = None,
    curve_formula: Curve = None,
    tunnel_formula: Tunnel = None,
    gradient_formula: Gradient = None,
    apply_over: Over = None,
    rotating_mass_factor: Rho = None,
) -> None:
    """Convert any readable input to trainsim's YAML (a train, a route, or a scenario with both)."""
    with user_errors():
        from trainsim.io import convert as conv

        if not inp.exists():
            raise InputError("input not found", file=str(inp))
        options = _options(locals())
        path, notes = conv.convert(inp, out, kind=kind.value if kind else None, **options)
    for note in notes:
        typer.echo(f"note: {note}")
    typer.echo(f"wrote {path}")


def _check_study(path: Path):  # -> trainsim.io.report.CheckReport
    from trainsim.batch import load_study
    from trainsim.io.report import CheckReport

    study = load_study(path)
    expansion = study.expand()
    figures = {
        "runs": f"{len(expansion):,}",
        "parameters": ", ".join(c.name for c in expansion.columns) or "(none)",
    }
    return CheckReport(str(path), "study", "trainsim/study v1", study.name, figures)


def _check_power(path: Path):  # -> trainsim.io.report.CheckReport
    from trainsim.io.power_file import SCHEMA, load_power_file
    from trainsim.io.report import CheckReport

    spec, network, services = load_power_file(path)
    figures = {
        "substations": str(len(network.substations)),
        "tracks": str(len(network.tracks)),
        "train services": str(len(services)),
    }
    return CheckReport(str(path), "power supply", f"{SCHEMA} v1", spec.name, figures)


def register_checkers() -> None:
    """Let ``trainsim check`` read the files of the layers above io: studies, operations, power."""
    from trainsim.io import loader
    from trainsim.io.operation_file import SCHEMA as OPERATION
    from trainsim.io.operation_file import check_operation

    loader.register_checker("trainsim/study", _check_study)
    loader.register_checker(OPERATION, check_operation)
    loader.register_checker("trainsim/power", _check_power)


def check(
    file: Annotated[
        Path,
        typer.Argument(
            help="Train, route or scenario file, any supported format (railML, spreadsheets too)."
        ),
    ],
    train_id: TrainId = None,
    formation_id: FormationId = None,
    ocps: Ocps = None,
    curve_formula: Curve = None,
    tunnel_formula: Tunnel = None,
    gradient_formula: Gradient = None,
    apply_over: Over = None,
    rotating_mass_factor: Rho = None,
) -> None:
    """Read a file and print what it holds, what was read and what was not (with lines), or why it is
    not usable."""
    with user_errors():
        from trainsim.io import convert as conv
        from trainsim.io import loader

        if not file.exists():
            raise InputError("file not found", file=str(file))
        options = _options(locals())
        report = conv.check_file(file, **options)
        if report is None:
            if options:
                raise InputError(
                    "these options apply to railML and spreadsheet files",
                    file=str(file),
                    field=next(iter(options)),
                )
            register_checkers()
            report = loader.check_file(file)
    typer.echo(report.to_text())


def _scenario(inputs: list[Path], options: dict[str, Any]) -> Any:
    """A scenario from one file (scenario, or railML / spreadsheet with train and route) or from
    a train file and a route file."""
    from trainsim.io import convert as conv
    from trainsim.io import loader
    from trainsim.model.scenario import Scenario

    for p in inputs:
        if not p.exists():
            raise InputError("input not found", file=str(p))
    if len(inputs) == 1:
        loaded = conv.detect_and_load(inputs[0], "scenario", **options)
        return loaded if loaded is not None else loader.load_scenario(inputs[0])
    if len(inputs) != 2:
        raise InputError("give one scenario file, or a train file and a route file")
    train = conv.detect_and_load(inputs[0], "train", **options) or loader.load_train(inputs[0])
    route = conv.detect_and_load(inputs[1], "route", **options) or loader.load_route(inputs[1])
    return Scenario(name=f"{train.name} on {route.name}", train=train, route=route)


def export_results(
    inputs: Annotated[
        list[Path], typer.Argument(help="A scenario (any format), or a train file and a route file.")
    ],
    out: Annotated[Path, typer.Option("--out", "-o", help="Directory for trace.* and summary.*.")],
    formats: Annotated[
        str, typer.Option("--format", help="Comma-separated: csv, parquet, json.")
    ] = "csv,parquet,json",
    train_id: TrainId = None,
    formation_id: FormationId = None,
    ocps: Ocps = None,
    curve_formula: Curve = None,
    tunnel_formula: Tunnel = None,
    gradient_formula: Gradient = None,
    apply_over: Over = None,
    rotating_mass_factor: Rho = None,
) -> None:
    """Run the fastest run and write its trace and summary as CSV, Parquet and/or JSON."""
    with user_errors():
        import trainsim
        from trainsim.io import results_export

        chosen = [f.strip().lower() for f in formats.split(",") if f.strip()]
        for f in chosen:
            if f not in results_export.FORMATS:
                raise InputError(
                    "unknown format", field="--format", value=f, allowed=", ".join(results_export.FORMATS)
                )
        options = _options(locals())
        scenario = _scenario(inputs, options)
        result = trainsim.run(scenario)
        written = results_export.write_results(result, out, chosen)
    typer.echo(json.dumps({"running_time_s": result.running_time_s, "energy_net_kwh": result.energy_kwh.net}))
    for p in written:
        typer.echo(f"wrote {p}")


def runtimes(
    railml: Annotated[
        Path, typer.Argument(help="railML 2 or 3 file with infrastructure, rolling stock and a timetable.")
    ],
    out: Annotated[Path, typer.Argument(help="The railML file to write (a copy with the running times).")],
    train_id: TrainId = None,
    formation_id: FormationId = None,
    curve_formula: Curve = None,
    tunnel_formula: Tunnel = None,
    gradient_formula: Gradient = None,
    apply_over: Over = None,
    rotating_mass_factor: Rho = None,
    train: Annotated[
        Path | None, typer.Option("--train", help="Run another train (any format) on the timetable's path.")
    ] = None,
) -> None:
    """Run the fastest run of a railML timetable train and write its running times back into the timetable
    (runTimes@minimalTime and times@scope='calculated')."""
    with user_errors():
        import trainsim
        from trainsim.io import convert as conv
        from trainsim.io import loader, results_export
        from trainsim.model.scenario import Scenario

        if not railml.exists():
            raise InputError("input not found", file=str(railml))
        options = _options(locals())
        route = conv.detect_and_load(railml, "route", **options)
        if route is None:
            raise InputError("not a railML file", file=str(railml))
        if train is not None:
            t = conv.detect_and_load(train, "train") or loader.load_train(train)
        else:
            t = conv.detect_and_load(railml, "train", **options)
        result = trainsim.run(Scenario(name=f"{t.name} on {route.name}", train=t, route=route))
        path = results_export.write_running_times_railml(result, railml, out, train_id=train_id)
    typer.echo(f"running time {result.running_time_s:.1f} s, net energy {result.energy_kwh.net:.2f} kWh")
    typer.echo(f"wrote {path}")
